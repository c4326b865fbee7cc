"""The simulation step: every aircraft advanced by ``dt`` in BlueSky 1.1.1's update order [docs/dynamics.md §2].

:func:`step_one` is the whole per-aircraft sub-step (performance update, autopilot, performance
limits, speed, heading, vertical speed, ground speed with wind, position), compiled with numba so
that each aircraft's values stay in registers and every transcendental is evaluated once. It uses
the scalar kernels of :mod:`~bluesky_gym.core.atmosphere` and
:mod:`~bluesky_gym.core.performance`, the same C math library functions in the same order as
BlueSky's numpy code, without floating-point contraction, so results are BlueSky's to the last bit
(the tests compare them with a readable numpy form of the step, and with BlueSky itself).

:func:`step_kernel` advances all aircraft by one step; :func:`run_kernel` advances each aircraft
through several steps while it sits in the CPU cache (valid while aircraft do not interact).
"""

from __future__ import annotations

import math

import numpy as np

from bluesky_gym.core.atmosphere import GAMMA_R, cas2tas_at, is_mach, isa, tas2cas_at
from bluesky_gym.core.jit import grid_range, jit, jit_inline, rint, scratch
from bluesky_gym.core.lnav import lnav_one
from bluesky_gym.core.performance import (
    AXMAX_ROTOR,
    C_FUEL_A,
    C_FUEL_B,
    C_FUEL_C,
    C_HMAX,
    C_MMO,
    C_ROTOR,
    C_V_ROTATE,
    C_VSMAX,
    C_VSMIN,
    PHASE_GD,
    PHASE_NA,
    fuel_flow,
    performance,
)
from bluesky_gym.core.scalar import DEG, RAD
from bluesky_gym.core.scalar import maximum as _maximum
from bluesky_gym.core.scalar import mod as _mod
from bluesky_gym.core.scalar import sign as _sign
from bluesky_gym.core.state import (
    I_ALT,
    I_AP_ALT,
    I_AP_TAS,
    I_AP_TRK,
    I_AP_VS,
    I_AX,
    I_AXMAX,
    I_CAS,
    I_DISTFLOWN,
    I_DRAG,
    I_FUELBURN,
    I_FUELFLOW,
    I_GS,
    I_GSEAST,
    I_GSNORTH,
    I_HDG,
    I_LAT,
    I_LON,
    I_MACH,
    I_SELALT,
    I_SELSPD,
    I_SELVS,
    I_TAS,
    I_THRUST,
    I_TRK,
    I_TURNPHI,
    I_VMAX,
    I_VMIN,
    I_VS,
    I_WINDEAST,
    I_WINDNORTH,
)
from bluesky_gym.core.units import BANK_DEFAULT, G0, R_EARTH, TAS_EPS, VS_DEFAULT, VS_RAMP, VS_SELECT_EPS, WIND_MIN_ALT

ALT_DECIMALS = 1e6  # BlueSky rounds the integrated altitude to 6 decimals (np.round(alt, 6))
TAS_FLOOR_DRIFT = 0.001  # m/s, floor of TAS in the wind-correction angle


@jit
def same(a: float, b: float) -> bool:
    """Bitwise-equal floats (so a memoised result is exactly what recomputing would give)."""
    return a == b and (a != 0.0 or math.copysign(1.0, a) == math.copysign(1.0, b))


# Columns of the memo table (one row per aircraft slot). Each pure sub-computation is skipped
# when its inputs are bit-identical to the previous step's, which is the common case in level,
# constant-speed flight; the result is then exactly what recomputing would give.
M_PERF_TAS, M_PERF_VS, M_PERF_ALT, M_PHASE, M_VMIN, M_VMAX, M_AXMAX, M_DRAG = range(8)
M_H, M_P_H, M_RHO_H, M_T_H = range(8, 12)
M_HT, M_P_T, M_RHO_T, M_T_T = range(12, 16)
M_SPD, M_SPD_H, M_APTAS = range(16, 19)
M_LIM_TAS, M_LIM_HT, M_LIM_VMIN, M_LIM_VMAX, M_LIM_OUT = range(19, 24)
M_CAS_V, M_CAS_H, M_CAS, M_MACH = range(24, 28)
M_TR_V, M_TR_BANK, M_TURNRATE = range(28, 31)
M_HDG, M_COS, M_SIN = range(31, 34)
MEMO_COLUMNS = 34


