"""Plan view of any task without a builder of its own: every aircraft around the ownship."""

from __future__ import annotations

from typing import Any

from bluesky_gym.render.scene import MapScene
from bluesky_gym.render.scenes.common import LEGEND_TRAFFIC, map_traffic, ownship_lines


def generic_scene(task: Any, i: int) -> MapScene:
    """All active aircraft with 5 NM rings; the view starts on the ownship and follows it."""
    sim = task.sim
    aircraft = map_traffic(task, i)
    lat = float(sim.lat[i, 0]) if sim.active[i, 0] else 52.0
    lon = float(sim.lon[i, 0]) if sim.active[i, 0] else 4.0
    return MapScene(lat, lon, 60.0, aircraft=aircraft, traffic_details=True, panel=ownship_lines(task, i), legend=LEGEND_TRAFFIC)
