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
from bluesky_gym.core.jit import fmod, grid_range, jit, jit_inline, scratch
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


# --- Which pairs are evaluated: all of them, or those a grid of latitude bands finds ---------------
#: The simulator's choices of pair search (``Simulator(pair_search=...)``).
PAIR_SEARCHES = ("auto", "all-pairs", "grid")
#: Aircraft slots per airspace from which ``pair_search="auto"`` searches the grid (below it: all pairs).
GRID_MIN_AIRCRAFT = 256
GRID_MARGIN_REL = 1e-6  # -, relative margin of the grid's reach (far above the rounding of detect_pair)
GRID_MARGIN_M = 1.0  # m, absolute margin of the grid's reach and of its vertical bound
GRID_PAIRS = 1024  # candidate pairs the grid's buffers make room for at first


def resolve_pair_search(pair_search: str, max_aircraft: int) -> str:
    """``"all-pairs"`` or ``"grid"``: ``pair_search`` itself, or what ``"auto"`` picks for ``max_aircraft`` slots per airspace.

    Raises:
        ValueError: A name not in :data:`PAIR_SEARCHES`.
    """
    if pair_search not in PAIR_SEARCHES:
        raise ValueError(f"pair_search {pair_search!r} not known; choose one of {', '.join(PAIR_SEARCHES)}")
    if pair_search == "auto":
        return "grid" if max_aircraft >= GRID_MIN_AIRCRAFT else "all-pairs"
    return pair_search


@dataclass(frozen=True)
class ConflictPairs:
    """The conflicts of every airspace as a list of ordered pairs, sorted by (airspace, ownship, intruder).

    The entries are those of :class:`Conflicts` where ``conflict`` is True (a loss of separation
    is always a conflict), for airspaces of ``n_aircraft`` slots.
    """

    n_aircraft: int  # slots per airspace
    env: NDArray[np.int64]  # airspace of each pair
    own: NDArray[np.int64]  # ownship slot
    intruder: NDArray[np.int64]  # intruder slot
    los: NDArray[np.bool_]  # loss of separation now
    qdr: Array  # deg, bearing ownship -> intruder
    dist: Array  # m, horizontal distance
    tcpa: Array  # s, time to closest point of approach
    dcpa: Array  # m, distance at closest point of approach (NaN when it is exactly 0)
    tlos: Array  # s, time to loss of separation

    @classmethod
    def from_dense(cls, c: Conflicts) -> ConflictPairs:
        """The conflict pairs of a :class:`Conflicts` picture."""
        env, own, intruder = np.nonzero(c.conflict)  # C order: sorted by (airspace, ownship, intruder)
        at = (env, own, intruder)
        return cls(int(c.conflict.shape[-1]), env, own, intruder, c.los[at], c.qdr[at], c.dist[at], c.tcpa[at], c.dcpa[at], c.tlos[at])

    @property
    def flat_own(self) -> NDArray[np.int64]:
        """The ownship as a flat aircraft index ``env * n_aircraft + own``."""
        return self.env * self.n_aircraft + self.own


