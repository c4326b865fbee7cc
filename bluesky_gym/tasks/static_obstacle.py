"""StaticObstacleEnv-v0: reach a waypoint around polygonal restricted areas (spec section 6)."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from bluesky_gym.core import geo
from bluesky_gym.core.units import KTS, MPS2KT, NM2KM
from bluesky_gym.tasks import compiled
from bluesky_gym.tasks.base import Array, BoolArray, BoxSpec, StepGeometry, Task, TaskConfig, check_int, check_range
from bluesky_gym.tasks.geometry import (
    PolygonSet,
    nm_to_latlon,
    point_at_distance,
    point_at_distance_scalar,
    points_in_polygons,
    polygon_area,
    random_convex_polygon,
    ref_kwikqdrdist,
    wrap180,
)

AC_LAT, AC_LON = 52.0, 4.0  # deg: BlueSky's default creation position
AC_HDG = 0.0  # deg: creation heading, replaced by the bearing to the waypoint
AC_ALT = 350.0  # m: the reference's "ALTITUDE 350" (meant as FL350) is used as metres (spec 6)
AC_SPD = 150.0  # m/s CAS (commented as kts in the reference)
D_HEADING = 45.0  # deg of heading change per unit action
D_SPEED = 20 / 3  # "kts" in the reference, but added to CAS in m/s (kept, spec 6)
REACH_REWARD = 1.0
DRIFT_PENALTY = -0.01  # per rad of |drift|
RESTRICTED_AREA_INTRUSION_PENALTY = -5.0  # per obstacle containing the aircraft
RADIUS_SCALE_NM = 50.0  # the reference divides the radius [NM] by OBSTACLE_AREA_RANGE[0] = 50
MAX_WAYPOINT_TRIES = 1000  # waypoint rejection sampling gives up after this many tries
BEARING_END = 360  # deg, exclusive upper bound of the integer bearing draws: [0, 359]
VIEW_SIZE_KM = 350.0  # width of the reference's square view, centred on the start position
VIEW_ORIGIN_BEARING = 315.0  # deg: the view's top-left corner as seen from the start
VERTEX_CAPACITY = 16  # initial vertex slots per polygon (grown when a polygon needs more)


@dataclass(frozen=True)
class StaticObstacleConfig(TaskConfig):
    """Scenario options of the static-obstacle task (defaults: the paper's).

    Attributes:
        num_obstacles: Restricted areas per episode (the obstacle vectors have this length).
        obstacle_distance_min: Lower bound of the integer obstacle-centre distance draw [km].
        obstacle_distance_max: Exclusive upper bound of that draw [km].
        obstacle_area_min: Minimum polygon area [NM^2]; the circumscribed circle's area is an
            integer draw in [2 * obstacle_area_min, obstacle_area_max).
        obstacle_area_max: Exclusive upper bound of the circle-area draw [NM^2]; at most
            pi * 50^2 so that ``restricted_area_radius`` stays within its declared [0, 1].
        waypoint_distance_min: Lower bound of the integer waypoint distance draw [km].
        waypoint_distance_max: Exclusive upper bound of that draw [km]; also the distance
            normalisation of the observation.
        distance_margin_km: Capture radius of the waypoint [km].

    """

    num_obstacles: int = 10
    obstacle_distance_min: int = 20
    obstacle_distance_max: int = 150
    obstacle_area_min: int = 50
    obstacle_area_max: int = 1000
    waypoint_distance_min: int = 100
    waypoint_distance_max: int = 170
    distance_margin_km: float = 5.0

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first invalid option."""
        check_int("num_obstacles", self.num_obstacles, 1, 50)
        check_int("obstacle_distance_min", self.obstacle_distance_min, 0, 1000)
        check_int("obstacle_distance_max", self.obstacle_distance_max, self.obstacle_distance_min + 1, 2000)
        check_int("obstacle_area_min", self.obstacle_area_min, 1, 3900)
        # The circle area is drawn from [2 * min, max): the draw needs 2 * min < max, and a
        # polygon inscribed in a circle of twice the minimum area can always reach it.
        check_int("obstacle_area_max", self.obstacle_area_max, 2 * self.obstacle_area_min + 1, int(np.pi * RADIUS_SCALE_NM**2))
        check_int("waypoint_distance_min", self.waypoint_distance_min, 0, 1000)
        check_int("waypoint_distance_max", self.waypoint_distance_max, self.waypoint_distance_min + 1, 2000)
        check_range("distance_margin_km", self.distance_margin_km, 0.0, 100.0, strict_low=True)


class StaticObstacleTask(Task):
    """Batched static-obstacle task; see :class:`bluesky_gym.envs.static_obstacle_env.StaticObstacleEnv`."""

    env_id: ClassVar[str] = "StaticObstacleEnv-v0"
    dt: ClassVar[float] = 1.0
    action_frequency: ClassVar[int] = 10
    max_episode_steps: ClassVar[int] = 100
    config_class: ClassVar[type[TaskConfig]] = StaticObstacleConfig
    info_keys: ClassVar[tuple[str, ...]] = ("total_reward", "waypoint_reached", "crashed", "average_drift")
    config: StaticObstacleConfig

    def max_aircraft(self) -> int:
        """One aircraft: the ownship (no traffic)."""
        return 1

    def build_observation_spec(self) -> dict[str, BoxSpec]:
        """Waypoint and obstacle observation, in the reference's key order."""
        k = (self.config.num_obstacles,)
        return {
            "destination_waypoint_distance": BoxSpec((1,)),
            "destination_waypoint_cos_drift": BoxSpec((1,)),
            "destination_waypoint_sin_drift": BoxSpec((1,)),
            "restricted_area_radius": BoxSpec(k, 0.0, 1.0),
            "restricted_area_distance": BoxSpec(k),
            "cos_difference_restricted_area_pos": BoxSpec(k),
            "sin_difference_restricted_area_pos": BoxSpec(k),
        }

    def build_action_spec(self) -> BoxSpec:
        """Heading and speed actions in [-1, 1]."""
        return BoxSpec((2,), -1.0, 1.0)

    # --- generator ------------------------------------------------------------------------------
    def allocate(self) -> None:
        """Obstacle polygons, waypoint, stale observation values and episode counters."""
        self._obstacle_cache: tuple[tuple[NDArray, ...], PolygonSet] | None = None
        n, k = self.n_envs, self.config.num_obstacles
        self.obstacle_centre_lat = np.zeros((n, k))  # deg
        self.obstacle_centre_lon = np.zeros((n, k))  # deg
        self.obstacle_radius = np.zeros((n, k))  # NM, radius of the circle the polygon is drawn on
        self.obstacle_area = np.zeros((n, k))  # NM^2, shoelace area of the polygon
        self.obstacle_lat = np.zeros((n, k, VERTEX_CAPACITY))  # deg, vertices (padded)
        self.obstacle_lon = np.zeros((n, k, VERTEX_CAPACITY))  # deg
        self.obstacle_nv = np.zeros((n, k), np.int64)  # vertex count of each polygon
        self.wpt_lat = np.zeros(n)  # deg
        self.wpt_lon = np.zeros(n)  # deg
        self.start_wpt_km = np.zeros(n)  # kwik distance start -> waypoint [km]
        self.view_origin_lat = np.zeros(n)  # deg: top-left corner of the reference's view
        self.view_origin_lon = np.zeros(n)
        # Waypoint distance [km] and drift [deg] as of the last observation: the per-sub-step
        # reward uses these stale values (spec 6).
        self.obs_wpt_km = np.zeros(n)
        self.obs_drift = np.zeros(n)
        self.wpt_reached = np.zeros(n, bool)
        self.crashed = np.zeros(n, bool)
        self.intrusions = np.zeros(n, np.int64)  # obstacle intrusions counted by the reward
        self.drift_sum_rad = np.zeros(n)  # sum of the per-sub-step |drift| samples [rad]
        self.drift_count = np.zeros(n, np.int64)

    def generate(self, envs: NDArray[np.int64]) -> None:
        """Aircraft, obstacle centres, polygons, waypoint, then the initial heading (spec 6)."""
        c = self.config
        k = c.num_obstacles
        self.sim.create(envs, 0, AC_LAT, AC_LON, AC_HDG, AC_ALT, AC_SPD)
        lat0, lon0 = self.sim.lat[envs, 0], self.sim.lon[envs, 0]
        view_km = np.sqrt(2 * (VIEW_SIZE_KM / 2) ** 2)
        self.view_origin_lat[envs], self.view_origin_lon[envs] = geo.kwikpos(lat0, lon0, VIEW_ORIGIN_BEARING, view_km / NM2KM)
        for j, e in enumerate(envs):
            rng = self.rngs[e]
            # All centres first, then the polygons, then the waypoint: the reference's draw order.
            d = np.empty(k, np.int64)
            b = np.empty(k, np.int64)
            for i in range(k):
                d[i] = rng.integers(c.obstacle_distance_min, c.obstacle_distance_max)
                b[i] = rng.integers(0, BEARING_END)
            clat, clon = point_at_distance(lat0[j], lon0[j], d, b)
            self.obstacle_centre_lat[e], self.obstacle_centre_lon[e] = clat, clon
            polys = []
            for i in range(k):
                circle_area = rng.integers(2 * c.obstacle_area_min, c.obstacle_area_max)
                radius = math.sqrt(int(circle_area) / math.pi)
                polys.append(random_convex_polygon(rng, radius, c.obstacle_area_min))
                self.obstacle_radius[e, i] = radius
                self.obstacle_area[e, i] = polygon_area(polys[-1])
            self._store_polygons(e, clat, clon, polys)
            self.wpt_lat[e], self.wpt_lon[e] = sample_waypoint(
                rng, lat0[j], lon0[j], self.obstacle_lat[e], self.obstacle_lon[e], self.obstacle_nv[e],
                c.waypoint_distance_min, c.waypoint_distance_max, compiled,
            )
        # The aircraft starts pointing at the waypoint: hdg and the autopilot track (spec 6).
        qdr, dist = ref_kwikqdrdist(lat0, lon0, self.wpt_lat[envs], self.wpt_lon[envs])
        self.sim.hdg[envs, 0] = qdr
        self.sim.ap_trk[envs, 0] = qdr
        self.start_wpt_km[envs] = dist * NM2KM
        self.wpt_reached[envs] = False
        self.crashed[envs] = False
        self.intrusions[envs] = 0
        self.drift_sum_rad[envs] = 0.0
        self.drift_count[envs] = 0
        dist_km, drift = self.waypoint_geometry()
        self.obs_wpt_km[envs] = dist_km[envs]
        self.obs_drift[envs] = drift[envs]

    def _store_polygons(self, e: int, clat: Array, clon: Array, polys: list[Array]) -> None:
        """Store episode ``e``'s polygons, (north, east) NM around their centres, as (lat, lon)."""
        nv = np.array([len(p) for p in polys])
        cap = self.obstacle_lat.shape[-1]
        if nv.max() > cap:  # rare: grow the vertex capacity of every polygon
            pad = ((0, 0), (0, 0), (0, max(int(nv.max()), 2 * cap) - cap))
            self.obstacle_lat = np.pad(self.obstacle_lat, pad)
            self.obstacle_lon = np.pad(self.obstacle_lon, pad)
        # All polygons in one conversion: each vertex with its polygon's centre.
        vertices = nm_to_latlon(np.stack([np.repeat(clat, nv), np.repeat(clon, nv)], axis=-1), np.concatenate(polys))
        mask = np.arange(self.obstacle_lat.shape[-1]) < nv[:, None]
        self.obstacle_lat[e] = 0.0
        self.obstacle_lon[e] = 0.0
        self.obstacle_lat[e][mask] = vertices[:, 0]
        self.obstacle_lon[e][mask] = vertices[:, 1]
        self.obstacle_nv[e] = nv

    # --- dynamics interface ---------------------------------------------------------------------
    def apply_action(self, action: Array) -> None:
        """Heading wrap180(hdg + 45 a0) and speed (CAS + 20/3 a1) * 1.94384 kts."""
        hdg = wrap180(self.sim.hdg[:, 0] + action[:, 0] * D_HEADING)
        spd_kts = (self.sim.cas[:, 0] + action[:, 1] * D_SPEED) * MPS2KT
        # "HDG KL001 <hdg>" then "SPD KL001 <kts>": BlueSky converts the speed with kts.
        self.sim.cmd_heading(self.all_envs, 0, hdg)
        self.sim.cmd_speed(self.all_envs, 0, spd_kts * KTS)

    def waypoint_geometry(self) -> tuple[Array, Array]:
        """(n_envs,) live kwik distance to the waypoint [km] and drift wrap180(hdg - qdr) [deg]."""
        qdr, dist = ref_kwikqdrdist(self.sim.lat[:, 0], self.sim.lon[:, 0], self.wpt_lat, self.wpt_lon)
        return dist * NM2KM, wrap180(self.sim.hdg[:, 0] - qdr)

    def inside_obstacles(self) -> NDArray[np.bool_]:
        """(n_envs, num_obstacles) whether each obstacle polygon contains the aircraft now."""
        out = np.empty(self.obstacle_nv.shape, bool)
        compiled.ownship_in_polygons(self.sim.lat, self.sim.lon, self.obstacle_lat, self.obstacle_lon, self.obstacle_nv, out)
        return out

    # --- observation ----------------------------------------------------------------------------
    def observe(self, g: StepGeometry | None = None) -> dict[str, Array]:
        """Waypoint and obstacle-centre geometry; stores the waypoint values the reward uses."""
        dist_km, drift = self.waypoint_geometry()
        self.obs_wpt_km = dist_km
        self.obs_drift = drift
        qdr_c, dist_c = self.kwik_from_ownship(self.obstacle_centre_lat, self.obstacle_centre_lon)
        bearing = np.deg2rad(wrap180(self.sim.hdg[:, :1] - qdr_c))
        scale = self.config.waypoint_distance_max
        rad = np.deg2rad(drift)
        return {
            "destination_waypoint_distance": (dist_km / scale)[:, None],
            "destination_waypoint_cos_drift": np.cos(rad)[:, None],
            "destination_waypoint_sin_drift": np.sin(rad)[:, None],
            "restricted_area_radius": self.obstacle_radius / RADIUS_SCALE_NM,
            "restricted_area_distance": dist_c * NM2KM / scale,
            "cos_difference_restricted_area_pos": np.cos(bearing),
            "sin_difference_restricted_area_pos": np.sin(bearing),
        }

    # --- reward ---------------------------------------------------------------------------------
    def evaluate(self) -> tuple[Array, BoolArray, dict[str, Array]]:
        """One sub-step's reward of every episode (see :meth:`evaluate_substep`)."""
        return self.evaluate_substep(np.ones(self.n_envs, bool))

    def evaluate_substep(self, running: BoolArray) -> tuple[Array, BoolArray, dict[str, Array]]:
        """Evaluate one sub-step as the reference does, with side effects only where ``running``.

        Waypoint distance and drift are the stale values of the last observation; the obstacle
        test uses the live position (spec 6).

        Args:
            running: (n_envs,) episodes still being stepped in this decision step.

        Returns:
            Reward, done flags and the components ``reach``, ``drift``, ``intrusion``.

        """
        new = running & (self.obs_wpt_km < self.config.distance_margin_km) & ~self.wpt_reached
        self.wpt_reached |= new
        reach = np.where(new, REACH_REWARD, 0.0)
        drift_rad = np.abs(np.deg2rad(self.obs_drift))
        drift = drift_rad * DRIFT_PENALTY
        self.drift_sum_rad += np.where(running, drift_rad, 0.0)
        self.drift_count += running
        count = self.inside_obstacles().sum(axis=1)
        intrusion = count * RESTRICTED_AREA_INTRUSION_PENALTY
        hit = running & (count > 0)
        self.crashed |= hit
        self.intrusions += np.where(running, count, 0)
        reward = reach + drift + intrusion
        return reward, self.wpt_reached | (count > 0), {"reach": reach, "drift": drift, "intrusion": intrusion}

    def advance(self) -> None:
        """The sub-steps and their rewards (:meth:`transition`), kept for :meth:`reward` (transitional)."""
        self._outcome = self.transition()

    def reward(self, g: StepGeometry) -> tuple[Array, BoolArray, dict[str, Array]]:
        """The reward of the last evaluated sub-step, computed by :meth:`advance`."""
        return self._outcome

    def measure(self, envs: NDArray[np.int64] | None = None) -> StepGeometry:
        """Common geometry (KPIs): drift to the waypoint now, whether it was reached."""
        g = super().measure(envs)
        return dataclasses.replace(g, drift_deg=self.waypoint_geometry()[1][g.envs], goal_reached=self.wpt_reached[g.envs].copy())

    def observe_envs(self, envs: NDArray[np.int64]) -> dict[str, Array]:
        """Observation of episodes ``envs`` only: the rows of the full observation."""
        return {k: v[envs] for k, v in self.observe().items()}

    def transition(self) -> tuple[Array, BoolArray, dict[str, Array]]:
        """Sub-steps with the reward evaluated after each; an episode stops at the sub-step it ends.

        The reference returns at once when an episode ends at sub-step k, with the observation of
        sub-step k. In a batch the other episodes keep stepping; the ended ones are stepped too
        (the physics is batched) and then put back to their state at sub-step k. Only the reward
        of the last evaluated sub-step is returned (spec 6).

        This is :meth:`evaluate_substep` after every sub-step, with the work that does not change
        between sub-steps done once: the waypoint distance and drift are the stale values of the
        last observation, so a waypoint is reached (and the episode ends) at the first sub-step
        or not at all, and only the obstacle test needs the live position.
        """
        if not self.substep_hooks:
            try:
                start = self.sim.snapshot()
            except NotImplementedError:  # physics that cannot rewind (the BlueSky adapter): one sub-step at a time
                start = None
            if start is not None:
                return self._transition_traced(start)
        n = self.n_envs
        running = np.ones(n, bool)
        last = np.zeros(n, np.int64)  # last evaluated sub-step of each episode
        count = np.zeros(n, np.int64)  # obstacles containing the aircraft at that sub-step
        reached = (self.obs_wpt_km < self.config.distance_margin_km) & ~self.wpt_reached
        done_anyway = self.wpt_reached | reached  # ends at the first sub-step, obstacles or not
        drift_rad = np.abs(np.deg2rad(self.obs_drift))
        frozen: list[tuple[NDArray[np.int64], dict[str, Any]]] = []
        for k in range(self.action_frequency):
            self.sim.step()
            self.drift_sum_rad += np.where(running, drift_rad, 0.0)
            self.drift_count += running
            c = self.inside_obstacles().sum(axis=1)
            ended = running & (done_anyway | (c > 0))
            last[running] = k
            count[running] = c[running]
            running &= ~ended
            for hook in self.substep_hooks:
                hook(self, k)
            if not running.any():
                break
            if ended.any() and k < self.action_frequency - 1:
                envs = np.flatnonzero(ended)
                frozen.append((envs, self.sim.snapshot(envs)))
        for envs, state in frozen:
            self.sim.restore(state, envs)
        return self._finish_transition(reached, done_anyway, drift_rad, count)

    def _transition_traced(self, start: dict[str, Any]) -> tuple[Array, BoolArray, dict[str, Array]]:
        """:meth:`transition` from one traced run of all sub-steps (compiled physics and geometry).

        The obstacle test needs only the ownship's position after each sub-step, so all sub-steps
        run in one call that records the positions; the episodes that ended before the last
        sub-step are then put back to the state they had when they ended by re-running them from
        a snapshot.
        """
        sim, n, steps = self.sim, self.n_envs, self.action_frequency
        reached = (self.obs_wpt_km < self.config.distance_margin_km) & ~self.wpt_reached
        done_anyway = self.wpt_reached | reached
        drift_rad = np.abs(np.deg2rad(self.obs_drift))
        track = sim.run(steps, trace=True)
        counts = np.empty((steps, n), np.int64)
        compiled.ownship_polygon_counts(track, self.obstacle_lat, self.obstacle_lon, self.obstacle_nv, counts)
        hit = done_anyway | (counts > 0)  # (steps, n): the episode ends at this sub-step
        ends = hit.any(axis=0)
        last = np.where(ends, hit.argmax(axis=0), steps - 1)  # last evaluated sub-step
        count = counts[last, self.all_envs]
        early = np.flatnonzero(last < steps - 1)
        if early.size:
            end = sim.snapshot()
            sim.restore(start)
            stopped = []
            for k in range(int(last[early].max()) + 1):
                sim.step()
                group = early[last[early] == k]
                if group.size:
                    stopped.append((group, sim.snapshot(group)))
            if early.size < n:  # when every episode ended early, the clocks stop there too
                sim.restore(end)
            for group, state in stopped:
                sim.restore(state, group)
        for k in range(int(last.max()) + 1):
            evaluated = last >= k
            self.drift_sum_rad += np.where(evaluated, drift_rad, 0.0)
            self.drift_count += evaluated
        return self._finish_transition(reached, done_anyway, drift_rad, count)

    def _finish_transition(
        self, reached: BoolArray, done_anyway: BoolArray, drift_rad: Array, count: NDArray[np.int64]
    ) -> tuple[Array, BoolArray, dict[str, Array]]:
        """Flags, counters and the last evaluated sub-step's reward."""
        self.wpt_reached |= reached
        self.crashed |= count > 0
        self.intrusions += count
        reach = np.where(reached, REACH_REWARD, 0.0)
        drift = drift_rad * DRIFT_PENALTY
        intrusion = count * RESTRICTED_AREA_INTRUSION_PENALTY
        reward = reach + drift + intrusion
        terminated = done_anyway | (count > 0)
        return reward, terminated, {"reach": reach, "drift": drift, "intrusion": intrusion}

    # --- info and KPIs --------------------------------------------------------------------------
    def average_drift(self) -> Array:
        """(n_envs,) mean of the per-sub-step |drift| samples [rad].

        0.0 before the first sample, where the reference's mean of an empty array is NaN.
        """
        return np.where(self.drift_count > 0, self.drift_sum_rad / np.maximum(self.drift_count, 1), 0.0)

    def episode_info(self) -> dict[str, Array]:
        """Return the reference's info: reward, reached and crashed flags (0/1), mean drift."""
        return {
            "total_reward": self.stats.total_reward.copy(),
            "waypoint_reached": self.wpt_reached.astype(np.int64),
            "crashed": self.crashed.astype(np.int64),
            "average_drift": self.average_drift(),
        }

    def drift_deg(self) -> Array:
        """|drift| to the waypoint at the last observation [deg]."""
        return np.abs(self.obs_drift)

    def goal_reached(self) -> BoolArray:
        """Whether the waypoint has been reached."""
        return self.wpt_reached.copy()

    def extra_track_km(self) -> Array:
        """Distance flown minus the start-to-waypoint kwik-distance [km]."""
        return self.sim.distflown[:, 0] / 1000.0 - self.start_wpt_km

    def kpis(self) -> dict[str, Array]:
        """Return the common KPIs plus ``kpi_obstacle_intrusions``."""
        out = super().kpis()
        out["kpi_obstacle_intrusions"] = self.intrusions.astype(np.float64)
        return out


def sample_waypoint(
    rng: np.random.Generator,
    lat: float,
    lon: float,
    poly_lat: Array,
    poly_lon: Array,
    n_vertices: NDArray[np.int64],
    d_min: int,
    d_max: int,
    kernels: Any = None,
) -> tuple[float, float]:
    """Rejection-sample a waypoint outside every obstacle, as the reference does.

    Each try draws an integer distance in [d_min, d_max) km and an integer bearing in [0, 359]
    deg from (lat, lon). As in the reference, the try counter is checked after the inside test,
    so the 1001st draw raises even when it is outside.

    Args:
        rng: The episode's generator.
        lat: Start latitude [deg].
        lon: Start longitude [deg].
        poly_lat: (K, V) obstacle vertex latitudes [deg].
        poly_lon: (K, V) obstacle vertex longitudes [deg].
        n_vertices: (K,) vertex counts.
        d_min: Lower bound of the distance draw [km].
        d_max: Exclusive upper bound of the distance draw [km].
        kernels: A task's compiled functions for the inside test, or None for numpy.

    Returns:
        The waypoint (lat, lon) [deg].

    Raises:
        RuntimeError: After more than 1000 tries.

    """
    tries = 0
    while True:
        tries += 1
        d = rng.integers(d_min, d_max)
        b = rng.integers(0, BEARING_END)
        wlat, wlon = point_at_distance_scalar(lat, lon, d, b)
        if kernels is not None:
            inside = np.empty((1, len(n_vertices)), bool)
            kernels.ownship_in_polygons(np.array([[wlat]]), np.array([[wlon]]), poly_lat[None], poly_lon[None], n_vertices[None], inside)
        else:
            inside = points_in_polygons(np.atleast_1d(wlat), np.atleast_1d(wlon), poly_lat, poly_lon, n_vertices)
        if tries > MAX_WAYPOINT_TRIES:
            raise RuntimeError(
                f"no waypoint outside the obstacles after {MAX_WAYPOINT_TRIES} tries; the obstacles cover the waypoint "
                "distance range: reduce num_obstacles or obstacle_area_max, or move the waypoint distance range"
            )
        if not inside.any():
            return float(wlat), float(wlon)
