"""PlanWaypointEnv-v0: fly over as many of five scattered waypoints as possible (docs/environments-v0.md §4)."""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from bluesky_gym.core import geo
from bluesky_gym.core.units import NM2KM
from bluesky_gym.environments.horizontal_cr.task import AIRBORNE_ALT
from bluesky_gym.tasks.base import Array, BoolArray, BoxSpec, StepGeometry, Task, TaskConfig, check_int, check_range
from bluesky_gym.tasks.geometry import point_at_distance, ref_kwikqdrdist, wrap180

AC_LAT, AC_LON = 52.0, 4.0  # deg: BlueSky's default creation position
AC_HDG = 0.0  # deg: creation heading (BlueSky's default, north)
AC_ALT = 0.0  # m: created on the ground, so OpenAP's ground phase caps CAS at 89 m/s (kept, docs/environments-v0.md §0)
AC_SPD = 150.0  # m/s CAS requested at creation
D_HEADING = 45.0  # deg of heading change per unit action
REACH_REWARD = 1.0  # per waypoint newly within the capture radius
# The reference draws bearings with randint(0, 359): integers in [0, 358] (kept, docs/environments-v0.md §4).
WAYPOINT_BEARING_END = 359  # deg, exclusive upper bound of the bearing draw
MAX_WAYPOINTS = 8  # the shortest-tour KPI enumerates all n! visiting orders
TOUR_CHUNK = 1 << 20  # leg lengths evaluated at once by the tour KPI (bounds its memory)
# -v1: how far the aircraft can get from a waypoint beyond the farthest draw in 300 steps of 10 s
# at 250 m/s [km]; waypoint_distance's declared bound follows from it.
WANDER_KM = 750.0


@dataclass(frozen=True)
class PlanWaypointMeasurement(StepGeometry):
    """One step's quantities of the waypoint-planning task, for the rows (episodes) ``envs``.

    No traffic and no single heading goal; ``goal_reached``: every waypoint reached, this step's included.
    """

    dist_km: Array  # (rows, num_waypoints) kwik distance to each waypoint
    drift: Array  # (rows, num_waypoints) deg, wrap180(hdg - qdr)
    reached_before: BoolArray  # (rows, num_waypoints) reached in an earlier step
    newly_reached: BoolArray  # (rows, num_waypoints) within the capture radius for the first time


