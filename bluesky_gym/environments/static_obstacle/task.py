"""StaticObstacleEnv-v0: reach a waypoint around polygonal restricted areas (docs/environments-v0.md §6)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from bluesky_gym.core import geo
from bluesky_gym.core.jit import grid_range, jit, jit_inline
from bluesky_gym.core.units import FL, KTS, NM2KM
from bluesky_gym.tasks import compiled
from bluesky_gym.tasks.base import (
    Array,
    BoolArray,
    BoxSpec,
    StepGeometry,
    Task,
    TaskConfig,
    check_int,
    check_range,
    command_heading_and_speed,
)
from bluesky_gym.tasks.compiled import DEG2RAD, kwikqdrdist_scalar, polygon_contains, wrap180_scalar
from bluesky_gym.tasks.geometry import (
    nm_to_latlon,
    point_at_distance,
    polygon_area,
    random_convex_polygon,
    ref_kwikqdrdist,
)

AC_LAT, AC_LON = 52.0, 4.0  # deg: BlueSky's default creation position
AC_HDG = 0.0  # deg: creation heading, replaced by the bearing to the waypoint
AC_ALT = 350.0  # m: the reference's "ALTITUDE 350" (meant as FL350) is used as metres (docs/environments-v0.md §6)
AC_SPD = 150.0  # m/s CAS (commented as kts in the reference)
D_HEADING = 45.0  # deg of heading change per unit action
D_SPEED = 20 / 3  # "kts" in the reference, but added to CAS in m/s (kept, docs/environments-v0.md §6)
REACH_REWARD = 1.0
DRIFT_PENALTY = -0.01  # per rad of |drift|
RESTRICTED_AREA_INTRUSION_PENALTY = -5.0  # per obstacle containing the aircraft
AVERAGE_DRIFT_EMPTY = 0.0  # rad: the average_drift info before the first sample (the reference's mean of nothing is NaN)
RADIUS_SCALE_NM = 50.0  # the reference divides the radius [NM] by OBSTACLE_AREA_RANGE[0] = 50
MAX_WAYPOINT_TRIES = 1000  # waypoint rejection sampling gives up after this many tries
BEARING_END = 360  # deg, exclusive upper bound of the integer bearing draws: [0, 359]
VIEW_SIZE_KM = 350.0  # width of the reference's square view, centred on the start position
VIEW_ORIGIN_BEARING = 315.0  # deg: the view's top-left corner as seen from the start
VERTEX_CAPACITY = 16  # initial vertex slots per polygon (grown when a polygon needs more)
# -v1 (see StaticObstacleConfig).
FLIGHT_LEVEL_ALTITUDE = 350 * FL  # m: FL350, the reference's intended ALTITUDE
START_CLEARANCE_KM = 5.0  # km between the start and the circle an obstacle polygon is drawn in
MAX_OBSTACLE_TRIES = 1000  # obstacle redraws per obstacle before giving up
# -v1 declared bound of the distances (/ waypoint_distance_max): 3 x the farthest draw.
DISTANCE_BOUND = 3.0


@dataclass(frozen=True)
class StaticObstacleMeasurement(StepGeometry):
    """One step's quantities of the static-obstacle task, for the rows (episodes) ``envs`` (:func:`obstacle_measure`).

    No traffic; ``drift_deg``: drift wrap180_scalar(hdg - qdr) to the waypoint now [deg];
    ``goal_reached``: the waypoint has been reached, this step included. The arrays are numpy
    arrays on the CPU, torch tensors in the device step
    (:mod:`~bluesky_gym.environments.static_obstacle.device_step`).
    """

    wpt_km: Array  # (rows,) kwik distance to the waypoint now
    obstacle_count: NDArray[np.int64]  # (rows,) obstacles containing the aircraft now
    newly_reached: BoolArray  # (rows,) reached in this step, by the last observation's distance (-v1: the distance now)
    stale_drift_rad: Array  # (rows,) |drift| [rad] the reward charges: the last observation's (-v1: now)
    waypoint_obs: Array  # (rows, 3) the waypoint's observation entries: distance / scale, cos(drift), sin(drift)
    obstacle_obs: Array  # (4, rows, num_obstacles) the obstacles' entries: radius / 50 NM, centre distance / scale, cos and sin of the bearing


def observation(g: StaticObstacleMeasurement) -> dict[str, Array]:
    """The observation entries of the rows ``g.envs``: views of the measured arrays (numpy arrays or torch tensors alike)."""
    w, o = g.waypoint_obs, g.obstacle_obs
    return {
        "destination_waypoint_distance": w[:, 0:1],
        "destination_waypoint_cos_drift": w[:, 1:2],
        "destination_waypoint_sin_drift": w[:, 2:3],
        "restricted_area_radius": o[0],
        "restricted_area_distance": o[1],
        "cos_difference_restricted_area_pos": o[2],
        "sin_difference_restricted_area_pos": o[3],
    }


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
        flight_level_altitude: ``-v1``: the aircraft flies at FL350 (10668 m), where BlueSky's
            envelope caps the CAS 150 m/s at M0.80 (TAS 237 m/s), so that the farthest waypoint
            (169 km) is within reach of the 100 steps of 10 s; ``-v0``: at 350 m (the reference's
            "FL350" used as metres), TAS 152 m/s, many goals out of reach.
        speed_step_in_knots: ``-v1``: the speed action changes CAS by 20/3 kt per unit;
            ``-v0``: by 20/3 m/s (the reference's "kts" added to m/s).
        step_reward: ``-v1``: the reward is evaluated once per decision step on the state after
            it (waypoint reached the same step, drift now; an obstacle entered in a sub-step ends
            the episode there); ``-v0``: per sub-step on the last observation's stale waypoint
            distance and drift, only the last sub-step's reward returned.
        clear_start: ``-v1``: an obstacle whose circle comes within 5 km of the start is redrawn
            (centre and polygon), so that no episode starts inside or at the edge of one;
            ``-v0``: no check (about 6% of the reference's episodes crash on step 1).

    """

    num_obstacles: int = 10
    obstacle_distance_min: int = 20
    obstacle_distance_max: int = 150
    obstacle_area_min: int = 50
    obstacle_area_max: int = 1000
    waypoint_distance_min: int = 100
    waypoint_distance_max: int = 170
    distance_margin_km: float = 5.0
    flight_level_altitude: bool = False
    speed_step_in_knots: bool = False
    step_reward: bool = False
    clear_start: bool = False

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
    """Batched static-obstacle task; see :class:`bluesky_gym.environments.static_obstacle.env.StaticObstacleEnv`."""

    env_id: ClassVar[str] = "StaticObstacleEnv-v0"
    dt: ClassVar[float] = 1.0
    action_frequency: ClassVar[int] = 10
    max_episode_steps: ClassVar[int] = 100
    config_class: ClassVar[type[TaskConfig]] = StaticObstacleConfig
    info_keys: ClassVar[tuple[str, ...]] = ("total_reward", "waypoint_reached", "crashed", "average_drift")
    route_km_array: ClassVar[str | None] = "start_wpt_km"
    config: StaticObstacleConfig

    def max_aircraft(self) -> int:
        """One aircraft: the ownship (no traffic)."""
        return 1

    def build_observation_spec(self) -> dict[str, BoxSpec]:
        """Waypoint and obstacle observation, in the reference's key order."""
        k = (self.config.num_obstacles,)
        if self.config.float32_spaces:
            far = float(np.ceil(DISTANCE_BOUND * max(1.0, self.config.obstacle_distance_max / self.config.waypoint_distance_max)))
            return {
                "destination_waypoint_distance": BoxSpec((1,), 0.0, far),
                "destination_waypoint_cos_drift": BoxSpec((1,), -1.0, 1.0),
                "destination_waypoint_sin_drift": BoxSpec((1,), -1.0, 1.0),
                "restricted_area_radius": BoxSpec(k, 0.0, 1.0),
                "restricted_area_distance": BoxSpec(k, 0.0, far),
                "cos_difference_restricted_area_pos": BoxSpec(k, -1.0, 1.0),
                "sin_difference_restricted_area_pos": BoxSpec(k, -1.0, 1.0),
            }
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
        # Waypoint distance [km] and drift [deg] the last observation showed: the per-sub-step
        # reward of the next step uses these stale values (docs/environments-v0.md §6).
        self.last_wpt_km = np.zeros(n)
        self.last_drift = np.zeros(n)
        self.wpt_reached = np.zeros(n, bool)
        self.crashed = np.zeros(n, bool)
        self.intrusions = np.zeros(n, np.int64)  # obstacle intrusions counted by the reward
        self.drift_sum_rad = np.zeros(n)  # sum of the per-sub-step |drift| samples [rad]
        self.drift_count = np.zeros(n, np.int64)

    def generate(self, envs: NDArray[np.int64]) -> None:
        """Aircraft, obstacle centres, polygons, waypoint, then the initial heading (docs/environments-v0.md §6)."""
        c = self.config
        k = c.num_obstacles
        self.sim.create(envs, 0, AC_LAT, AC_LON, AC_HDG, FLIGHT_LEVEL_ALTITUDE if c.flight_level_altitude else AC_ALT, AC_SPD)
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
            if c.clear_start:
                self._clear_start(rng, j, e, lat0, lon0, d, b, clat, clon, polys)
            self._store_polygons(e, clat, clon, polys)
            self.wpt_lat[e], self.wpt_lon[e] = sample_waypoint(
                rng,
                lat0[j],
                lon0[j],
                self.obstacle_lat[e],
                self.obstacle_lon[e],
                self.obstacle_nv[e],
                c.waypoint_distance_min,
                c.waypoint_distance_max,
            )
        # The aircraft starts pointing at the waypoint: hdg and the autopilot track (docs/environments-v0.md §6).
        qdr, dist = ref_kwikqdrdist(lat0, lon0, self.wpt_lat[envs], self.wpt_lon[envs])
        self.sim.set_state(envs, 0, hdg=qdr)
        self.sim.set_autopilot(envs, 0, ap_trk=qdr)
        self.start_wpt_km[envs] = dist * NM2KM
        self.wpt_reached[envs] = False
        self.crashed[envs] = False
        self.intrusions[envs] = 0
        self.drift_sum_rad[envs] = 0.0
        self.drift_count[envs] = 0
        self.remember(self.measure(envs))

    def _clear_start(
        self,
        rng: np.random.Generator,
        j: int,
        e: int,
        lat0: Array,
        lon0: Array,
        d: NDArray[np.int64],
        b: NDArray[np.int64],
        clat: Array,
        clon: Array,
        polys: list[Array],
    ) -> None:
        """``-v1``: redraw (centre, then polygon) every obstacle whose circle comes within :data:`START_CLEARANCE_KM` of the start.

        The polygon lies in the circle of ``obstacle_radius`` around its centre, so a centre
        farther than radius + clearance leaves the start outside the obstacle with that margin.
        Updates ``clat``, ``clon``, ``polys`` and the episode's radius and area in place.
        """
        c = self.config
        for i in range(len(polys)):
            for _ in range(MAX_OBSTACLE_TRIES):
                if d[i] > self.obstacle_radius[e, i] * NM2KM + START_CLEARANCE_KM:
                    break
                d[i] = rng.integers(c.obstacle_distance_min, c.obstacle_distance_max)
                b[i] = rng.integers(0, BEARING_END)
                circle_area = rng.integers(2 * c.obstacle_area_min, c.obstacle_area_max)
                radius = math.sqrt(int(circle_area) / math.pi)
                polys[i] = random_convex_polygon(rng, radius, c.obstacle_area_min)
                self.obstacle_radius[e, i] = radius
                self.obstacle_area[e, i] = polygon_area(polys[i])
            else:
                raise RuntimeError(
                    f"no obstacle clear of the start after {MAX_OBSTACLE_TRIES} draws: raise obstacle_distance_max or lower obstacle_area_max"
                )
            lat, lon = point_at_distance(lat0[j], lon0[j], d[i], b[i])
            clat[i], clon[i] = float(lat), float(lon)
        self.obstacle_centre_lat[e], self.obstacle_centre_lon[e] = clat, clon

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

    # --- action -------------------------------------------------------------------------------
    def apply_action(self, action: Array) -> None:
        """Heading wrap180(hdg + 45 a0) and speed (CAS + 20/3 a1) * 1.94384 kts.

        "HDG KL001 <hdg>" then "SPD KL001 <kts>": BlueSky converts the speed with kts
        (:func:`~bluesky_gym.tasks.base.command_heading_and_speed`).
        """
        command_heading_and_speed(self.sim, self.all_envs, self.ownship, action, D_HEADING, speed_change(self.config))

    # --- sub-steps ------------------------------------------------------------------------------
    def advance(self) -> None:
        """Run the sub-steps; an episode stops at the sub-step it ends (the reference returns there).

        The reference evaluates the reward after every sub-step and returns at once when the
        episode ends, with the state of that sub-step. Its waypoint terms use the stale values of
        the last observation, so a waypoint is reached (and the episode ends) at the first sub-step
        or not at all; only the obstacle test needs the positions after each sub-step, which
        :class:`SubstepEnd` gets from the physics' traced run (the kernel
        :func:`obstacle_substep_end`). Every evaluated sub-step adds one |drift| sample to
        ``average_drift`` (:func:`obstacle_drift_samples`).
        """
        end = SubstepEnd(self)
        self.sim.run(self.action_frequency, stop=end)
        if not self.config.step_reward:  # -v1 samples the drift once per decision step (reward)
            obstacle_drift_samples(self.last_drift, end.ended_at, self.action_frequency, self.drift_sum_rad, self.drift_count)

    # --- measure --------------------------------------------------------------------------------
    def waypoint_geometry(self, envs: NDArray[np.int64] | None = None) -> tuple[Array, Array]:
        """Live kwik distance to the waypoint [km] and drift wrap180(hdg - qdr) [deg] of episodes ``envs`` (all when None)."""
        g = self.measure(envs)
        assert g.drift_deg is not None
        return g.wpt_km, g.drift_deg

    def inside_obstacles(self, envs: NDArray[np.int64] | slice | None = None) -> NDArray[np.bool_]:
        """(rows, num_obstacles) whether each obstacle polygon of episodes ``envs`` (all when None) contains the aircraft now."""
        rows = slice(None) if envs is None else envs
        s = self.sim
        nv = self.obstacle_nv[rows]
        out = np.empty(nv.shape, bool)
        compiled.ownship_in_polygons(s.lat[rows], s.lon[rows], self.obstacle_lat[rows], self.obstacle_lon[rows], nv, out)
        return out

    def measure(self, envs: NDArray[np.int64] | None = None) -> StaticObstacleMeasurement:
        """Waypoint and obstacle geometry now, the obstacles around the aircraft, the stale waypoint terms, of episodes ``envs``.

        The kernel :func:`obstacle_measure`; all episodes when ``envs`` is None.
        """
        ids = self.all_envs if envs is None else np.asarray(envs, dtype=np.int64)
        s, c = self.sim, self.config
        rows, k = ids.size, c.num_obstacles
        wpt_km, drift, stale = np.empty(rows), np.empty(rows), np.empty(rows)
        count, reached, goal = np.empty(rows, np.int64), np.empty(rows, bool), np.empty(rows, bool)
        waypoint_obs, obstacle_obs = np.empty((rows, 3)), np.empty((4, rows, k))
        obstacle_measure(
            ids,
            s.lat,
            s.lon,
            s.hdg,
            self.wpt_lat,
            self.wpt_lon,
            self.obstacle_centre_lat,
            self.obstacle_centre_lon,
            self.obstacle_radius,
            self.obstacle_lat,
            self.obstacle_lon,
            self.obstacle_nv,
            self.last_wpt_km,
            self.last_drift,
            self.wpt_reached,
            float(c.distance_margin_km),
            bool(c.step_reward),
            float(c.waypoint_distance_max),
            wpt_km,
            drift,
            count,
            reached,
            stale,
            goal,
            waypoint_obs,
            obstacle_obs,
        )
        shape = (rows, s.max_aircraft)
        return StaticObstacleMeasurement(
            envs=ids,
            separation_nm=np.full(shape, np.inf),
            los=np.zeros(shape, bool),
            drift_deg=drift,
            goal_reached=goal,
            wpt_km=wpt_km,
            obstacle_count=count,
            newly_reached=reached,
            stale_drift_rad=stale,
            waypoint_obs=waypoint_obs,
            obstacle_obs=obstacle_obs,
        )

    # --- observation ----------------------------------------------------------------------------
    def observe(self, g: StepGeometry | None = None) -> dict[str, Array]:
        """Waypoint distance and drift, then the obstacle radii and the distances and bearings of their centres, of the rows ``g.envs``."""
        g = self.measure() if g is None else g
        assert isinstance(g, StaticObstacleMeasurement)
        return observation(g)

    # --- reward and termination -----------------------------------------------------------------
    def reward(self, g: StepGeometry) -> tuple[Array, BoolArray, dict[str, Array]]:
        """The last evaluated sub-step's reward of all episodes; ends at the waypoint or inside an obstacle (docs/environments-v0.md §6).

        +1 for reaching the waypoint and -0.01 per rad of |drift| (both from the stale values of the
        last observation), -5 per obstacle containing the aircraft. Records the flags and
        counters, and this step's observation values for the next step (:func:`obstacle_reward`).
        """
        assert isinstance(g, StaticObstacleMeasurement)
        n = self.n_envs
        reward, reach, drift, intrusion, terminated = np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(n, bool)
        obstacle_reward(
            g.envs,
            g.newly_reached,
            g.obstacle_count,
            g.stale_drift_rad,
            g.goal_reached,
            g.wpt_km,
            g.drift_deg,
            bool(self.config.step_reward),
            self.wpt_reached,
            self.crashed,
            self.intrusions,
            self.last_wpt_km,
            self.last_drift,
            self.drift_sum_rad,
            self.drift_count,
            reward,
            reach,
            drift,
            intrusion,
            terminated,
        )
        return reward, terminated, {"reach": reach, "drift": drift, "intrusion": intrusion}

    def remember(self, g: StaticObstacleMeasurement) -> None:
        """Keep the waypoint distance and drift of the observation of ``g`` (rows ``g.envs``) for the next step's reward."""
        self.last_wpt_km[g.envs] = g.wpt_km
        assert g.drift_deg is not None
        self.last_drift[g.envs] = g.drift_deg

    # --- info and KPIs --------------------------------------------------------------------------
    def average_drift(self) -> Array:
        """(n_envs,) mean of the per-sub-step |drift| samples [rad] (:func:`~bluesky_gym.tasks.compiled.sample_means`).

        0.0 before the first sample, where the reference's mean of an empty array is NaN.
        """
        out = np.empty(self.n_envs)
        compiled.sample_means(self.drift_sum_rad, self.drift_count, AVERAGE_DRIFT_EMPTY, out)
        return out

    def episode_info(self) -> dict[str, Array]:
        """Return the reference's info: reward, reached and crashed flags (0/1), mean drift."""
        return {
            "total_reward": self.stats.total_reward.copy(),
            "waypoint_reached": self.wpt_reached.astype(np.int64),
            "crashed": self.crashed.astype(np.int64),
            "average_drift": self.average_drift(),
        }

    def kpis(self) -> dict[str, Array]:
        """Return the common KPIs plus ``kpi_obstacle_intrusions``."""
        out = super().kpis()
        out["kpi_obstacle_intrusions"] = self.intrusions.astype(np.float64)
        return out


