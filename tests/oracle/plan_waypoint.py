"""Readable numpy form of PlanWaypoint's step (test oracle).

The package computes it once, in the kernels of
:mod:`bluesky_gym.environments.plan_waypoint.task`; the tests compare those to this form to the
last bit. The arrays are the simulator's (n_envs, max_aircraft) ones (the aircraft in slot 0) and
the task's (n_envs, num_waypoints) waypoints.
"""

from __future__ import annotations

import numpy as np

from bluesky_gym.core.units import NM2KM
from bluesky_gym.tasks.base import wrap180
from tests.oracle.geometry import ref_kwikqdrdist

Array = np.ndarray


def measure(lat: Array, lon: Array, hdg: Array, wpt_lat: Array, wpt_lon: Array, wpt_reached: Array, margin_km: float) -> dict[str, Array]:
    """Distance [km] and drift [deg] to every waypoint, the reach flags before and new in this step, and whether all are reached."""
    qdr, dist = ref_kwikqdrdist(lat[:, :1], lon[:, :1], wpt_lat, wpt_lon)
    dist_km = dist * NM2KM
    before = wpt_reached.copy()
    new = (dist_km < margin_km) & ~before
    return {"dist_km": dist_km, "drift": wrap180(hdg[:, :1] - qdr), "before": before, "new": new, "goal": (before | new).all(axis=1)}


def observation(g: dict[str, Array], same_step: bool, distance_max: int) -> dict[str, Array]:
    """The observation: the reference masks with the integer (1 - reached) (-0.0 where a masked value is negative)."""
    reached = g["before"] | g["new"] if same_step else g["before"]
    m = np.where(reached, 0.0, 1.0)
    rad = np.deg2rad(g["drift"])
    return {
        "waypoint_distance": m * g["dist_km"] / distance_max,
        "cos_difference": m * np.cos(rad),
        "sin_difference": m * np.sin(rad),
        "waypoint_reached": reached.astype(np.float64),
    }


def reward(g: dict[str, Array], reach_reward: float) -> Array:
    """``reach_reward`` per newly reached waypoint."""
    return g["new"].sum(axis=1) * reach_reward  # type: ignore[no-any-return]


def extra_track_km(distflown: Array, tour_km: Array) -> Array:
    """Distance flown by the aircraft [km] minus the shortest tour [km]."""
    return distflown[:, 0] / 1000.0 - tour_km  # type: ignore[no-any-return]
