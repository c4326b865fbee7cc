"""Optional compiled kernel: the whole per-aircraft sub-step fused into one loop.

The numpy implementation in :mod:`bluesky_gym.core.simulator` is the reference. It issues about
150 whole-array numpy calls per step; most of the time goes into ~25 transcendental passes
(``pow``, ``exp``, ``sin``...) over the arrays and into call overhead at small batch sizes. This
module compiles the identical arithmetic, operation by operation, into one loop with numba, so
each aircraft's values stay in registers and every transcendental is evaluated once.

It is bit-identical to the numpy path: both call the same C math library functions in the same
order on the same operands, floating-point contraction (FMA) is not enabled (no fastmath), and
the tests compare the two kernels to the last bit. It is used automatically when numba is
installed (the ``fast`` extra); ``Simulator(kernel="numpy")`` forces the reference path.
"""

from __future__ import annotations

import math

import numpy as np

from bluesky_gym.core import performance as pf
from bluesky_gym.core.jit import AVAILABLE as AVAILABLE
from bluesky_gym.core.jit import jit, jit_inline
from bluesky_gym.core.scalar import maximum as _maximum
from bluesky_gym.core.scalar import mod as _mod
from bluesky_gym.core.scalar import sign as _sign
from bluesky_gym.core.simulator import FIELD_INDEX
from bluesky_gym.core.units import FPM, FT, G0, R_EARTH

_RAD = np.pi / 180.0  # numpy's deg2rad factor
_DEG = 180.0 / np.pi  # numpy's rad2deg factor
_GAMMA_R = 1.40 * 287.05287  # gamma * R, as BlueSky's vvsound evaluates it
_R = 287.05287
_P0 = 101325.0
_RHO0 = 1.225
_7P0_RHO0 = 7.0 * _P0 / _RHO0
_P10 = float(pf._P10)
_P35 = float(pf._P35)
_VCAS_REF = float(pf._VCAS_REF)
_FT_10000 = 10000 * FT
_FT_35000 = 35000 * FT
_VS_RAMP = 300 * FPM
_VS_DEFAULT = 1500 * FPM
_WIND_MIN_ALT = 50.0 * FT
_BANK_DEFAULT = 0.4363323129985824
# Rows of the float state block.
_I_LAT = FIELD_INDEX["lat"]
_I_LON = FIELD_INDEX["lon"]
_I_ALT = FIELD_INDEX["alt"]
_I_HDG = FIELD_INDEX["hdg"]
_I_TRK = FIELD_INDEX["trk"]
_I_TAS = FIELD_INDEX["tas"]
_I_CAS = FIELD_INDEX["cas"]
_I_MACH = FIELD_INDEX["mach"]
_I_GS = FIELD_INDEX["gs"]
_I_GSNORTH = FIELD_INDEX["gsnorth"]
_I_GSEAST = FIELD_INDEX["gseast"]
_I_VS = FIELD_INDEX["vs"]
_I_AX = FIELD_INDEX["ax"]
_I_WINDNORTH = FIELD_INDEX["windnorth"]
_I_WINDEAST = FIELD_INDEX["windeast"]
_I_DISTFLOWN = FIELD_INDEX["distflown"]
_I_ACTWP_LAT = FIELD_INDEX["actwp_lat"]
_I_ACTWP_LON = FIELD_INDEX["actwp_lon"]
_I_CURLEGDIR = FIELD_INDEX["curlegdir"]
_I_TURNDIST = FIELD_INDEX["turndist"]
_I_NEXT_QDR = FIELD_INDEX["next_qdr"]
_I_SELSPD = FIELD_INDEX["selspd"]
_I_SELALT = FIELD_INDEX["selalt"]
_I_SELVS = FIELD_INDEX["selvs"]
_I_AP_TRK = FIELD_INDEX["ap_trk"]
_I_AP_TAS = FIELD_INDEX["ap_tas"]
_I_AP_VS = FIELD_INDEX["ap_vs"]
_I_AP_ALT = FIELD_INDEX["ap_alt"]
_I_TURNPHI = FIELD_INDEX["turnphi"]
_I_VMIN = FIELD_INDEX["vmin"]
_I_VMAX = FIELD_INDEX["vmax"]
_I_AXMAX = FIELD_INDEX["axmax"]