@jit_inline
def perf_row(table, t):  # type: ignore[no-untyped-def]
    """Row ``t`` of the performance table as the tuples :func:`step_one` takes: (perf_tuple, limit_tuple)."""
    r = table[t]
    perf = (r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8], r[9], r[10], r[11], r[12], r[13], r[14], r[15], r[16], r[17], r[18])
    return perf, (r[C_HMAX], r[C_VSMAX], r[C_MMO], r[C_V_ROTATE], r[C_FUEL_A], r[C_FUEL_B], r[C_FUEL_C], r[C_VSMIN], r[C_ROTOR])


@jit_inline
def step_one(F, i, phase, wn, we, haswind, any_wind, do_perf, dt, perf, limits, memo, part, follow, res_trk, res_gs, res_alt, res_vs):  # type: ignore[no-untyped-def]
    """Advance aircraft ``i`` by one step (the body of :func:`step_kernel`), or by one of its two parts.

    ``perf`` and ``limits`` are the aircraft's type's :func:`perf_row` tuples (``limits`` carries
    the fuel-flow coefficients, vsmin and the rotor flag too; a rotorcraft flies BlueSky's rotor
    model [docs/dynamics.md §1.2b]). ``part`` 0 is the
    whole step. With conflict resolution BlueSky's ASAS runs between the autopilot and the
    kinematics, so the step runs in two parts: ``part`` 1 is the performance update and the
    autopilot, ``part`` 2 the rest, which flies, where ``follow``, the resolution's track [deg],
    ground speed [m/s] (made a TAS against the wind, as BlueSky's ``APorASAS``), altitude [m] and
    vertical speed [m/s] instead of the autopilot's. One function serves the whole step and both
    parts, so the plain step compiles to the same code as an undivided one (and runs as fast).
    """
    hmax, vsmax, mmo, v_rotate, fuel_a, fuel_b, fuel_c, vsmin, rotor_flag = limits
    rotor = rotor_flag != 0.0
    mm = memo[i]
    if part != 2:
        # Performance update from the start-of-step state [docs/dynamics.md §2.1].
        if do_perf and rotor:
            # BlueSky's rotor model: phase NA, its fixed envelope and axmax; no drag, thrust or fuel flow [§1.2b].
            phase[i] = PHASE_NA
            F[I_VMIN, i] = perf[12]
            F[I_VMAX, i] = perf[13]
            F[I_AXMAX, i] = AXMAX_ROTOR
        elif do_perf:
            if not (same(F[I_TAS, i], mm[M_PERF_TAS]) and same(F[I_VS, i], mm[M_PERF_VS]) and same(F[I_ALT, i], mm[M_PERF_ALT])):
                ph, vmn, vmx, axm, drag = performance(F[I_TAS, i], F[I_VS, i], F[I_ALT, i], perf)
                mm[M_PERF_TAS], mm[M_PERF_VS], mm[M_PERF_ALT] = F[I_TAS, i], F[I_VS, i], F[I_ALT, i]
                mm[M_PHASE], mm[M_VMIN], mm[M_VMAX], mm[M_AXMAX], mm[M_DRAG] = ph, vmn, vmx, axm, drag
            phase[i] = int(mm[M_PHASE])
            F[I_VMIN, i] = mm[M_VMIN]
            F[I_VMAX, i] = mm[M_VMAX]
            F[I_AXMAX, i] = mm[M_AXMAX]
            # Drag, net thrust and fuel flow: outputs only, with the previous step's ax [§1.4a].
            F[I_DRAG, i] = mm[M_DRAG]
            F[I_THRUST, i], F[I_FUELFLOW, i] = fuel_flow(mm[M_DRAG], F[I_AX, i], perf[0], perf[2], perf[3], fuel_a, fuel_b, fuel_c)
        h = F[I_ALT, i]
        if not same(h, mm[M_H]):
            mm[M_H] = h
            mm[M_P_H], mm[M_RHO_H], mm[M_T_H] = isa(h)
        p_h, rho_h, t_h = mm[M_P_H], mm[M_RHO_H], mm[M_T_H]
        # Autopilot [docs/dynamics.md §2.3].
        sv = F[I_SELVS, i]
        apvs = sv if abs(sv) > VS_SELECT_EPS else VS_DEFAULT
        F[I_AP_VS, i] = apvs
        apalt = F[I_SELALT, i]
        F[I_AP_ALT, i] = apalt
        spd = F[I_SELSPD, i]
        if not (same(spd, mm[M_SPD]) and same(h, mm[M_SPD_H])):
            if is_mach(spd):
                mm[M_APTAS] = spd * math.sqrt(GAMMA_R * t_h)
            else:
                mm[M_APTAS] = cas2tas_at(spd, p_h, rho_h)
            mm[M_SPD], mm[M_SPD_H] = spd, h
        aptas = mm[M_APTAS]
        F[I_AP_TAS, i] = aptas
        trk_t = F[I_AP_TRK, i]
        if part == 1:
            return
    else:
        h = F[I_ALT, i]
        p_h, rho_h, t_h = mm[M_P_H], mm[M_RHO_H], mm[M_T_H]
        trk_t, aptas, apalt, apvs = F[I_AP_TRK, i], F[I_AP_TAS, i], F[I_AP_ALT, i], F[I_AP_VS, i]
        if follow:
            trk_t, aptas, apalt, apvs = res_trk, res_gs, res_alt, res_vs
            if any_wind and haswind[i]:
                tn = res_gs * math.cos(trk_t * RAD) - wn[i]
                te = res_gs * math.sin(trk_t * RAD) - we[i]
                aptas = math.sqrt(tn**2 + te**2)
    vs_t = abs(apvs)
    if any_wind:
        vwn, vwe = wn[i], we[i]
        vw = math.sqrt(vwn * vwn + vwe * vwe)
        winddir = math.atan2(vwe, vwn)
        drift = trk_t * RAD - winddir
        s = vw * math.sin(drift) / _maximum(TAS_FLOOR_DRIFT, F[I_TAS, i])
        s = min(1.0, max(-1.0, s)) if s == s else s
        steer = math.asin(s)
        hdg_t = _mod(trk_t + steer * DEG, 360.0)
    else:
        hdg_t = _mod(trk_t, 360.0)
    # Performance limits at the target altitude [docs/dynamics.md §1.5].
    alt_t = hmax if apalt > hmax else apalt
    if rotor:
        # A rotorcraft's TAS and vertical speed are clipped to its envelope as they are [§1.2b].
        tas_t = F[I_VMIN, i] if aptas < F[I_VMIN, i] else aptas
        if aptas > F[I_VMAX, i]:
            tas_t = F[I_VMAX, i]
        vs_r = vsmin if vs_t < vsmin else vs_t
        if vs_t > vsmax:
            vs_r = vsmax
        vs_t = vs_r
    else:
        if not same(alt_t, mm[M_HT]):
            mm[M_HT] = alt_t
            mm[M_P_T], mm[M_RHO_T], mm[M_T_T] = isa(alt_t)
        if not (
            same(aptas, mm[M_LIM_TAS]) and same(alt_t, mm[M_LIM_HT]) and same(F[I_VMIN, i], mm[M_LIM_VMIN]) and same(F[I_VMAX, i], mm[M_LIM_VMAX])
        ):
            p_t, rho_t = mm[M_P_T], mm[M_RHO_T]
            intent_cas = tas2cas_at(aptas, p_t, rho_t)
            allow_cas = F[I_VMIN, i] if intent_cas < F[I_VMIN, i] else intent_cas
            if intent_cas > F[I_VMAX, i]:
                allow_cas = F[I_VMAX, i]
            lim = cas2tas_at(allow_cas, p_t, rho_t)
            sound_t = math.sqrt(GAMMA_R * mm[M_T_T])
            if lim / sound_t > mmo:
                lim = mmo * sound_t
            mm[M_LIM_OUT] = lim
            mm[M_LIM_TAS], mm[M_LIM_HT], mm[M_LIM_VMIN], mm[M_LIM_VMAX] = aptas, alt_t, F[I_VMIN, i], F[I_VMAX, i]
        tas_t = mm[M_LIM_OUT]
        if vs_t > 0 and vs_t > vsmax:
            vs_t = (1 - F[I_AX, i] / F[I_AXMAX, i]) * vsmax
        if phase[i] == PHASE_GD and F[I_TAS, i] < v_rotate:
            vs_t = 0.0
    # Speed [docs/dynamics.md §2.2 step 6].
    delta_spd = tas_t - F[I_TAS, i]
    if abs(delta_spd) > abs(dt * F[I_AXMAX, i]):
        a_x = 1.0 * _sign(delta_spd) * F[I_AXMAX, i]
        v_new = F[I_TAS, i] + a_x * dt
    else:
        a_x = 0.0 * _sign(delta_spd) * F[I_AXMAX, i]
        v_new = tas_t
    F[I_AX, i] = a_x
    F[I_TAS, i] = v_new
    if not (same(v_new, mm[M_CAS_V]) and same(h, mm[M_CAS_H])):
        mm[M_CAS] = tas2cas_at(v_new, p_h, rho_h)
        mm[M_MACH] = v_new / math.sqrt(GAMMA_R * t_h)
        mm[M_CAS_V], mm[M_CAS_H] = v_new, h
    F[I_CAS, i] = mm[M_CAS]
    F[I_MACH, i] = mm[M_MACH]
    # Heading [step 7].
    bank = F[I_TURNPHI, i] if F[I_TURNPHI, i] > TAS_EPS * TAS_EPS else BANK_DEFAULT
    if not (same(v_new, mm[M_TR_V]) and same(bank, mm[M_TR_BANK])):
        mm[M_TURNRATE] = (G0 * math.tan(bank) / _maximum(v_new, TAS_EPS)) * DEG
        mm[M_TR_V], mm[M_TR_BANK] = v_new, bank
    turnrate = mm[M_TURNRATE]
    delhdg = _mod(hdg_t - F[I_HDG, i] + 180, 360) - 180
    if abs(delhdg) > abs(dt * turnrate):
        new_hdg = _mod(F[I_HDG, i] + dt * turnrate * _sign(delhdg), 360.0)
    else:
        new_hdg = _mod(hdg_t, 360.0)
    F[I_HDG, i] = new_hdg
    # Vertical [step 8].
    vs_old = F[I_VS, i]
    delta_alt = alt_t - h
    swaltsel = abs(delta_alt) > 1.05 * _maximum(abs(dt * vs_t), abs(dt * vs_old))
    target_vs = (1.0 if swaltsel else 0.0) * _sign(delta_alt) * abs(vs_t)
    delta_vs = target_vs - vs_old
    if abs(delta_vs) > VS_RAMP:
        vs_new = vs_old + 1.0 * _sign(delta_vs) * VS_RAMP * dt
    else:
        vs_new = target_vs
    if not math.isfinite(vs_new):
        vs_new = 0.0
    F[I_VS, i] = vs_new
    # Ground speed [step 9, docs/dynamics.md §1.7].
    if not same(new_hdg, mm[M_HDG]):
        hr = new_hdg * RAD
        mm[M_COS], mm[M_SIN] = math.cos(hr), math.sin(hr)
        mm[M_HDG] = new_hdg
    gn = v_new * mm[M_COS]
    ge = v_new * mm[M_SIN]
    if any_wind:
        vwn, vwe = wn[i], we[i]
        F[I_WINDNORTH, i] = vwn
        F[I_WINDEAST, i] = vwe
        apply = haswind[i] and h > WIND_MIN_ALT
        fa = 1.0 if apply else 0.0
        gn = gn + vwn * fa
        ge = ge + vwe * fa
        if apply:
            g = math.sqrt(gn * gn + ge * ge)
            tr = _mod(math.atan2(ge, gn) * DEG, 360.0)
        else:
            g = v_new
            tr = new_hdg
    else:
        F[I_WINDNORTH, i] = 0.0
        F[I_WINDEAST, i] = 0.0
        g = v_new
        tr = new_hdg
    F[I_GSNORTH, i] = gn
    F[I_GSEAST, i] = ge
    F[I_GS, i] = g
    F[I_TRK, i] = tr
    # Position [step 10].
    if swaltsel:
        F[I_ALT, i] = rint((h + vs_new * dt) * ALT_DECIMALS) / ALT_DECIMALS
    else:
        F[I_ALT, i] = alt_t
    la = F[I_LAT, i] + (dt * gn / R_EARTH) * DEG
    F[I_LAT, i] = la
    coslat = math.cos(la * RAD)
    F[I_LON, i] = F[I_LON, i] + (dt * ge / coslat / R_EARTH) * DEG
    F[I_DISTFLOWN, i] = F[I_DISTFLOWN, i] + g * dt
    F[I_FUELBURN, i] = F[I_FUELBURN, i] + F[I_FUELFLOW, i] * dt


