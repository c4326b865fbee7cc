"""Scene builders: each reads a task's state for one episode and returns a scene.

A builder is a function ``(task, env_index) -> MapScene | SideScene`` that only reads the task.
The renderer draws the builder it is given (:class:`~bluesky_gym.render.renderer.Renderer`'s
``scene`` argument); each environment's builder lives in its folder
(``bluesky_gym.environments.<name>.scene``) and its row of the environment table
(:mod:`bluesky_gym.envs.registry`) names it; this package holds the parts they share. :func:`~bluesky_gym.render.scenes.generic.generic_scene`
draws every aircraft on a plan view around the ownship, for tasks without a scene of their own.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from bluesky_gym.render.scene import Scene

SceneBuilder = Callable[[Any, int], Scene]