@jit_inline
def may_conflict(
    lat_i: float,
    lon_i: float,
    alt_i: float,
    vs_i: float,
    u_i: float,
    v_i: float,
    cos_i: float,
    lat_j: float,
    lon_j: float,
    alt_j: float,
    vs_j: float,
    u_j: float,
    v_j: float,
    cos_j: float,
    rpz: float,
    hpz: float,
    lookahead: float,
) -> bool:
    """False only for a pair that :func:`detect_pair` cannot find in conflict (finite states, ``|lat| <= 90``); symmetric in i and j.

    A conflict needs a moment ``t`` in ``[0, lookahead]`` at which the pair is inside the
    protected zone: horizontally, the relative position ``r - w t`` (``r`` the intruder's
    position relative to the ownship on :func:`detect_pair`'s flat earth, ``w`` the ownship's
    velocity relative to the intruder's) is then within ``rpz`` of the origin, so the segment
    ``{w t}`` passes within ``rpz`` of ``r``; vertically, the altitude difference now is at most
    ``hpz + |dvs| * lookahead``. :func:`detect_pair` scales the longitude difference by the
    cosine of the mean latitude (without wrapping the longitude), which lies between the
    cosines of the two latitudes and 1 where they straddle the equator: ``r`` is known to within
    half that spread, which widens the zone. The bounds have margins (:data:`GRID_MARGIN_REL`,
    :data:`GRID_MARGIN_M`) far above rounding.

    Args:
        lat_i: Ownship latitude [deg] (and so on for the intruder ``j``).
        lon_i: Longitude [deg].
        alt_i: Altitude [m].
        vs_i: Vertical speed [m/s].
        u_i: Ground speed east [m/s] (``gs * sin(trk)``).
        v_i: Ground speed north [m/s].
        cos_i: Cosine of the latitude, clipped at 0.
        lat_j: Intruder latitude [deg].
        lon_j: Intruder longitude [deg].
        alt_j: Intruder altitude [m].
        vs_j: Intruder vertical speed [m/s].
        u_j: Intruder ground speed east [m/s].
        v_j: Intruder ground speed north [m/s].
        cos_j: Cosine of the intruder's latitude, clipped at 0.
        rpz: Protected-zone radius [m].
        hpz: Protected-zone half height [m].
        lookahead: Look-ahead time [s] (negative counts as 0).
    """
    look = lookahead if lookahead > 0.0 else 0.0
    if abs(alt_i - alt_j) > (hpz + abs(vs_i - vs_j) * look) * (1.0 + GRID_MARGIN_REL) + GRID_MARGIN_M:
        return False
    c_lo = cos_i if cos_i < cos_j else cos_j
    c_hi = 1.0 if (lat_i <= 0.0) != (lat_j <= 0.0) else (cos_j if cos_i < cos_j else cos_i)
    dlon = (lon_j - lon_i) * DEG2RAD * R_EARTH
    rx = dlon * (0.5 * (c_lo + c_hi))
    ry = (lat_j - lat_i) * DEG2RAD * R_EARTH
    spread = 0.5 * abs(dlon) * (c_hi - c_lo)
    wx = u_i - u_j
    wy = v_i - v_j
    w2 = wx * wx + wy * wy
    t = 0.0
    if w2 > 0.0:
        t = (rx * wx + ry * wy) / w2
        t = 0.0 if t < 0.0 else (look if t > look else t)
    ex = rx - wx * t
    ey = ry - wy * t
    zone = (rpz + spread) * (1.0 + GRID_MARGIN_REL) + GRID_MARGIN_M
    return ex * ex + ey * ey <= zone * zone


@jit_inline
def record_pair(i, j, lat, lon, alt, gs, trk, vs, rpz, hpz, lookahead, pair_ij, pair_f, pair_los, counts):  # type: ignore[no-untyped-def]
    """:func:`detect_pair` of ownship ``i`` and intruder ``j`` (flat indices); a conflict is appended to the pair buffers.

    ``counts[0]`` counts the conflicts found, also those past the buffers' room (which are not written).
    """
    c, lo, q, d, t, dc, ti = detect_pair(
        lat[i], lon[i], alt[i], gs[i], trk[i], vs[i],
        lat[j], lon[j], alt[j], gs[j], trk[j], vs[j],
        rpz, hpz, lookahead,
    )  # fmt: skip
    if c:
        k = counts[0]
        if k < pair_los.shape[0]:
            pair_ij[0, k] = i
            pair_ij[1, k] = j
            pair_los[k] = lo
            pair_f[0, k] = q
            pair_f[1, k] = d
            pair_f[2, k] = t
            pair_f[3, k] = dc
            pair_f[4, k] = ti
        counts[0] = k + 1


