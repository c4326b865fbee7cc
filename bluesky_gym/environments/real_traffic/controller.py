"""RealTrafficCREnv-v0's classical controller: follow the recorded path, avoiding conflicts.

For the intruder within 2000 ft vertically with the nearest predicted loss of separation (within
``REAL_TRAFFIC_LOOKAHEAD_S``), it turns away from the side on which the intruder passes.
"""

from __future__ import annotations

import numpy as np

from bluesky_gym.core.units import FT, NM
from bluesky_gym.environments.real_traffic import task as rt
from bluesky_gym.training.policies import Array, Obs, Policy, cpa_turn

REAL_TRAFFIC_LOOKAHEAD_S = 300.0  # s: conflict look-ahead
REAL_TRAFFIC_VERTICAL_ALERT_M = 2000.0 * FT  # m: traffic further above or below is not avoided
REAL_TRAFFIC_FAR_M = 1e9  # m: where an ignored intruder is put


class RealTrafficController(Policy):
    """RealTrafficCREnv-v0: follow the recorded path; turn away from the most urgent conflict with traffic within 2000 ft."""

    name = "classical"

    def act(self, obs: Obs) -> Array:
        """Compute the controller's actions (heading and speed; zero: the recorded path and speed)."""
        intr = np.asarray(obs["intruders"])
        if intr.shape[-1] != rt.INTRUDER_FEATURES:  # -v1: the rows as one vector
            intr = intr.reshape(*intr.shape[:-1], rt.NUM_INTRUDERS, rt.INTRUDER_FEATURES)
        near = (intr[..., 6] > 0.5) & (np.abs(intr[..., 4] * rt.ALTITUDE_SCALE) < REAL_TRAFFIC_VERTICAL_ALERT_M)
        pos = rt.POSITION_SCALE * NM
        alert, turn = cpa_turn(
            np.where(near, intr[..., 1] * pos, REAL_TRAFFIC_FAR_M),  # out of the vertical band: far away, never alerts
            np.where(near, intr[..., 0] * pos, REAL_TRAFFIC_FAR_M),
            intr[..., 3] * rt.VELOCITY_SCALE,
            intr[..., 2] * rt.VELOCITY_SCALE,
            rt.INTRUSION_NM * NM,
            REAL_TRAFFIC_LOOKAHEAD_S,
        )
        heading = np.where(alert, turn, 0.0)
        return np.stack([heading, np.zeros_like(heading)], axis=1)
