"""StaticObstacleEnv-v0's classical controller: full speed on the heading nearest the goal with a clear path.

It flies at the highest speed towards the goal on the heading closest to it whose straight path
(to the goal, at most ``OBSTACLE_LOOKAHEAD_KM``) stays outside every obstacle's enclosing circle
plus ``OBSTACLE_MARGIN_KM``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from bluesky_gym.core.units import NM2KM
from bluesky_gym.environments.static_obstacle import task as static_obstacle
from bluesky_gym.environments.static_obstacle.task import StaticObstacleConfig
from bluesky_gym.training.policies import Array, Obs, Policy, angle, task_config

OBSTACLE_DIST_SCALE = float(StaticObstacleConfig.waypoint_distance_max)  # km per unit of distance (default scenario)
OBSTACLE_RADIUS_SCALE_KM = static_obstacle.RADIUS_SCALE_NM * NM2KM  # km per unit of restricted_area_radius
OBSTACLE_MARGIN_KM = 3.0  # km: clearance kept from an obstacle's enclosing circle
OBSTACLE_LOOKAHEAD_KM = 60.0  # km: length of the path checked for obstacles
CANDIDATE_TURNS = np.arange(-180.0, 180.0, 5.0)  # deg, relative headings searched


class StaticObstacleController(Policy):
    """StaticObstacleEnv-v0: full speed on the heading nearest the goal with a clear path.

    The distances are decoded with the default scenario's normalisation, or with that of the
    environment the controller is bound to.
    """

    name = "classical"

    def __init__(self) -> None:
        self.distance_scale_km = OBSTACLE_DIST_SCALE

    def bind(self, env: Any) -> None:
        """Decode with the distance normalisation of ``env``'s scenario."""
        config = task_config(env)
        if isinstance(config, StaticObstacleConfig):
            self.distance_scale_km = float(config.waypoint_distance_max)

    def act(self, obs: Obs) -> Array:
        """Compute the controller's actions."""
        goal_rel = -angle(obs["destination_waypoint_sin_drift"][:, 0], obs["destination_waypoint_cos_drift"][:, 0])  # deg, + right
        goal_km = obs["destination_waypoint_distance"][:, 0] * self.distance_scale_km
        d = obs["restricted_area_distance"] * self.distance_scale_km  # (n, m) km
        r = obs["restricted_area_radius"] * OBSTACLE_RADIUS_SCALE_KM + OBSTACLE_MARGIN_KM
        beta = -angle(obs["sin_difference_restricted_area_pos"], obs["cos_difference_restricted_area_pos"])  # + right
        # Candidate relative headings (n, c); the path to check for each (n, c, m).
        cand = CANDIDATE_TURNS[None, :]
        rel = np.radians(beta[:, None, :] - cand[:, :, None])
        along = d[:, None, :] * np.cos(rel)
        across = np.abs(d[:, None, :] * np.sin(rel))
        length = np.minimum(goal_km, OBSTACLE_LOOKAHEAD_KM)[:, None, None]
        inside = (d < r)[:, None, :]  # already within an enclosing circle: that circle is ignored
        blocked = ~inside & (across < r[:, None, :]) & (along > 0.0) & (along < length + r[:, None, :])
        clear = ~np.any(blocked, axis=2)
        off_goal = np.abs((cand - goal_rel[:, None] + 180.0) % 360.0 - 180.0)
        best = np.argmin(np.where(clear, off_goal, np.inf), axis=1)
        turn = np.where(clear.any(axis=1), CANDIDATE_TURNS[best], goal_rel)
        heading = np.clip(turn / static_obstacle.D_HEADING, -1.0, 1.0)
        return np.stack([heading, np.ones_like(heading)], axis=1)
