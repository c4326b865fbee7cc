"""One scene builder per task id: reads a task's state for one episode and returns a scene.

A builder is a function ``(task, env_index) -> MapScene | SideScene``. Builders only read the
task. A task id without a builder of its own gets :func:`~bluesky_gym.render.scenes.generic.generic_scene`
(every aircraft on a plan view around the ownship), so new environments render from day one.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import Any

from bluesky_gym.render.scene import Scene

SceneBuilder = Callable[[Any, int], Scene]

# task id -> "module:function" inside this package (imported on first use)
BUILDERS: dict[str, str] = {
    "DescentEnv-v0": "descent:descent_scene",
    "VerticalCREnv-v0": "vertical_cr:vertical_cr_scene",
    "HorizontalCREnv-v0": "horizontal_cr:horizontal_cr_scene",
    "PlanWaypointEnv-v0": "plan_waypoint:plan_waypoint_scene",
    "SectorCREnv-v0": "sector_cr:sector_cr_scene",
    "StaticObstacleEnv-v0": "static_obstacle:static_obstacle_scene",
    "MergeEnv-v0": "merge:merge_scene",
}


def scene_builder(task: Any) -> SceneBuilder:
    """The scene builder of ``task`` (by its ``env_id``), or the generic plan view."""
    target = BUILDERS.get(getattr(task, "env_id", ""), "generic:generic_scene")
    module, func = target.split(":")
    try:
        mod = importlib.import_module(f"{__name__}.{module}")
    except ModuleNotFoundError as exc:
        if exc.name != f"{__name__}.{module}":
            raise
        mod = importlib.import_module(f"{__name__}.generic")
        func = "generic_scene"
    return getattr(mod, func)
