"""Oracle: BlueSky's ``creconfs`` intruder placement as readable numpy array code.

The package computes it with the scalar kernel bluesky_gym.core.conflicts.conflict_geometry; the
tests compare both to the last bit.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from bluesky_gym.core.conflicts import PZ_HEIGHT, PZ_RADIUS
from bluesky_gym.core.units import NM

from . import atmosphere as isa
from . import geo

if TYPE_CHECKING:
    from bluesky_gym.core.simulator import Simulator

Array = NDArray[np.float64]


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
    actype: str | list[str] | None = None,
) -> None:
    """Create intruders in conflict with target aircraft (BlueSky ``traf.creconfs``) [docs/dynamics.md §3].

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

    sim.create(env, slot, aclat, aclon, achdg, acalt, acspd, actype=actype)
    sim.cmd_altitude(env, slot, altref, acvs)
    sim.vs[env, slot] = acvs