@jit
def _atmos(h):
    """Vector ISA (p, rho, T) at ``h`` [m], BlueSky's ``vatmos`` operation order."""
    t = 288.15 - 0.0065 * h
    if not t > 216.65:  # np.maximum(x, 216.65) propagates NaN
        t = 216.65 if t == t else t
    rhotrop = 1.225 * math.pow(t / 288.15, 4.256848030018761)
    dh = h - 11000.0
    if not dh > 0.0:
        dh = 0.0 if dh == dh else dh
    rho = rhotrop * math.exp(-dh / 6341.552161)
    p = rho * _R * t
    return p, rho, t


@jit
def _tas2cas(tas, p, rho):
    qdyn = p * (math.pow(1.0 + rho * tas * tas / (7.0 * p), 3.5) - 1.0)
    cas = math.sqrt(_7P0_RHO0 * (math.pow(qdyn / _P0 + 1.0, 2.0 / 7.0) - 1.0))
    return -1 * cas if tas < 0 else cas


@jit
def _cas2tas(cas, p, rho):
    qdyn = _P0 * (math.pow(1.0 + _RHO0 * cas * cas / (7.0 * _P0), 3.5) - 1.0)
    tas = math.sqrt(7.0 * p / rho * (math.pow(1.0 + qdyn / p, 2.0 / 7.0) - 1.0))
    return -1 * tas if cas < 0 else tas




@jit
def _performance(tas, vs, alt, perf):
    """OpenAP phase, speed envelope and axmax [dynamics.md 1.3-1.4]."""
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
    roc = vs / 0.00508
    a = alt / 0.3048
    ph = 0
    if a <= 75:
        ph = 1
    if a >= 75 and a <= 1000 and roc >= 150:
        ph = 2
    if a >= 75 and a <= 1000 and roc <= -150:
        ph = 6
    if a >= 1000 and roc >= 150:
        ph = 3
    if a >= 1000 and roc <= -150:
        ph = 5
    if a >= 10000 and roc <= 150 and roc >= -150:
        ph = 4
    if ph == 1:
        vmin, vmax = 0.0, vmax_gd
    elif ph == 6:
        vmin, vmax = vmin_ap, vmax_ap
    else:
        vmin, vmax = vmin_er, vmax_er

    if ph == 1:
        cd0, k = cd0_to + cd0_gear, k_to
    elif ph == 2:
        cd0, k = cd0_to, k_to
    elif ph == 6:
        cd0, k = cd0_ld, k_ld
    else:
        cd0, k = cd0_clean, k_clean
    p, rho, t = _atmos(alt)
    rhovs = 0.5 * rho * (tas * tas) * wing_area
    cl = mass * G0 / rhovs
    drag = rhovs * (cd0 + k * (cl * cl))

    thr0 = n_eng * eng_thr
    if ph == 1:  # take-off thrust ratio
        mach_to = tas / math.sqrt(_GAMMA_R * t)
        pp = p / _P0
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
        mach = v / math.sqrt(_GAMMA_R * t)
        vcas = _tas2cas(v, p, rho)
        f35 = (200 + 0.2 * thr0 / 4.448) * 4.448
        if alt > _FT_35000:
            d = -0.4204 * (mach / 0.8) + 1.0824
            b = math.pow(mach / 0.8, -0.11)
            ratio = d * math.log(p / _P35) + b
        else:
            vratio = vcas / _VCAS_REF
            a2 = math.pow(vratio, -0.1)
            n = 2.667e-05 * roc_fpm + 0.8633
            if alt > _FT_10000:
                ratio = a2 * math.pow(p / _P35, -0.355 * vratio + n)
            else:
                f10 = f35 * a2 * math.pow(_P10 / _P35, -0.355 * vratio + n)
                m = -1.2043e-1 * vratio - 8.8889e-9 * (roc_fpm * roc_fpm) + 2.4444e-5 * roc_fpm + 4.7379e-1
                ratio = m * (p / _P35) + (f10 / f35 - m * (_P10 / _P35))
        ratio = ratio * f35 / thr0
    max_thrust = ratio * n_eng * eng_thr
    axmax = (max_thrust - drag) / mass
    if ph == 1:
        axmax = ax_gd
    if axmax < ax_floor:
        axmax = ax_floor
    return ph, vmin, vmax, axmax


