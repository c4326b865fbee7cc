"""Pictures of the multi-agent episodes, drawn with the package's renderer.

The scene builders here read a :class:`~bluesky_gym.multiagent.base.MultiAgentTask` and return a
north-up :class:`~bluesky_gym.render.scene.MapScene`: every agent in the agent colour (red while
in a loss of separation with any other aircraft, with its protected-zone ring), its goal and a
dashed line to it, and the airspace of the problem (sector, FAF and runway). The renderer adds
trails, the scale and the text panel (step, team return, LoS events, minimum separation, agents
active / completed).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from bluesky_gym.core.units import NM2KM
from bluesky_gym.environments.horizontal_cr import task as hc
from bluesky_gym.environments.merge import task as mg
from bluesky_gym.environments.merge.scene import RUNWAY_HDG, RUNWAY_LENGTH_KM
from bluesky_gym.envs.registry import multiagent_entry
from bluesky_gym.render import palette as pal
from bluesky_gym.render.scene import Area, Fix, Line, MapAircraft, MapScene, Runway
from bluesky_gym.render.scenes.common import fit_extent
from bluesky_gym.tasks.geometry import point_at_distance

if TYPE_CHECKING:
    from bluesky_gym.multiagent.base import MultiAgentTask
    from bluesky_gym.render.renderer import Renderer

LEGEND: list[tuple[pal.Color, str]] = [
    (pal.OWNSHIP, "agent (every aircraft)"),
    (pal.LOS, "loss of separation"),
    (pal.GOAL, "agent's goal"),
]


def agent_name(slot: int) -> str:
    """Agent id of aircraft slot ``slot`` (also the PettingZoo agent name)."""
    return f"aircraft_{slot}"


def _callsign(slot: int) -> str:
    return f"A{slot}"


def _agents(task: MultiAgentTask, i: int) -> list[MapAircraft]:
    s = task.sim
    los = task.stats.in_los[i]
    return [
        MapAircraft(
            key=int(k),
            lat=float(s.lat[i, k]),
            lon=float(s.lon[i, k]),
            hdg=float(s.hdg[i, k]),
            trk=float(s.trk[i, k]),
            gs=float(s.gs[i, k]),
            alt=float(s.alt[i, k]),
            callsign=_callsign(int(k)),
            role="own",
            los=bool(los[k]),
            ring_nm=float(task.intrusion_distance),
        )
        for k in np.flatnonzero(s.active[i])
    ]


def _goal_lines(task: MultiAgentTask, i: int) -> list[Line]:
    s = task.sim
    tlat, tlon = task.targets()
    return [Line([float(s.lat[i, k]), float(tlat[i, k])], [float(s.lon[i, k]), float(tlon[i, k])], pal.ROUTE) for k in np.flatnonzero(s.active[i])]


def _panel(task: MultiAgentTask, i: int) -> list[tuple[str, str]]:
    st = task.stats
    return [
        ("agents", f"{int(task.sim.active[i].sum())} / {int(st.n_start[i])}"),
        (f"{task.completion}s", str(int(st.completed[i]))),
    ]


def sector_cr_scene(task: Any, i: int) -> MapScene:
    """Draw the sector, every agent with its 5 NM zone and its exit point."""
    scn = task.scenario
    nv = int(scn.n_vertices[i])
    plat, plon = scn.poly_lat[i, :nv].tolist(), scn.poly_lon[i, :nv].tolist()
    if nv >= 3:
        clat, clon, half = fit_extent(plat, plon, margin_nm=6.0, min_half_nm=30.0)
    else:  # before the first reset
        clat, clon, half = 52.0, 4.4, 40.0
    active = np.flatnonzero(task.sim.active[i])
    fixes = [Fix(float(scn.wpt_lat[i, k]), float(scn.wpt_lon[i, k])) for k in active]
    panel = [*_panel(task, i), ("inside", str(int((task.inside()[i] & task.sim.active[i]).sum())))]
    return MapScene(
        clat,
        clon,
        half,
        aircraft=_agents(task, i),
        fixes=fixes,
        areas=[Area(plat, plon, kind="sector")] if nv >= 3 else [],
        lines=_goal_lines(task, i),
        follow=None,
        panel=panel,
        legend=[*LEGEND, (pal.AIRSPACE_EDGE, "sector")],
    )


def merge_scene(task: Any, i: int) -> MapScene:
    """Draw the FAF (10 NM capture), runway (20 NM goal), the arrival sector and every agent with its 4 NM zone."""
    s = task.sim
    active = np.flatnonzero(s.active[i])
    lat_pts = [mg.RWY_LAT, mg.FAF_LAT, *s.lat[i, active].tolist()]
    lon_pts = [mg.RWY_LON, mg.FAF_LON, *s.lon[i, active].tolist()]
    clat, clon, half = fit_extent(lat_pts, lon_pts, margin_nm=22.0, min_half_nm=60.0, max_half_nm=220.0)
    bearing = float(task.config.spawn_bearing_deg)
    reach = max(float(task.config.intruder_distance_km[1]), float(task.config.spawn_distance_km[1]))
    lines = [Line([mg.FAF_LAT, mg.RWY_LAT], [mg.FAF_LON, mg.RWY_LON], pal.ROUTE)]
    for b in (-bearing, bearing):
        lat, lon = point_at_distance(mg.FAF_LAT, mg.FAF_LON, reach, b)
        lines.append(Line([mg.FAF_LAT, float(lat)], [mg.FAF_LON, float(lon)], pal.ROUTE))
    fixes = [
        Fix(mg.FAF_LAT, mg.FAF_LON, "FAF", capture_nm=mg.DISTANCE_MARGIN, kind="faf"),
        Fix(mg.RWY_LAT, mg.RWY_LON, "", capture_nm=mg.GOAL_MARGIN, kind="ring"),
    ]
    panel = [*_panel(task, i), ("past FAF", str(int((task.wpt_reach[i] != 0)[active].sum())))]
    return MapScene(
        clat,
        clon,
        half,
        aircraft=_agents(task, i),
        fixes=fixes,
        runways=[Runway(mg.RWY_LAT, mg.RWY_LON, RUNWAY_HDG, RUNWAY_LENGTH_KM, "RWY")],
        lines=lines,
        follow=None,
        panel=panel,
        legend=LEGEND,
    )


def horizontal_cr_scene(task: Any, i: int) -> MapScene:
    """Draw every agent with its 5 NM zone and its waypoint (5 km capture ring)."""
    s = task.sim
    used = task.wpt_lat[i] != 0.0
    if used.any():
        lat_pts = [*task.start_lat[i, used].tolist(), *task.wpt_lat[i, used].tolist()]
        lon_pts = [*task.start_lon[i, used].tolist(), *task.wpt_lon[i, used].tolist()]
        clat, clon, half = fit_extent(lat_pts, lon_pts, margin_nm=15.0, min_half_nm=45.0)
    else:  # before the first reset
        clat, clon, half = hc.START_LAT, hc.START_LON, 60.0
    fixes = [
        Fix(float(task.wpt_lat[i, k]), float(task.wpt_lon[i, k]), _callsign(int(k)), capture_nm=hc.DISTANCE_MARGIN / NM2KM)
        for k in np.flatnonzero(s.active[i])
    ]
    return MapScene(
        clat,
        clon,
        half,
        aircraft=_agents(task, i),
        fixes=fixes,
        lines=_goal_lines(task, i),
        follow=None,
        panel=_panel(task, i),
        legend=LEGEND,
    )


def make_renderer(task: MultiAgentTask, render_mode: str, fps: float = 30.0) -> Renderer:
    """Return a renderer of the package drawing the multi-agent scene of ``task``.

    Args:
        task: The multi-agent task (read only).
        render_mode: ``"rgb_array"`` or ``"human"``.
        fps: Frame-rate limit of the window in ``"human"`` mode.

    Raises:
        ImportError: If pygame is not installed.

    """
    from bluesky_gym.render import make_renderer as make_single_agent_renderer

    return make_single_agent_renderer(task, render_mode, fps, scene=multiagent_entry(task.name).scene_builder())
