"""DenseSectorCREnv-v0: SectorCR's map, with the traffic now in the sector and the spawn rate in the panel."""

from __future__ import annotations

import dataclasses
from typing import Any

from bluesky_gym.render.scene import MapScene
from bluesky_gym.render.scenes.sector_cr import sector_cr_scene


def dense_sector_cr_scene(task: Any, i: int) -> MapScene:
    """SectorCR's scene (:func:`~bluesky_gym.render.scenes.sector_cr.sector_cr_scene`); the panel counts the traffic now and shows the flow."""
    scene = sector_cr_scene(task, i)
    panel = [line for line in scene.panel if line[0] != "traffic"]
    panel += [
        ("traffic", str(int(task.sim.active[i, 1:].sum()))),
        ("spawn rate", f"{float(task.spawn_rate_now()[i]):.0f} /h"),
        ("entered", str(int(task.spawned[i]))),
    ]
    return dataclasses.replace(scene, panel=panel)
