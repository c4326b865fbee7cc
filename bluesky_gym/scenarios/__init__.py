"""BlueSky scenario files (``.scn``) on any physics: reading, playing, generating and exporting.

* :mod:`~bluesky_gym.scenarios.parser`: ``.scn`` text to a typed, time-ordered command list;
* :mod:`~bluesky_gym.scenarios.player`: plays scenarios on a :class:`~bluesky_gym.core.physics.Physics`,
  one airspace per scenario, with BlueSky's timing;
* :mod:`~bluesky_gym.scenarios.geometries`: the classic conflict-benchmark geometries as ``.scn`` text;
* :mod:`~bluesky_gym.scenarios.export`: a physics wrapper that logs an episode and writes it as ``.scn``.

See docs/scenarios.md.
"""

from bluesky_gym.scenarios.parser import ScenarioError, ScenarioFile, parse_scenario, read_scenario
from bluesky_gym.scenarios.player import TRAJECTORY_COLUMNS, ScenarioPlayer

__all__ = ["TRAJECTORY_COLUMNS", "ScenarioError", "ScenarioFile", "ScenarioPlayer", "parse_scenario", "read_scenario"]