@jit
def _same(a, b):
    """Bitwise-equal floats (so a memoised result is exactly what recomputing would give)."""
    return a == b and (a != 0.0 or math.copysign(1.0, a) == math.copysign(1.0, b))


# Columns of the memo table (one row per aircraft slot). Each pure sub-computation is skipped
# when its inputs are bit-identical to the previous step's, which is the common case in level,
# constant-speed flight; the result is then exactly what recomputing would give.
M_PERF_TAS, M_PERF_VS, M_PERF_ALT, M_PHASE, M_VMIN, M_VMAX, M_AXMAX = range(7)
M_H, M_P_H, M_RHO_H, M_T_H = range(7, 11)
M_HT, M_P_T, M_RHO_T, M_T_T = range(11, 15)
M_SPD, M_SPD_H, M_APTAS = range(15, 18)
M_LIM_TAS, M_LIM_HT, M_LIM_VMIN, M_LIM_VMAX, M_LIM_OUT = range(18, 23)
M_CAS_V, M_CAS_H, M_CAS, M_MACH = range(23, 27)
M_TR_V, M_TR_BANK, M_TURNRATE = range(27, 30)
M_HDG, M_COS, M_SIN = range(30, 33)
MEMO_COLUMNS = 33


# --- LNAV [dynamics.md 2.6], per aircraft -----------------------------------------------------
_A2 = 6378137.0 * 6378137.0
_B2 = 6356752.314245 * 6356752.314245
_A4 = _A2 * _A2
_B4 = _B2 * _B2
_WGS84_A = 6378137.0
_WGS84_B = 6356752.314245
_DEG2RAD = 0.017453292519943295
_RAD2DEG = 57.29577951308232
_M2NM = 0.0005399568034557236
_NM = 1852.0
# g0 * tan(bank) of a waypoint turn: deg2rad(rad2deg(bankdef)) as BlueSky's calcturn evaluates it.
_G_TAN_LNAV = G0 * float(np.tan(np.deg2rad(np.rad2deg(np.float64(_BANK_DEFAULT)))))
_BANK_LNAV = float(np.deg2rad(np.rad2deg(np.float64(_BANK_DEFAULT))))


@jit
def _rwgs84_sc(sinlat, coslat):
    s2 = sinlat * sinlat
    c2 = coslat * coslat
    return math.sqrt((_A4 * c2 + _B4 * s2) / (_A2 * c2 + _B2 * s2))


@jit
def _qdrdist_compiled(latd1, lond1, latd2, lond2):
    """Scalar copy of :func:`bluesky_gym.core.geo.qdrdist` (deg, NM)."""
    lat1 = _DEG2RAD * latd1
    lon1 = _DEG2RAD * lond1
    lat2 = _DEG2RAD * latd2
    lon2 = _DEG2RAD * lond2
    sinlat1, coslat1 = math.sin(lat1), math.cos(lat1)
    sinlat2, coslat2 = math.sin(lat2), math.cos(lat2)
    dlon = lon2 - lon1
    qdr = _RAD2DEG * math.atan2(math.sin(dlon) * coslat2, sinlat2 * coslat1 - sinlat1 * coslat2 * math.cos(dlon))
    sindlat2 = math.sin(0.5 * (lat2 - lat1))
    sindlon2 = math.sin(0.5 * dlon)
    if lat1 * lat2 >= 0.0:
        mid = 0.5 * (lat1 + lat2)
        r = _rwgs84_sc(math.sin(mid), math.cos(mid))
    else:
        r = (
            0.5
            * (abs(lat1) * (_rwgs84_sc(sinlat1, coslat1) + _WGS84_A) + abs(lat2) * (_rwgs84_sc(sinlat2, coslat2) + _WGS84_A))
            / (abs(lat1) + abs(lat2))
        )
    root = sindlat2 * sindlat2 + coslat1 * coslat2 * sindlon2 * sindlon2
    dist = 2.0 * r * math.atan2(math.sqrt(root), math.sqrt(1.0 - root))
    return qdr, _M2NM * dist


