"""SectorCREnv-v0: north-up map of the sector, the ownship's exit point and the traffic."""

from __future__ import annotations

from typing import Any

from bluesky_gym.environments.sector_cr.task import INTRUSION_DISTANCE
from bluesky_gym.render import palette as pal
from bluesky_gym.render.scene import Area, Fix, Line, MapScene
from bluesky_gym.render.scenes.common import LEGEND_TRAFFIC, drift_line, fit_extent, map_traffic, ownship_lines

LEGEND = [*LEGEND_TRAFFIC, (pal.GOAL, "ownship's exit point"), (pal.AIRSPACE_EDGE, "sector")]


def sector_cr_scene(task: Any, i: int) -> MapScene:
    """The sector polygon, the ownship's exit point (bearing line dashed) and 5 NM zones."""
    sim = task.sim
    nv = int(task.n_vertices[i])
    plat = task.poly_lat[i, :nv].tolist()
    plon = task.poly_lon[i, :nv].tolist()
    if nv >= 3:
        clat, clon, half = fit_extent(plat, plon, margin_nm=6.0, min_half_nm=30.0)
    else:  # before the first reset
        clat, clon, half = 52.0, 4.4, 40.0
    aircraft = map_traffic(task, i, ring_nm=INTRUSION_DISTANCE)
    fixes, lines = [], []
    if sim.active[i, 0]:
        wlat, wlon = float(task.wpt_lat[i, 0]), float(task.wpt_lon[i, 0])
        fixes.append(Fix(wlat, wlon, "EXIT"))
        lines.append(Line([float(sim.lat[i, 0]), wlat], [float(sim.lon[i, 0]), wlon], pal.ROUTE))
    inside = bool(task.agent_inside()[i]) if nv >= 3 else False
    panel = [
        *ownship_lines(task, i),
        drift_line(float(task.waypoint_drift()[i])),
        ("in sector", "yes" if inside else "no"),
        ("traffic", str(max(int(task.num_ac[i]) - 1, 0))),
    ]
    return MapScene(
        clat,
        clon,
        half,
        aircraft=aircraft,
        fixes=fixes,
        areas=[Area(plat, plon, kind="sector")] if nv >= 3 else [],
        lines=lines,
        follow=None,
        panel=panel,
        legend=LEGEND,
    )
