"""OpenAP A320 performance as BlueSky 1.1.1 applies it [docs/dynamics.md §1.2-1.5].

The model supplies three things to the kinematics: the flight phase, the speed envelope of that
phase, and the maximum longitudinal acceleration ``axmax`` from maximum thrust and drag. It is
evaluated from the state at the *start* of a simulation step, before the autopilot runs
(:func:`performance`, a scalar kernel called by the step kernel).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from bluesky_gym.core.atmosphere import GAMMA_R, isa, tas2cas_at
from bluesky_gym.core.jit import jit, python_form
from bluesky_gym.core.units import FPM, FT, G0, P0

# OpenAP flight phases.
PHASE_NA, PHASE_GD, PHASE_IC, PHASE_CL, PHASE_CR, PHASE_DE, PHASE_AP = range(7)


@dataclass(frozen=True)
class AircraftPerformance:
    """Constant performance data of one aircraft type (OpenAP 2.6.2 values as BlueSky loads them)."""

    mass: float = 60300.0  # kg, (OEW + MTOW) / 2
    wing_area: float = 124.0  # m^2
    engine_count: int = 2
    engine_max_thrust: float = 117900.0  # N, static, per engine
    bypass_ratio: float = 5.9
    cd0_clean: float = 0.018
    k_clean: float = 0.039
    cd0_takeoff: float = 0.018932161954476924
    k_takeoff: float = 0.037164510631143066
    cd0_gear: float = 0.017
    cd0_landing: float = 0.023749550672667687
    k_landing: float = 0.0344613704952352
    vmin_enroute: float = 67.0  # m/s CAS
    vmax_enroute: float = 163.0  # m/s CAS
    vmin_approach: float = 67.0  # m/s CAS
    vmax_approach: float = 77.0  # m/s CAS
    vmax_ground: float = 89.0  # m/s CAS (OpenAP's initial-climb maximum, used on the ground)
    v_rotate: float = 74.5  # m/s TAS; on the ground vs is forced to 0 below it
    hmax: float = 11060.0  # m, ceiling
    vsmax: float = 16.04  # m/s
    vsmin: float = 3.6  # m/s: OpenAP's smallest climb rate, BlueSky's perf.vsmin (used by conflict resolution)
    mmo: float = 0.8  # maximum Mach number
    axmax_initial: float = 2.37  # m/s^2 until the first performance update
    axmax_ground: float = 2.0  # m/s^2
    axmax_floor: float = 0.5  # m/s^2

    @property
    def static_thrust(self) -> float:
        """Total static maximum thrust [N]."""
        return float(self.engine_count * self.engine_max_thrust)


A320 = AircraftPerformance()


def perf_tuple(perf: AircraftPerformance) -> tuple[float, ...]:
    """The performance constants in the argument order of :func:`performance`."""
    return (
        perf.mass,
        perf.wing_area,
        float(perf.engine_count),
        perf.engine_max_thrust,
        perf.bypass_ratio,
        perf.cd0_clean,
        perf.k_clean,
        perf.cd0_takeoff,
        perf.k_takeoff,
        perf.cd0_gear,
        perf.cd0_landing,
        perf.k_landing,
        perf.vmin_enroute,
        perf.vmax_enroute,
        perf.vmin_approach,
        perf.vmax_approach,
        perf.vmax_ground,
        perf.axmax_ground,
        perf.axmax_floor,
    )


def limit_tuple(perf: AircraftPerformance) -> tuple[float, float, float, float]:
    """The envelope limits (hmax, vsmax, mmo, v_rotate) as the step kernel takes them."""
    return (perf.hmax, perf.vsmax, perf.mmo, perf.v_rotate)


# Thrust-model reference points: pressure at 10000 ft and 35000 ft, CAS of Mach 0.8 at 35000 ft.
H_10000FT = 10000 * FT  # m
H_35000FT = 35000 * FT  # m
P_10000FT = python_form(isa)(H_10000FT)[0]  # Pa
P_35000FT, _RHO35, _T35 = python_form(isa)(H_35000FT)
VCAS_REF = python_form(tas2cas_at)(0.8 * math.sqrt(GAMMA_R * _T35), P_35000FT, _RHO35)  # m/s
ROC_FPM = 0.00508  # m/s per ft/min, OpenAP's literal (== FPM)
LBF = 4.448  # N per pound-force, OpenAP's literal


@jit
def flight_phase(tas: float, vs: float, alt: float) -> int:
    """OpenAP phase from TAS [m/s], vertical speed [m/s] and altitude [m] [docs/dynamics.md §1.3]."""
    roc = vs / ROC_FPM
    a = alt / FT
    ph = PHASE_NA
    if a <= 75:
        ph = PHASE_GD
    if a >= 75 and a <= 1000 and roc >= 150:
        ph = PHASE_IC
    if a >= 75 and a <= 1000 and roc <= -150:
        ph = PHASE_AP
    if a >= 1000 and roc >= 150:
        ph = PHASE_CL
    if a >= 1000 and roc <= -150:
        ph = PHASE_DE
    if a >= 10000 and roc <= 150 and roc >= -150:
        ph = PHASE_CR
    return ph


@jit
def performance(tas: float, vs: float, alt: float, perf: tuple[float, ...]) -> tuple[int, float, float, float]:
    """OpenAP phase, CAS envelope [m/s] and axmax [m/s^2] [docs/dynamics.md §1.3-1.4].

    Includes BlueSky's always-true en-route envelope test (quirk 9.1).

    Args:
        tas: True airspeed [m/s].
        vs: Vertical speed [m/s].
        alt: Altitude [m].
        perf: The aircraft's :func:`perf_tuple`.

    Returns:
        (phase, vmin, vmax, axmax).
    """
    (
        mass,
        wing_area,
        n_eng,
        eng_thr,
        bpr,
        cd0_clean,
        k_clean,
        cd0_to,
        k_to,
        cd0_gear,
        cd0_ld,
        k_ld,
        vmin_er,
        vmax_er,
        vmin_ap,
        vmax_ap,
        vmax_gd,
        ax_gd,
        ax_floor,
    ) = perf
    ph = flight_phase(tas, vs, alt)
    if ph == PHASE_GD:
        vmin, vmax = 0.0, vmax_gd
    elif ph == PHASE_AP:
        vmin, vmax = vmin_ap, vmax_ap
    else:
        vmin, vmax = vmin_er, vmax_er

    if ph == PHASE_GD:
        cd0, k = cd0_to + cd0_gear, k_to
    elif ph == PHASE_IC:
        cd0, k = cd0_to, k_to
    elif ph == PHASE_AP:
        cd0, k = cd0_ld, k_ld
    else:
        cd0, k = cd0_clean, k_clean
    p, rho, t = isa(alt)
    rhovs = 0.5 * rho * (tas * tas) * wing_area
    cl = mass * G0 / rhovs
    drag = rhovs * (cd0 + k * (cl * cl))

    thr0 = n_eng * eng_thr
    if ph == PHASE_GD:  # take-off thrust ratio
        mach_to = tas / math.sqrt(GAMMA_R * t)
        pp = p / P0
        a_ = -0.4327 * (pp * pp) + 1.3855 * pp + 0.0472
        z_ = 0.9106 * math.pow(pp, 3.0) - 1.7736 * (pp * pp) + 1.8697 * pp
        x_ = 0.1377 * math.pow(pp, 3.0) - 0.4374 * (pp * pp) + 1.3003 * pp
        ratio = (
            a_
            - 0.377 * (1 + bpr) / math.sqrt((1 + 0.82 * bpr) * (0.0606 * bpr + 0.6337)) * z_ * mach_to
            + (0.23 + 0.19 * math.sqrt(bpr)) * x_ * (mach_to * mach_to)
        )
    else:  # in-flight thrust ratio
        roc_fpm = abs(vs / FPM)
        v = 10.0 if tas < 10 else tas
        mach = v / math.sqrt(GAMMA_R * t)
        vcas = tas2cas_at(v, p, rho)
        f35 = (200 + 0.2 * thr0 / LBF) * LBF
        if alt > H_35000FT:
            d = -0.4204 * (mach / 0.8) + 1.0824
            b = math.pow(mach / 0.8, -0.11)
            ratio = d * math.log(p / P_35000FT) + b
        else:
            vratio = vcas / VCAS_REF
            a2 = math.pow(vratio, -0.1)
            n = 2.667e-05 * roc_fpm + 0.8633
            if alt > H_10000FT:
                ratio = a2 * math.pow(p / P_35000FT, -0.355 * vratio + n)
            else:
                f10 = f35 * a2 * math.pow(P_10000FT / P_35000FT, -0.355 * vratio + n)
                m = -1.2043e-1 * vratio - 8.8889e-9 * (roc_fpm * roc_fpm) + 2.4444e-5 * roc_fpm + 4.7379e-1
                ratio = m * (p / P_35000FT) + (f10 / f35 - m * (P_10000FT / P_35000FT))
        ratio = ratio * f35 / thr0
    max_thrust = ratio * n_eng * eng_thr
    axmax = (max_thrust - drag) / mass
    if ph == PHASE_GD:
        axmax = ax_gd
    if axmax < ax_floor:
        axmax = ax_floor
    return ph, vmin, vmax, axmax
