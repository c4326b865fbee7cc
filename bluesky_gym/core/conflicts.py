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
from bluesky_gym.core.jit import fmod, grid_range, jit, jit_inline
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
GRID_PARTNERS = 8  # candidate partners per aircraft the grid's scan makes room for at first


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
def scan_band(p, s, t, exhaustive, reach_deg, band_cos, lat, lon, alt, vs, u, v, cosl, rpz, hpz, lookahead, out, n):  # type: ignore[no-untyped-def]
    """The partners of the aircraft at position ``p`` among positions ``s .. t-1`` (one band's, by longitude), after ``n``; returns the new count.

    See :func:`grid_scan_loop`; the partners go to ``out[p, n:]`` as far as it has room.
    """
    hi = math.inf
    if not exhaustive:
        c = minimum(cosl[p], band_cos)
        if c > 0.0 and reach_deg < 180.0 * c:
            w = reach_deg / c
            hi = lon[p] + w
            lo_lon = lon[p] - w
            a = s
            z = t
            while a < z:  # the first position with lon >= lo_lon
                mid = (a + z) // 2
                if lon[mid] < lo_lon:
                    a = mid + 1
                else:
                    z = mid
            s = a
    lat_p, lon_p, alt_p, vs_p, u_p, v_p, cos_p = lat[p], lon[p], alt[p], vs[p], u[p], v[p], cosl[p]
    for q in range(s, t):
        if lon[q] > hi:
            break
        if not exhaustive:
            if not may_conflict(lat_p, lon_p, alt_p, vs_p, u_p, v_p, cos_p, lat[q], lon[q], alt[q], vs[q], u[q], v[q], cosl[q], rpz, hpz, lookahead):
                continue
        if n < out.shape[1]:
            out[p, n] = q
        n += 1
    return n


@jit
def grid_scan_loop(  # type: ignore[no-untyped-def]
    m, order, band, env_band0, env_nb, exhaustive, reach_deg, band_start, band_cos,
    lat, lon, alt, vs, u, v, cosl, rpz, hpz, lookahead, counts, out,
):  # fmt: skip
    """The candidate pairs of every airspace from the grid of latitude bands; all arrays by position in the grid's order.

    Each airspace's aircraft lie in bands of latitude at least one reach (the largest distance a
    pair in conflict can have) high, counted from ``env_band0[e]``. Position ``p`` holds aircraft
    ``order[p]`` (flat index ``env * m + slot``) of band ``band[p]``, by band and then by
    longitude, and the state arrays are in that order. The aircraft at ``p`` pairs with the later
    positions of its band and those of the next band, in the window of longitude its reach spans
    at the smallest cosine of latitude, where :func:`may_conflict` (symmetric) allows: each
    unordered pair once. An airspace marked ``exhaustive`` (non-finite or out-of-range states) has
    one band and every pair is a candidate. The partners' positions go to ``out[p, :]`` (as many
    as it holds) and their number to ``counts[p]``.
    """
    for p in grid_range(order.shape[0]):
        e = order[p] // m
        b = band[p]
        x = exhaustive[e]
        r = reach_deg[e]
        n = scan_band(p, p + 1, band_start[b + 1], x, r, band_cos[b], lat, lon, alt, vs, u, v, cosl, rpz, hpz, lookahead, out, 0)
        if b + 1 < env_band0[e] + env_nb[e]:
            c = b + 1
            n = scan_band(p, band_start[c], band_start[c + 1], x, r, band_cos[c], lat, lon, alt, vs, u, v, cosl, rpz, hpz, lookahead, out, n)
        counts[p] = n


@jit
def grid_bounds_loop(m, good, lat, lon, alt, gs, trk, vs, exhaustive, bounds):  # type: ignore[no-untyped-def]
    """Per airspace: whether its grid must be ``exhaustive`` (an active aircraft with a non-finite state or ``|lat| > 90``), and ``bounds``.

    ``bounds`` (4, n_envs): the largest ground speed [m/s], the smallest and the largest latitude
    and the smallest longitude [deg] of the active aircraft (0 where none).
    """
    for e in grid_range(exhaustive.shape[0]):
        x = False
        g = 0.0
        lo = math.inf
        hi = -math.inf
        west = math.inf
        for k in range(e * m, (e + 1) * m):
            if not good[k]:
                continue
            s = lat[k] + lon[k] + alt[k] + gs[k] + trk[k] + vs[k]
            if not (s - s == 0.0) or abs(lat[k]) > 90.0:  # a NaN or an infinity
                x = True
            else:
                g = maximum(g, abs(gs[k]))
                lo = minimum(lo, lat[k])
                hi = maximum(hi, lat[k])
                west = minimum(west, lon[k])
        exhaustive[e] = x
        bounds[0, e] = g
        bounds[1, e] = lo if lo <= hi else 0.0
        bounds[2, e] = hi if lo <= hi else 0.0
        bounds[3, e] = west if lo <= hi else 0.0


