"""Plan view of recorded traffic: callsigns, and each aircraft's recorded track ghosted behind it."""

from __future__ import annotations

from typing import Any

import numpy as np

from bluesky_gym.render import palette as pal
from bluesky_gym.render.scene import Line, MapScene
from bluesky_gym.render.scenes.common import LEGEND_TRAFFIC, drift_line, map_traffic, ownship_lines

GHOST_OWN: pal.Color = (60, 120, 80)  # the ownship's recorded track
GHOST_TRAFFIC: pal.Color = (110, 96, 64)  # the traffic's recorded tracks
GHOST_STEP_S = 20.0  # s between the points of a ghost track
VIEW_HALF_NM = 40.0  # NM
LABEL_RANGE_NM = {"all": None, "near": 20.0}


def real_traffic_scene(task: Any, i: int) -> MapScene:
    """Every aircraft with its recorded callsign, the recorded tracks since the window start ghosted."""
    sim = task.sim
    player = task.player
    flights = task.flights
    labels = task.config.labels
    now = float(player.now(np.array([i]))[0])
    start = float(player.start[i])

    def callsign(slot: int) -> str:
        f = int(player.flight[i, slot])
        return str(flights.callsign[f]) if f >= 0 else ""

    aircraft = map_traffic(task, i, callsign=callsign)
    lines = []
    for s in np.flatnonzero(sim.active[i]):
        f = int(player.flight[i, s])
        t0 = max(start, float(flights.t0[f]))
        times = np.arange(t0, now + 1e-9, GHOST_STEP_S)
        if len(times) < 2:
            continue
        rec = flights.at(np.full(len(times), f), times)
        lines.append(Line(rec["lat"].tolist(), rec["lon"].tolist(), GHOST_OWN if s == 0 else GHOST_TRAFFIC, dashed=True))
    lat = float(sim.lat[i, 0]) if sim.active[i, 0] else float(np.mean(sim.lat[i][sim.active[i]]))
    lon = float(sim.lon[i, 0]) if sim.active[i, 0] else float(np.mean(sim.lon[i][sim.active[i]]))
    g = task.measure(np.array([i]))
    panel = ownship_lines(task, i)
    panel.append(("route dev.", f"{float(g.route_nm[0]):+.2f} NM"))
    if g.drift_deg is not None:
        panel.append(drift_line(float(g.drift_deg[0])))
    panel.append(("aircraft", f"{int(sim.active[i].sum())}"))
    legend = [*LEGEND_TRAFFIC, (GHOST_TRAFFIC, "recorded tracks")]
    return MapScene(
        lat,
        lon,
        VIEW_HALF_NM,
        aircraft=aircraft,
        lines=lines,
        traffic_details=True,
        label_range_nm=LABEL_RANGE_NM.get(labels),
        labels=labels != "none",
        panel=panel,
        legend=legend,
    )
