"""DenseSectorCREnv-v0: SectorCR's map, with the spawn rate in the panel (the info panel counts the traffic and the entries)."""

from __future__ import annotations

import dataclasses
from typing import Any

from bluesky_gym.render.scene import MapScene
from bluesky_gym.render.scenes.sector_cr import sector_cr_scene


def dense_sector_cr_scene(task: Any, i: int) -> MapScene:
    """SectorCR's scene (:func:`~bluesky_gym.render.scenes.sector_cr.sector_cr_scene`) with the current spawn rate.

    SectorCR's initial traffic count is left out of the panel: the info lines show the traffic now
    (``traffic``) and the aircraft that entered (``spawned``).
    """
    scene = sector_cr_scene(task, i)
    panel = [line for line in scene.panel if line[0] != "traffic"]
    panel.append(("spawn rate", f"{float(task.spawn_rate_now()[i]):.0f} /h"))
    return dataclasses.replace(scene, panel=panel)