@jit
def grid_band_loop(m, good, lat, lon, exhaustive, lat0, lon0, band_h, env_nb, env_band0, band, within, key):  # type: ignore[no-untyped-def]
    """Every active aircraft's band (counted over all airspaces), its place ``within`` the band, and a sort ``key``.

    Within a band the aircraft go by longitude; in an exhaustive airspace (one band) by slot.
    The key orders them by band and nearly by ``within`` (:func:`sort_bands` makes it exact).
    """
    for k in grid_range(good.shape[0]):
        if not good[k]:
            continue
        e = k // m
        if exhaustive[e]:
            band[k] = env_band0[e]
            within[k] = k - e * m
            key[k] = env_band0[e] * 1024.0 + within[k] / m
            continue
        b = int(math.floor((lat[k] - lat0[e]) / band_h[e]))
        if b > env_nb[e] - 1:
            b = env_nb[e] - 1
        band[k] = env_band0[e] + b
        within[k] = lon[k]
        key[k] = band[k] * 1024.0 + (lon[k] - lon0[e]) / 360.0


@jit
def sort_bands(order, band, within):  # type: ignore[no-untyped-def]
    """Insertion sort of ``order`` by (``band``, ``within``) of its aircraft, in place; fast on a nearly sorted ``order``."""
    for k in range(1, order.shape[0]):
        x = order[k]
        bk = band[x]
        lk = within[x]
        j = k - 1
        while j >= 0 and (band[order[j]] > bk or (band[order[j]] == bk and within[order[j]] > lk)):
            order[j + 1] = order[j]
            j -= 1
        order[j + 1] = x


@jit
def detect_pairs_loop(own, intruder, lat, lon, alt, gs, trk, vs, rpz, hpz, lookahead, conflict, los, qdr, dist, tcpa, dcpa, tin):  # type: ignore[no-untyped-def]
    """:func:`detect_pair` of listed ordered pairs (flat aircraft indices); outputs one per pair."""
    for p in grid_range(own.shape[0]):
        i = own[p]
        j = intruder[p]
        c, lo, q, d, t, dc, ti = detect_pair(
            lat[i], lon[i], alt[i], gs[i], trk[i], vs[i],
            lat[j], lon[j], alt[j], gs[j], trk[j], vs[j],
            rpz, hpz, lookahead,
        )  # fmt: skip
        conflict[p] = c
        los[p] = lo
        qdr[p] = q
        dist[p] = d
        tcpa[p] = t
        dcpa[p] = dc
        tin[p] = ti


