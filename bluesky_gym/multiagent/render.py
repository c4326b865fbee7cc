"""Pictures of the multi-agent episodes, drawn with the package's renderer.

The scene builders (one per environment, in its folder's ``multiagent.py``, named by its registry
row) read a :class:`~bluesky_gym.multiagent.base.MultiAgentTask` and return a north-up
:class:`~bluesky_gym.render.scene.MapScene` made with the parts here: every agent in the agent colour (red while
in a loss of separation with any other aircraft, with its protected-zone ring), its goal and a
dashed line to it, and the airspace of the problem (sector, FAF and runway). The renderer adds
trails, the scale and the text panel (step, team return, LoS events, minimum separation, agents
active / completed).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from bluesky_gym.envs.registry import multiagent_entry
from bluesky_gym.render import palette as pal
from bluesky_gym.render.scene import Line, MapAircraft

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


def callsign(slot: int) -> str:
    """The callsign drawn for aircraft slot ``slot``."""
    return f"A{slot}"


def agent_aircraft(task: MultiAgentTask, i: int) -> list[MapAircraft]:
    """Every active agent of episode ``i`` in the agent colour (red in a loss of separation), with its protected-zone ring."""
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
            callsign=callsign(int(k)),
            role="own",
            los=bool(los[k]),
            ring_nm=float(task.intrusion_distance),
        )
        for k in np.flatnonzero(s.active[i])
    ]


def goal_lines(task: MultiAgentTask, i: int) -> list[Line]:
    """A line from every active agent of episode ``i`` to its goal."""
    s = task.sim
    tlat, tlon = task.targets()
    return [Line([float(s.lat[i, k]), float(tlat[i, k])], [float(s.lon[i, k]), float(tlon[i, k])], pal.ROUTE) for k in np.flatnonzero(s.active[i])]


def panel_rows(task: MultiAgentTask, i: int) -> list[tuple[str, str]]:
    """The text panel rows every multi-agent picture shows: agents active of those at the start, agents completed."""
    st = task.stats
    return [
        ("agents", f"{int(task.sim.active[i].sum())} / {int(st.n_start[i])}"),
        (f"{task.completion}s", str(int(st.completed[i]))),
    ]


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