@jit
def _rwgs84_python(latd):
    lat = latd * _RAD
    coslat = math.cos(lat)
    sinlat = math.sin(lat)
    an = _WGS84_A * _WGS84_A * coslat
    bn = _WGS84_B * _WGS84_B * sinlat
    ad = _WGS84_A * coslat
    bd = _WGS84_B * sinlat
    return math.sqrt((an * an + bn * bn) / (ad * ad + bd * bd))


@jit
def _qdrdist_python(latd1, lond1, latd2, lond2):
    """Scalar copy of :func:`bluesky_gym.core.geo.qdrdist_python` (deg, NM)."""
    res1 = _rwgs84_python(0.5 * (latd1 + latd2))
    if latd1 * latd2 >= 0.0:
        r = res1
    else:
        r1 = _rwgs84_python(latd1)
        r2 = _rwgs84_python(latd2)
        res2 = 0.5 * (abs(latd1) * (r1 + _WGS84_A) + abs(latd2) * (r2 + _WGS84_A)) / _maximum(0.000001, abs(latd1) + abs(latd2))
        r = 0.0 * res1 + 1.0 * res2
    lat1 = latd1 * _RAD
    lon1 = lond1 * _RAD
    lat2 = latd2 * _RAD
    lon2 = lond2 * _RAD
    d = r * math.acos(math.cos(lat1) * math.cos(lat2) * math.cos(lon2 - lon1) + math.sin(lat1) * math.sin(lat2))
    coslat1 = math.cos(lat1)
    coslat2 = math.cos(lat2)
    qdr = math.atan2(math.sin(lon2 - lon1) * coslat2, coslat1 * math.sin(lat2) - math.sin(lat1) * coslat2 * math.cos(lon2 - lon1)) * _DEG
    return qdr, d / _NM


@jit
def _qdrdist(python_geo, latd1, lond1, latd2, lond2):
    if python_geo:
        return _qdrdist_python(latd1, lond1, latd2, lond2)
    return _qdrdist_compiled(latd1, lond1, latd2, lond2)


@jit
def _degto180(x):
    return _mod(x + 180.0, 360) - 180.0


@jit
def _turn_distance(tas, qdr, next_qdr):
    local_next = qdr if next_qdr < -900.0 else next_qdr
    turnrad = tas * tas / _G_TAN_LNAV
    return abs(turnrad * math.tan(0.5 * abs(_degto180(_mod(qdr, 360.0) - _mod(local_next, 360.0))) * _RAD))


@jit_inline
def _lnav_one(F, i, swlnav, swvnav, swvnavspd, swlastwp, active, iactwp, nwp, route_lat, route_lon, python_geo):
    """LNAV of aircraft ``i`` (mirrors ``Simulator._update_lnav``)."""
    if not swlnav[i]:
        return
    qdr, distnm = _qdrdist(python_geo, F[_I_LAT, i], F[_I_LON, i], F[_I_ACTWP_LAT, i], F[_I_ACTWP_LON, i])
    dist = distnm * _NM
    close2wp = dist / _maximum(0.0001, abs(F[_I_GS, i])) < 4.0
    tooclose2turn = close2wp and abs(_degto180(_mod(F[_I_TRK, i], 360.0) - _mod(qdr, 360.0))) > 90.0
    awayorpassed = tooclose2turn or abs(_degto180(qdr - F[_I_CURLEGDIR, i])) > 90.0
    if active[i] and (awayorpassed or dist < F[_I_TURNDIST, i]):
        if swlastwp[i]:
            swlnav[i] = False
            swvnav[i] = False
            swvnavspd[i] = False
        else:
            n = nwp[i]
            iact = iactwp[i]
            lnavon = iact < n - 1
            if lnavon:
                iact += 1
            iactwp[i] = iact
            swlastwp[i] = iact == n - 1
            if iact > -1 and iact < n - 1:
                nq, _ = _qdrdist(python_geo, route_lat[i, iact], route_lon[i, iact], route_lat[i, iact + 1], route_lon[i, iact + 1])
            else:
                nq = -999.0
            F[_I_NEXT_QDR, i] = nq
            if not lnavon:
                swlnav[i] = False
            swvnav[i] = swvnav[i] and swlnav[i]
            wlat, wlon = route_lat[i, iact], route_lon[i, iact]
            F[_I_ACTWP_LAT, i] = wlat
            F[_I_ACTWP_LON, i] = wlon
            qdr, _ = _qdrdist(python_geo, F[_I_LAT, i], F[_I_LON, i], wlat, wlon)
            F[_I_CURLEGDIR, i] = qdr
            F[_I_TURNDIST, i] = _turn_distance(F[_I_TAS, i], qdr, nq)
            F[_I_TURNPHI, i] = _BANK_LNAV
    if swlnav[i]:
        F[_I_AP_TRK, i] = _mod(qdr, 360.0)


