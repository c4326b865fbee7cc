"""Multi-agent Merge: every arrival is an agent merging via the FAF to the runway (adapted from docs/environments-v0.md §7).

The scenario is MergeEnv-v0's (:class:`~bluesky_gym.environments.merge.task.MergeTask` generates it): 20
aircraft at 10000 m north of the final approach fix, within +-15 deg of the approach radial. In
the single-agent environment aircraft 0 is controlled and the others fly LNAV via the FAF to the
runway; here every aircraft is an agent with MergeEnv-v0's observation, action and reward from
its own point of view (an aircraft's LNAV route is switched off by its first heading command):
the observation and reward are MergeEnv-v0's own functions (:func:`bluesky_gym.environments.merge.task.measure`,
:func:`~bluesky_gym.environments.merge.task.observation`, :func:`~bluesky_gym.environments.merge.task.reward`) applied to
every agent's slot.

Version history:
    * Observations now computed by the single-agent task functions for each agent: drift, target
      and intruder distances and bearings use the single-agent (BlueSky Python) kwik forms, and
      the neighbours are sorted by MergeEnv-v0's ``kwikdist_matrix``, instead of the core's kwik
      form (values differ in the last bits).
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from bluesky_gym.environments.merge import task as mg
from bluesky_gym.environments.merge.scene import RUNWAY_HDG, RUNWAY_LENGTH_KM
from bluesky_gym.multiagent.base import Array, BoolArray, IntArray, MultiAgentTask, mask_padding, padding_mask
from bluesky_gym.multiagent.centralised import CentralisedEnv
from bluesky_gym.multiagent.render import LEGEND, agent_aircraft, panel_rows
from bluesky_gym.render import palette as pal
from bluesky_gym.render.scene import Fix, Line, MapScene, Runway
from bluesky_gym.render.scenes.common import fit_extent
from bluesky_gym.tasks.base import BoxSpec, StepGeometry
from bluesky_gym.tasks.geometry import point_at_distance


class MergeMultiAgentTask(MultiAgentTask):
    """Batched multi-agent merge.

    Per agent (every aircraft):

    * observation: MergeEnv-v0's keys from its own point of view: ``cos(drift)``, ``sin(drift)``
      to its current target (the FAF, then the runway once the FAF was reached), ``airspeed``
      (TAS [m/s], not normalised, as MergeEnv-v0), ``waypoint_dist`` (kwik NM to the target / 250),
      ``faf_reached`` (0/1, with MergeEnv-v0's one-step lag), and its 5 nearest other aircraft by
      kwik distance: ``x_r``, ``y_r`` (north / east [m] / 1e6), ``vx_r``, ``vy_r`` (TAS-vector
      difference / 150), ``cos(track)``, ``sin(track)``, ``distances`` (NM / 250) and
      ``traffic_mask`` (0 for padding when fewer than 5 other aircraft are left);
    * action: ``Box(-1, 1, (2,))``: HDG wrap180(heading + 15 a0), SPD (CAS + 20 a1) kt-converted;
    * reward: +1 when it first comes within 10 NM of the FAF, -0.1 |drift| [rad], -1 per other
      aircraft within 4 NM;
    * the agent terminates (arrives) when, after the FAF, it is within 20 NM of the runway; its
      aircraft is removed. All agents are truncated at the time limit (50 steps of 50 s).
    """

    name: ClassVar[str] = "merge_v0"
    env_id: ClassVar[str] = "Merge multi-agent"
    scenario_class = mg.MergeTask
    intrusion_distance: ClassVar[float] = mg.INTRUSION_DISTANCE
    state_origin: ClassVar[tuple[float, float]] = (mg.FAF_LAT, mg.FAF_LON)
    state_scale_nm: ClassVar[float] = mg.WAYPOINT_DIST_SCALE
    completion: ClassVar[str] = "arrival"
    unsupported_options: ClassVar[tuple[str, ...]] = ("faf_same_step", "faf_distance_in_nm", "margins_in_km", "normalise_airspeed")
    num_neighbours: ClassVar[int] = mg.NUM_AC_STATE
    heading_step: ClassVar[float] = mg.D_HEADING
    speed_step: ClassVar[float | None] = mg.D_SPEED
    scenario: mg.MergeTask

    def build_observation_spec(self) -> dict[str, BoxSpec]:
        """MergeEnv-v0's keys and bounds, plus ``traffic_mask``."""
        k = self.num_neighbours
        spec = {key: BoxSpec((1,), -1.0, 1.0) for key in ("cos(drift)", "sin(drift)")}
        spec.update({key: BoxSpec((1,)) for key in ("airspeed", "waypoint_dist")})
        spec["faf_reached"] = BoxSpec((1,), 0.0, 1.0)
        spec.update({key: BoxSpec((k,)) for key in ("x_r", "y_r", "vx_r", "vy_r")})
        spec.update({key: BoxSpec((k,), -1.0, 1.0) for key in ("cos(track)", "sin(track)")})
        spec["distances"] = BoxSpec((k,))
        spec["traffic_mask"] = BoxSpec((k,), 0.0, 1.0)
        return spec

    def build_action_spec(self) -> BoxSpec:
        """Heading change and speed change, each in [-1, 1]."""
        return BoxSpec((2,), -1.0, 1.0)

    def allocate(self) -> None:
        """Per-agent target state."""
        shape = (self.n_envs, self.n_agents)
        self.wpt_reach = np.zeros(shape, np.int64)  # 0 before the FAF, 1 after (the observed flag)
        self.faf_reached = np.zeros(shape, np.int64)  # 0, 1 (FAF) or 2 (near the runway)

    def on_reset(self, envs: IntArray) -> None:
        """Every agent starts towards the FAF."""
        self.wpt_reach[envs] = 0
        self.faf_reached[envs] = 0

    def apply_action(self, action: Array) -> None:
        """HDG wrap180(hdg + 15 a0); SPD (CAS + 20 a1) * 1.94384 kt, for every acting agent."""
        self.command_heading_and_speed(action, mg.D_HEADING, mg.D_SPEED)

    def targets(self) -> tuple[Array, Array]:
        """Return the FAF, or the runway for agents that reached the FAF."""
        return mg.target(self.wpt_reach != 0)

    def measure_rows(self, envs: IntArray, own: IntArray) -> mg.MergeGeometry:
        """MergeEnv-v0's geometry of the agents ``own`` of episodes ``envs``."""
        return mg.measure(self.sim, envs, own, self.wpt_reach[envs, own] != 0)

    def observe_rows(self, g: StepGeometry) -> dict[str, Array]:
        """MergeEnv-v0's observation of each agent; padding entries zeroed, plus ``traffic_mask``."""
        return mask_padding(mg.observation(g), mg.INTRUDER_KEYS, padding_mask(g.n_others, self.num_neighbours))  # type: ignore[arg-type, attr-defined]

    def reward_rows(self, g: StepGeometry) -> tuple[Array, BoolArray, dict[str, Array]]:
        """FAF reach reward, runway arrival, drift and intrusion penalties (MergeEnv-v0's, per agent)."""
        r, reach_faf, near_runway, _, components = mg.reward(g)  # type: ignore[arg-type]
        rows = (g.envs, g.own)  # type: ignore[attr-defined]
        self.wpt_reach[rows] = np.where(reach_faf, 1, self.wpt_reach[rows])
        self.faf_reached[rows] = np.where(reach_faf, 1, np.where(near_runway, 2, self.faf_reached[rows]))
        return r, near_runway, components


class MergeCentralisedEnv(CentralisedEnv):
    """MergeCentralised-v0: one agent steers every arrival (see :mod:`bluesky_gym.multiagent.centralised`)."""

    task_class = MergeMultiAgentTask


def merge_multiagent_scene(task: Any, i: int) -> MapScene:
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
    panel = [*panel_rows(task, i), ("past FAF", str(int((task.wpt_reach[i] != 0)[active].sum())))]
    return MapScene(
        clat,
        clon,
        half,
        aircraft=agent_aircraft(task, i),
        fixes=fixes,
        runways=[Runway(mg.RWY_LAT, mg.RWY_LON, RUNWAY_HDG, RUNWAY_LENGTH_KM, "RWY")],
        lines=lines,
        follow=None,
        panel=panel,
        legend=LEGEND,
    )
