"""Oracle: OpenAP A320 performance as BlueSky 1.1.1 applies it, as readable numpy array code.

The package computes it with the scalar kernel bluesky_gym.core.performance.performance; the
tests compare both to the last bit.

The model supplies three things to the kinematics: the flight phase, the speed envelope of that
phase, and the maximum longitudinal acceleration ``axmax`` from maximum thrust and drag. It is
evaluated from the state at the *start* of a simulation step, before the autopilot runs.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from bluesky_gym.core.aircraft import aircraft_performance
from bluesky_gym.core.performance import PHASE_AP, PHASE_CL, PHASE_CR, PHASE_DE, PHASE_GD, PHASE_IC, AircraftPerformance
from bluesky_gym.core.units import FPM, FT, G0

from . import atmosphere as isa

A320 = aircraft_performance("A320")  # the performance data every oracle function defaults to

Array = NDArray[np.float64]

_FT_10000 = 10000 * FT
_FT_35000 = 35000 * FT
_P10 = isa.vpressure(np.float64(_FT_10000))
_P35 = isa.vpressure(np.float64(_FT_35000))
_VCAS_REF = isa.vtas2cas(isa.vmach2tas(np.float64(0.8), np.float64(_FT_35000)), np.float64(_FT_35000))


def flight_phase(tas: Array, vs: Array, alt: Array) -> NDArray[np.int64]:
    """OpenAP phase from TAS [m/s], vertical speed [m/s] and altitude [m] [docs/dynamics.md §1.3]."""
    roc = vs / 0.00508
    a = alt / 0.3048
    ph = np.zeros(np.shape(alt), dtype=np.int64)
    ph[a <= 75] = PHASE_GD
    low = (a >= 75) & (a <= 1000)
    ph[low & (roc >= 150)] = PHASE_IC
    ph[low & (roc <= -150)] = PHASE_AP
    high = a >= 1000
    ph[high & (roc >= 150)] = PHASE_CL
    ph[high & (roc <= -150)] = PHASE_DE
    ph[(a >= 10000) & (roc <= 150) & (roc >= -150)] = PHASE_CR
    return ph


def speed_envelope(phase: NDArray[np.int64], perf: AircraftPerformance = A320) -> tuple[Array, Array]:
    """CAS envelope [m/s] per phase, including BlueSky's always-true en-route test (quirk 9.1)."""
    gd = phase == PHASE_GD
    ap = phase == PHASE_AP
    vmin = np.where(gd, 0.0, np.where(ap, perf.vmin_approach, perf.vmin_enroute))
    vmax = np.where(gd, perf.vmax_ground, np.where(ap, perf.vmax_approach, perf.vmax_enroute))
    return vmin, vmax


def max_thrust_ratio(phase: NDArray[np.int64], tas: Array, alt: Array, vs: Array, perf: AircraftPerformance = A320) -> Array:
    """Maximum-thrust ratio of OpenAP's thrust model (take-off on ground, in-flight otherwise)."""
    thr0 = perf.static_thrust
    bpr = perf.bypass_ratio
    # Take-off ratio.
    mach_to = isa.vtas2mach(tas, alt)
    pp = isa.vpressure(alt) / isa.P0
    a_ = -0.4327 * pp**2 + 1.3855 * pp + 0.0472
    z_ = 0.9106 * pp**3 - 1.7736 * pp**2 + 1.8697 * pp
    x_ = 0.1377 * pp**3 - 0.4374 * pp**2 + 1.3003 * pp
    ratio_to = (
        a_ - 0.377 * (1 + bpr) / np.sqrt((1 + 0.82 * bpr) * (0.0606 * bpr + 0.6337)) * z_ * mach_to + (0.23 + 0.19 * np.sqrt(bpr)) * x_ * mach_to**2
    )
    # In-flight ratio.
    roc = np.abs(np.asarray(vs / FPM))
    v = np.where(tas < 10, 10, tas)
    p, rho, _ = isa.vatmos(alt)
    mach = isa.vtas2mach(v, alt)
    vcas = isa.tas2cas_from_atmos(v, p, rho)
    f35 = (200 + 0.2 * thr0 / 4.448) * 4.448
    d = -0.4204 * (mach / 0.8) + 1.0824
    b = (mach / 0.8) ** (-0.11)
    ratio_seg3 = d * np.log(p / _P35) + b
    vratio = vcas / _VCAS_REF
    a = vratio ** (-0.1)
    n = 2.667e-05 * roc + 0.8633
    ratio_seg2 = a * (p / _P35) ** (-0.355 * vratio + n)
    f10 = f35 * a * (_P10 / _P35) ** (-0.355 * vratio + n)
    m = -1.2043e-1 * vratio - 8.8889e-9 * roc**2 + 2.4444e-5 * roc + 4.7379e-1
    ratio_seg1 = m * (p / _P35) + (f10 / f35 - m * (_P10 / _P35))
    ratio = np.where(alt > _FT_35000, ratio_seg3, np.where(alt > _FT_10000, ratio_seg2, ratio_seg1))
    ratio_inflight = ratio * f35 / thr0
    return np.where(phase == PHASE_GD, ratio_to, ratio_inflight)