@jit
def step_kernel(F, phase, wn, we, haswind, any_wind, do_perf, dt, table, actype, memo, active):  # type: ignore[no-untyped-def]
    """Advance every aircraft by one step, in BlueSky's update order.

    Args:
        F: The float state block, (fields, aircraft); rows in ``FIELD_INDEX`` order.
        phase: (aircraft,) flight phases.
        wn: (aircraft,) wind north [m/s] (empty without wind).
        we: (aircraft,) wind east [m/s].
        haswind: (aircraft,) whether the aircraft's airspace has wind.
        any_wind: Whether any airspace has wind.
        do_perf: Whether the performance model updates this step.
        dt: Time step [s].
        table: Performance table, (types, ``N_COEFFICIENTS``): one ``table_row`` per aircraft type.
        actype: (aircraft,) row of ``table`` of each aircraft, or an empty array when every
            aircraft is of the type of row 0 (the one-type fast path: one memory stream less).
        memo: (aircraft, MEMO_COLUMNS) memo table.
        active: (aircraft,) slots holding an aircraft; empty slots are skipped (their values are
            meaningless).
    """
    one_type = actype.shape[0] == 0
    perf, limits = perf_row(table, 0)  # every aircraft's, with one type
    for i in grid_range(F.shape[1]):
        if active[i]:
            if not one_type:
                perf, limits = perf_row(table, actype[i])
            step_one(F, i, phase, wn, we, haswind, any_wind, do_perf, dt, perf, limits, memo, 0, False, 0.0, 0.0, 0.0, 0.0)


