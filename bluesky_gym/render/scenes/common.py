"""Helpers shared by the scene builders (reading simulator state, fitting a view)."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from bluesky_gym.core.conflicts import PZ_RADIUS
from bluesky_gym.core.units import FT, MPS2KT, NM
from bluesky_gym.render import palette as pal
from bluesky_gym.render.scene import MapAircraft

PZ_RADIUS_NM = PZ_RADIUS / NM  # NM, BlueSky's default protected zone radius
OWNSHIP_CALLSIGN = "KL001"

LEGEND_TRAFFIC: list[tuple[pal.Color, str]] = [
    (pal.OWNSHIP, "ownship (agent)"),
    (pal.INTRUDER, "traffic"),
    (pal.LOS, "loss of separation"),
]


def separation(task: Any, i: int) -> tuple[np.ndarray, np.ndarray]:
    """Distance [NM] from the ownship to every slot of episode ``i`` and the LoS flags."""
    dist, los = task.ownship_separation()
    return np.asarray(dist[i], dtype=np.float64), np.asarray(los[i], dtype=bool)


def default_callsign(slot: int) -> str:
    """The reference's aircraft ids: KL001 for the ownship, "0", "1", ... for intruders."""
    return OWNSHIP_CALLSIGN if slot == 0 else str(slot - 1)


def map_traffic(
    task: Any,
    i: int,
    ring_nm: float | None = PZ_RADIUS_NM,
    callsign: Callable[[int], str] = default_callsign,
    los: Sequence[bool] | np.ndarray | None = None,
    dim: Sequence[bool] | np.ndarray | None = None,
    slots: Sequence[int] | None = None,
) -> list[MapAircraft]:
    """Every active aircraft of episode ``i`` for a plan view; the ownship (slot 0) first.

    Args:
        task: The task.
        i: Episode index.
        ring_nm: Protected-zone ring radius [NM] (None: no rings).
        callsign: Slot -> label.
        los: Per-slot loss-of-separation flags (default: the task's ``ownship_separation``).
        dim: Per-slot flags for traffic drawn faded.
        slots: Slots to include (default: all active ones).
    """
    sim = task.sim
    if los is None:
        los = separation(task, i)[1]
    los_arr = np.asarray(los, dtype=bool)
    any_los = bool(los_arr[1:].any()) if los_arr.size > 1 else False
    active = np.flatnonzero(sim.active[i]) if slots is None else [s for s in slots if sim.active[i, s]]
    out = []
    for s in active:
        s = int(s)
        own = s == 0
        out.append(
            MapAircraft(
                key=s,
                lat=float(sim.lat[i, s]),
                lon=float(sim.lon[i, s]),
                hdg=float(sim.hdg[i, s]),
                trk=float(sim.trk[i, s]),
                gs=float(sim.gs[i, s]),
                alt=float(sim.alt[i, s]),
                callsign=callsign(s),
                role="own" if own else "intruder",
                los=any_los if own else bool(los_arr[s]),
                ring_nm=ring_nm,
                dim=bool(dim[s]) if dim is not None and not own else False,
            )
        )
    return out


def fit_extent(
    lat: Sequence[float], lon: Sequence[float], margin_nm: float, min_half_nm: float, max_half_nm: float = math.inf
) -> tuple[float, float, float]:
    """Centre (lat, lon) and half width [NM] of a square view holding the points.

    Args:
        lat: Latitudes [deg] of the points to show.
        lon: Longitudes [deg].
        margin_nm: Free margin around the points [NM].
        min_half_nm: Smallest half width [NM].
        max_half_nm: Largest half width [NM].
    """
    la = np.asarray(lat, dtype=np.float64)
    lo = np.asarray(lon, dtype=np.float64)
    clat = 0.5 * (la.min() + la.max())
    clon = 0.5 * (lo.min() + lo.max())
    coslat = math.cos(math.radians(clat))
    half = max(0.5 * (la.max() - la.min()) * 60.0, 0.5 * (lo.max() - lo.min()) * 60.0 * coslat) + margin_nm
    return float(clat), float(clon), float(min(max(half, min_half_nm), max_half_nm))


def ownship_lines(task: Any, i: int) -> list[tuple[str, str]]:
    """Panel lines with the ownship's state (heading, speeds, altitude)."""
    sim = task.sim
    if not sim.active[i, 0]:
        return [("ownship", "-")]
    alt = float(sim.alt[i, 0])
    return [
        ("HDG", f"{float(sim.hdg[i, 0]) % 360:05.1f} deg"),
        ("CAS / GS", f"{float(sim.cas[i, 0]) * MPS2KT:.0f} / {float(sim.gs[i, 0]) * MPS2KT:.0f} kt"),
        ("ALT", f"{alt:.0f} m  FL{max(alt, 0) / FT / 100:03.0f}"),
    ]


def drift_line(drift_deg: float) -> tuple[str, str]:
    """A panel line with a drift angle (positive: heading right of the goal bearing)."""
    return ("drift", f"{drift_deg:+.1f} deg")
