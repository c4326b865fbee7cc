"""PlanWaypointEnv-v0's classical controller: fly to the nearest waypoint not reached yet."""

from __future__ import annotations

from typing import Any

import numpy as np

from bluesky_gym.environments.plan_waypoint import task as plan_waypoint
from bluesky_gym.environments.plan_waypoint.task import PlanWaypointConfig
from bluesky_gym.training.policies import Array, Obs, Policy, angle, task_config

# Scenario options that set an observation scale: the defaults until the controller is bound to
# its environment (Policy.bind), then that environment's values.
WAYPOINT_DIST_PLAN = float(PlanWaypointConfig.waypoint_distance_max)  # km per unit of waypoint_distance (default scenario)
CAPTURE_KM = PlanWaypointConfig.distance_margin_km  # km: waypoints this near count as reached (default scenario)


class PlanWaypointController(Policy):
    """PlanWaypointEnv-v0: fly to the nearest waypoint not yet reached.

    The waypoint distances are decoded with the default scenario's normalisation and capture
    radius, or with those of the environment the controller is bound to.
    """

    name = "classical"

    def __init__(self) -> None:
        self.distance_scale_km = WAYPOINT_DIST_PLAN
        self.capture_km = CAPTURE_KM

    def bind(self, env: Any) -> None:
        """Decode with the waypoint-distance normalisation and capture radius of ``env``'s scenario."""
        config = task_config(env)
        if isinstance(config, PlanWaypointConfig):
            self.distance_scale_km = float(config.waypoint_distance_max)
            self.capture_km = float(config.distance_margin_km)

    def act(self, obs: Obs) -> Array:
        """Compute the controller's actions."""
        dist = obs["waypoint_distance"] * self.distance_scale_km
        open_ = (obs["waypoint_reached"] < 0.5) & (dist >= self.capture_km)
        k = np.argmin(np.where(open_, dist, np.inf), axis=1)
        rows = np.arange(len(k))
        drift = angle(obs["sin_difference"][rows, k], obs["cos_difference"][rows, k])
        a = np.clip(-drift / plan_waypoint.D_HEADING, -1.0, 1.0)
        return np.where(open_.any(axis=1), a, 0.0)[:, None]