def speed_change(config: StaticObstacleConfig) -> float:
    """CAS change per unit of the speed action [m/s]: 20/3 "kts" added as m/s (``-v0``), 20/3 kt (``-v1``, ``speed_step_in_knots``)."""
    return D_SPEED * KTS if config.speed_step_in_knots else D_SPEED


def sample_waypoint(
    rng: np.random.Generator,
    lat: float,
    lon: float,
    poly_lat: Array,
    poly_lon: Array,
    n_vertices: NDArray[np.int64],
    d_min: int,
    d_max: int,
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
        wlat, wlon = point_at_distance(lat, lon, d, b)
        inside = np.empty((1, len(n_vertices)), bool)
        compiled.ownship_in_polygons(np.array([[wlat]]), np.array([[wlon]]), poly_lat[None], poly_lon[None], n_vertices[None], inside)
        if tries > MAX_WAYPOINT_TRIES:
            raise RuntimeError(
                f"no waypoint outside the obstacles after {MAX_WAYPOINT_TRIES} tries; the obstacles cover the waypoint "
                "distance range: reduce num_obstacles or obstacle_area_max, or move the waypoint distance range"
            )
        if not inside.any():
            return float(wlat), float(wlon)


class SubstepEnd:
    """The ``stop`` rule of a decision step's sub-steps (see :meth:`Physics.run`): the kernel :func:`obstacle_substep_end`.

    An episode ends at the first sub-step after which its aircraft is inside an obstacle, or
    (``-v0``) at the first sub-step when it ends anyway: its waypoint was reached, or the last
    observation was within the capture radius.

    Args:
        task: The task whose episodes run (its obstacles, waypoint flags and last observation).
    """

    def __init__(self, task: StaticObstacleTask) -> None:
        self.task = task
        #: (n_envs,) sub-steps after which each episode ended (1..k) in the last track seen, 0 if it did not.
        self.ended_at = np.zeros(task.n_envs, np.int64)

    def __call__(self, track: Array) -> NDArray[np.int64]:
        """``ended_at`` of the positions ``track`` (k, 2, n_envs, max_aircraft) after k sub-steps."""
        t = self.task
        self.ended_at = np.zeros(t.n_envs, np.int64)
        obstacle_substep_end(
            track[:, 0],
            track[:, 1],
            1,
            t.obstacle_lat,
            t.obstacle_lon,
            t.obstacle_nv,
            not t.config.step_reward,
            t.last_wpt_km,
            t.wpt_reached,
            float(t.config.distance_margin_km),
            self.ended_at,
        )
        return self.ended_at


# --- kernels: the task's rules, compiled for the CPU and for CUDA (the device step launches them) ---
@jit_inline
def _newly_within(distance_km, reached, margin_km):
    """A waypoint not reached before and within the capture radius at ``distance_km`` [km]."""
    return distance_km < margin_km and not reached


@jit_inline
def _abs_rad(deg):
    """|angle| [rad] of an angle [deg] (numpy's ``abs(deg2rad(deg))``): the drift the reward charges."""
    return abs(deg * DEG2RAD)


@jit_inline
def _first_inside(lat_track, lon_track, e, poly_lat, poly_lon, nv, limit):
    """The first of the track's first ``limit`` positions of episode ``e``'s ownship inside a polygon (1-based), or 0.

    A point outside the polygon's latitude range crosses no edge, so the even-odd test says
    "outside" for it: only the others are tested.
    """
    if nv == 0:
        return 0
    lo = hi = poly_lat[0]
    for v in range(1, nv):
        lo = min(lo, poly_lat[v])
        hi = max(hi, poly_lat[v])
    for k in range(limit):
        y = lat_track[k, e, 0]
        if lo <= y < hi and polygon_contains(y, lon_track[k, e, 0], poly_lat, poly_lon, nv):
            return k + 1
    return 0


@jit
def obstacle_measure(
    envs,
    lat,
    lon,
    hdg,
    wpt_lat,
    wpt_lon,
    centre_lat,
    centre_lon,
    radius,
    poly_lat,
    poly_lon,
    n_vertices,
    last_wpt_km,
    last_drift,
    wpt_reached,
    margin_km,
    step_reward,
    distance_scale,
    wpt_km_out,
    drift_out,
    count_out,
    reached_out,
    stale_out,
    goal_out,
    waypoint_out,
    obstacle_out,
):
    """:meth:`StaticObstacleTask.measure` of rows ``r`` (episode ``envs[r]``, the ownship in slot 0).

    Outputs per row: the kwik distance to the waypoint [km] and the drift wrap180_scalar(hdg - qdr) to
    it [deg]; the obstacles containing the aircraft (even-odd test); whether the waypoint is
    reached now for the first time and the |drift| [rad] the reward charges (``step_reward``:
    the distance and drift now; else the last observation's, ``last_*``); whether the goal is
    reached; the observation entries: ``waypoint_out`` (rows, 3) the distance / ``distance_scale``,
    cos and sin of the drift, ``obstacle_out`` (4, rows, K) per obstacle its radius /
    :data:`RADIUS_SCALE_NM`, the kwik distance to its centre [km] / ``distance_scale`` and cos and
    sin of wrap180_scalar(hdg - bearing to the centre).
    """
    for r in grid_range(envs.shape[0]):
        e = envs[r]
        lat0, lon0, hdg0 = lat[e, 0], lon[e, 0], hdg[e, 0]
        qdr, dist = kwikqdrdist_scalar(lat0, lon0, wpt_lat[e], wpt_lon[e])
        wpt_km = dist * NM2KM
        drift = wrap180_scalar(hdg0 - qdr)
        if step_reward:
            reached = _newly_within(wpt_km, wpt_reached[e], margin_km)
            stale = _abs_rad(drift)
        else:
            reached = _newly_within(last_wpt_km[e], wpt_reached[e], margin_km)
            stale = _abs_rad(last_drift[e])
        count = 0
        for k in range(n_vertices.shape[1]):
            if polygon_contains(lat0, lon0, poly_lat[e, k], poly_lon[e, k], n_vertices[e, k]):
                count += 1
            qdr_c, dist_c = kwikqdrdist_scalar(lat0, lon0, centre_lat[e, k], centre_lon[e, k])
            bearing = wrap180_scalar(hdg0 - qdr_c) * DEG2RAD
            obstacle_out[0, r, k] = radius[e, k] / RADIUS_SCALE_NM
            obstacle_out[1, r, k] = dist_c * NM2KM / distance_scale
            obstacle_out[2, r, k] = math.cos(bearing)
            obstacle_out[3, r, k] = math.sin(bearing)
        wpt_km_out[r] = wpt_km
        drift_out[r] = drift
        count_out[r] = count
        reached_out[r] = reached
        stale_out[r] = stale
        goal_out[r] = wpt_reached[e] or reached
        rad = drift * DEG2RAD
        waypoint_out[r, 0] = wpt_km / distance_scale
        waypoint_out[r, 1] = math.cos(rad)
        waypoint_out[r, 2] = math.sin(rad)


@jit
def obstacle_reward(
    envs,
    newly_reached,
    count,
    stale_drift_rad,
    goal_reached,
    wpt_km,
    drift,
    step_reward,
    wpt_reached,
    crashed,
    intrusions,
    last_wpt_km,
    last_drift,
    drift_sum_rad,
    drift_count,
    reward_out,
    reach_out,
    drift_out,
    intrusion_out,
    terminated_out,
):
    """:meth:`StaticObstacleTask.reward` of rows ``r`` (episode ``envs[r]``) from :func:`obstacle_measure`'s outputs.

    +1 for the waypoint reached now, -0.01 per rad of the charged |drift|, -5 per obstacle
    containing the aircraft; terminated at the goal or inside an obstacle. Updates the episode's
    reached and crashed flags, its intrusion count, the last observation's waypoint distance and
    drift (the next step's stale terms) and (``step_reward``) its |drift| samples.
    """
    for r in grid_range(envs.shape[0]):
        e = envs[r]
        c = count[r]
        wpt_reached[e] = wpt_reached[e] or newly_reached[r]
        crashed[e] = crashed[e] or c > 0
        intrusions[e] += c
        last_wpt_km[e] = wpt_km[r]
        last_drift[e] = drift[r]
        if step_reward:  # -v1: one |drift| sample per decision step
            drift_sum_rad[e] += stale_drift_rad[r]
            drift_count[e] += 1
        reach = REACH_REWARD if newly_reached[r] else 0.0
        drift_r = stale_drift_rad[r] * DRIFT_PENALTY
        intrusion = c * RESTRICTED_AREA_INTRUSION_PENALTY
        reach_out[r] = reach
        drift_out[r] = drift_r
        intrusion_out[r] = intrusion
        reward_out[r] = reach + drift_r + intrusion
        terminated_out[r] = goal_reached[r] or c > 0


@jit
def obstacle_substep_end(lat_track, lon_track, first, poly_lat, poly_lon, n_vertices, stale_goal, last_wpt_km, wpt_reached, margin_km, ended_at):
    """The sub-step at which each episode ends, for the episodes that have not (``ended_at[e] == 0``).

    ``lat_track``/``lon_track`` (k, n_envs, m): the positions after sub-steps ``first`` ..
    ``first + k - 1``. An episode ends at the first of them after which its ownship is inside
    one of its obstacles, or at once where it ends anyway (``stale_goal``, ``-v0``: its waypoint
    was reached before, or is reached by the last observation's distance ``last_wpt_km``).
    """
    for e in grid_range(ended_at.shape[0]):
        if ended_at[e] > 0:
            continue
        if stale_goal and (wpt_reached[e] or _newly_within(last_wpt_km[e], wpt_reached[e], margin_km)):
            ended_at[e] = first
            continue
        best = lat_track.shape[0] + 1  # the earliest position inside an obstacle so far (1-based; beyond the track: none)
        for j in range(n_vertices.shape[1]):
            hit = _first_inside(lat_track, lon_track, e, poly_lat[e, j], poly_lon[e, j], n_vertices[e, j], best - 1)
            if hit > 0:
                best = hit
        if best <= lat_track.shape[0]:
            ended_at[e] = first + best - 1


@jit
def obstacle_drift_samples(last_drift, ended_at, substeps, drift_sum_rad, drift_count):
    """``-v0``: one sample of the last observation's |drift| [rad] per evaluated sub-step (``ended_at[e]``, or all ``substeps``)."""
    for e in grid_range(drift_sum_rad.shape[0]):
        times = ended_at[e] if ended_at[e] > 0 else substeps
        value = _abs_rad(last_drift[e])
        for _ in range(times):
            drift_sum_rad[e] += value
        drift_count[e] += times


@jit
def hold_ended(ended_at, substep, state, held):
    """The device step's sub-steps: keep the state (fields, n_envs, m) of the episodes that ended at ``substep`` in ``held``."""
    for e in grid_range(ended_at.shape[0]):
        if ended_at[e] == substep:
            for f in range(state.shape[0]):
                for j in range(state.shape[2]):
                    held[f, e, j] = state[f, e, j]


@jit
def restore_ended(ended_at, substeps, state, held):
    """The device step's sub-steps: give the episodes that ended before the last of ``substeps`` their state :func:`hold_ended` kept."""
    for e in grid_range(ended_at.shape[0]):
        if 0 < ended_at[e] < substeps:
            for f in range(state.shape[0]):
                for j in range(state.shape[2]):
                    state[f, e, j] = held[f, e, j]
