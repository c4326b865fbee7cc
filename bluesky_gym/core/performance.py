"""OpenAP performance as BlueSky 1.1.1 applies it, for every type [docs/dynamics.md §1.2-1.5].

The model supplies three things to the kinematics: the flight phase, the speed envelope of that
phase, and the maximum longitudinal acceleration ``axmax`` from maximum thrust and drag. It is
evaluated from the state at the *start* of a simulation step, before the autopilot runs
(:func:`performance`, a scalar kernel called by the step kernel). The same update gives the
aircraft's drag, net thrust and fuel flow (:func:`fuel_flow`), outputs that nothing in the
kinematics reads [docs/dynamics.md §1.4a]. A rotorcraft (``AircraftPerformance.rotor``) has none
of this: BlueSky's rotor model keeps its envelope fixed, its phase NA and its ``axmax`` at
:data:`AXMAX_ROTOR`, and computes no drag, thrust or fuel flow [docs/dynamics.md §1.2b].
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from bluesky_gym.core.atmosphere import GAMMA_R, isa, tas2cas_at
from bluesky_gym.core.jit import jit, python_form
from bluesky_gym.core.units import FPM, FT, G0, P0

# OpenAP flight phases.
PHASE_NA, PHASE_GD, PHASE_IC, PHASE_CL, PHASE_CR, PHASE_DE, PHASE_AP = range(7)
AXMAX_GROUND = 2.0  # m/s^2, BlueSky's fixed-wing maximum acceleration on the ground
AXMAX_FLOOR = 0.5  # m/s^2, BlueSky's global minimum of axmax
AXMAX_ROTOR = 3.5  # m/s^2, BlueSky's axmax of every rotorcraft (from its first performance update on)
AXMAX_CREATED = 2.0  # m/s^2, BlueSky's axmax of a new aircraft whose model sets none (a rotorcraft), until the first update


@dataclass(frozen=True)
class AircraftPerformance:
    """Constant performance data of one aircraft type, as BlueSky 1.1.1's OpenAP model loads it.

    Built from the ``openap`` package's files by :func:`bluesky_gym.core.aircraft.aircraft_performance`
    (the only source of these numbers); see docs/dynamics.md §1.2.
    """

    name: str  # type designator the data is filed under, e.g. "A320" (a synonym keeps its own name)
    mass: float  # kg, (OEW + MTOW) / 2
    wing_area: float  # m^2
    engine_count: int
    engine_max_thrust: float  # N, static, per engine
    bypass_ratio: float
    cd0_clean: float
    k_clean: float
    cd0_takeoff: float
    k_takeoff: float
    cd0_gear: float
    cd0_landing: float
    k_landing: float
    vmin_enroute: float  # m/s CAS; a rotorcraft's whole envelope is in TAS (BlueSky's perf.vmin/vmax of its rotor model)
    vmax_enroute: float  # m/s CAS (a rotorcraft: TAS)
    vmin_approach: float  # m/s CAS
    vmax_approach: float  # m/s CAS
    vmax_ground: float  # m/s CAS (OpenAP's initial-climb maximum, used on the ground)
    v_rotate: float  # m/s TAS (OpenAP's minimum take-off speed); on the ground vs is forced to 0 below it
    hmax: float  # m, ceiling
    vsmax: float  # m/s
    vsmin: float  # m/s: OpenAP's smallest climb rate, BlueSky's perf.vsmin (used by conflict resolution); a rotorcraft's fastest descent (< 0)
    mmo: float  # maximum Mach number
    axmax_initial: float  # m/s^2 until the first performance update (WRAP's maximum take-off acceleration)
    fuel_a: float  # kg/s per engine: quadratic coefficient of the fuel flow in the thrust ratio (ICAO fit)
    fuel_b: float  # kg/s per engine: linear coefficient
    fuel_c: float  # kg/s per engine: constant term
    axmax_ground: float = AXMAX_GROUND  # m/s^2
    axmax_floor: float = AXMAX_FLOOR  # m/s^2
    rotor: bool = False  # BlueSky's rotor model (lift type "rotor"): the fixed-wing quantities above are NaN

    @property
    def static_thrust(self) -> float:
        """Total static maximum thrust [N]."""
        return float(self.engine_count * self.engine_max_thrust)


def perf_tuple(perf: AircraftPerformance) -> tuple[float, ...]:
    """The performance constants in the argument order of :func:`performance` (columns 0-18 of a table row)."""
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


def limit_tuple(perf: AircraftPerformance) -> tuple[float, float, float, float, float, float, float, float, float]:
    """The step kernel's limits (columns 19-27 of a table row).

    In order: hmax, vsmax, mmo, v_rotate, the fuel-flow coefficients (a, b, c), vsmin and the
    rotor flag (1.0 for BlueSky's rotor model, else 0.0).
    """
    return (perf.hmax, perf.vsmax, perf.mmo, perf.v_rotate, perf.fuel_a, perf.fuel_b, perf.fuel_c, perf.vsmin, 1.0 if perf.rotor else 0.0)


#: Columns of a row of the performance table: :func:`perf_tuple` then :func:`limit_tuple`.
N_PERF = 19
C_HMAX, C_VSMAX, C_MMO, C_V_ROTATE, C_FUEL_A, C_FUEL_B, C_FUEL_C, C_VSMIN, C_ROTOR = range(N_PERF, N_PERF + 9)
N_COEFFICIENTS = N_PERF + 9


def table_row(perf: AircraftPerformance) -> tuple[float, ...]:
    """One row of the performance table the step kernel reads per aircraft (``N_COEFFICIENTS`` values)."""
    return perf_tuple(perf) + limit_tuple(perf)


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
def performance(tas: float, vs: float, alt: float, perf: tuple[float, ...]) -> tuple[int, float, float, float, float]:
    """OpenAP phase, CAS envelope [m/s], axmax [m/s^2] and drag [N] [docs/dynamics.md §1.3-1.4].

    Includes BlueSky's always-true en-route envelope test (quirk 9.1).

    Args:
        tas: True airspeed [m/s].
        vs: Vertical speed [m/s].
        alt: Altitude [m].
        perf: The aircraft's :func:`perf_tuple`, or its row of the performance table (only the
            first ``N_PERF`` values are read).

    Returns:
        (phase, vmin, vmax, axmax, drag).
    """
    mass = perf[0]
    wing_area = perf[1]
    n_eng = perf[2]
    eng_thr = perf[3]
    bpr = perf[4]
    vmin_er, vmax_er, vmin_ap, vmax_ap, vmax_gd = perf[12], perf[13], perf[14], perf[15], perf[16]
    ax_gd, ax_floor = perf[17], perf[18]
    ph = flight_phase(tas, vs, alt)
    if ph == PHASE_GD:
        vmin, vmax = 0.0, vmax_gd
    elif ph == PHASE_AP:
        vmin, vmax = vmin_ap, vmax_ap
    else:
        vmin, vmax = vmin_er, vmax_er

    if ph == PHASE_GD:
        cd0, k = perf[7] + perf[9], perf[8]  # take-off polar plus gear
    elif ph == PHASE_IC:
        cd0, k = perf[7], perf[8]
    elif ph == PHASE_AP:
        cd0, k = perf[10], perf[11]
    else:
        cd0, k = perf[5], perf[6]
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
    return ph, vmin, vmax, axmax, drag


@jit
def fuel_flow(drag: float, ax: float, mass: float, n_eng: float, eng_thr: float, a: float, b: float, c: float) -> tuple[float, float]:
    """Net thrust [N] and fuel flow [kg/s], as BlueSky 1.1.1's OpenAP update computes them [docs/dynamics.md §1.4a].

    The thrust is what holds the last step's acceleration against the drag, ``T = D + m ax``; the
    fuel flow is ICAO's quadratic fit per engine in the thrust ratio ``T / (n Tmax0)``, times the
    number of engines. BlueSky evaluates them after the drag, with the ``ax`` of the previous step.

    Args:
        drag: Drag [N] (:func:`performance`).
        ax: Longitudinal acceleration of the last step [m/s^2].
        mass: Mass [kg].
        n_eng: Number of engines.
        eng_thr: Static maximum thrust per engine [N].
        a: Quadratic coefficient of the fuel flow per engine [kg/s].
        b: Linear coefficient [kg/s].
        c: Constant term [kg/s].

    Returns:
        (thrust, fuelflow).
    """
    thrust = drag + mass * ax
    ratio = thrust / (n_eng * eng_thr)
    return thrust, n_eng * (a * (ratio * ratio) + b * ratio + c)