@jit_inline
def scan_window(  # type: ignore[no-untyped-def]
    p, a, t, hi, full, order, s_lat, s_lon, s_alt, s_vs, s_u, s_v, s_cos, rpz, hpz, lookahead, cand, counts,
):  # fmt: skip
    """The candidate pairs of the aircraft at grid position ``p`` with those at ``a .. t-1`` up to longitude ``hi`` (one cell's, by longitude).

    Where :func:`may_conflict` allows (everywhere in a ``full`` airspace), the pair (flat indices)
    is a candidate: appended to ``cand`` (2, room) as far as it has room, and counted in ``counts[1]``.
    """
    i = order[p]
    lat_p, lon_p, alt_p, vs_p, u_p, v_p, cos_p = s_lat[p], s_lon[p], s_alt[p], s_vs[p], s_u[p], s_v[p], s_cos[p]
    for q in range(a, t):
        if not full:
            if s_lon[q] > hi:
                break
            if not may_conflict(
                lat_p, lon_p, alt_p, vs_p, u_p, v_p, cos_p, s_lat[q], s_lon[q], s_alt[q], s_vs[q], s_u[q], s_v[q], s_cos[q], rpz, hpz, lookahead
            ):
                continue
        k = counts[1]
        if k < cand.shape[1]:
            cand[0, k] = i
            cand[1, k] = order[q]
        counts[1] = k + 1


@jit_inline
def half_width(reach_deg, c):  # type: ignore[no-untyped-def]
    """The longitude [deg] that the reach ``reach_deg`` spans where the cosine of latitude is at least ``c``; infinite near the poles."""
    if c > 0.0 and reach_deg < 180.0 * c:
        return reach_deg / c
    return math.inf


@jit_inline
def scan_cell(  # type: ignore[no-untyped-def]
    p, s, t, own, full, reach_deg, cell_cos, order, s_lat, s_lon, s_alt, s_vs, s_u, s_v, s_cos, rpz, hpz, lookahead, cand, counts,
):  # fmt: skip
    """:func:`scan_window` of the aircraft at grid position ``p`` with the cell at ``s .. t-1`` (``own``: the later aircraft of p's own cell).

    See :func:`grid_detect_kernel`. The window is the longitude the reach spans at the smallest
    cosine of latitude of the two (the cell's bound ``cell_cos``), found by bisection; the later
    aircraft of p's own cell lie at ``lon >= lon_p`` already.
    """
    hi = math.inf
    a = s
    if not full:
        w = half_width(reach_deg, minimum(s_cos[p], cell_cos))
        hi = s_lon[p] + w
        lo_lon = s_lon[p] - w
        z = s if own else t
        while a < z:  # the first position with lon >= lo_lon
            mid = (a + z) >> 1
            if s_lon[mid] < lo_lon:
                a = mid + 1
            else:
                z = mid
    scan_window(p, a, t, hi, full, order, s_lat, s_lon, s_alt, s_vs, s_u, s_v, s_cos, rpz, hpz, lookahead, cand, counts)


@jit_inline
def sweep_cell(  # type: ignore[no-untyped-def]
    p, k, ptr, wid, t, order, s_lat, s_lon, s_alt, s_vs, s_u, s_v, s_cos, rpz, hpz, lookahead, cand, counts,
):  # fmt: skip
    """:func:`scan_window` of the aircraft at grid position ``p`` with the ``k``-th neighbour cell of its cell, ending at ``t``.

    The aircraft of a cell come by rising longitude, so the first position of the neighbour's
    window (half width ``wid[k]``, the reach at the smaller cosine bound of the two cells) only
    moves forward: ``ptr[k]`` keeps it from one aircraft of the cell to the next.
    """
    a = ptr[k]
    lo_lon = s_lon[p] - wid[k]
    while a < t and s_lon[a] < lo_lon:
        a += 1
    ptr[k] = a
    scan_window(p, a, t, s_lon[p] + wid[k], False, order, s_lat, s_lon, s_alt, s_vs, s_u, s_v, s_cos, rpz, hpz, lookahead, cand, counts)


