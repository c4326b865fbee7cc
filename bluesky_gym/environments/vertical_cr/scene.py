"""VerticalCREnv-v0: side view of the descent with the intruders' separation boxes, plus a plan view."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from bluesky_gym.core import geo
from bluesky_gym.core.units import NM2KM
from bluesky_gym.environments.descent.scene import side_ownship, vertical_lines
from bluesky_gym.environments.vertical_cr.task import INTRUSION_DISTANCE, VERTICAL_MARGIN
from bluesky_gym.render import palette as pal
from bluesky_gym.render.scene import MapScene, SideAircraft, SideScene
from bluesky_gym.render.scenes.common import LEGEND_TRAFFIC, default_callsign, map_traffic, separation

INSET_HALF_WIDTH_NM = 30.0

LEGEND = [
    *LEGEND_TRAFFIC,
    (pal.INTRUDER_FAR, f"traffic > {INTRUSION_DISTANCE:g} NM off route"),
    (pal.GOAL, "target altitude"),
]


def vertical_cr_scene(task: Any, i: int) -> SideScene:
    """Altitude against distance to the runway; intruders are projected on the ownship's route.

    An intruder's separation box spans the intrusion distance (5 NM) along the route and the
    vertical margin (1000 ft) up and down; it turns red during a loss of separation. Intruders
    more than 5 NM to the side of the route are faded (the projection hides that offset) and
    labelled with it; the plan view in the corner shows the horizontal picture.
    """
    sim = task.sim
    rd = float(task.runway_distance()[i])
    aircraft = side_ownship(task, i, rd)
    dist, los = separation(task, i)
    dim = np.zeros(sim.max_aircraft, bool)
    if sim.active[i, 0]:
        own_lat, own_lon, own_hdg = float(sim.lat[i, 0]), float(sim.lon[i, 0]), float(sim.hdg[i, 0])
        for s in (np.flatnonzero(sim.active[i, 1:]) + 1).tolist():
            qdr, d_nm = geo.kwikqdrdist(own_lat, own_lon, float(sim.lat[i, s]), float(sim.lon[i, s]))
            rel = math.radians(float(qdr) - own_hdg)  # bearing of the intruder relative to the route
            along_km = float(d_nm) * NM2KM * math.cos(rel)
            cross_nm = float(d_nm) * math.sin(rel)  # positive: right of the route
            dim[s] = abs(cross_nm) >= INTRUSION_DISTANCE and not los[s]
            aircraft.append(
                SideAircraft(
                    key=s,
                    x_km=rd - along_km,
                    alt=float(sim.alt[i, s]),
                    vx=float(sim.gs[i, s]) * math.cos(math.radians(float(sim.hdg[i, s]) - own_hdg)),
                    vs=float(sim.vs[i, s]),
                    callsign=default_callsign(s),
                    los=bool(los[s]),
                    box=(INTRUSION_DISTANCE * NM2KM, VERTICAL_MARGIN),
                    dim=bool(dim[s]),
                    note=f"{abs(cross_nm):.0f} NM {'R' if cross_nm >= 0 else 'L'}",
                )
            )
    vertical = np.abs(sim.alt[i] - sim.alt[i, 0]) >= VERTICAL_MARGIN
    inset = None
    if sim.active[i, 0]:
        inset = MapScene(
            float(sim.lat[i, 0]),
            float(sim.lon[i, 0]),
            INSET_HALF_WIDTH_NM,
            aircraft=map_traffic(task, i, ring_nm=INTRUSION_DISTANCE, los=los, dim=vertical),
            follow=None,
        )
    in_los = int(np.count_nonzero(los))
    panel = vertical_lines(task, i, rd)
    near = int(np.count_nonzero(np.isfinite(dist) & (dist < 2 * INTRUSION_DISTANCE)))
    panel.append(("traffic < 10 NM", str(near)))
    return SideScene(
        x_max_km=float(task.config.runway_distance_km) + 5.0,
        x_min_km=-10.0,
        alt_max=5000.0,
        aircraft=aircraft,
        target_alt=float(task.target_alt[i]) if sim.active[i, 0] else None,
        runway_km=3.0,
        inset=inset,
        panel=panel + ([("intrusions now", str(in_los))] if in_los else []),
        legend=LEGEND,
    )
