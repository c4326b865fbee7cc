"""SectorCREnv-v0's reference policies.

* The classical controller: turn to the exit waypoint; for the intruder with the nearest predicted
  loss of separation (closest point of approach closer than the protected zone plus margin,
  within ``SECTOR_LOOKAHEAD_S``), turn away from the side on which it passes.
* MVP's mapping: heading and speed resolution (``BOTH``), steering to the exit otherwise.
"""

from __future__ import annotations

from bluesky_gym.core.units import NM
from bluesky_gym.environments.sector_cr import task as sector_cr
from bluesky_gym.training.policies import MVPMapping, SteerAndAvoid, SteerToGoal

SECTOR_LOOKAHEAD_S = 180.0  # s: conflict look-ahead


class SectorCRController(SteerAndAvoid):
    """SectorCREnv-v0: steer to the exit waypoint; turn away from the most urgent conflict."""

    heading_step = sector_cr.D_HEADING
    pos_scale = sector_cr.POSITION_SCALE
    vn_scale = sector_cr.VX_SCALE
    ve_scale = sector_cr.VY_SCALE
    pz_m = sector_cr.INTRUSION_DISTANCE * NM
    lookahead_s = SECTOR_LOOKAHEAD_S


#: MVP's mapping, the registry row's ``mvp`` (a -v1 id uses it too; with ``speed_step_in_knots`` the speed step is in knots).
SECTOR_CR_MVP = MVPMapping(
    lambda: SteerToGoal("sin(drift)", "cos(drift)", sector_cr.D_HEADING, 2),
    rmethh="BOTH",
    rpz_nm=sector_cr.INTRUSION_DISTANCE,
    heading_step=sector_cr.D_HEADING,
    speed_step=sector_cr.D_VELOCITY,
)
