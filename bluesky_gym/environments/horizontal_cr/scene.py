"""HorizontalCREnv-v0: north-up map of the ownship, its waypoint due north and the intruders."""

from __future__ import annotations

from typing import Any

from bluesky_gym.core.units import NM2KM
from bluesky_gym.environments.horizontal_cr.task import DISTANCE_MARGIN, INTRUSION_DISTANCE, START_LAT, START_LON
from bluesky_gym.render import palette as pal
from bluesky_gym.render.scene import Fix, Line, MapScene
from bluesky_gym.render.scenes.common import LEGEND_TRAFFIC, drift_line, fit_extent, map_traffic, ownship_lines

LEGEND = [*LEGEND_TRAFFIC, (pal.GOAL, "waypoint (5 km capture)")]


def horizontal_cr_scene(task: Any, i: int) -> MapScene:
    """Start, waypoint and traffic with 5 NM protected zones; the planned track is dashed."""
    wlat, wlon = float(task.wpt_lat[i]), float(task.wpt_lon[i])
    clat, clon, half = fit_extent([START_LAT, wlat], [START_LON, wlon], margin_nm=25.0, min_half_nm=45.0)
    dist_km, drift = task.waypoint_geometry()
    panel = [*ownship_lines(task, i), ("to waypoint", f"{float(dist_km[i]):.1f} km"), drift_line(float(drift[i]))]
    return MapScene(
        clat,
        clon,
        half,
        aircraft=map_traffic(task, i, ring_nm=INTRUSION_DISTANCE),
        fixes=[Fix(wlat, wlon, "WPT", done=bool(task.wpt_reach[i]), capture_nm=DISTANCE_MARGIN / NM2KM)],
        lines=[Line([START_LAT, wlat], [START_LON, wlon], pal.ROUTE)],
        panel=panel,
        legend=LEGEND,
    )
