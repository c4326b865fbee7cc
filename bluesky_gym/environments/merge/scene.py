"""MergeEnv-v0: north-up map of the arrival stream, the FAF, the runway and the ownship."""

from __future__ import annotations

from typing import Any

import numpy as np

from bluesky_gym.core import geo
from bluesky_gym.environments.merge.task import FAF_BEARING, INTRUSION_DISTANCE, RWY_LAT, RWY_LON
from bluesky_gym.render import palette as pal
from bluesky_gym.render.scene import Fix, Line, MapScene, Runway
from bluesky_gym.render.scenes.common import LEGEND_TRAFFIC, OWNSHIP_CALLSIGN, drift_line, fit_extent, map_traffic, ownship_lines
from bluesky_gym.tasks.geometry import point_at_distance

RUNWAY_HDG = (FAF_BEARING + 180.0) % 360.0  # deg: arrivals come from the FAF (due north) and land towards the runway
RUNWAY_LENGTH_KM = 3.3  # km: length of the drawn runway
FIT_RUNWAY_NM = 150.0  # NM: a FAF at most this far from the runway is drawn with it in one view


def _callsign(slot: int) -> str:
    return OWNSHIP_CALLSIGN if slot == 0 else f"INT{slot - 1}"


def merge_scene(task: Any, i: int) -> MapScene:
    """The arrival picture around the final approach fix.

    FAF with its capture ring (10 NM in -v0), the runway with its goal ring (20 NM in -v0), the
    arrival sector (the spawn radials from the FAF) and the traffic with 4 NM protected zones.
    """
    sim = task.sim
    space = task.airspace
    faf_lat, faf_lon = space.faf_lat, space.faf_lon
    legend = [
        *LEGEND_TRAFFIC,
        (pal.GOAL, f"FAF ({space.faf_margin_nm:.3g} NM) / runway ({space.goal_margin_nm:.3g} NM)"),
        (pal.ROUTE, "arrival sector and approach"),
    ]
    # The view holds the runway, the FAF and the start; with a FAF farther out than that fits
    # (the -v1 200 NM) it holds the FAF, the start and the ownship, and the runway when targeted.
    near = float(geo.kwikdist(faf_lat, faf_lon, RWY_LAT, RWY_LON)) <= FIT_RUNWAY_NM or int(task.wpt_reach[i]) != 0
    lat_pts = [RWY_LAT, faf_lat] if near else [faf_lat, float(sim.lat[i, 0])]
    lon_pts = [RWY_LON, faf_lon] if near else [faf_lon, float(sim.lon[i, 0])]
    if sim.active[i, 0]:
        lat_pts.append(float(task.start_lat[i]))
        lon_pts.append(float(task.start_lon[i]))
    clat, clon, half = fit_extent(lat_pts, lon_pts, margin_nm=22.0, min_half_nm=60.0, max_half_nm=160.0)
    bearing = float(task.config.spawn_bearing_deg)
    reach = max(float(task.config.intruder_distance_km[1]), float(task.config.spawn_distance_km[1]))
    lines = [Line([faf_lat, RWY_LAT], [faf_lon, RWY_LON], pal.ROUTE)]
    for b in (-bearing, bearing):
        lat, lon = point_at_distance(faf_lat, faf_lon, reach, b)
        lines.append(Line([faf_lat, float(lat)], [faf_lon, float(lon)], pal.ROUTE))
    faf_done = int(task.wpt_reach[i]) != 0
    fixes = [
        Fix(faf_lat, faf_lon, "FAF", done=faf_done, capture_nm=space.faf_margin_nm, kind="faf"),
        Fix(RWY_LAT, RWY_LON, "", done=False, capture_nm=space.goal_margin_nm, kind="ring"),
    ]
    tlat, tlon = task.target()
    qdr, dist = geo.kwikqdrdist(sim.lat[i, 0], sim.lon[i, 0], tlat[i], tlon[i])
    drift = (float(sim.hdg[i, 0]) - float(qdr) + 180.0) % 360.0 - 180.0
    panel = [
        *ownship_lines(task, i),
        ("target", "runway" if faf_done else "FAF"),
        ("to target", f"{float(dist):.1f} NM"),
        drift_line(drift),
    ]
    dist_all, _ = task.ownship_separation()
    panel.append(("traffic < 20 NM", str(int(np.count_nonzero(dist_all[i] < 20.0)))))
    return MapScene(
        clat,
        clon,
        half,
        aircraft=map_traffic(task, i, ring_nm=INTRUSION_DISTANCE, callsign=_callsign),
        fixes=fixes,
        runways=[Runway(RWY_LAT, RWY_LON, RUNWAY_HDG, RUNWAY_LENGTH_KM, "RWY")],
        lines=lines,
        label_range_nm=30.0,
        panel=panel,
        legend=legend,
    )