def drag(phase: NDArray[np.int64], tas: Array, alt: Array, perf: AircraftPerformance = A320) -> Array:
    """Drag [N] = qS (cd0 + k CL^2), with the polar of the phase [docs/dynamics.md §1.4]."""
    gd = phase == PHASE_GD
    ap = phase == PHASE_AP
    ic = phase == PHASE_IC
    cd0 = np.where(gd, perf.cd0_takeoff + perf.cd0_gear, np.where(ic, perf.cd0_takeoff, np.where(ap, perf.cd0_landing, perf.cd0_clean)))
    k = np.where(gd | ic, perf.k_takeoff, np.where(ap, perf.k_landing, perf.k_clean))
    rho = isa.vdensity(alt)
    rhovs = 0.5 * rho * tas**2 * perf.wing_area
    cl = perf.mass * G0 / rhovs
    return rhovs * (cd0 + k * cl**2)


def thrust_and_fuel_flow(drag: Array, ax: Array, perf: AircraftPerformance = A320) -> tuple[Array, Array]:
    """Net thrust [N] = D + m ax and fuel flow [kg/s] = n (a r^2 + b r + c), r = T / (n Tmax0) [docs/dynamics.md §1.4a]."""
    thrust = drag + perf.mass * ax
    ratio = thrust / (perf.engine_count * perf.engine_max_thrust)
    return thrust, perf.engine_count * (perf.fuel_a * ratio**2 + perf.fuel_b * ratio + perf.fuel_c)


def max_acceleration(phase: NDArray[np.int64], tas: Array, alt: Array, vs: Array, perf: AircraftPerformance = A320) -> Array:
    """Maximum longitudinal acceleration ``axmax`` [m/s^2] = (Tmax - D) / m [docs/dynamics.md §1.4]."""
    gd = phase == PHASE_GD
    d = drag(phase, tas, alt, perf)
    max_thrust = max_thrust_ratio(phase, tas, alt, vs, perf) * perf.engine_count * perf.engine_max_thrust
    axmax = (max_thrust - d) / perf.mass
    axmax = np.where(gd, perf.axmax_ground, axmax)
    return np.where(axmax < perf.axmax_floor, perf.axmax_floor, axmax)


def apply_limits(
    tas_target: Array,
    vs_target: Array,
    alt_target: Array,
    ax: Array,
    tas: Array,
    phase: NDArray[np.int64],
    vmin: Array,
    vmax: Array,
    axmax: Array,
    perf: AircraftPerformance = A320,
) -> tuple[Array, Array, Array]:
    """Clip autopilot targets to the envelope, evaluated at the *target* altitude (quirk 9.3).

    Returns:
        Allowed TAS [m/s], allowed vertical-speed magnitude [m/s] and allowed altitude [m].
    """
    allow_h = np.where(alt_target > perf.hmax, perf.hmax, alt_target)
    p, rho, t = isa.vatmos(allow_h)
    intent_cas = isa.tas2cas_from_atmos(tas_target, p, rho)
    allow_cas = np.where(intent_cas < vmin, vmin, intent_cas)
    allow_cas = np.where(intent_cas > vmax, vmax, allow_cas)
    allow_tas = isa.cas2tas_from_atmos(allow_cas, p, rho)
    sound = np.sqrt(isa.GAMMA * isa.R_AIR * t)
    allow_tas = np.where(allow_tas / sound > perf.mmo, perf.mmo * sound, allow_tas)
    vs_max_with_acc = (1 - ax / axmax) * perf.vsmax
    allow_vs = np.where((vs_target > 0) & (vs_target > perf.vsmax), vs_max_with_acc, vs_target)
    allow_vs = np.where((phase == PHASE_GD) & (tas < perf.v_rotate), 0, allow_vs)
    # Rotorcraft: TAS and vertical speed clipped to the rotor envelope as they are [docs/dynamics.md §1.2b].
    rotor_tas = np.where(tas_target < vmin, vmin, tas_target)
    rotor_tas = np.where(tas_target > vmax, vmax, rotor_tas)
    rotor_vs = np.where(vs_target < perf.vsmin, perf.vsmin, vs_target)
    rotor_vs = np.where(vs_target > perf.vsmax, perf.vsmax, rotor_vs)
    allow_tas = np.where(perf.rotor, rotor_tas, allow_tas)
    allow_vs = np.where(perf.rotor, rotor_vs, allow_vs)
    return allow_tas, allow_vs, allow_h
