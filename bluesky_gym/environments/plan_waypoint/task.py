"""PlanWaypointEnv-v0: fly over as many of five scattered waypoints as possible (docs/environments-v0.md §4).

The step's rules (the heading command, the waypoint geometry, the observation, the reward and
the reach flags, the info's count and the extra-track KPI) are the kernels at the end of this
module: the task calls them on the CPU, and the vector environment's device step
(:mod:`bluesky_gym.environments.plan_waypoint.device_step`) launches their CUDA forms.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from bluesky_gym.core import geo
from bluesky_gym.core.jit import grid_range, jit
from bluesky_gym.core.units import NM2KM
from bluesky_gym.environments.horizontal_cr.task import AIRBORNE_ALT
from bluesky_gym.tasks import compiled
from bluesky_gym.tasks.base import Array, BoolArray, BoxSpec, StepGeometry, Task, TaskConfig, check_int, check_range
from bluesky_gym.tasks.compiled import DEG2RAD, kwikqdrdist_scalar, wrap180_scalar
from bluesky_gym.tasks.geometry import point_at_distance

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
#: The observation's keys, in the reference's order.
OBSERVATION_KEYS = ("waypoint_distance", "cos_difference", "sin_difference", "waypoint_reached")


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
    #: The extra track is measured from the shortest tour through every waypoint centre (it can be
    #: negative: a waypoint counts as reached anywhere within its capture radius).
    route_km_array: ClassVar[str | None] = "tour_km"
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
        """Heading target hdg + 45 a (the reference's "HDG" command, not wrapped): :func:`~bluesky_gym.tasks.compiled.heading_targets`."""
        target = np.empty(self.n_envs)
        compiled.heading_targets(self.sim.hdg[:, 0], np.ascontiguousarray(action), D_HEADING, target)
        self.sim.cmd_heading(self.all_envs, 0, target)

    # --- measure --------------------------------------------------------------------------------
    def waypoint_geometry(self, envs: NDArray[np.int64] | None = None) -> tuple[Array, Array]:
        """(rows, num_waypoints) kwik distance [km] and drift wrap180(hdg - qdr) [deg] of episodes ``envs`` (all when None)."""
        g = self.measure(envs)
        return g.dist_km, g.drift

    def measure(self, envs: NDArray[np.int64] | None = None) -> PlanWaypointMeasurement:
        """Distance and drift to every waypoint, and which ones the aircraft is within the capture radius of, for episodes ``envs``.

        The kernel :func:`waypoint_measure`.
        """
        ids = self.all_envs if envs is None else np.asarray(envs, dtype=np.int64)
        shape = (ids.size, self.config.num_waypoints)
        dist_km, drift = np.empty(shape), np.empty(shape)
        reached_before, new, goal = np.empty(shape, bool), np.empty(shape, bool), np.empty(ids.size, bool)
        s = self.sim
        waypoint_measure(
            ids,
            s.lat,
            s.lon,
            s.hdg,
            self.wpt_lat,
            self.wpt_lon,
            self.wpt_reached,
            float(self.config.distance_margin_km),
            dist_km,
            drift,
            reached_before,
            new,
            goal,
        )
        separation = (ids.size, s.max_aircraft)
        return PlanWaypointMeasurement(
            envs=ids,
            separation_nm=np.full(separation, np.inf),
            los=np.zeros(separation, bool),
            drift_deg=None,
            goal_reached=goal,
            dist_km=dist_km,
            drift=drift,
            reached_before=reached_before,
            newly_reached=new,
        )

    # --- observation ----------------------------------------------------------------------------
    def observe(self, g: StepGeometry | None = None) -> dict[str, Array]:
        """Masked distance and drift per waypoint, and the reach flags as floats, of the rows ``g.envs``: :func:`waypoint_observation`."""
        g = self.measure() if g is None else g
        assert isinstance(g, PlanWaypointMeasurement)
        out = {key: np.empty(g.dist_km.shape) for key in OBSERVATION_KEYS}
        waypoint_observation(
            g.dist_km,
            g.drift,
            g.reached_before,
            g.newly_reached,
            self.config.reach_same_step,
            float(self.config.waypoint_distance_max),
            *out.values(),
        )
        return out

    # --- reward and termination -----------------------------------------------------------------
    def reward(self, g: StepGeometry) -> tuple[Array, BoolArray, dict[str, Array]]:
        """+1 per newly reached waypoint, recorded in the reach flags (:func:`waypoint_reward`); terminated when all are reached."""
        assert isinstance(g, PlanWaypointMeasurement)
        reward, reach = np.empty(g.envs.size), np.empty(g.envs.size)
        waypoint_reward(g.envs, g.newly_reached, REACH_REWARD, self.wpt_reached, reward, reach)
        return reward, g.goal_reached, {"reach": reach}

    def episode_info(self) -> dict[str, Array]:
        """``total_reward`` and ``waypoints_completed`` (:func:`count_reached`)."""
        completed: NDArray[Any] = np.empty(self.n_envs, np.int64)
        count_reached(self.wpt_reached, completed)
        return {"total_reward": self.stats.total_reward.copy(), "waypoints_completed": completed}


# --- kernels: the step's rules, for the CPU and the device step ------------------------------------
@jit
def waypoint_measure(envs, lat, lon, hdg, wpt_lat, wpt_lon, wpt_reached, margin_km, dist_out, drift_out, before_out, new_out, goal_out):
    """The waypoint geometry of episodes ``envs`` (rows): :class:`PlanWaypointMeasurement`'s arrays.

    Args:
        envs: (p,) the episode of each row.
        lat: (n, m) latitudes [deg] (the aircraft: slot 0).
        lon: (n, m) longitudes [deg].
        hdg: (n, m) headings [deg].
        wpt_lat: (n, w) waypoint latitudes [deg].
        wpt_lon: (n, w) waypoint longitudes [deg].
        wpt_reached: (n, w) the waypoints reached in earlier steps.
        margin_km: Capture radius [km].
        dist_out: (p, w) kwik distance to each waypoint [km].
        drift_out: (p, w) wrap180_scalar(hdg - kwik bearing) [deg].
        before_out: (p, w) reached in an earlier step.
        new_out: (p, w) within the capture radius for the first time.
        goal_out: (p,) every waypoint reached, this step's included.
    """
    for r in grid_range(envs.shape[0]):
        e = envs[r]
        goal = True
        for i in range(wpt_lat.shape[1]):
            qdr, dist = kwikqdrdist_scalar(lat[e, 0], lon[e, 0], wpt_lat[e, i], wpt_lon[e, i])
            d = dist * NM2KM
            before = wpt_reached[e, i]
            new = d < margin_km and not before
            dist_out[r, i] = d
            drift_out[r, i] = wrap180_scalar(hdg[e, 0] - qdr)
            before_out[r, i] = before
            new_out[r, i] = new
            if not (before or new):
                goal = False
        goal_out[r] = goal


@jit
def waypoint_observation(dist_km, drift, before, new, same_step, distance_scale, distance_out, cos_out, sin_out, reached_out):
    """The observation of :func:`waypoint_measure`'s rows: masked distance and drift per waypoint, and the reach flags.

    A waypoint shows as reached when it was reached in an earlier step, or with ``same_step``
    (``-v1``) also in this one. The reference masks with the integer (1 - reached), so a masked
    entry is 0.0 times the value: -0.0 where the value is negative (docs/environments-v0.md §4).
    Distances are divided by ``distance_scale`` [km].
    """
    for r in grid_range(dist_km.shape[0]):
        for i in range(dist_km.shape[1]):
            reached = before[r, i] or (same_step and new[r, i])
            m = 0.0 if reached else 1.0
            rad = drift[r, i] * DEG2RAD
            distance_out[r, i] = m * dist_km[r, i] / distance_scale
            cos_out[r, i] = m * math.cos(rad)
            sin_out[r, i] = m * math.sin(rad)
            reached_out[r, i] = 1.0 if reached else 0.0


@jit
def waypoint_reward(envs, new, reach_reward, wpt_reached, reward_out, reach_out):
    """``reach_reward`` per waypoint newly reached by row ``r`` (episode ``envs[r]``), flagged as reached in ``wpt_reached`` (n, w)."""
    for r in grid_range(envs.shape[0]):
        e = envs[r]
        count = 0
        for i in range(new.shape[1]):
            if new[r, i]:
                count += 1
                wpt_reached[e, i] = True
        reach = count * reach_reward
        reward_out[r] = reach
        reach_out[r] = reach


@jit
def count_reached(wpt_reached, out):
    """(n,) the waypoints each episode has reached (``wpt_reached`` (n, w))."""
    for e in grid_range(out.shape[0]):
        count = 0
        for i in range(wpt_reached.shape[1]):
            if wpt_reached[e, i]:
                count += 1
        out[e] = count