@jit
def velocity_loop(gs, trk, lat, u, v, cosl):  # type: ignore[no-untyped-def]
    """Ground velocity east and north [m/s] (as :func:`detect_pair` computes them) and the cosine of latitude clipped at 0."""
    for k in grid_range(gs.shape[0]):
        u[k] = gs[k] * math.sin(trk[k] * DEG2RAD)
        v[k] = gs[k] * math.cos(trk[k] * DEG2RAD)
        cosl[k] = maximum(math.cos(lat[k] * DEG2RAD), 0.0)


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
) -> ConflictPairs:
    """The conflicts of :func:`detect`, as pairs, evaluating only the pairs that a grid of latitude bands finds.

    The same :func:`detect_pair` evaluates each pair, so the conflicts and their quantities are
    those of :func:`detect` to the bit; the grid (:func:`grid_scan_loop`, :func:`may_conflict`)
    only leaves out pairs that cannot be in conflict, so the work grows about linearly with the
    number of aircraft at a given traffic density. All inputs are shaped (n_envs, n_aircraft).
    """
    active = np.ascontiguousarray(active, dtype=np.bool_)
    n_envs, m = active.shape
    lat, lon, alt, gs, trk, vs = (float_array(x, active.shape).reshape(-1) for x in (lat, lon, alt, gs, trk, vs))
    good = active.reshape(-1)
    n = good.shape[0]
    # Per airspace: the reach (largest distance of a pair in conflict), the bands of latitude.
    exhaustive = np.empty(n_envs, np.bool_)
    bounds = np.empty((4, n_envs))  # largest ground speed, smallest and largest latitude, smallest longitude
    grid_bounds_loop(m, good, lat, lon, alt, gs, trk, vs, exhaustive, bounds)
    gs_max, lat0, lat1, lon0 = bounds
    reach_deg = ((float(rpz) + 2.0 * gs_max * max(float(lookahead), 0.0)) * (1.0 + GRID_MARGIN_REL) + GRID_MARGIN_M) / R_EARTH * RAD2DEG
    band_h = np.maximum(reach_deg, (lat1 - lat0) / (4 * m + 64))  # no smaller than the reach, nor many more bands than aircraft
    env_nb = np.where(exhaustive, 1, np.floor((lat1 - lat0) / band_h).astype(np.int64) + 1)
    env_band0 = np.zeros(n_envs, np.int64)
    np.cumsum(env_nb[:-1], out=env_band0[1:])
    band, within, key = np.empty(n, np.int64), np.empty(n), np.empty(n)
    grid_band_loop(m, good, lat, lon, exhaustive, lat0, lon0, band_h, env_nb, env_band0, band, within, key)
    # The smallest cosine of latitude over each band (its edge farthest from the equator).
    n_bands = int(env_nb.sum())
    band_env = np.repeat(np.arange(n_envs), env_nb)
    edge_lo = lat0[band_env] + (np.arange(n_bands) - env_band0[band_env]) * band_h[band_env]
    edge = np.minimum(np.maximum(np.abs(edge_lo), np.abs(edge_lo + band_h[band_env])), 90.0)
    band_cos = np.maximum(np.cos(edge * DEG2RAD), 0.0)
    # The aircraft by band, then longitude: a quick sort of a key close to that order, made exact by an insertion sort.
    members = np.flatnonzero(good)
    order = members[np.argsort(key[members])]
    sort_bands(order, band, within)
    s_band = np.ascontiguousarray(band[order])
    band_start = np.searchsorted(s_band, np.arange(n_bands + 1)).astype(np.int64)
    # The state in the grid's order, so that the scans read memory in sequence.
    s_lat, s_lon, s_alt, s_gs, s_trk, s_vs = (x[order] for x in (lat, lon, alt, gs, trk, vs))
    p_all = order.size
    u, v, cosl = np.empty(p_all), np.empty(p_all), np.empty(p_all)
    velocity_loop(s_gs, s_trk, s_lat, u, v, cosl)
    rpz, hpz, lookahead = float(rpz), float(hpz), float(lookahead)
    counts = np.zeros(p_all, np.int64)
    args = (
        m,
        order,
        s_band,
        env_band0,
        env_nb,
        exhaustive,
        reach_deg,
        band_start,
        band_cos,
        s_lat,
        s_lon,
        s_alt,
        s_vs,
        u,
        v,
        cosl,
        rpz,
        hpz,
        lookahead,
    )
    partners = np.empty((p_all, GRID_PARTNERS), np.int64)
    grid_scan_loop(*args, counts, partners)
    most = int(counts.max(initial=0))
    if most > GRID_PARTNERS:  # a crowded airspace: scan again with room for all
        partners = np.empty((p_all, most), np.int64)
        grid_scan_loop(*args, counts, partners)
    intruder = partners[np.arange(partners.shape[1]) < counts[:, None]]
    first = np.repeat(np.arange(p_all, dtype=np.int64), counts)
    own, intruder = np.concatenate((first, intruder)), np.concatenate((intruder, first))  # both orders of each pair
    p = own.size
    conflict, los = np.empty(p, np.bool_), np.empty(p, np.bool_)
    qdr, dist, tcpa, dcpa, tin = (np.empty(p) for _ in range(5))
    detect_pairs_loop(own, intruder, s_lat, s_lon, s_alt, s_gs, s_trk, s_vs, rpz, hpz, lookahead, conflict, los, qdr, dist, tcpa, dcpa, tin)
    sel = np.flatnonzero(conflict)
    own, intruder = order[own[sel]], order[intruder[sel]]
    sort = np.lexsort((intruder, own))
    own, sel = own[sort], sel[sort]
    return ConflictPairs(m, own // m, own % m, intruder[sort] % m, los[sel], qdr[sel], dist[sel], tcpa[sel], dcpa[sel], tin[sel])


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
) -> ConflictPairs:
    """The conflict pairs of ``detector``: CSTATEBASED by :func:`detect_grid`, STATEBASED by :func:`detect_statebased` (all pairs).

    Raises:
        ValueError: Another detector name.
    """
    if detector == "CSTATEBASED":
        return detect_grid(lat, lon, alt, gs, trk, vs, active, rpz, hpz, lookahead)
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
