"""Multi-agent SectorCR: every aircraft crossing the sector is an agent (adapted from docs/environments-v0.md §5).

The scenario is SectorCREnv-v0's (:class:`~bluesky_gym.environments.sector_cr.task.SectorCRTask` generates
it): a random convex sector with ``max(ceil(density * area), 5)`` aircraft, each flying from a
random point inside towards its own exit point on the boundary. Here every aircraft is an agent
with the single-agent observation, action and reward, seen from its own point of view: the
observation and reward are SectorCREnv-v0's own functions
(:func:`bluesky_gym.environments.sector_cr.task.measure`, :func:`~bluesky_gym.environments.sector_cr.task.observation`,
:func:`~bluesky_gym.environments.sector_cr.task.reward`) applied to every agent's slot.

Version history:
    * Observations now computed by the single-agent task functions for each agent: the drift uses
      the single-agent (BlueSky Python) kwik form and the intrusion test the single-agent kwik
      distance, instead of the core's kwik form (values differ in the last bits).
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from bluesky_gym.environments.sector_cr import task as sc
from bluesky_gym.multiagent.base import Array, BoolArray, IntArray, MultiAgentTask, mask_padding, padding_mask
from bluesky_gym.multiagent.centralised import CentralisedEnv
from bluesky_gym.multiagent.render import LEGEND, agent_aircraft, goal_lines, panel_rows
from bluesky_gym.render import palette as pal
from bluesky_gym.render.scene import Area, Fix, MapScene
from bluesky_gym.render.scenes.common import fit_extent
from bluesky_gym.tasks import compiled
from bluesky_gym.tasks.base import BoxSpec, StepGeometry

STATE_SCALE_NM = 40.0  # NM: positions in the global state (the sector's circle has a 34.5 NM radius)


class SectorCRMultiAgentTask(MultiAgentTask):
    """Batched multi-agent sector conflict resolution.

    Per agent (every aircraft of the sector):

    * observation: ``cos(drift)``, ``sin(drift)`` (drift = wrap180(heading - kwik bearing to its own
      exit point)), ``airspeed`` = (TAS - 150) / 6, and its 4 nearest other aircraft by flat
      distance, in ascending order: ``x_r``, ``y_r`` (their position minus its own, north / east
      [m] / 13000), ``vx_r`` / 32, ``vy_r`` / 66 (TAS-vector difference, north / east [m/s]),
      ``cos(track)``, ``sin(track)`` of the relative velocity, ``distances`` = (d [m] - 50000) /
      15000, and ``traffic_mask`` (1 for a real neighbour, 0 for padding: when fewer than 4 other
      aircraft are left, the missing entries are zeros). The constants and key names are
      SectorCREnv-v0's; ``airspeed`` is declared unbounded here (its values leave [-1, 1]);
    * action: ``Box(-1, 1, (2,))``: HDG wrap180(heading + 22.5 a0), SPD (CAS + 20/3 a1) kt-converted
      exactly as SectorCREnv-v0 (a CAS step of up to 6.67 m/s);
    * reward: -0.1 |drift| [rad] - 1 per other aircraft within 5 NM (kwik distance), every step;
    * the agent leaves (``truncated``, as the single-agent episode's end) when it is outside the
      sector; its aircraft is removed. All agents are truncated at the time limit (200 steps).
    """

    name: ClassVar[str] = "sector_cr_v0"
    env_id: ClassVar[str] = "SectorCR multi-agent"
    scenario_class = sc.SectorCRTask
    intrusion_distance: ClassVar[float] = sc.INTRUSION_DISTANCE
    state_origin: ClassVar[tuple[float, float]] = sc.CENTER
    state_scale_nm: ClassVar[float] = STATE_SCALE_NM
    completion: ClassVar[str] = "exit"
    unsupported_options: ClassVar[tuple[str, ...]] = ("exit_ends_episode",)
    heading_step: ClassVar[float] = sc.D_HEADING
    speed_step: ClassVar[float | None] = sc.D_VELOCITY
    config: sc.SectorCRConfig
    num_neighbours: ClassVar[int] = sc.NUM_AC_STATE
    scenario: sc.SectorCRTask

    def build_observation_spec(self) -> dict[str, BoxSpec]:
        """SectorCREnv-v0's keys, from each agent's point of view, plus ``traffic_mask``."""
        k = self.num_neighbours
        spec = {key: BoxSpec((1,), -1.0, 1.0) for key in ("cos(drift)", "sin(drift)")}
        spec["airspeed"] = BoxSpec((1,))
        spec.update({key: BoxSpec((k,)) for key in ("x_r", "y_r", "vx_r", "vy_r")})
        spec.update({key: BoxSpec((k,), -1.0, 1.0) for key in ("cos(track)", "sin(track)")})
        spec["distances"] = BoxSpec((k,))
        spec["traffic_mask"] = BoxSpec((k,), 0.0, 1.0)
        return spec

    def build_action_spec(self) -> BoxSpec:
        """Heading change and speed change, each in [-1, 1]."""
        return BoxSpec((2,), -1.0, 1.0)

    def apply_action(self, action: Array) -> None:
        """HDG wrap180(hdg + 22.5 a0); SPD (CAS + 20/3 a1) * 1.94384 kt, for every acting agent."""
        self.command_heading_and_speed(action, sc.D_HEADING, sc.speed_change(self.config))

    def targets(self) -> tuple[Array, Array]:
        """Each aircraft's exit point."""
        return self.scenario.wpt_lat, self.scenario.wpt_lon

    def measure_rows(self, envs: IntArray, own: IntArray) -> sc.SectorGeometry:
        """SectorCREnv-v0's geometry of the agents ``own`` of episodes ``envs``."""
        return sc.measure(self.sim, self.scenario, envs, own)

    def observe_rows(self, g: StepGeometry) -> dict[str, Array]:
        """SectorCREnv-v0's observation of each agent; padding entries zeroed, plus ``traffic_mask``."""
        return mask_padding(sc.observation(g), sc.INTRUDER_KEYS, padding_mask(g.n_others, self.num_neighbours))  # type: ignore[arg-type, attr-defined]

    def reward_rows(self, g: StepGeometry) -> tuple[Array, BoolArray, dict[str, Array]]:
        """Drift and intrusion penalties; no agent terminates (leaving the sector truncates it)."""
        r, _, components = sc.reward(g)  # type: ignore[arg-type]
        return r, np.zeros(len(g.envs), bool), components

    def inside(self) -> BoolArray:
        """(n_envs, n_agents) aircraft inside their episode's sector (2-D even-odd test on lat/lon)."""
        s, scn = self.sim, self.scenario
        envs, own = np.nonzero(np.ones_like(s.active))
        out = np.empty(envs.size, bool)
        compiled.slots_in_polygons(envs, own, s.lat, s.lon, scn.poly_lat, scn.poly_lon, scn.n_vertices, out)
        return out.reshape(s.active.shape)

    def leaving(self, g: StepGeometry) -> BoolArray:
        """Agents outside the sector leave (the single-agent episode's truncation)."""
        return ~g.inside  # type: ignore[attr-defined]


class SectorCRCentralisedEnv(CentralisedEnv):
    """SectorCRCentralised-v0: one agent steers every aircraft of the sector (see :mod:`bluesky_gym.multiagent.centralised`)."""

    task_class = SectorCRMultiAgentTask


def sector_cr_multiagent_scene(task: Any, i: int) -> MapScene:
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
    panel = [*panel_rows(task, i), ("inside", str(int((task.inside()[i] & task.sim.active[i]).sum())))]
    return MapScene(
        clat,
        clon,
        half,
        aircraft=agent_aircraft(task, i),
        fixes=fixes,
        areas=[Area(plat, plon, kind="sector")] if nv >= 3 else [],
        lines=goal_lines(task, i),
        follow=None,
        panel=panel,
        legend=[*LEGEND, (pal.AIRSPACE_EDGE, "sector")],
    )
