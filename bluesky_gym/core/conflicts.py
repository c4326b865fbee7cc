"""Conflict geometry: BlueSky's ``creconfs`` intruder placement and state-based detection.

Both are batched: ``create_conflicts`` places one intruder per requested (airspace, target) pair,
and :func:`detect` evaluates every ordered aircraft pair of every airspace at once with the
symmetric, correct geometry of BlueSky's compiled CSTATEBASED detector [docs/dynamics.md §3, §5].
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from bluesky_gym.core import geo
from bluesky_gym.core.atmosphere import casormach2tas, isa_layered, tas2cas_at
from bluesky_gym.core.geo import kwikpos_s
from bluesky_gym.core.jit import fmod, grid_range, jit
from bluesky_gym.core.scalar import DEG, RAD, divide, maximum, minimum, sign
from bluesky_gym.core.state import aircraft_index
from bluesky_gym.core.units import DEG2RAD, FT, M2NM, NM, R_EARTH, RAD2DEG

if TYPE_CHECKING:
    from bluesky_gym.core.simulator import Simulator

Array = NDArray[np.float64]

PZ_RADIUS = 5.0 * NM  # m, BlueSky's default horizontal protected-zone radius (asas_pzr)
PZ_HEIGHT = 1000.0 * FT  # m, default protected-zone half height (asas_pzh)
LOOKAHEAD = 300.0  # s, default look-ahead time (asas_dtlookahead)


@jit
def conflict_geometry(
    latref: float,
    lonref: float,
    altref: float,
    trkref_deg: float,
    gsref: float,
    vsref: float,
    dpsi: float,
    dcpa: float,
    tlosh: float,
    dh: float,
    tlosv: float,
    tas: float,
    wn_ref: float,
    we_ref: float,
    rpz: float,
    hpz: float,
) -> tuple[float, float, float, float, float, float]:
    """Position, altitude, vertical speed and ground velocity of one ``creconfs`` intruder [docs/dynamics.md §3].

    Args:
        latref: Target latitude [deg].
        lonref: Target longitude [deg].
        altref: Target altitude [m].
        trkref_deg: Target track [deg].
        gsref: Target ground speed [m/s].
        vsref: Target vertical speed [m/s].
        dpsi: Track difference intruder - target [deg].
        dcpa: Distance at the closest point of approach [NM].
        tlosh: Time to horizontal loss of separation [s].
        dh: Altitude offset [m], NaN for none.
        tlosv: Time to vertical loss of separation [s] (used with ``dh``).
        tas: Intruder TAS [m/s], NaN for "the target's ground speed".
        wn_ref: Wind north at the target [m/s] (used with ``tas``).
        we_ref: Wind east at the target [m/s].
        rpz: Protected-zone radius [m].
        hpz: Protected-zone half height [m].

    Returns:
        (lat [deg], lon [deg], alt [m], vs [m/s], ground speed north, east [m/s]).
    """
    trkref = trkref_deg * RAD
    cpa = dcpa * NM
    trk = trkref + dpsi * RAD
    if dh != dh:
        acalt = altref
        acvs = 0.0
    else:
        acalt = altref + dh
        acvs = vsref - sign(dh) * (abs(dh) - hpz) / tlosv
    if tas == tas:
        gsn, gse = tas * math.cos(trk) + wn_ref, tas * math.sin(trk) + we_ref
    else:
        gsn, gse = gsref * math.cos(trk), gsref * math.sin(trk)
    vreln, vrele = gsref * math.cos(trkref) - gsn, gsref * math.sin(trkref) - gse
    vrel = math.sqrt(vreln * vreln + vrele * vrele)
    drelcpa = tlosh * vrel + (0.0 if cpa > rpz else math.sqrt(maximum(rpz * rpz - cpa * cpa, 0.0)))
    dist = math.sqrt(drelcpa * drelcpa + cpa * cpa)
    rd = drelcpa / dist
    rx = cpa / dist
    brn = math.atan2(-rx * vreln + rd * vrele, rd * vreln + rx * vrele) * DEG
    aclat, aclon = kwikpos_s(latref, lonref, brn, dist / NM)
    return aclat, aclon, acalt, acvs, gsn, gse


@jit
def _geometry_loop(latref, lonref, altref, trkref, gsref, vsref, dpsi, dcpa, tlosh, dh, tlosv, tas, wn, we, rpz, hpz, out):  # type: ignore[no-untyped-def]
    for i in grid_range(latref.shape[0]):
        r = conflict_geometry(latref[i], lonref[i], altref[i], trkref[i], gsref[i], vsref[i],
                              dpsi[i], dcpa[i], tlosh[i], dh[i], tlosv[i], tas[i], wn[i], we[i], rpz, hpz)  # fmt: skip
        for k in range(6):
            out[k, i] = r[k]


@jit
def _speed_loop(gsn, gse, wn, we, acalt, cas, hdg):  # type: ignore[no-untyped-def]
    for i in grid_range(gsn.shape[0]):
        tasn, tase = gsn[i] - wn[i], gse[i] - we[i]
        p, rho, _ = isa_layered(acalt[i])
        cas[i] = tas2cas_at(math.sqrt(tasn * tasn + tase * tase), p, rho)
        hdg[i] = math.atan2(tase, tasn) * DEG


def create_conflicts(
    sim: Simulator,
    env: ArrayLike,
    target: ArrayLike,
    slot: ArrayLike,
    dpsi: ArrayLike,
    dcpa: ArrayLike,
    tlosh: ArrayLike,
    dh: ArrayLike | None = None,
    tlosv: ArrayLike | None = None,
    spd: ArrayLike | None = None,
    rpz: float = PZ_RADIUS,
    hpz: float = PZ_HEIGHT,
    actype: str | Sequence[str] | NDArray[np.str_] | None = None,
) -> None:
    """Create intruders in conflict with target aircraft (BlueSky ``traf.creconfs``) [docs/dynamics.md §3].

    The geometry is :func:`conflict_geometry`; the intruder's CAS comes from BlueSky's layered ISA.

    Args:
        sim: The simulator.
        env: Airspace of each intruder.
        target: Slot of the target (ownship) aircraft.
        slot: Free slot for the intruder.
        dpsi: Track difference intruder - target [deg].
        dcpa: Predicted distance at the closest point of approach [NM].
        tlosh: Time to horizontal loss of separation [s].
        dh: Altitude offset [m] (BlueSky adds it in metres), or None for the same altitude.
        tlosv: Time to vertical loss of separation [s] (defaults to ``tlosh``).
        spd: Intruder CAS [m/s] or Mach, or None for the target's ground speed.
        rpz: Protected-zone radius [m].
        hpz: Protected-zone half height [m].
        actype: Intruder type (one name or one per intruder), or None for the default type. The
            geometry does not depend on it; each intruder is created on its own, as BlueSky does.
    """
    env, target = aircraft_index(env, target, sim.n_envs, sim.max_aircraft)
    _, slot = aircraft_index(env, slot, sim.n_envs, sim.max_aircraft)
    n = env.size

    def bc(x: ArrayLike) -> Array:
        return np.ascontiguousarray(np.broadcast_to(np.asarray(x, dtype=np.float64), (n,)))

    dpsi, dcpa, tlosh = bc(dpsi), bc(dcpa), bc(tlosh)
    latref, lonref, altref = sim.lat[env, target], sim.lon[env, target], sim.alt[env, target]
    dh_a = np.full(n, np.nan) if dh is None else bc(dh)
    tlosv_a = tlosh if tlosv is None else bc(tlosv)
    if spd is None:
        tas = wn = we = np.full(n, np.nan)
    else:
        acalt = altref if dh is None else altref + dh_a
        tas = casormach2tas(bc(spd), acalt)
        wn, we = (np.ascontiguousarray(w, dtype=np.float64) for w in sim.wind.at(env, latref, lonref))
    out = np.empty((6, n))
    _geometry_loop(latref, lonref, altref, sim.trk[env, target], sim.gs[env, target], sim.vs[env, target],
                   dpsi, dcpa, tlosh, dh_a, tlosv_a, tas, wn, we, float(rpz), float(hpz), out)  # fmt: skip
    aclat, aclon, acalt, acvs, gsn, gse = out
    wn2, we2 = (np.ascontiguousarray(w, dtype=np.float64) for w in sim.wind.at(env, aclat, aclon))
    acspd, achdg = np.empty(n), np.empty(n)
    _speed_loop(gsn, gse, wn2, we2, acalt, acspd, achdg)
    sim.create(env, slot, aclat, aclon, achdg, acalt, acspd, actype=actype)
    sim.cmd_altitude(env, slot, altref, acvs)
    sim.vs[env, slot] = acvs


@dataclass(frozen=True)
class Conflicts:
    """Pairwise conflict picture of every airspace; arrays shaped (n_envs, n_aircraft, n_aircraft).

    Entry ``[e, i, j]`` describes intruder ``j`` as seen from ownship ``i`` (``i != j``).
    """

    conflict: NDArray[np.bool_]  # predicted conflict within the look-ahead time
    los: NDArray[np.bool_]  # loss of separation now (inside both the radius and the height)
    qdr: Array  # deg, bearing i -> j in (-180, 180]
    dist: Array  # m, horizontal distance
    tcpa: Array  # s, time to closest point of approach
    dcpa: Array  # m, distance at closest point of approach (NaN when it is exactly 0)
    tlos: Array  # s, time to loss of separation

    @property
    def in_conflict(self) -> NDArray[np.bool_]:
        """(n_envs, n_aircraft) aircraft with at least one conflict."""
        return np.asarray(self.conflict.any(axis=-1))


def detect(
    lat: Array,
    lon: Array,
    alt: Array,
    gs: Array,
    trk: Array,
    vs: Array,
    active: NDArray[np.bool_],
    rpz: float = PZ_RADIUS,
    hpz: float = PZ_HEIGHT,
    lookahead: float = LOOKAHEAD,
) -> Conflicts:
    """State-based conflict detection over all ordered pairs (BlueSky CSTATEBASED) [docs/dynamics.md §5].

    All inputs are shaped (n_envs, n_aircraft). Only pairs of active aircraft can conflict.
    """
    active = np.ascontiguousarray(active, dtype=np.bool_)
    lat, lon, alt, gs, trk, vs = (
        np.ascontiguousarray(np.broadcast_to(np.asarray(x, dtype=np.float64), active.shape)) for x in (lat, lon, alt, gs, trk, vs)
    )
    pairs = active.shape + (active.shape[-1],)
    conflict, los = np.empty(pairs, np.bool_), np.empty(pairs, np.bool_)
    qdr, dist, tcpa, dcpa, tin = (np.empty(pairs) for _ in range(5))
    detect_loop(lat, lon, alt, gs, trk, vs, active, float(rpz), float(hpz), float(lookahead), conflict, los, qdr, dist, tcpa, dcpa, tin)
    return Conflicts(conflict, los, qdr, dist, tcpa, dcpa, tin)


@jit
def detect_pair(
    lat_i: float,
    lon_i: float,
    alt_i: float,
    gs_i: float,
    trk_i: float,
    vs_i: float,
    lat_j: float,
    lon_j: float,
    alt_j: float,
    gs_j: float,
    trk_j: float,
    vs_j: float,
    rpz: float,
    hpz: float,
    lookahead: float,
) -> tuple[bool, bool, float, float, float, float, float]:
    """CSTATEBASED for one ordered pair, ownship ``i`` and intruder ``j`` (not masked by activity) [docs/dynamics.md §5].

    Returns:
        (conflict, loss of separation, bearing i -> j [deg], distance [m], time to CPA [s],
        distance at CPA [m], time to loss of separation [s]); see :class:`Conflicts`.
    """
    u_i = gs_i * math.sin(trk_i * DEG2RAD)
    v_i = gs_i * math.cos(trk_i * DEG2RAD)
    u_j = gs_j * math.sin(trk_j * DEG2RAD)
    v_j = gs_j * math.cos(trk_j * DEG2RAD)
    du = u_i - u_j
    dv = v_i - v_j
    lat1 = lat_i * DEG2RAD
    lat2 = lat_j * DEG2RAD
    dlat = lat2 - lat1
    dlon = lon_j * DEG2RAD - lon_i * DEG2RAD
    cavelat = math.cos(0.5 * (lat1 + lat2))
    d = R_EARTH * math.sqrt(dlat * dlat + dlon * dlon * cavelat * cavelat)
    q = fmod(math.atan2(dlon * cavelat, dlat), 360.0)
    dx = d * math.sin(q)
    dy = d * math.cos(q)
    vreldotdx = du * dx + dv * dy
    los_h = d < rpz
    vrel2 = du * du + dv * dv
    tcpa = divide(vreldotdx, vrel2)
    cpa2 = d * d - vreldotdx * tcpa
    dcpa = math.sqrt(cpa2) if cpa2 >= 0.0 else math.nan
    dth = math.sqrt(divide(maximum(rpz * rpz - cpa2, 0.0), vrel2))
    tin_h = tcpa - dth
    tout_h = tcpa + dth
    hor = (vreldotdx >= 0.0) or los_h
    hor = hor and (los_h or tin_h <= lookahead)

    dalt = alt_i - alt_j
    dvs = vs_i - vs_j
    los_v = abs(dalt) < hpz
    if abs(dvs) > 1e-6:
        tcrosshi = (dalt + hpz) / -dvs
        tcrosslo = (dalt - hpz) / -dvs
        tin_v = maximum(0.0, minimum(tcrosslo, tcrosshi))
        tout_v = maximum(tcrosslo, tcrosshi)
        ver = tin_v <= lookahead and tout_v > 0.0
    else:
        tin_v = 0.0
        tout_v = 1e4
        ver = los_v
    tin = maximum(tin_h, tin_v)
    tout = minimum(tout_h, tout_v)
    conflict = ver and hor and tin <= lookahead and tin < tout and tout > 0.0
    return conflict, conflict and los_h and los_v, q * RAD2DEG, d, tcpa, dcpa, tin


@jit
def detect_loop(lat, lon, alt, gs, trk, vs, active, rpz, hpz, lookahead, conflict, los, qdr, dist, tcpa, dcpa, tin):  # type: ignore[no-untyped-def]
    """:func:`detect_pair` over every ordered pair of every airspace (one airspace per ``grid_range`` index); outputs (n_envs, m, m)."""
    m = active.shape[1]
    for e in grid_range(active.shape[0]):
        for i in range(m):
            for j in range(m):
                c, lo, q, d, t, dc, ti = detect_pair(
                    lat[e, i], lon[e, i], alt[e, i], gs[e, i], trk[e, i], vs[e, i],
                    lat[e, j], lon[e, j], alt[e, j], gs[e, j], trk[e, j], vs[e, j],
                    rpz, hpz, lookahead,
                )  # fmt: skip
                pair = active[e, i] and active[e, j] and i != j
                conflict[e, i, j] = pair and c
                los[e, i, j] = pair and lo
                qdr[e, i, j] = q
                dist[e, i, j] = d
                tcpa[e, i, j] = t
                dcpa[e, i, j] = dc
                tin[e, i, j] = ti


#: Conflict detectors by BlueSky name (``ASAS <name>``): the compiled CSTATEBASED and the Python STATEBASED.
DETECTORS = ("CSTATEBASED", "STATEBASED")
NO_CONFLICT_TIME = 1e8  # s, STATEBASED's entry/exit time of a pair without horizontal conflict
SELF_PAIR = 1e9  # m, s: what STATEBASED adds on the diagonal (distance, time to CPA, altitude difference)
SPEED2_FLOOR = 1e-6  # m^2/s^2 and m/s: STATEBASED's floor of the squared relative speed and of the vertical-speed difference


def detect_statebased(
    lat: Array,
    lon: Array,
    alt: Array,
    gs: Array,
    trk: Array,
    vs: Array,
    active: NDArray[np.bool_],
    rpz: float = PZ_RADIUS,
    hpz: float = PZ_HEIGHT,
    lookahead: float = LOOKAHEAD,
    python_geo: bool = False,
) -> Conflicts:
    """BlueSky 1.1.1's Python STATEBASED detection (what ``ASAS ON`` selects), over all ordered pairs [docs/dynamics.md §5].

    Its formulas differ from CSTATEBASED's (:func:`detect`) in their floors and in how a pair
    without horizontal conflict is timed. It takes its bearings from BlueSky's
    ``kwikqdrdist_matrix``: the compiled one (BlueSky's default, ``python_geo=False``) gives the
    pair (i, j) with i > j the bearing j -> i, so the higher-index aircraft see approaching
    intruders on the wrong side and those pairs appear only in loss of separation; the Python one
    (when BlueSky runs with its Python geo functions, see ``Simulator(geo=...)``) is correct.
    Aircraft are indexed by slot, which is BlueSky's creation order. All inputs are shaped
    (n_envs, n_aircraft).
    """
    n = lat.shape[-1]
    upper = np.triu(np.ones((n, n), dtype=bool), 1)
    eye = np.eye(n)
    with np.errstate(all="ignore"):
        if python_geo:
            qdr, dist_nm = geo.kwikqdrdist_matrix_python(lat, lon)
        else:
            q_ij, d_ij = geo.kwikqdrdist(lat[..., :, None], lon[..., :, None], lat[..., None, :], lon[..., None, :])
            qdr = np.where(upper, q_ij, np.swapaxes(q_ij, -1, -2))  # the matrix form copies i -> j into (j, i)
            qdr = np.where(eye > 0, 0.0, qdr)
            dist_nm = np.where(eye > 0, 0.0, np.where(upper, d_ij, np.swapaxes(d_ij, -1, -2)))
        dist = dist_nm * NM + SELF_PAIR * eye
        qdrrad = np.radians(qdr)
        dx = dist * np.sin(qdrrad)
        dy = dist * np.cos(qdrrad)
        trkrad = np.radians(trk)
        u = gs * np.sin(trkrad)
        v = gs * np.cos(trkrad)
        du = u[..., None, :] - u[..., :, None]
        dv = v[..., None, :] - v[..., :, None]
        dv2 = du * du + dv * dv
        dv2 = np.where(np.abs(dv2) < SPEED2_FLOOR, SPEED2_FLOOR, dv2)
        vrel = np.sqrt(dv2)
        tcpa = -(du * dx + dv * dy) / dv2 + SELF_PAIR * eye
        dcpa2 = np.abs(dist * dist - tcpa * tcpa * dv2)
        r2 = rpz * rpz
        swhorconf = dcpa2 < r2
        dtinhor = np.sqrt(np.maximum(0.0, r2 - dcpa2)) / vrel
        tinhor = np.where(swhorconf, tcpa - dtinhor, NO_CONFLICT_TIME)
        touthor = np.where(swhorconf, tcpa + dtinhor, -NO_CONFLICT_TIME)
        dalt = alt[..., None, :] - alt[..., :, None] + SELF_PAIR * eye
        dvs = vs[..., None, :] - vs[..., :, None]
        dvs = np.where(np.abs(dvs) < SPEED2_FLOOR, SPEED2_FLOOR, dvs)
        tcrosshi = (dalt + hpz) / -dvs
        tcrosslo = (dalt - hpz) / -dvs
        tinconf = np.maximum(np.minimum(tcrosshi, tcrosslo), tinhor)
        toutconf = np.minimum(np.maximum(tcrosshi, tcrosslo), touthor)
        pair = active[..., :, None] & active[..., None, :] & ~np.eye(n, dtype=bool)
        conflict = pair & swhorconf & (tinconf <= toutconf) & (toutconf > 0.0) & (tinconf < lookahead)
        los = pair & (dist < rpz) & (np.abs(dalt) < hpz)
        return Conflicts(conflict, los, qdr, dist, tcpa, np.sqrt(dcpa2), tinconf)


def detect_with(
    detector: str,
    lat: Array,
    lon: Array,
    alt: Array,
    gs: Array,
    trk: Array,
    vs: Array,
    active: NDArray[np.bool_],
    rpz: float = PZ_RADIUS,
    hpz: float = PZ_HEIGHT,
    lookahead: float = LOOKAHEAD,
    python_geo: bool = False,
) -> Conflicts:
    """:func:`detect` (``"CSTATEBASED"``) or :func:`detect_statebased` (``"STATEBASED"``, with ``python_geo``).

    Raises:
        ValueError: Another detector name.
    """
    if detector == "CSTATEBASED":
        return detect(lat, lon, alt, gs, trk, vs, active, rpz, hpz, lookahead)
    if detector == "STATEBASED":
        return detect_statebased(lat, lon, alt, gs, trk, vs, active, rpz, hpz, lookahead, python_geo)
    raise ValueError(f"conflict detector {detector!r} not known; choose one of {', '.join(DETECTORS)}")


def horizontal_distance_nm(lat: Array, lon: Array) -> Array:
    """(…, n, n) kwik distance [NM] between all aircraft pairs of each airspace."""
    return geo.kwikdist(lat[..., :, None], lon[..., :, None], lat[..., None, :], lon[..., None, :])


__all__ = [
    "Conflicts",
    "DETECTORS",
    "create_conflicts",
    "detect",
    "detect_statebased",
    "detect_with",
    "horizontal_distance_nm",
    "PZ_RADIUS",
    "PZ_HEIGHT",
    "LOOKAHEAD",
    "M2NM",
]