@dataclass(frozen=True)
class PlanWaypointConfig(TaskConfig):
    """Scenario options of the waypoint-planning task (defaults: the paper's).

    Attributes:
        num_waypoints: Waypoints per episode (the observation vectors have this length).
        waypoint_distance_min: Lower bound of the integer waypoint distance draw [km].
        waypoint_distance_max: Exclusive upper bound of that draw [km]; also the distance
            normalisation of the observation.
        distance_margin_km: Capture radius of a waypoint [km].
        airborne_start: ``-v1``: the aircraft starts at FL100, where it flies the CAS 150 m/s of
            the scenario; ``-v0``: at altitude 0, in BlueSky's ground phase, capped at 89 m/s.
        reach_same_step: ``-v1``: a waypoint reached in a step shows as reached (and masked) in
            that step's observation; ``-v0``: from the next one (the reference's one-step lag).

    """

    num_waypoints: int = 5
    waypoint_distance_min: int = 0
    waypoint_distance_max: int = 75
    distance_margin_km: float = 5.0
    airborne_start: bool = False
    reach_same_step: bool = False

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first invalid option."""
        check_int("num_waypoints", self.num_waypoints, 1, MAX_WAYPOINTS)
        check_int("waypoint_distance_min", self.waypoint_distance_min, 0, 1000)
        check_int("waypoint_distance_max", self.waypoint_distance_max, self.waypoint_distance_min + 1, 2000)
        check_range("distance_margin_km", self.distance_margin_km, 0.0, 100.0, strict_low=True)


class PlanWaypointTask(Task):
    """Batched waypoint-planning task; see :class:`bluesky_gym.environments.plan_waypoint.env.PlanWaypointEnv`."""

    env_id: ClassVar[str] = "PlanWaypointEnv-v0"
    dt: ClassVar[float] = 1.0
    action_frequency: ClassVar[int] = 10
    max_episode_steps: ClassVar[int] = 300
    config_class: ClassVar[type[TaskConfig]] = PlanWaypointConfig
    info_keys: ClassVar[tuple[str, ...]] = ("total_reward", "waypoints_completed")
    config: PlanWaypointConfig

    def max_aircraft(self) -> int:
        """One aircraft: the ownship (no traffic)."""
        return 1

    def build_observation_spec(self) -> dict[str, BoxSpec]:
        """Four vectors of one entry per waypoint, in the reference's key order."""
        w = (self.config.num_waypoints,)
        if self.config.float32_spaces:
            return {
                "waypoint_distance": BoxSpec(w, 0.0, float(np.ceil(1.0 + WANDER_KM / self.config.waypoint_distance_max))),
                "cos_difference": BoxSpec(w, -1.0, 1.0),
                "sin_difference": BoxSpec(w, -1.0, 1.0),
                "waypoint_reached": BoxSpec(w, 0.0, 1.0),
            }
        return {
            "waypoint_distance": BoxSpec(w),
            "cos_difference": BoxSpec(w),
            "sin_difference": BoxSpec(w),
            "waypoint_reached": BoxSpec(w, 0.0, 1.0),
        }

    def build_action_spec(self) -> BoxSpec:
        """One heading action in [-1, 1]."""
        return BoxSpec((1,), -1.0, 1.0)

    # --- generator ------------------------------------------------------------------------------
    def allocate(self) -> None:
        """Waypoint positions, their draws and reach flags, (n_envs, num_waypoints) each."""
        shape = (self.n_envs, self.config.num_waypoints)
        self.wpt_lat = np.zeros(shape)  # deg
        self.wpt_lon = np.zeros(shape)  # deg
        self.wpt_draw_km = np.zeros(shape, np.int64)  # the integer distance draw [km]
        self.wpt_draw_bearing = np.zeros(shape, np.int64)  # the integer bearing draw [deg]
        self.wpt_reached = np.zeros(shape, bool)
        self.tour_km = np.zeros(self.n_envs)  # shortest start->all-waypoints polyline [km]
        self._orders = np.array(list(itertools.permutations(range(1, shape[1] + 1))))  # (n!, n) node ids

    def generate(self, envs: NDArray[np.int64]) -> None:
        """Create the aircraft, then draw the waypoints (distance, bearing) one by one."""
        c = self.config
        self.sim.create(envs, 0, AC_LAT, AC_LON, AC_HDG, AIRBORNE_ALT if c.airborne_start else AC_ALT, AC_SPD)
        for e in envs:
            rng = self.rngs[e]
            for i in range(c.num_waypoints):  # distance then bearing, waypoint by waypoint
                self.wpt_draw_km[e, i] = rng.integers(c.waypoint_distance_min, c.waypoint_distance_max)
                self.wpt_draw_bearing[e, i] = rng.integers(0, WAYPOINT_BEARING_END)
        # Placed from the aircraft's current position (after a clean reset: its creation point).
        lat0, lon0 = self.sim.lat[envs, :1], self.sim.lon[envs, :1]
        self.wpt_lat[envs], self.wpt_lon[envs] = point_at_distance(lat0, lon0, self.wpt_draw_km[envs], self.wpt_draw_bearing[envs])
        self.wpt_reached[envs] = False
        chunk = max(1, TOUR_CHUNK // self._orders.size)
        for s in range(0, envs.size, chunk):
            self.tour_km[envs[s : s + chunk]] = self._shortest_tour_km(envs[s : s + chunk])

    def _shortest_tour_km(self, envs: NDArray[np.int64]) -> Array:
        """Shortest polyline from the start through every waypoint centre (kwik distances, km)."""
        lat = np.concatenate([self.sim.lat[envs, :1], self.wpt_lat[envs]], axis=1)  # node 0: the start
        lon = np.concatenate([self.sim.lon[envs, :1], self.wpt_lon[envs]], axis=1)
        dist = geo.kwikdist(lat[:, :, None], lon[:, :, None], lat[:, None, :], lon[:, None, :]) * NM2KM
        o = self._orders
        length = dist[:, 0, o[:, 0]] + dist[:, o[:, :-1], o[:, 1:]].sum(axis=-1)  # (envs, n!)
        shortest: Array = length.min(axis=1)
        return shortest

    # --- action -------------------------------------------------------------------------------
    def apply_action(self, action: Array) -> None:
        """Heading target hdg + 45 a (the reference's "HDG" command, not wrapped)."""
        self.sim.cmd_heading(self.all_envs, 0, self.sim.hdg[:, 0] + action[:, 0] * D_HEADING)

    # --- measure --------------------------------------------------------------------------------
    def waypoint_geometry(self, envs: NDArray[np.int64] | slice | None = None) -> tuple[Array, Array]:
        """(rows, num_waypoints) kwik distance [km] and drift wrap180(hdg - qdr) [deg] of episodes ``envs`` (all when None)."""
        rows = slice(None) if envs is None else envs
        s = self.sim
        qdr, dist = ref_kwikqdrdist(s.lat[rows, :1], s.lon[rows, :1], self.wpt_lat[rows], self.wpt_lon[rows])
        return dist * NM2KM, wrap180(s.hdg[rows, :1] - qdr)

    def measure(self, envs: NDArray[np.int64] | None = None) -> PlanWaypointMeasurement:
        """Distance and drift to every waypoint, and which ones the aircraft is within the capture radius of, for episodes ``envs``."""
        ids = self.all_envs if envs is None else np.asarray(envs, dtype=np.int64)
        rows: NDArray[np.int64] | slice = slice(None) if envs is None else ids  # a slice: views, no copies
        dist_km, drift = self.waypoint_geometry(rows)
        reached_before = self.wpt_reached[rows].copy()  # the reward updates the flags
        new = (dist_km < self.config.distance_margin_km) & ~reached_before
        shape = (ids.size, self.sim.max_aircraft)
        return PlanWaypointMeasurement(
            envs=ids,
            separation_nm=np.full(shape, np.inf),
            los=np.zeros(shape, bool),
            drift_deg=None,
            goal_reached=np.asarray((reached_before | new).all(axis=1)),
            dist_km=dist_km,
            drift=drift,
            reached_before=reached_before,
            newly_reached=new,
        )

    # --- observation ----------------------------------------------------------------------------
    def observe(self, g: StepGeometry | None = None) -> dict[str, Array]:
        """Masked distance and drift per waypoint, and the reach flags as floats, of the rows ``g.envs``."""
        g = self.measure() if g is None else g
        assert isinstance(g, PlanWaypointMeasurement)
        # The reference masks with the integer (1 - reached), so a masked entry is 0.0 times the
        # value: -0.0 where the value is negative (docs/environments-v0.md §4). A waypoint reached in this step still
        # shows as unreached (the one-step lag, docs/environments-v0.md §4).
        # -v1 shows this step's reaches at once.
        reached = g.reached_before | g.newly_reached if self.config.reach_same_step else g.reached_before
        m = np.where(reached, 0.0, 1.0)
        rad = np.deg2rad(g.drift)
        return {
            "waypoint_distance": m * g.dist_km / self.config.waypoint_distance_max,
            "cos_difference": m * np.cos(rad),
            "sin_difference": m * np.sin(rad),
            "waypoint_reached": reached.astype(np.float64),
        }

    # --- reward and termination -----------------------------------------------------------------
    def reward(self, g: StepGeometry) -> tuple[Array, BoolArray, dict[str, Array]]:
        """+1 per newly reached waypoint (recorded); terminated when all are reached (all episodes)."""
        assert isinstance(g, PlanWaypointMeasurement)
        self.wpt_reached |= g.newly_reached
        reach = g.newly_reached.sum(axis=1) * REACH_REWARD
        return reach, g.goal_reached, {"reach": reach}

    def episode_info(self) -> dict[str, Array]:
        """``total_reward`` and ``waypoints_completed``."""
        return {"total_reward": self.stats.total_reward.copy(), "waypoints_completed": self.wpt_reached.sum(axis=1)}

    def extra_track_km(self) -> Array:
        """Distance flown minus the shortest polyline from the start through all waypoint centres.

        It can be negative: a waypoint counts as reached anywhere within the capture radius.
        """
        return self.sim.distflown[:, 0] / 1000.0 - self.tour_km
