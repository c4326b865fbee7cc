"""MergeEnv-v0's reference policies.

* The classical controller: turn to the FAF, then the runway; for the intruder with the nearest
  predicted loss of separation (within ``MERGE_LOOKAHEAD_S``), turn away from the side on which it
  passes.
* MVP's mapping: heading and speed resolution (``BOTH``), steering to the goal otherwise.
"""

from __future__ import annotations

from bluesky_gym.core.units import NM
from bluesky_gym.environments.merge import task as merge
from bluesky_gym.training.policies import MVPMapping, SteerAndAvoid, SteerToGoal

MERGE_LOOKAHEAD_S = 300.0  # s: conflict look-ahead


class MergeController(SteerAndAvoid):
    """MergeEnv-v0: steer to the FAF then the runway; turn away from the most urgent conflict."""

    heading_step = merge.D_HEADING
    pos_scale = merge.POSITION_SCALE
    vn_scale = merge.SPEED_SCALE
    ve_scale = merge.SPEED_SCALE
    pz_m = merge.INTRUSION_DISTANCE * NM
    lookahead_s = MERGE_LOOKAHEAD_S


#: MVP's mapping, the registry row's ``mvp`` (a -v1 id uses it too; with ``speed_step_in_knots`` the speed step is in knots).
MERGE_MVP = MVPMapping(
    lambda: SteerToGoal("sin(drift)", "cos(drift)", merge.D_HEADING, 2),
    rmethh="BOTH",
    rpz_nm=merge.INTRUSION_DISTANCE,
    heading_step=merge.D_HEADING,
    speed_step=merge.D_SPEED,
)