@jit
def lnav_kernel(F, swlnav, swvnav, swvnavspd, swlastwp, active, iactwp, nwp, route_lat, route_lon, python_geo):
    """LNAV of every aircraft (flattened arrays; ``route_*`` shaped (aircraft, waypoints))."""
    for i in range(F.shape[1]):
        _lnav_one(F, i, swlnav, swvnav, swvnavspd, swlastwp, active, iactwp, nwp, route_lat, route_lon, python_geo)


@jit_inline
def _step_one(F, i, phase, wn, we, haswind, any_wind, do_perf, dt, perf, limits, memo):
    """Advance aircraft ``i`` by one step (the body of :func:`step_kernel`)."""
    hmax, vsmax, mmo, v_rotate = limits
    mm = memo[i]
    # Performance update from the start-of-step state [dynamics.md 2.1].
    if do_perf:
        if not (_same(F[_I_TAS, i], mm[M_PERF_TAS]) and _same(F[_I_VS, i], mm[M_PERF_VS]) and _same(F[_I_ALT, i], mm[M_PERF_ALT])):
            ph, vmn, vmx, axm = _performance(F[_I_TAS, i], F[_I_VS, i], F[_I_ALT, i], perf)
            mm[M_PERF_TAS], mm[M_PERF_VS], mm[M_PERF_ALT] = F[_I_TAS, i], F[_I_VS, i], F[_I_ALT, i]
            mm[M_PHASE], mm[M_VMIN], mm[M_VMAX], mm[M_AXMAX] = ph, vmn, vmx, axm
        phase[i] = int(mm[M_PHASE])
        F[_I_VMIN, i] = mm[M_VMIN]
        F[_I_VMAX, i] = mm[M_VMAX]
        F[_I_AXMAX, i] = mm[M_AXMAX]
    h = F[_I_ALT, i]
    if not _same(h, mm[M_H]):
        mm[M_H] = h
        mm[M_P_H], mm[M_RHO_H], mm[M_T_H] = _atmos(h)
    p_h, rho_h, t_h = mm[M_P_H], mm[M_RHO_H], mm[M_T_H]
    # Autopilot [dynamics.md 2.3].
    sv = F[_I_SELVS, i]
    apvs = sv if abs(sv) > 0.1 else _VS_DEFAULT
    F[_I_AP_VS, i] = apvs
    apalt = F[_I_SELALT, i]
    F[_I_AP_ALT, i] = apalt
    spd = F[_I_SELSPD, i]
    if not (_same(spd, mm[M_SPD]) and _same(h, mm[M_SPD_H])):
        if spd > 0.1 and spd < 2.0:
            mm[M_APTAS] = spd * math.sqrt(_GAMMA_R * t_h)
        else:
            mm[M_APTAS] = _cas2tas(spd, p_h, rho_h)
        mm[M_SPD], mm[M_SPD_H] = spd, h
    aptas = mm[M_APTAS]
    F[_I_AP_TAS, i] = aptas
    trk_t = F[_I_AP_TRK, i]
    vs_t = abs(apvs)
    if any_wind:
        vwn, vwe = wn[i], we[i]
        vw = math.sqrt(vwn * vwn + vwe * vwe)
        winddir = math.atan2(vwe, vwn)
        drift = trk_t * _RAD - winddir
        s = vw * math.sin(drift) / _maximum(0.001, F[_I_TAS, i])
        s = min(1.0, max(-1.0, s)) if s == s else s
        steer = math.asin(s)
        hdg_t = _mod(trk_t + steer * _DEG, 360.0)
    else:
        hdg_t = _mod(trk_t, 360.0)
    # Performance limits at the target altitude [dynamics.md 1.5].
    alt_t = hmax if apalt > hmax else apalt
    if not _same(alt_t, mm[M_HT]):
        mm[M_HT] = alt_t
        mm[M_P_T], mm[M_RHO_T], mm[M_T_T] = _atmos(alt_t)
    if not (
        _same(aptas, mm[M_LIM_TAS]) and _same(alt_t, mm[M_LIM_HT]) and _same(F[_I_VMIN, i], mm[M_LIM_VMIN]) and _same(F[_I_VMAX, i], mm[M_LIM_VMAX])
    ):
        p_t, rho_t = mm[M_P_T], mm[M_RHO_T]
        intent_cas = _tas2cas(aptas, p_t, rho_t)
        allow_cas = F[_I_VMIN, i] if intent_cas < F[_I_VMIN, i] else intent_cas
        if intent_cas > F[_I_VMAX, i]:
            allow_cas = F[_I_VMAX, i]
        lim = _cas2tas(allow_cas, p_t, rho_t)
        sound_t = math.sqrt(_GAMMA_R * mm[M_T_T])
        if lim / sound_t > mmo:
            lim = mmo * sound_t
        mm[M_LIM_OUT] = lim
        mm[M_LIM_TAS], mm[M_LIM_HT], mm[M_LIM_VMIN], mm[M_LIM_VMAX] = aptas, alt_t, F[_I_VMIN, i], F[_I_VMAX, i]
    tas_t = mm[M_LIM_OUT]
    if vs_t > 0 and vs_t > vsmax:
        vs_t = (1 - F[_I_AX, i] / F[_I_AXMAX, i]) * vsmax
    if phase[i] == 1 and F[_I_TAS, i] < v_rotate:
        vs_t = 0.0
    # Speed [dynamics.md 2.2 step 6].
    delta_spd = tas_t - F[_I_TAS, i]
    if abs(delta_spd) > abs(dt * F[_I_AXMAX, i]):
        a_x = 1.0 * _sign(delta_spd) * F[_I_AXMAX, i]
        v_new = F[_I_TAS, i] + a_x * dt
    else:
        a_x = 0.0 * _sign(delta_spd) * F[_I_AXMAX, i]
        v_new = tas_t
    F[_I_AX, i] = a_x
    F[_I_TAS, i] = v_new
    if not (_same(v_new, mm[M_CAS_V]) and _same(h, mm[M_CAS_H])):
        mm[M_CAS] = _tas2cas(v_new, p_h, rho_h)
        mm[M_MACH] = v_new / math.sqrt(_GAMMA_R * t_h)
        mm[M_CAS_V], mm[M_CAS_H] = v_new, h
    F[_I_CAS, i] = mm[M_CAS]
    F[_I_MACH, i] = mm[M_MACH]
    # Heading [step 7].
    bank = F[_I_TURNPHI, i] if F[_I_TURNPHI, i] > 0.01 * 0.01 else _BANK_DEFAULT
    if not (_same(v_new, mm[M_TR_V]) and _same(bank, mm[M_TR_BANK])):
        mm[M_TURNRATE] = (G0 * math.tan(bank) / _maximum(v_new, 0.01)) * _DEG
        mm[M_TR_V], mm[M_TR_BANK] = v_new, bank
    turnrate = mm[M_TURNRATE]
    delhdg = _mod(hdg_t - F[_I_HDG, i] + 180, 360) - 180
    if abs(delhdg) > abs(dt * turnrate):
        new_hdg = _mod(F[_I_HDG, i] + dt * turnrate * _sign(delhdg), 360.0)
    else:
        new_hdg = _mod(hdg_t, 360.0)
    F[_I_HDG, i] = new_hdg
    # Vertical [step 8].
    vs_old = F[_I_VS, i]
    delta_alt = alt_t - h
    swaltsel = abs(delta_alt) > 1.05 * _maximum(abs(dt * vs_t), abs(dt * vs_old))
    target_vs = (1.0 if swaltsel else 0.0) * _sign(delta_alt) * abs(vs_t)
    delta_vs = target_vs - vs_old
    if abs(delta_vs) > _VS_RAMP:
        vs_new = vs_old + 1.0 * _sign(delta_vs) * _VS_RAMP * dt
    else:
        vs_new = target_vs
    if not math.isfinite(vs_new):
        vs_new = 0.0
    F[_I_VS, i] = vs_new
    # Ground speed [step 9, dynamics.md 1.7].
    if not _same(new_hdg, mm[M_HDG]):
        hr = new_hdg * _RAD
        mm[M_COS], mm[M_SIN] = math.cos(hr), math.sin(hr)
        mm[M_HDG] = new_hdg
    gn = v_new * mm[M_COS]
    ge = v_new * mm[M_SIN]
    if any_wind:
        vwn, vwe = wn[i], we[i]
        F[_I_WINDNORTH, i] = vwn
        F[_I_WINDEAST, i] = vwe
        apply = haswind[i] and h > _WIND_MIN_ALT
        fa = 1.0 if apply else 0.0
        gn = gn + vwn * fa
        ge = ge + vwe * fa
        if apply:
            g = math.sqrt(gn * gn + ge * ge)
            tr = _mod(math.atan2(ge, gn) * _DEG, 360.0)
        else:
            g = v_new
            tr = new_hdg
    else:
        F[_I_WINDNORTH, i] = 0.0
        F[_I_WINDEAST, i] = 0.0
        g = v_new
        tr = new_hdg
    F[_I_GSNORTH, i] = gn
    F[_I_GSEAST, i] = ge
    F[_I_GS, i] = g
    F[_I_TRK, i] = tr
    # Position [step 10].
    if swaltsel:
        F[_I_ALT, i] = np.rint((h + vs_new * dt) * 1e6) / 1e6
    else:
        F[_I_ALT, i] = alt_t
    la = F[_I_LAT, i] + (dt * gn / R_EARTH) * _DEG
    F[_I_LAT, i] = la
    coslat = math.cos(la * _RAD)
    F[_I_LON, i] = F[_I_LON, i] + (dt * ge / coslat / R_EARTH) * _DEG
    F[_I_DISTFLOWN, i] = F[_I_DISTFLOWN, i] + g * dt


