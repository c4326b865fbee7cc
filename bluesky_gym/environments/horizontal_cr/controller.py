"""HorizontalCREnv-v0's reference policies.

* The classical controller: turn to the waypoint; turn away (full heading step) from the closest
  intruder that is closing in within ``HORIZONTAL_ALERT_KM`` km in front of the aircraft. It keeps
  the previous observation's intruder distances (the intruders are not sorted);
  :meth:`~bluesky_gym.training.policies.Policy.reset` clears them.
* MVP's mapping: heading resolution (``HDG``), steering to the waypoint otherwise.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from bluesky_gym.environments.horizontal_cr import task as horizontal_cr
from bluesky_gym.training.policies import Array, ClosingTracker, MVPMapping, Obs, Policy, SteerToGoal, angle

HORIZONTAL_ALERT_KM = 30.0  # km: closing intruders in front and nearer than this are avoided


class HorizontalCRController(Policy):
    """HorizontalCREnv-v0: steer to the waypoint; turn away from the closest closing intruder."""

    name = "classical"

    def __init__(self) -> None:
        self.tracker = ClosingTracker()

    def reset(self, envs: NDArray[np.bool_] | None = None) -> None:
        """Forget the previous intruder distances of ``envs`` (all when None)."""
        self.tracker.reset(envs)

    def act(self, obs: Obs) -> Array:
        """Compute the controller's actions."""
        drift = angle(obs["sin_drift"][:, 0], obs["cos_drift"][:, 0])
        a = np.clip(-drift / horizontal_cr.D_HEADING, -1.0, 1.0)
        dist = obs["intruder_distance"] * horizontal_cr.DISTANCE_SCALE
        closing = self.tracker.closing(dist)
        ahead = obs["cos_difference_pos"] > 0.0
        threat = np.where(closing & ahead & (dist < HORIZONTAL_ALERT_KM), dist, np.inf)
        k = np.argmin(threat, axis=1)
        rows = np.arange(len(k))
        alert = np.isfinite(threat[rows, k])
        # difference_pos = hdg - bearing > 0: the intruder is on the left, so turn right (a > 0).
        away = np.where(obs["sin_difference_pos"][rows, k] >= 0.0, 1.0, -1.0)
        return np.where(alert, away, a)[:, None]


#: MVP's mapping, the registry row's ``mvp`` (a -v1 id uses it too; with ``speed_step_in_knots`` the speed step is in knots).
HORIZONTAL_CR_MVP = MVPMapping(
    lambda: SteerToGoal("sin_drift", "cos_drift", horizontal_cr.D_HEADING, 1),
    rmethh="HDG",
    rpz_nm=horizontal_cr.INTRUSION_DISTANCE,
    heading_step=horizontal_cr.D_HEADING,
)
