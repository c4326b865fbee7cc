"""Helpers of the task tests: seeded, reset tasks and the kwik geometry written out independently of the package."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

#: Radius of the kwik (flat-earth) geometry and of the reference's spawn geometry [m].
R_EARTH = 6371000.0
#: The same radius [km].
R_KM = R_EARTH / 1000.0
#: Nautical mile [m].
NM = 1852.0


def seeded_task(task_class: type, n_envs: int | None = None, seeds: Sequence[int] | None = None, **options: Any) -> Any:
    """A task of ``task_class`` configured with ``options``, its episodes seeded (default seeds 0..n_envs-1) and reset.

    ``n_envs`` defaults to the number of seeds (or 1).
    """
    if n_envs is None:
        n_envs = len(seeds) if seeds is not None else 1
    seeds = list(range(n_envs)) if seeds is None else list(seeds)
    task = task_class(n_envs, task_class.make_config(options))
    task.seed(task.all_envs, [np.random.default_rng(s) for s in seeds])
    task.reset()
    return task


def north_of(lat: float, dist_m: float) -> float:
    """Latitude ``dist_m`` north of ``lat`` in the kwik metric."""
    return lat + np.degrees(dist_m / R_EARTH)


def east_of(lat: float, lon: float, dist_m: float) -> float:
    """Longitude ``dist_m`` east of ``(lat, lon)`` in the kwik metric (same latitude)."""
    return lon + np.degrees(dist_m / (R_EARTH * np.cos(np.radians(lat))))


def kwik(lat1: float, lon1: float, lat2: float, lon2: float) -> tuple[float, float]:
    """Flat-earth bearing [deg, -180..180, as BlueSky's qdrdist] and distance [km], written out independently.

    The formulas of docs/environments-v0.md, Conventions.
    """
    dlat = math.radians(lat2) - math.radians(lat1)
    dlon = math.radians(lon2) - math.radians(lon1)
    c = math.cos(0.5 * (math.radians(lat1) + math.radians(lat2)))
    return math.degrees(math.atan2(dlon * c, dlat)), R_KM * math.hypot(dlat, dlon * c)


def great_circle(lat1: float, lon1: float, lat2: float, lon2: float) -> tuple[float, float]:
    """Initial bearing [deg, 0..360) and haversine distance [km] on a 6371 km sphere."""
    p1, p2 = math.radians(lat1), math.radians(lat2)
    dl = math.radians(lon2 - lon1)
    a = math.sin((p2 - p1) / 2) ** 2 + math.cos(p1) * math.cos(p2) * math.sin(dl / 2) ** 2
    d = 2 * R_KM * math.asin(math.sqrt(a))
    b = math.degrees(math.atan2(math.sin(dl) * math.cos(p2), math.cos(p1) * math.sin(p2) - math.sin(p1) * math.cos(p2) * math.cos(dl)))
    return b % 360, d
