"""PlanWaypointEnv-v0: north-up map of the ownship and its five waypoints."""

from __future__ import annotations

from typing import Any

import numpy as np

from bluesky_gym.core.units import NM2KM
from bluesky_gym.environments.plan_waypoint.task import AC_LAT, AC_LON
from bluesky_gym.render import palette as pal
from bluesky_gym.render.scene import Fix, MapScene
from bluesky_gym.render.scenes.common import fit_extent, map_traffic, ownship_lines

LEGEND = [(pal.OWNSHIP, "ownship (agent)"), (pal.GOAL, "waypoint to visit"), (pal.GOAL_DONE, "waypoint reached")]


def plan_waypoint_scene(task: Any, i: int) -> MapScene:
    """The waypoints with their capture rings (grey once reached) around the start point."""
    wlat, wlon = task.wpt_lat[i], task.wpt_lon[i]
    done = task.wpt_reached[i]
    capture = float(task.config.distance_margin_km) / NM2KM
    clat, clon, half = fit_extent([AC_LAT, *wlat.tolist()], [AC_LON, *wlon.tolist()], margin_nm=12.0, min_half_nm=25.0)
    fixes = [Fix(float(a), float(o), f"WP{k + 1}", done=bool(d), capture_nm=capture) for k, (a, o, d) in enumerate(zip(wlat, wlon, done))]
    dist_km, _ = task.waypoint_geometry()
    left = np.where(done, np.inf, dist_km[i])
    panel = [*ownship_lines(task, i), ("reached", f"{int(done.sum())} / {done.size}")]
    if np.isfinite(left).any():
        k = int(np.argmin(left))
        panel.append(("nearest open", f"WP{k + 1} {float(left[k]):.1f} km"))
    return MapScene(
        clat,
        clon,
        half,
        aircraft=map_traffic(task, i, ring_nm=None),
        fixes=fixes,
        panel=panel,
        legend=LEGEND,
    )
