"""StaticObstacleEnv-v0: north-up map of the restricted areas, the waypoint and the ownship."""

from __future__ import annotations

from typing import Any

import numpy as np

from bluesky_gym.core.units import NM2KM
from bluesky_gym.environments.static_obstacle.task import AC_LAT, AC_LON
from bluesky_gym.render import palette as pal
from bluesky_gym.render.scene import Area, Fix, Line, MapScene
from bluesky_gym.render.scenes.common import drift_line, fit_extent, map_traffic, ownship_lines

LEGEND = [
    (pal.OWNSHIP, "ownship (agent)"),
    (pal.OBSTACLE_EDGE, "restricted area"),
    (pal.LOS, "inside a restricted area"),
    (pal.GOAL, "waypoint (5 km capture)"),
]


def static_obstacle_scene(task: Any, i: int) -> MapScene:
    """Restricted areas (red while the ownship is inside one), the waypoint and the direct track."""
    sim = task.sim
    inside = task.inside_obstacles()[i]
    areas = []
    lat_pts, lon_pts = [AC_LAT], [AC_LON]
    for k in range(task.obstacle_nv.shape[1]):
        nv = int(task.obstacle_nv[i, k])
        if nv < 3:
            continue
        lat = task.obstacle_lat[i, k, :nv].tolist()
        lon = task.obstacle_lon[i, k, :nv].tolist()
        areas.append(Area(lat, lon, kind="obstacle", label=f"R{k + 1}", violated=bool(inside[k])))
        lat_pts += lat
        lon_pts += lon
    wlat, wlon = float(task.wpt_lat[i]), float(task.wpt_lon[i])
    if areas:
        lat_pts.append(wlat)
        lon_pts.append(wlon)
    clat, clon, half = fit_extent(lat_pts, lon_pts, margin_nm=8.0, min_half_nm=40.0)
    aircraft = map_traffic(task, i, ring_nm=None, los=np.zeros(sim.max_aircraft, bool))
    if aircraft and inside.any():
        aircraft[0].los = True
    fixes = [Fix(wlat, wlon, "WPT", done=bool(task.wpt_reached[i]), capture_nm=float(task.config.distance_margin_km) / NM2KM)] if areas else []
    lines = [Line([float(sim.lat[i, 0]), wlat], [float(sim.lon[i, 0]), wlon], pal.ROUTE)] if areas and sim.active[i, 0] else []
    dist_km, drift = task.waypoint_geometry()
    panel = [
        *ownship_lines(task, i),
        ("to waypoint", f"{float(dist_km[i]):.1f} km"),
        drift_line(float(drift[i])),
        ("in restricted", str(int(inside.sum()))),
    ]
    return MapScene(clat, clon, half, aircraft=aircraft, fixes=fixes, areas=areas, lines=lines, panel=panel, legend=LEGEND)
