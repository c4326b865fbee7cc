"""VerticalCREnv-v0's reference policies.

* The classical controller: the descent controller, plus, for the closest intruder that is closing
  in within ``VERTICAL_ALERT_KM`` km and less than ``VERTICAL_ALERT_ALT`` m away vertically, an
  altitude at least that far above or below it (whichever side it already is on; above when below
  would be too low). It keeps the previous observation's intruder distances (the intruders are not
  sorted); :meth:`~bluesky_gym.training.policies.Policy.reset` clears them.
* MVP's mapping: vertical resolution (``V/S``) on top of the descent controller.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from bluesky_gym.environments.descent.controller import STEP_S_VERTICAL, DescentController
from bluesky_gym.environments.descent.task import ALT_STD
from bluesky_gym.environments.vertical_cr import task as vertical_cr
from bluesky_gym.training.policies import Array, ClosingTracker, MVPMapping, Obs, vertical_speed_action

VERTICAL_ALERT_KM = 40.0  # km: intruders closer than this (and closing in) are avoided
VERTICAL_ALERT_ALT = 450.0  # m: vertical distance kept from an alerting intruder
VERTICAL_MIN_ALT = 300.0  # m: do not avoid downwards below this


class VerticalCRController(DescentController):
    """VerticalCREnv-v0: the descent controller plus vertical avoidance of closing intruders."""

    def __init__(self) -> None:
        self.tracker = ClosingTracker()

    def reset(self, envs: NDArray[np.bool_] | None = None) -> None:
        """Forget the previous intruder distances of ``envs`` (all when None)."""
        self.tracker.reset(envs)

    def act(self, obs: Obs) -> Array:
        """Compute the controller's actions."""
        alt, wanted = self.target_altitude(obs)
        dist = obs["intruder_distance"] * vertical_cr.INTRUDER_DISTANCE_SCALE  # (n, k) km
        dalt = obs["altitude_difference"] * ALT_STD  # intruder minus own, m
        closing = self.tracker.closing(dist)
        # Intruders near the wanted altitude that are closing in.
        near = closing & (dist < VERTICAL_ALERT_KM) & (np.abs(wanted[:, None] - (alt[:, None] + dalt)) < VERTICAL_ALERT_ALT)
        d_alert = np.where(near, dist, np.inf)
        k = np.argmin(d_alert, axis=1)
        rows = np.arange(len(k))
        alert = np.isfinite(d_alert[rows, k])
        int_alt = alt + dalt[rows, k]
        below = int_alt - VERTICAL_ALERT_ALT
        above = int_alt + VERTICAL_ALERT_ALT
        go_below = (int_alt > alt) & (below > VERTICAL_MIN_ALT)
        avoid = np.where(go_below, np.minimum(wanted, below), np.maximum(wanted, above))
        wanted = np.where(alert, avoid, wanted)
        return vertical_speed_action((wanted - alt) / STEP_S_VERTICAL)[:, None]


#: MVP's mapping, the registry row's ``mvp`` (a -v1 id uses it too; with ``speed_step_in_knots`` the speed step is in knots).
VERTICAL_CR_MVP = MVPMapping(DescentController, rmethv="V/S", rpz_nm=vertical_cr.INTRUSION_DISTANCE, hpz_m=vertical_cr.VERTICAL_MARGIN, vertical=True)