@jit
def pre_kernel(F, phase, do_perf, table, actype, memo, active):  # type: ignore[no-untyped-def]
    """The first part of a step with conflict resolution (performance update and autopilot), every aircraft; arguments as :func:`step_kernel`."""
    one_type = actype.shape[0] == 0
    perf, limits = perf_row(table, 0)
    no_wind = scratch(0, np.float64)  # this part reads no wind and no time step
    no_airspace_wind = scratch(0, np.bool_)
    for i in grid_range(F.shape[1]):
        if active[i]:
            if not one_type:
                perf, limits = perf_row(table, actype[i])
            step_one(F, i, phase, no_wind, no_wind, no_airspace_wind, False, do_perf, 0.0, perf, limits, memo, 1, False, 0.0, 0.0, 0.0, 0.0)


@jit
def post_kernel(F, phase, wn, we, haswind, any_wind, dt, table, actype, memo, active, follow, res_trk, res_gs, res_alt, res_vs):  # type: ignore[no-untyped-def]
    """The second part of a step with conflict resolution, every aircraft, flying the resolution where ``follow`` (BlueSky's ``APorASAS``).

    Arguments as :func:`step_kernel`, plus per aircraft: ``follow`` (bool) and the resolution's
    track [deg], ground speed [m/s], altitude [m] and vertical speed [m/s] (see :func:`step_one`).
    """
    one_type = actype.shape[0] == 0
    perf, limits = perf_row(table, 0)
    for i in grid_range(F.shape[1]):
        if active[i]:
            if not one_type:
                perf, limits = perf_row(table, actype[i])
            step_one(
                F, i, phase, wn, we, haswind, any_wind, False, dt, perf, limits, memo, 2, follow[i], res_trk[i], res_gs[i], res_alt[i], res_vs[i]
            )