@jit
def grid_detect_kernel(  # type: ignore[no-untyped-def]
    m, good, lat, lon, alt, gs, trk, vs, rpz, hpz, lookahead, prev, env_f, env_i, cell_start, cell_cos, cell_info, cell_of, order, pcell, sw,
    cand, pair_ij, pair_f, pair_los, row, out_ij, out_f, out_los, counts,
):  # fmt: skip
    """CSTATEBASED conflict detection of every airspace on a grid of cells; the conflicts as pairs sorted by (ownship, intruder).

    Per airspace (``m`` slots each; the state flat, ``good`` the active aircraft), the reach (the
    largest distance of a pair in conflict, ``rpz + 2 gs_max lookahead`` with margins) gives bands
    of latitude at least one reach high (at most about ``4 m``). Each band holds layers of
    altitude of the level aircraft (vertical speed 0), at least ``hpz`` high with margins (the
    largest altitude difference of a level pair in conflict), and one cell for the others. The
    aircraft are put in cell order (starting from the order ``prev`` of the last call, so that the
    sort by longitude within each cell has little to do). A level aircraft pairs with the later
    aircraft of its cell, those of the layer above in its band and those of the three nearest
    layers of the next band; a climbing or descending one with the later aircraft of its cell,
    those of the next band's such cell, and the level aircraft of every layer of its band and of
    the bands on either side: each unordered pair of neighbouring cells once, within the window of
    longitude the reach spans at the band's smallest cosine of latitude, where
    :func:`may_conflict` allows (:func:`scan_cell`; a level aircraft's windows in the neighbour
    cells start where the previous aircraft of its cell left them, :func:`sweep_cell`, since both
    cells come by longitude). A pair more than one band or one layer apart
    cannot be in conflict. An airspace with a non-finite state or ``|lat| > 90`` is one cell whose
    pairs are all evaluated. The candidates, in both orders, go through :func:`detect_pair`.

    Outputs: ``order[:n]``, ``pcell[:n]`` (the aircraft and their cell by grid position),
    ``counts`` (conflicts found, candidate pairs, aircraft placed ``n``); where the candidates fit
    ``cand`` (2, room; the conflict buffers have room for twice as many), ``out_ij`` (flat ownship, flat intruder), ``out_f`` (bearing,
    distance, time to CPA, distance at CPA, time to loss of separation), ``out_los`` sorted by
    ownship and intruder, and ``row`` (aircraft ``k``'s conflicts are ``row[k]:row[k + 1]``).
    ``env_f``, ``env_i``, ``cell_start``, ``cell_cos``, ``cell_info`` (airspace, band, layer of
    each cell), ``cell_of``, ``sw``, ``cand``, ``pair_*`` are work arrays.
    """
    n_envs = env_i.shape[1]
    n = good.shape[0]
    look = lookahead if lookahead > 0.0 else 0.0
    # 1. Per airspace: the bounds of its aircraft, its bands and layers, and the cosine bound of each cell.
    n_cells = 0
    for e in range(n_envs):
        full = False
        g = 0.0
        lo = math.inf
        hi = -math.inf
        a0 = math.inf
        a1 = -math.inf
        for k in range(e * m, (e + 1) * m):
            if not good[k]:
                continue
            x = lat[k] + lon[k] + alt[k] + gs[k] + trk[k] + vs[k]
            if not (x - x == 0.0) or abs(lat[k]) > 90.0:  # a NaN or an infinity
                full = True
            else:
                g = maximum(g, abs(gs[k]))
                lo = minimum(lo, lat[k])
                hi = maximum(hi, lat[k])
                if vs[k] == 0.0:  # level: the layers of altitude span these
                    a0 = minimum(a0, alt[k])
                    a1 = maximum(a1, alt[k])
        if lo > hi:  # no aircraft with a finite state
            lo = hi = 0.0
        if a0 > a1:  # no level aircraft
            a0 = a1 = 0.0
        reach = ((rpz + 2.0 * g * look) * (1.0 + GRID_MARGIN_REL) + GRID_MARGIN_M) / R_EARTH * RAD2DEG
        nb = 1
        nl = 0  # layers of level aircraft per band (each band also has a cell for the others)
        band_h = 1.0
        layer_h = 1.0
        if not full:
            band_h = maximum(reach, (hi - lo) / (4 * m + 64))  # no smaller than the reach, nor many more bands than aircraft
            nb = int(math.floor((hi - lo) / band_h)) + 1
            nl = 1
            span = a1 - a0
            if span - span == 0.0:
                vreach = (hpz * (1.0 + GRID_MARGIN_REL) + GRID_MARGIN_M) * (
                    1.0 + GRID_MARGIN_REL
                ) + GRID_MARGIN_M  # may_conflict's bound of level pairs, with margin
                layer_h = maximum(vreach, span / max(1, (4 * m + 64) // nb))
                nl = int(math.floor(span / layer_h)) + 1
        env_f[0, e] = reach
        env_f[1, e] = band_h
        env_f[2, e] = lo
        env_f[3, e] = a0
        env_f[4, e] = layer_h
        env_i[0, e] = 1 if full else 0
        env_i[1, e] = nb
        env_i[2, e] = nl
        env_i[3, e] = n_cells
        for b in range(nb):
            edge_lo = lo + b * band_h
            edge = minimum(maximum(abs(edge_lo), abs(edge_lo + band_h)), 90.0)  # the band's edge farthest from the equator
            c = maximum(math.cos(edge * DEG2RAD), 0.0)
            for la in range(nl + 1):
                d = n_cells + b * (nl + 1) + la
                cell_cos[d] = c
                cell_info[0, d] = e
                cell_info[1, d] = b
                cell_info[2, d] = la
        n_cells += nb * (nl + 1)
    # 2. The cell of every aircraft, and the aircraft by cell (a counting sort, in the last call's order).
    for c in range(n_cells + 1):
        cell_start[c] = 0
    for e in range(n_envs):
        for k in range(e * m, (e + 1) * m):
            if not good[k]:
                continue
            c = env_i[3, e]
            if env_i[0, e] == 0:
                b = int(math.floor((lat[k] - env_f[2, e]) / env_f[1, e]))
                if b > env_i[1, e] - 1:
                    b = env_i[1, e] - 1
                nl = env_i[2, e]
                la = nl  # climbing or descending: the band's last cell
                if vs[k] == 0.0:
                    la = 0
                    if nl > 1:
                        la = int(math.floor((alt[k] - env_f[3, e]) / env_f[4, e]))
                        if la > nl - 1:
                            la = nl - 1
                c += b * (nl + 1) + la
            cell_of[k] = c
            cell_start[c + 1] += 1
    for c in range(n_cells):
        cell_start[c + 1] += cell_start[c]
    placed = 0
    for r in range(prev.shape[0] + n):
        k = prev[r] if r < prev.shape[0] else r - prev.shape[0]
        if k < 0 or k >= n or not good[k] or cell_of[k] < 0:
            continue
        c = cell_of[k]
        order[cell_start[c]] = k
        pcell[cell_start[c]] = c
        cell_start[c] += 1
        cell_of[k] = -1  # placed
        placed += 1
    for c in range(n_cells, 0, -1):
        cell_start[c] = cell_start[c - 1]
    cell_start[0] = 0
    counts[2] = placed
    # 3. Within each cell by longitude (an airspace searched in full: by slot); an insertion sort of a nearly sorted order.
    key = sw[1]
    for p in range(placed):
        k = order[p]
        e = cell_info[0, pcell[p]]
        key[p] = lon[k] if env_i[0, e] == 0 else k - e * m
    for c in range(n_cells):
        for p in range(cell_start[c] + 1, cell_start[c + 1]):
            k = order[p]
            x = key[p]
            q = p - 1
            while q >= cell_start[c] and key[q] > x:
                order[q + 1] = order[q]
                key[q + 1] = key[q]
                q -= 1
            order[q + 1] = k
            key[q + 1] = x
    # 4. The state by grid position, so that the scans read memory in sequence.
    for p in range(placed):
        k = order[p]
        sw[0, p] = lat[k]
        sw[2, p] = alt[k]
        sw[3, p] = vs[k]
        sw[4, p] = gs[k] * math.sin(trk[k] * DEG2RAD)  # ground velocity as detect_pair computes it
        sw[5, p] = gs[k] * math.cos(trk[k] * DEG2RAD)
        sw[6, p] = maximum(math.cos(lat[k] * DEG2RAD), 0.0)
    # 5. The scans: each unordered pair of neighbouring cells once.
    counts[0] = 0
    counts[1] = 0
    s_lat, s_lon, s_alt, s_vs, s_u, s_v, s_cos = sw[0], sw[1], sw[2], sw[3], sw[4], sw[5], sw[6]
    ptr = scratch(4, np.int64)  # a level aircraft's neighbour cells: the first position of each one's window ...
    wid = scratch(4, np.float64)  # ... and its half width in longitude
    end = scratch(4, np.int64)  # ... and its end (0 where the cell does not exist)
    for p in range(placed):
        c = pcell[p]
        e = cell_info[0, c]
        b = cell_info[1, c]
        la = cell_info[2, c]
        full = env_i[0, e] != 0
        nb = env_i[1, e]
        nl = env_i[2, e]
        reach = env_f[0, e]
        scan_cell(p, p + 1, cell_start[c + 1], True, full, reach, cell_cos[c], order, s_lat, s_lon, s_alt, s_vs, s_u, s_v, s_cos,
                  rpz, hpz, lookahead, cand, counts)  # fmt: skip
        if full:
            continue
        c0 = env_i[3, e]
        if la < nl:  # level: the layer above, and the three nearest layers of the next band
            if p == cell_start[c]:  # the cell's first aircraft: its neighbours' windows start at their first aircraft
                for k in range(4):
                    d = c + 1 if k == 0 else c0 + (b + 1) * (nl + 1) + la - 2 + k
                    there = la + 1 < nl if k == 0 else b + 1 < nb and 0 <= la - 2 + k < nl
                    end[k] = cell_start[d + 1] if there else 0
                    ptr[k] = cell_start[d] if there else 0
                    wid[k] = half_width(reach, minimum(cell_cos[c], cell_cos[d])) if there else 0.0
            for k in range(4):
                if end[k] > 0:
                    sweep_cell(p, k, ptr, wid, end[k], order, s_lat, s_lon, s_alt, s_vs, s_u, s_v, s_cos, rpz, hpz, lookahead, cand, counts)
            continue
        # Climbing or descending: the next band's such aircraft, and the level aircraft of every layer of this band and its two neighbours.
        if b + 1 < nb:
            d = c0 + (b + 1) * (nl + 1) + nl
            scan_cell(p, cell_start[d], cell_start[d + 1], False, full, reach, cell_cos[d], order, s_lat, s_lon, s_alt, s_vs, s_u,
                      s_v, s_cos, rpz, hpz, lookahead, cand, counts)  # fmt: skip
        for b2 in range(max(b - 1, 0), min(b + 2, nb)):
            for l2 in range(nl):
                d = c0 + b2 * (nl + 1) + l2
                scan_cell(p, cell_start[d], cell_start[d + 1], False, full, reach, cell_cos[d], order, s_lat, s_lon, s_alt, s_vs, s_u,
                          s_v, s_cos, rpz, hpz, lookahead, cand, counts)  # fmt: skip
    if counts[1] > cand.shape[1]:
        return  # no room for all candidates (the caller makes room and calls again)
    # 6. Both orders of each candidate pair through detect_pair (the conflict buffers hold twice the candidates).
    for f in range(counts[1]):
        record_pair(cand[0, f], cand[1, f], lat, lon, alt, gs, trk, vs, rpz, hpz, lookahead, pair_ij, pair_f, pair_los, counts)
        record_pair(cand[1, f], cand[0, f], lat, lon, alt, gs, trk, vs, rpz, hpz, lookahead, pair_ij, pair_f, pair_los, counts)
    # 7. The conflicts by ownship (a counting sort), then by intruder within each ownship.
    found = counts[0]
    for k in range(n + 1):
        row[k] = 0
    for f in range(found):
        row[pair_ij[0, f] + 1] += 1
    for k in range(n):
        row[k + 1] += row[k]
    for f in range(found):
        g = row[pair_ij[0, f]]
        row[pair_ij[0, f]] += 1
        out_ij[0, g] = pair_ij[0, f]
        out_ij[1, g] = pair_ij[1, f]
        for r in range(5):
            out_f[r, g] = pair_f[r, f]
        out_los[g] = pair_los[f]
    for k in range(n, 0, -1):
        row[k] = row[k - 1]
    row[0] = 0
    for k in range(n):
        for g in range(row[k] + 1, row[k + 1]):  # an ownship's few pairs by intruder (an insertion sort)
            h = g
            while h > row[k] and out_ij[1, h - 1] > out_ij[1, h]:
                for r in range(2):
                    out_ij[r, h - 1], out_ij[r, h] = out_ij[r, h], out_ij[r, h - 1]
                for r in range(5):
                    out_f[r, h - 1], out_f[r, h] = out_f[r, h], out_f[r, h - 1]
                out_los[h - 1], out_los[h] = out_los[h], out_los[h - 1]
                h -= 1


class GridWork:
    """The work arrays of :func:`detect_grid`, kept from call to call, and the grid's last order of the aircraft.

    Reusing them saves the allocations of every call, and the sort of each call starts from the
    order of the last one, which the aircraft have barely changed. Any order gives the same result,
    so one :class:`GridWork` may serve any traffic (it is resized to the airspaces it is given).
    """

    def __init__(self) -> None:
        self.shape = (0, 0)
        self.n_order = 0
        self.counts = np.zeros(3, np.int64)

    def fit(self, n_envs: int, m: int) -> None:
        """Size the arrays for ``n_envs`` airspaces of ``m`` slots (the last order is forgotten if the shape changes)."""
        if self.shape == (n_envs, m):
            return
        n = n_envs * m
        self.shape = (n_envs, m)
        self.n_order = 0
        self.env_f = np.empty((5, n_envs))
        self.env_i = np.empty((4, n_envs), np.int64)
        cells = n_envs * 3 * (4 * m + 65)  # at most 4 m + 65 bands per airspace, about twice as many layers, and one more cell per band
        self.cell_start = np.empty(cells + 1, np.int64)
        self.cell_cos = np.empty(cells)
        self.cell_info = np.empty((3, cells), np.int64)
        self.cell_of = np.empty(n, np.int64)
        self.order = np.empty(n, np.int64)
        self.spare = np.empty(n, np.int64)
        self.pcell = np.empty(n, np.int64)
        self.sorted_state = np.empty((7, n))
        self.row = np.zeros(n + 1, np.int64)
        self.reserve(GRID_PAIRS)

    def reserve(self, candidates: int) -> None:
        """Room for ``candidates`` candidate pairs (and their conflicts, at most two each)."""
        self.cand = np.empty((2, candidates), np.int64)
        pairs = 2 * candidates
        self.pair_ij, self.out_ij = np.empty((2, pairs), np.int64), np.empty((2, pairs), np.int64)
        self.pair_f, self.out_f = np.empty((5, pairs)), np.empty((5, pairs))
        self.pair_los, self.out_los = np.empty(pairs, np.bool_), np.empty(pairs, np.bool_)

    def detect(
        self,
        lat: Array,
        lon: Array,
        alt: Array,
        gs: Array,
        trk: Array,
        vs: Array,
        active: NDArray[np.bool_],
        rpz: float,
        hpz: float,
        lookahead: float,
    ) -> int:
        """:func:`grid_detect_kernel` of the state (shaped (n_envs, n_aircraft), as :func:`detect_grid`'s); the number of conflicts found.

        The conflicts are left in the arrays: :attr:`row`, :attr:`out_ij`, :attr:`out_f`,
        :attr:`out_los` (see :func:`grid_detect_kernel`).
        """
        active = np.ascontiguousarray(active, dtype=np.bool_)
        n_envs, m = active.shape
        lat, lon, alt, gs, trk, vs = (float_array(x, active.shape).reshape(-1) for x in (lat, lon, alt, gs, trk, vs))
        self.fit(n_envs, m)
        prev, out = self.order[: self.n_order], self.spare
        while True:
            grid_detect_kernel(
                m, active.reshape(-1), lat, lon, alt, gs, trk, vs, float(rpz), float(hpz), float(lookahead), prev, self.env_f,
                self.env_i, self.cell_start, self.cell_cos, self.cell_info, self.cell_of, out, self.pcell, self.sorted_state,
                self.cand, self.pair_ij, self.pair_f, self.pair_los, self.row, self.out_ij, self.out_f, self.out_los, self.counts,
            )  # fmt: skip
            if self.counts[1] <= self.cand.shape[1]:
                break
            self.reserve(2 * int(self.counts[1]))  # a crowded airspace: again with room for all
        self.order, self.spare, self.n_order = out, self.order, int(self.counts[2])
        return int(self.counts[0])

    @property
    def evaluated(self) -> int:
        """How many ordered pairs the last call evaluated with :func:`detect_pair` (both orders of each candidate)."""
        return 2 * int(self.counts[1])


def detect_grid(
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
    work: GridWork | None = None,
) -> ConflictPairs:
    """The conflicts of :func:`detect`, as pairs, evaluating only the pairs that a grid of cells finds.

    The same :func:`detect_pair` evaluates each pair, so the conflicts and their quantities are
    those of :func:`detect` to the bit; the grid (:func:`grid_detect_kernel`, :func:`may_conflict`)
    only leaves out pairs that cannot be in conflict, so the work grows about linearly with the
    number of aircraft at a given traffic density. All inputs are shaped (n_envs, n_aircraft).

    Args:
        lat: Latitude [deg] (the others likewise: :func:`detect`'s).
        lon: Longitude [deg].
        alt: Altitude [m].
        gs: Ground speed [m/s].
        trk: Track [deg].
        vs: Vertical speed [m/s].
        active: The aircraft that exist.
        rpz: Protected-zone radius [m].
        hpz: Protected-zone half height [m].
        lookahead: Look-ahead time [s].
        work: Work arrays to reuse from call to call (None: new ones); after the call its ``row``
            gives each aircraft's conflicts (flat index ``k``: entries ``row[k]:row[k + 1]``).
    """
    w = GridWork() if work is None else work
    found = w.detect(lat, lon, alt, gs, trk, vs, active, rpz, hpz, lookahead)
    m = w.shape[1]
    own = w.out_ij[0, :found].copy()
    f = w.out_f[:, :found]
    return ConflictPairs(m, own // m, own % m, w.out_ij[1, :found] % m, w.out_los[:found].copy(), *(f[r].copy() for r in range(5)))


def detect_pairs(
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
    detector: str = "CSTATEBASED",
    python_geo: bool = False,
    work: GridWork | None = None,
) -> ConflictPairs:
    """The conflict pairs of ``detector``: CSTATEBASED by :func:`detect_grid` (with ``work``), STATEBASED by :func:`detect_statebased` (all pairs).

    Raises:
        ValueError: Another detector name.
    """
    if detector == "CSTATEBASED":
        return detect_grid(lat, lon, alt, gs, trk, vs, active, rpz, hpz, lookahead, work)
    return ConflictPairs.from_dense(detect_with(detector, lat, lon, alt, gs, trk, vs, active, rpz, hpz, lookahead, python_geo))


def float_array(x: ArrayLike, shape: tuple[int, ...]) -> Array:
    """``x`` as a C-contiguous float64 array of ``shape`` (broadcast; no copy where it already is one)."""
    if isinstance(x, np.ndarray) and x.dtype == np.float64 and x.shape == shape and x.flags.c_contiguous:
        return x
    return np.ascontiguousarray(np.broadcast_to(np.asarray(x, dtype=np.float64), shape))


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
    eye = np.eye(n)
    with np.errstate(all="ignore"):
        qdr, dist_nm = geo.kwikqdrdist_matrix(lat, lon, python_geo)
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
    "ConflictPairs",
    "Conflicts",
    "GRID_MIN_AIRCRAFT",
    "GridWork",
    "PAIR_SEARCHES",
    "DETECTORS",
    "create_conflicts",
    "detect",
    "detect_grid",
    "detect_pairs",
    "detect_statebased",
    "detect_with",
    "horizontal_distance_nm",
    "PZ_RADIUS",
    "PZ_HEIGHT",
    "LOOKAHEAD",
    "M2NM",
]
