"""Conflict geometry: BlueSky's ``creconfs`` intruder placement and state-based detection.

Both are batched: ``create_conflicts`` places one intruder per requested (airspace, target) pair,
and :func:`detect` evaluates every ordered aircraft pair of every airspace at once with the
symmetric, correct geometry of BlueSky's compiled CSTATEBASED detector [dynamics.md 3, 5].
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from bluesky_gym.core import atmosphere as isa
from bluesky_gym.core import geo
from bluesky_gym.core.units import DEG2RAD, FT, M2NM, NM, R_EARTH, RAD2DEG

if TYPE_CHECKING:
    from bluesky_gym.core.simulator import Simulator

Array = NDArray[np.float64]

PZ_RADIUS = 5.0 * NM  # m, BlueSky's default horizontal protected-zone radius (asas_pzr)
PZ_HEIGHT = 1000.0 * FT  # m, default protected-zone half height (asas_pzh)
LOOKAHEAD = 300.0  # s, default look-ahead time (asas_dtlookahead)


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
) -> None:
    """Create intruders in conflict with target aircraft (BlueSky ``traf.creconfs``) [dynamics.md 3].

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
    """
    env, target = sim._index(env, target)
    _, slot = sim._index(env, slot)
    n = env.size
    bc = lambda x: np.broadcast_to(np.asarray(x, dtype=np.float64), (n,))  # noqa: E731
    dpsi, dcpa, tlosh = bc(dpsi), bc(dcpa), bc(tlosh)
    latref = sim.lat[env, target]
    lonref = sim.lon[env, target]
    altref = sim.alt[env, target]
    trkref = np.radians(sim.trk[env, target])
    gsref = sim.gs[env, target]
    vsref = sim.vs[env, target]
    cpa = dcpa * NM
    trk = trkref + np.radians(dpsi)

    if dh is None:
        acalt = altref.copy()
        acvs = np.zeros(n)
    else:
        dh = bc(dh)
        tv = tlosh if tlosv is None else bc(tlosv)
        acalt = altref + dh
        acvs = vsref - np.sign(dh) * (np.abs(dh) - hpz) / tv

    if spd is not None:
        spd = bc(spd)
        tas = isa.casormach2tas(spd, acalt)
        wn, we = sim.wind.at(env, latref, lonref)
        gsn, gse = tas * np.cos(trk) + wn, tas * np.sin(trk) + we
    else:
        gsn, gse = gsref * np.cos(trk), gsref * np.sin(trk)

    vreln, vrele = gsref * np.cos(trkref) - gsn, gsref * np.sin(trkref) - gse
    vrel = np.sqrt(vreln * vreln + vrele * vrele)
    drelcpa = tlosh * vrel + np.where(cpa > rpz, 0.0, np.sqrt(np.maximum(rpz * rpz - cpa * cpa, 0.0)))
    dist = np.sqrt(drelcpa * drelcpa + cpa * cpa)
    rd = drelcpa / dist
    rx = cpa / dist
    brn = np.degrees(np.arctan2(-rx * vreln + rd * vrele, rd * vreln + rx * vrele))
    aclat, aclon = geo.kwikpos(latref, lonref, brn, dist / NM)
    wn, we = sim.wind.at(env, aclat, aclon)
    tasn, tase = gsn - wn, gse - we
    acspd = isa.tas2cas(np.sqrt(tasn * tasn + tase * tase), acalt)
    achdg = np.degrees(np.arctan2(tase, tasn))

    sim.create(env, slot, aclat, aclon, achdg, acalt, acspd)
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
        return self.conflict.any(axis=-1)


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
    """State-based conflict detection over all ordered pairs (BlueSky CSTATEBASED) [dynamics.md 5].

    All inputs are shaped (n_envs, n_aircraft). Only pairs of active aircraft can conflict.
    """
    with np.errstate(all="ignore"):
        trkr = trk * DEG2RAD
        u = gs * np.sin(trkr)
        v = gs * np.cos(trkr)
        du = u[..., :, None] - u[..., None, :]
        dv = v[..., :, None] - v[..., None, :]
        lat1, lat2 = (lat * DEG2RAD)[..., :, None], (lat * DEG2RAD)[..., None, :]
        lon1, lon2 = (lon * DEG2RAD)[..., :, None], (lon * DEG2RAD)[..., None, :]
        dlat, dlon = lat2 - lat1, lon2 - lon1
        cavelat = np.cos(0.5 * (lat1 + lat2))
        d = R_EARTH * np.sqrt(dlat * dlat + dlon * dlon * cavelat * cavelat)
        q = np.fmod(np.arctan2(dlon * cavelat, dlat), 360.0)
        dx, dy = d * np.sin(q), d * np.cos(q)
        vreldotdx = du * dx + dv * dy
        los_h = d < rpz
        vrel2 = du * du + dv * dv
        tcpa = vreldotdx / vrel2
        cpa2 = d * d - vreldotdx * tcpa
        dcpa = np.sqrt(cpa2)
        dth = np.sqrt(np.maximum(rpz * rpz - cpa2, 0.0) / vrel2)
        tin_h, tout_h = tcpa - dth, tcpa + dth
        hor = (vreldotdx >= 0.0) | los_h
        hor &= los_h | (tin_h <= lookahead)

        dalt = alt[..., :, None] - alt[..., None, :]
        dvs = vs[..., :, None] - vs[..., None, :]
        los_v = np.abs(dalt) < hpz
        moving = np.abs(dvs) > 1e-6
        tcrosshi = (dalt + hpz) / -dvs
        tcrosslo = (dalt - hpz) / -dvs
        tin_v = np.where(moving, np.maximum(0.0, np.minimum(tcrosslo, tcrosshi)), 0.0)
        tout_v = np.where(moving, np.maximum(tcrosslo, tcrosshi), 1e4)
        ver = np.where(moving, (tin_v <= lookahead) & (tout_v > 0.0), los_v)

        tin = np.maximum(tin_h, tin_v)
        tout = np.minimum(tout_h, tout_v)
        n = lat.shape[-1]
        pair = active[..., :, None] & active[..., None, :] & ~np.eye(n, dtype=bool)
        conflict = pair & ver & hor & (tin <= lookahead) & (tin < tout) & (tout > 0.0)
        los = conflict & los_h & los_v
    return Conflicts(conflict, los, q * RAD2DEG, d, tcpa, dcpa, tin)


def horizontal_distance_nm(lat: Array, lon: Array) -> Array:
    """(…, n, n) kwik distance [NM] between all aircraft pairs of each airspace."""
    return geo.kwikdist(lat[..., :, None], lon[..., :, None], lat[..., None, :], lon[..., None, :])


__all__ = ["Conflicts", "create_conflicts", "detect", "horizontal_distance_nm", "PZ_RADIUS", "PZ_HEIGHT", "LOOKAHEAD", "M2NM"]
