"""Multi-agent HorizontalCR: the ownship and its intruders are all agents (adapted from docs/environments-v0.md §3).

The scenario is HorizontalCREnv-v0's (:class:`~bluesky_gym.environments.horizontal_cr.task.HorizontalCRTask`
generates it): an aircraft at 52N 4E heading north to a waypoint 100-149 km due north, and 5
intruders placed by ``creconfs`` in conflict with it. Every aircraft here is an agent and needs a
goal: the first aircraft keeps the single-agent waypoint; each intruder gets a waypoint on its
initial track, as far beyond its predicted closest point of approach with the first aircraft as
its start is before it (so the designed conflict lies half way), at least
``waypoint_distance_min`` km away. These waypoints need no random draws: a seed gives the
single-agent scenario of the same seed.

Observation and reward are HorizontalCREnv-v0's own functions
(:func:`bluesky_gym.environments.horizontal_cr.task.measure` with the nearest other aircraft,
:func:`~bluesky_gym.environments.horizontal_cr.task.observation`, :func:`~bluesky_gym.environments.horizontal_cr.task.reward`)
applied to every agent's slot.

Version history:
    * Observations now computed by the single-agent task functions for each agent (the same kwik
      forms as before: the values are unchanged).
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from bluesky_gym.core import geo
from bluesky_gym.core.physics import Physics
from bluesky_gym.core.units import KM, NM, NM2KM, R_EARTH
from bluesky_gym.environments.horizontal_cr import task as hc
from bluesky_gym.multiagent.base import Array, BoolArray, IntArray, MultiAgentTask, mask_padding, padding_mask
from bluesky_gym.multiagent.centralised import CentralisedEnv
from bluesky_gym.multiagent.render import LEGEND, agent_aircraft, callsign, goal_lines, panel_rows
from bluesky_gym.render.scene import Fix, MapScene
from bluesky_gym.render.scenes.common import fit_extent
from bluesky_gym.tasks import compiled
from bluesky_gym.tasks.base import BoxSpec, StepGeometry


def rhumb_destination(lat: Array, lon: Array, d_km: Array, bearing: Array) -> tuple[Array, Array]:
    """Point [deg] at ``d_km`` along the constant-heading (rhumb) line of ``bearing`` [deg] from (lat, lon).

    BlueSky moves an aircraft holding its heading along a rhumb line on a sphere of radius
    6371 km; a great-circle destination of the same bearing would lie several km to its side
    after a few hundred km, outside a 5 km capture radius.
    """
    phi1 = np.radians(lat)
    theta = np.radians(bearing)
    delta = np.asarray(d_km, dtype=np.float64) * KM / R_EARTH
    phi2 = phi1 + delta * np.cos(theta)
    dpsi = np.log(np.tan(np.pi / 4 + phi2 / 2) / np.tan(np.pi / 4 + phi1 / 2))
    with np.errstate(invalid="ignore", divide="ignore"):
        q = np.where(np.abs(dpsi) > 1e-12, (phi2 - phi1) / dpsi, np.cos(phi1))
    return np.degrees(phi2), lon + np.degrees(delta * np.sin(theta) / q)


def mirrored_waypoints(sim: Physics, envs: IntArray, min_km: float) -> tuple[Array, Array]:
    """Waypoints of the aircraft of ``envs``: the mirror image of each start about its CPA with slot 0.

    Each aircraft's closest point of approach with the aircraft in slot 0 is predicted from the
    current positions and ground-velocity vectors (straight flight, flat earth); its waypoint is
    on its current track (the rhumb line it flies while holding its heading) at twice the
    distance to that point (at least ``min_km``).

    Returns:
        Latitude and longitude [deg], (len(envs), max_aircraft). Slot 0's entries are meaningless.

    """
    lat, lon = sim.lat[envs], sim.lon[envs]
    trk, gs = np.deg2rad(sim.trk[envs]), sim.gs[envs]
    qdr, dist = geo.kwikqdrdist(lat[:, :1], lon[:, :1], lat, lon)
    rn = dist * NM * np.cos(np.deg2rad(qdr))  # position relative to slot 0 [m], north
    re = dist * NM * np.sin(np.deg2rad(qdr))
    vn, ve = gs * np.cos(trk), gs * np.sin(trk)
    dvn, dve = vn - vn[:, :1], ve - ve[:, :1]
    v2 = dvn * dvn + dve * dve
    with np.errstate(invalid="ignore", divide="ignore"):
        tcpa = np.where(v2 > 0, -(rn * dvn + re * dve) / v2, 0.0)
    d_km = np.maximum(2.0 * gs * np.maximum(tcpa, 0.0) / KM, min_km)
    return rhumb_destination(lat, lon, d_km, np.rad2deg(trk))


class HorizontalCRMultiAgentTask(MultiAgentTask):
    """Batched multi-agent horizontal conflict resolution.

    Per agent (every aircraft):

    * observation: HorizontalCREnv-v0's keys from its own point of view: the other aircraft (up
      to ``num_intruders``), **sorted by ascending distance** (there is no creation order from
      another aircraft's point of view): ``intruder_distance`` (km / 150), ``cos_difference_pos``,
      ``sin_difference_pos`` of wrap180(own heading - bearing to it), ``x_difference_speed``,
      ``y_difference_speed`` (its velocity in the own frame, / 150), ``waypoint_distance`` (km / 150),
      ``cos_drift``, ``sin_drift``, and ``traffic_mask`` (0 for padding once aircraft have left);
    * action: ``Box(-1, 1, (1,))``: HDG = heading at the last observation + 45 a;
    * reward: +1 when it first comes within 5 km of its waypoint, -0.1 |drift| [rad], -1 per
      other aircraft within 5 NM;
    * the agent terminates (arrives) on reaching its waypoint; its aircraft is removed. All agents
      are truncated at the time limit (300 steps of 50 s).

    As in HorizontalCREnv-v0 every aircraft is at altitude 0, so BlueSky's ground phase limits it
    to 89 m/s.
    """

    name: ClassVar[str] = "horizontal_cr_v0"
    env_id: ClassVar[str] = "HorizontalCR multi-agent"
    scenario_class = hc.HorizontalCRTask
    config: hc.HorizontalCRConfig
    intrusion_distance: ClassVar[float] = hc.INTRUSION_DISTANCE
    state_origin: ClassVar[tuple[float, float]] = (hc.START_LAT, hc.START_LON)
    state_scale_nm: ClassVar[float] = hc.DISTANCE_SCALE / NM2KM
    completion: ClassVar[str] = "arrival"
    heading_step: ClassVar[float] = hc.D_HEADING
    scenario: hc.HorizontalCRTask

    @property
    def num_neighbours(self) -> int:
        """Other aircraft in an observation: the configured number of intruders."""
        return int(self.config.num_intruders)

    def build_observation_spec(self) -> dict[str, BoxSpec]:
        """HorizontalCREnv-v0's keys (intruders sorted by distance), plus ``traffic_mask``."""
        k = self.num_neighbours
        spec = {key: BoxSpec((k,)) for key in ("intruder_distance", "x_difference_speed", "y_difference_speed")}
        spec.update({key: BoxSpec((k,), -1.0, 1.0) for key in ("cos_difference_pos", "sin_difference_pos")})
        order = ("intruder_distance", "cos_difference_pos", "sin_difference_pos", "x_difference_speed", "y_difference_speed")
        spec = {key: spec[key] for key in order}
        spec["waypoint_distance"] = BoxSpec((1,))
        spec.update({key: BoxSpec((1,), -1.0, 1.0) for key in ("cos_drift", "sin_drift")})
        spec["traffic_mask"] = BoxSpec((k,), 0.0, 1.0)
        return spec

    def build_action_spec(self) -> BoxSpec:
        """Heading change, one value in [-1, 1]."""
        return BoxSpec((1,), -1.0, 1.0)

    def allocate(self) -> None:
        """Per-agent waypoints and state."""
        shape = (self.n_envs, self.n_agents)
        self.wpt_lat = np.zeros(shape)  # deg
        self.wpt_lon = np.zeros(shape)
        self.wpt_reach = np.zeros(shape, bool)
        self.ac_hdg = np.zeros(shape)  # deg: heading at the last observation (the action's reference)
        self.start_lat = np.zeros(shape)  # deg
        self.start_lon = np.zeros(shape)

    def on_reset(self, envs: IntArray) -> None:
        """Slot 0 keeps the single-agent waypoint; the others get mirrored waypoints."""
        s = self.sim
        lat, lon = mirrored_waypoints(s, envs, float(self.config.waypoint_distance_min))
        lat[:, 0] = self.scenario.wpt_lat[envs]
        lon[:, 0] = self.scenario.wpt_lon[envs]
        self.wpt_lat[envs] = np.where(s.active[envs], lat, 0.0)
        self.wpt_lon[envs] = np.where(s.active[envs], lon, 0.0)
        self.wpt_reach[envs] = False
        self.ac_hdg[envs] = s.hdg[envs]
        self.start_lat[envs] = s.lat[envs]
        self.start_lon[envs] = s.lon[envs]

    def apply_action(self, action: Array) -> None:
        """HDG = heading at the last observation + 45 a, for every acting agent."""
        e, k = np.nonzero(self.acting)
        target = np.empty(e.size)
        compiled.heading_targets(self.ac_hdg[e, k], action[e, k], hc.D_HEADING, target)
        self.sim.cmd_heading(e, k, target)

    def targets(self) -> tuple[Array, Array]:
        """Each aircraft's waypoint."""
        return self.wpt_lat, self.wpt_lon

    def measure_rows(self, envs: IntArray, own: IntArray) -> hc.HorizontalCRGeometry:
        """HorizontalCREnv-v0's geometry of the agents ``own`` of episodes ``envs``, with the nearest other aircraft."""
        rows = (envs, own)
        return hc.measure(self.sim, envs, own, self.wpt_lat[rows], self.wpt_lon[rows], self.wpt_reach[rows], nearest=True, k=self.num_neighbours)

    def observe_rows(self, g: StepGeometry) -> dict[str, Array]:
        """HorizontalCREnv-v0's observation of each agent; padding entries zeroed, plus ``traffic_mask``.

        Stores the observed heading: the agent's next action's reference.
        """
        self.ac_hdg[g.envs, g.own] = g.heading  # type: ignore[attr-defined]
        return mask_padding(hc.observation(g), hc.INTRUDER_KEYS, padding_mask(g.n_others, self.num_neighbours))  # type: ignore[arg-type, attr-defined]

    def reward_rows(self, g: StepGeometry) -> tuple[Array, BoolArray, dict[str, Array]]:
        """Reach reward (terminates the agent), drift and intrusion penalties."""
        r, _, components = hc.reward(g)  # type: ignore[arg-type]
        self.wpt_reach[g.envs, g.own] = g.goal_reached  # type: ignore[attr-defined]
        return r, g.newly_reached, components  # type: ignore[attr-defined]


class HorizontalCRCentralisedEnv(CentralisedEnv):
    """HorizontalCRCentralised-v0: one agent steers the ownship and its intruders (see :mod:`bluesky_gym.multiagent.centralised`)."""

    task_class = HorizontalCRMultiAgentTask


def horizontal_cr_multiagent_scene(task: Any, i: int) -> MapScene:
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
        Fix(float(task.wpt_lat[i, k]), float(task.wpt_lon[i, k]), callsign(int(k)), capture_nm=hc.DISTANCE_MARGIN / NM2KM)
        for k in np.flatnonzero(s.active[i])
    ]
    return MapScene(
        clat,
        clon,
        half,
        aircraft=agent_aircraft(task, i),
        fixes=fixes,
        lines=goal_lines(task, i),
        follow=None,
        panel=panel_rows(task, i),
        legend=LEGEND,
    )