@jit
def run_kernel(F, phase, wn, we, haswind, any_wind, perf_due, dt, table, actype, memo, active, lnav, trace):  # type: ignore[no-untyped-def]
    """Advance every aircraft by ``len(perf_due)`` steps, aircraft by aircraft.

    Valid when aircraft do not interact within these steps, which holds for the physics and
    LNAV as long as the wind does not depend on position (none or uniform). Each aircraft then
    stays in cache for all its steps. Same arguments as :func:`step_kernel`, with
    ``perf_due[k]`` telling whether the performance model updates in step ``k`` and ``lnav``
    the LNAV arrays ``(swlnav, swvnav, swvnavspd, swlastwp, active, iactwp, nwp, route_lat,
    route_lon, python_geo)``, or None when no aircraft flies LNAV. ``trace`` is None, or a
    ``(steps, 2, aircraft)`` array that receives each aircraft's latitude and longitude after
    every step.
    """
    one_type = actype.shape[0] == 0
    perf, limits = perf_row(table, 0)  # every aircraft's, with one type
    for i in grid_range(F.shape[1]):
        if not active[i]:
            continue
        if not one_type:
            perf, limits = perf_row(table, actype[i])
        for k in range(perf_due.shape[0]):
            if lnav is not None:
                lnav_one(F, i, lnav[0], lnav[1], lnav[2], lnav[3], lnav[4], lnav[5], lnav[6], lnav[7], lnav[8], lnav[9])
            step_one(F, i, phase, wn, we, haswind, any_wind, perf_due[k], dt, perf, limits, memo, 0, False, 0.0, 0.0, 0.0, 0.0)
            if trace is not None:
                trace[k, 0, i] = F[I_LAT, i]
                trace[k, 1, i] = F[I_LON, i]
