"""DescentEnv-v0's classical controller: hold the target altitude, then a glide path to the runway.

It holds the target altitude and descends along a glide path (``GLIDE_SLOPE`` m per km of runway
distance, down to ``RUNWAY_ALT`` m) once that path is below the target.
"""

from __future__ import annotations

import numpy as np

from bluesky_gym.environments.descent.task import ALT_MEAN, ALT_STD, RWY_DIS_MEAN, RWY_DIS_STD, DescentTask
from bluesky_gym.training.policies import Array, Obs, Policy, vertical_speed_action

# The observation scales are the task's; the numbers declared here are the controller's tuning.
STEP_S_VERTICAL = DescentTask.dt * DescentTask.action_frequency  # s per decision step
GROUND_SPEED_EST = 0.17  # km/s, typical ground speed of the descent scenarios (CAS 150 m/s)
GLIDE_SLOPE = 80.0  # m per km of runway distance: steeper than the ~70 m/km possible, as the command lags
RUNWAY_ALT = 60.0  # m, altitude aimed at over the runway threshold (alt <= 0 before it crashes)


class DescentController(Policy):
    """DescentEnv-v0: hold the target altitude, then follow a glide path to the runway."""

    name = "classical"

    def target_altitude(self, obs: Obs) -> tuple[Array, Array]:
        """Return the current and the wanted altitude [m] at the end of the next step."""
        alt = obs["altitude"][:, 0] * ALT_STD + ALT_MEAN
        target = obs["target_altitude"][:, 0] * ALT_STD + ALT_MEAN
        rd_next = obs["runway_distance"][:, 0] * RWY_DIS_STD + RWY_DIS_MEAN - GROUND_SPEED_EST * STEP_S_VERTICAL
        glide = RUNWAY_ALT + GLIDE_SLOPE * np.maximum(rd_next, 0.0)
        return alt, np.minimum(target, glide)

    def act(self, obs: Obs) -> Array:
        """Compute the controller's actions."""
        alt, wanted = self.target_altitude(obs)
        return vertical_speed_action((wanted - alt) / STEP_S_VERTICAL)[:, None]