@jit
def step_kernel(F, phase, wn, we, haswind, any_wind, do_perf, dt, perf, limits, memo, active):
    """Advance every aircraft by one step; mirrors ``Simulator.step`` operation by operation.

    Args:
        F: The float state block, (fields, aircraft); rows in ``FIELD_INDEX`` order.
        phase: (aircraft,) flight phases.
        wn: (aircraft,) wind north [m/s] (empty without wind).
        we: (aircraft,) wind east [m/s].
        haswind: (aircraft,) whether the aircraft's airspace has wind.
        any_wind: Whether any airspace has wind.
        do_perf: Whether the performance model updates this step.
        dt: Time step [s].
        perf: Performance constants (``perf_tuple``).
        limits: (hmax, vsmax, mmo, v_rotate).
        memo: (aircraft, MEMO_COLUMNS) memo table.
        active: (aircraft,) slots holding an aircraft; empty slots are skipped (their values are
            meaningless, unlike in the numpy path, which computes them too).
    """
    for i in range(F.shape[1]):
        if active[i]:
            _step_one(F, i, phase, wn, we, haswind, any_wind, do_perf, dt, perf, limits, memo)


@jit
def run_kernel(F, phase, wn, we, haswind, any_wind, perf_due, dt, perf, limits, memo, active, lnav, trace):
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
    for i in range(F.shape[1]):
        if not active[i]:
            continue
        for k in range(perf_due.shape[0]):
            if lnav is not None:
                _lnav_one(F, i, lnav[0], lnav[1], lnav[2], lnav[3], lnav[4], lnav[5], lnav[6], lnav[7], lnav[8], lnav[9])
            _step_one(F, i, phase, wn, we, haswind, any_wind, perf_due[k], dt, perf, limits, memo)
            if trace is not None:
                trace[k, 0, i] = F[_I_LAT, i]
                trace[k, 1, i] = F[_I_LON, i]


def perf_tuple(perf: pf.AircraftPerformance) -> tuple[float, ...]:
    """The performance constants in the kernel's argument order."""
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
