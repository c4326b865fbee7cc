"""MergeEnv-v0: merge the ownship into a stream of arrivals via a final approach fix (spec section 7)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from bluesky_gym.core.units import KTS, MPS2KT, NM2KM
from bluesky_gym.tasks.base import Array, BoolArray, BoxSpec, Task, TaskConfig, check_int, check_pair, check_range, wrap180
from bluesky_gym.tasks.geometry import point_at_distance, ref_kwikdist, ref_kwikdist_matrix, ref_kwikqdrdist
from bluesky_gym.tasks.sector_cr import relative_velocity

# Airspace (reference values).
RWY_LAT, RWY_LON = 52.36239301495972, 4.713195734579777  # deg: runway (Schiphol)
FAF_DISTANCE = 200.0  # km (the reference comments NM) due north of the runway
FAF_BEARING = 0.0  # deg
_faf = point_at_distance(RWY_LAT, RWY_LON, FAF_DISTANCE, FAF_BEARING)
FAF_LAT, FAF_LON = float(_faf[0]), float(_faf[1])  # deg: final approach fix (54.161036, 4.713196)

# Scenario defaults (reference values).
NUM_AC = 20  # ownship + 19 intruders
SPAWN_DISTANCE = (50.0, 200.0)  # km from the FAF: ownship
INTRUDER_DISTANCE = (20.0, 500.0)  # km from the FAF: intruders
SPAWN_BEARING = 15.0  # deg: spawn radials from the FAF are uniform in [-15, 15]
AC_SPD = 100.0  # m/s CAS
AC_ALT = 10000.0  # m

# MDP (reference values).
DISTANCE_MARGIN = 10.0  # NM (commented km in the reference, compared against NM)
GOAL_MARGIN = 2 * DISTANCE_MARGIN  # NM from the runway after the FAF: episode done
REACH_REWARD = 1.0
DRIFT_PENALTY = -0.1  # per rad of |drift|, per step
INTRUSION_PENALTY = -1.0  # per intruder within INTRUSION_DISTANCE, per step
INTRUSION_DISTANCE = 4.0  # NM, horizontal only (all aircraft share one altitude)
D_HEADING = 15.0  # deg of heading change per unit action
D_SPEED = 20.0  # m/s of CAS change per unit action
NUM_AC_STATE = 5  # intruders in the observation (the closest ones)
WAYPOINT_DIST_SCALE = 250.0  # NM: waypoint_dist and distances are divided by 250
POSITION_SCALE = 1e6  # m: x_r, y_r
SPEED_SCALE = 150.0  # m/s: vx_r, vy_r
M_PER_KM = 1000.0

_OBS_SCALES = (POSITION_SCALE, SPEED_SCALE, WAYPOINT_DIST_SCALE)  # for the compiled observation
MAX_NUM_AC = 200  # largest supported traffic count
ALT_MAX = 11060.0  # m: the A320's altitude ceiling
CAS_RANGE = (67.0, 163.0)  # m/s: the A320's CAS envelope away from the ground


@dataclass(frozen=True)
class MergeConfig(TaskConfig):
    """Scenario options of the merge task (defaults: the paper's).

    Attributes:
        num_aircraft: Aircraft in the scenario, ownship included (at least 6: the observation
            holds the 5 closest intruders).
        spawn_distance_km: (low, high) of the ownship's uniform distance from the FAF [km].
        intruder_distance_km: (low, high) of each intruder's uniform distance from the FAF [km].
        spawn_bearing_deg: Spawn radials from the FAF are uniform in [-b, b] [deg, true].
        ac_speed: CAS of every aircraft at creation [m/s] (the paper's logs used 150).
        altitude: Altitude of every aircraft [m].

    """

    num_aircraft: int = NUM_AC
    spawn_distance_km: tuple[float, float] = SPAWN_DISTANCE
    intruder_distance_km: tuple[float, float] = INTRUDER_DISTANCE
    spawn_bearing_deg: float = SPAWN_BEARING
    ac_speed: float = AC_SPD
    altitude: float = AC_ALT

    def __post_init__(self) -> None:
        # Lists given through gym.make keyword arguments are stored as tuples (hashable config).
        for name in ("spawn_distance_km", "intruder_distance_km"):
            value = getattr(self, name)
            if isinstance(value, list):
                object.__setattr__(self, name, tuple(value))

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first invalid option."""
        check_int("num_aircraft", self.num_aircraft, NUM_AC_STATE + 1, MAX_NUM_AC)
        for name in ("spawn_distance_km", "intruder_distance_km"):
            low, high = check_pair(name, getattr(self, name))
            if not 0 <= low <= high <= 2000.0:
                raise ValueError(f"{name} must satisfy 0 <= low <= high <= 2000 km, got {getattr(self, name)}")
        check_range("spawn_bearing_deg", self.spawn_bearing_deg, 0.0, 180.0)
        check_range("ac_speed", self.ac_speed, *CAS_RANGE)
        check_range("altitude", self.altitude, 0.0, ALT_MAX, strict_low=True)


class MergeTask(Task):
    """Batched merge task; see :class:`bluesky_gym.envs.merge_env.MergeEnv` for the MDP."""

    env_id: ClassVar[str] = "MergeEnv-v0"
    dt: ClassVar[float] = 5.0
    action_frequency: ClassVar[int] = 10
    max_episode_steps: ClassVar[int] = 50
    config_class: ClassVar[type[TaskConfig]] = MergeConfig
    info_keys: ClassVar[tuple[str, ...]] = ("total_reward", "faf_reach", "average_drift", "total_intrusions")
    config: MergeConfig

    def max_aircraft(self) -> int:
        """Ownship plus intruders."""
        return self.config.num_aircraft

    def max_waypoints(self) -> int:
        """Intruder routes: the FAF, then the runway as destination."""
        return 2

    def build_observation_spec(self) -> dict[str, BoxSpec]:
        """Declare the reference's keys and bounds."""
        spec = {k: BoxSpec((1,), -1.0, 1.0) for k in ("cos(drift)", "sin(drift)")}
        spec.update({k: BoxSpec((1,)) for k in ("airspeed", "waypoint_dist")})
        spec["faf_reached"] = BoxSpec((1,), 0.0, 1.0)
        spec.update({k: BoxSpec((NUM_AC_STATE,)) for k in ("x_r", "y_r", "vx_r", "vy_r", "cos(track)", "sin(track)", "distances")})
        return spec

    def build_action_spec(self) -> BoxSpec:
        """Heading change and speed change, each in [-1, 1]."""
        return BoxSpec((2,), -1.0, 1.0)

    # --- generator ------------------------------------------------------------------------------
    def allocate(self) -> None:
        """Per-episode arrays."""
        n = self.n_envs
        self.wpt_reach = np.zeros(n, np.int64)  # 0 before the FAF, 1 after (the observed flag)
        self.faf_reached = np.zeros(n, np.int64)  # 0, 1 (FAF) or 2 (near the runway): info faf_reach
        self.drift = np.zeros(n)  # deg, drift to the current target at the last observation
        self.waypoint_dist = np.zeros(n)  # NM, kwik distance to the current target at the last observation
        self.total_intrusions = np.zeros(n, np.int64)
        self.drift_rad_sum = np.zeros(n)  # sum of |drift| [rad] (average_drift)
        self.drift_rad_n = np.zeros(n, np.int64)
        self.start_lat = np.zeros(n)  # deg, ownship start (extra-track KPI)
        self.start_lon = np.zeros(n)

    def generate(self, envs: NDArray[np.int64]) -> None:
        """Ownship north of the FAF, intruders on the same radial sector flying LNAV FAF -> runway."""
        c = self.config
        n_int = c.num_aircraft - 1
        b = c.spawn_bearing_deg
        own = np.empty((envs.size, 2))  # (bearing from the FAF, distance km)
        intr = np.empty((envs.size, n_int, 2))
        for k, e in enumerate(envs):
            rng = self.rngs[e]
            # The reference's Python ``random.uniform`` draws, from the episode generator, in its
            # order: ownship bearing, distance, then bearing and distance of each intruder.
            own[k] = rng.uniform((-b, c.spawn_distance_km[0]), (b, c.spawn_distance_km[1]))
            intr[k] = rng.uniform((-b, c.intruder_distance_km[0]), (b, c.intruder_distance_km[1]), size=(n_int, 2))
        lat, lon = point_at_distance(FAF_LAT, FAF_LON, own[:, 1], own[:, 0])
        # Heading b - 180 points back at the FAF; it is stored unwrapped (e.g. -170), as BlueSky does.
        self.sim.create(envs, 0, lat, lon, own[:, 0] - 180, c.altitude, c.ac_speed)
        self.start_lat[envs] = lat
        self.start_lon[envs] = lon
        env = np.repeat(envs, n_int)
        slot = np.tile(np.arange(1, n_int + 1), envs.size)
        ilat, ilon = point_at_distance(FAF_LAT, FAF_LON, intr[..., 1].ravel(), intr[..., 0].ravel())
        self.sim.create(env, slot, ilat, ilon, intr[..., 0].ravel() - 180, c.altitude, c.ac_speed)
        # "INTi addwpt FAF" then "INTi dest RWY": LNAV direct to the FAF, then the runway; VNAV stays off.
        self.sim.add_waypoint(env, slot, FAF_LAT, FAF_LON)
        self.sim.set_destination(env, slot, RWY_LAT, RWY_LON)
        self.wpt_reach[envs] = 0
        self.faf_reached[envs] = 0
        self.drift[envs] = 0.0
        self.waypoint_dist[envs] = 0.0
        self.total_intrusions[envs] = 0
        self.drift_rad_sum[envs] = 0.0
        self.drift_rad_n[envs] = 0

    # --- dynamics interface ---------------------------------------------------------------------
    def apply_action(self, action: Array) -> None:
        """HDG wrap180(hdg + 15 a0); SPD (CAS + 20 a1) * 1.94384 kt (spec section 7)."""
        s = self.sim
        heading_new = wrap180(s.hdg[:, 0] + action[:, 0] * D_HEADING)
        # Stacked as knots; BlueSky converts back with 1 kt = 0.514444 m/s.
        speed_kts = (s.cas[:, 0] + action[:, 1] * D_SPEED) * MPS2KT
        s.cmd_heading(self.all_envs, 0, heading_new)
        s.cmd_speed(self.all_envs, 0, speed_kts * KTS)

    # --- observation ----------------------------------------------------------------------------
    def target(self) -> tuple[Array, Array]:
        """(n_envs,) lat, lon [deg] of the current target: the FAF, then the runway once reached."""
        after = self.wpt_reach != 0
        return np.where(after, RWY_LAT, FAF_LAT), np.where(after, RWY_LON, FAF_LON)

    def observe(self) -> dict[str, Array]:
        """Ownship drift, airspeed and target distance, and the 5 closest intruders by kwik distance."""
        s = self.sim
        tlat, tlon = self.target()
        if self.compiled:
            return self._observe_compiled(tlat, tlon)
        # BlueSky's Python kwik forms (bearing mod 360, degrees subtracted first), which the
        # reference runs use.
        qdr, dist = ref_kwikqdrdist(s.lat[:, 0], s.lon[:, 0], tlat, tlon)
        drift = wrap180(s.hdg[:, 0] - qdr)
        self.drift = drift
        self.waypoint_dist = dist
        brg, d_int = ref_kwikqdrdist(s.lat[:, :1], s.lon[:, :1], s.lat[:, 1:], s.lon[:, 1:])
        d_sort = ref_kwikdist_matrix(s.lat[:, :1], s.lon[:, :1], s.lat[:, 1:], s.lon[:, 1:])
        vx_r, vy_r = relative_velocity(s.hdg, s.tas)
        track = np.arctan2(vy_r, vx_r)
        order = np.argsort(np.where(s.active[:, 1:], d_sort, np.inf), axis=1, kind="stable")[:, :NUM_AC_STATE]

        def closest(a: Array) -> Array:
            return np.take_along_axis(a, order, axis=1)

        d_m = d_int * NM2KM * M_PER_KM
        return {
            "cos(drift)": np.cos(np.deg2rad(drift))[:, None],
            "sin(drift)": np.sin(np.deg2rad(drift))[:, None],
            "airspeed": s.tas[:, :1].copy(),  # m/s, not normalised (reference)
            "waypoint_dist": (dist / WAYPOINT_DIST_SCALE)[:, None],
            # The reach flag as it was before this step's reward (one-step lag, spec section 7).
            "faf_reached": self.wpt_reach[:, None].astype(np.float64),
            "x_r": closest(d_m * np.cos(np.deg2rad(brg))) / POSITION_SCALE,
            "y_r": closest(d_m * np.sin(np.deg2rad(brg))) / POSITION_SCALE,
            "vx_r": closest(vx_r) / SPEED_SCALE,
            "vy_r": closest(vy_r) / SPEED_SCALE,
            "cos(track)": np.cos(closest(track)),
            "sin(track)": np.sin(closest(track)),
            "distances": closest(d_sort) / WAYPOINT_DIST_SCALE,
        }

    def _observe_compiled(self, tlat: Array, tlon: Array, envs: NDArray[np.int64] | None = None) -> dict[str, Array]:
        """The same observation through :func:`bluesky_gym.tasks.compiled.merge_observe` (of ``envs`` only if given)."""
        s = self.sim
        rows = self.all_envs if envs is None else envs
        n = len(rows)
        own = np.empty((n, 4))
        intruders = np.empty((n, 7, NUM_AC_STATE))
        self.kernels.merge_observe(rows, s.lat, s.lon, s.hdg, s.tas, s.active, tlat, tlon, _OBS_SCALES, own, intruders)
        if envs is None:
            self.drift = own[:, 0].copy()
            self.waypoint_dist = own[:, 1].copy()
        else:
            self.drift[envs] = own[:, 0]
            self.waypoint_dist[envs] = own[:, 1]
        obs = {
            "cos(drift)": own[:, 2:3],
            "sin(drift)": own[:, 3:4],
            "airspeed": s.tas[rows, :1],
            "waypoint_dist": own[:, 1:2] / WAYPOINT_DIST_SCALE,
            "faf_reached": self.wpt_reach[rows, None].astype(np.float64),
        }
        obs.update(zip(("x_r", "y_r", "vx_r", "vy_r", "cos(track)", "sin(track)", "distances"), intruders.transpose(1, 0, 2)))
        return obs

    def observe_envs(self, envs: NDArray[np.int64]) -> dict[str, Array]:
        """Observation of episodes ``envs`` only (compiled: computed for those alone)."""
        if self.compiled:
            tlat, tlon = self.target()
            return self._observe_compiled(tlat, tlon, np.asarray(envs, dtype=np.int64))
        return super().observe_envs(envs)

    # --- reward ---------------------------------------------------------------------------------
    def intrusions(self) -> BoolArray:
        """(n_envs, max_aircraft - 1) intruders within 4 NM (kwik distance) of the ownship."""
        return self.kwik_separation(INTRUSION_DISTANCE)[1][:, 1:]

    def evaluate(self) -> tuple[Array, BoolArray, dict[str, Array]]:
        """FAF reach reward, runway goal, drift and intrusion penalties."""
        # Waypoint logic on the distance of the last observation (to the FAF, or to the runway
        # once the FAF was reached in an earlier step).
        reach_faf = (self.waypoint_dist < DISTANCE_MARGIN) & (self.wpt_reach != 1)
        near_runway = ~reach_faf & (self.waypoint_dist < GOAL_MARGIN) & (self.wpt_reach == 1)
        self.wpt_reach = np.where(reach_faf, 1, self.wpt_reach)
        self.faf_reached = np.where(reach_faf, 1, np.where(near_runway, 2, self.faf_reached))
        reach = np.where(reach_faf, REACH_REWARD, 0.0)
        abs_drift = np.abs(np.deg2rad(self.drift))
        self.drift_rad_sum += abs_drift
        self.drift_rad_n += 1
        drift_reward = abs_drift * DRIFT_PENALTY
        count = self.intrusions().sum(axis=1)
        self.total_intrusions += count
        intrusion = count * INTRUSION_PENALTY + 0.0  # + 0.0: no intrusion gives +0.0, as the reference's integer 0
        reward = reach + drift_reward + intrusion
        return reward, near_runway, {"reach": reach, "drift": drift_reward, "intrusion": intrusion}

    def episode_info(self) -> dict[str, Array]:
        """Info keys of the reference, (n_envs,) each."""
        # The reference's mean of an empty list is NaN at reset; v0 reports 0.0 until a sample exists.
        n = self.drift_rad_n
        return {
            "total_reward": self.stats.total_reward.copy(),
            "faf_reach": self.faf_reached.copy(),
            "average_drift": np.where(n > 0, self.drift_rad_sum / np.maximum(n, 1), 0.0),
            "total_intrusions": self.total_intrusions.copy(),
        }

    # --- KPIs -----------------------------------------------------------------------------------
    def ownship_separation(self) -> tuple[Array, BoolArray]:
        """Kwik distance [NM] from the ownship to every other aircraft and the intrusion flags."""
        return self.kwik_separation(INTRUSION_DISTANCE)

    def drift_deg(self) -> Array | None:
        """(n_envs,) |drift| to the current target at the last observation [deg]."""
        return np.abs(self.drift)

    def goal_reached(self) -> BoolArray:
        """(n_envs,) FAF passed and within 20 NM of the runway (faf_reach == 2)."""
        return self.faf_reached == 2

    def extra_track_km(self) -> Array:
        """(n_envs,) distance flown minus the nominal route start -> FAF -> 20 NM before the runway [km]."""
        to_faf = ref_kwikdist(self.start_lat, self.start_lon, FAF_LAT, FAF_LON)
        faf_to_rwy = ref_kwikdist(FAF_LAT, FAF_LON, RWY_LAT, RWY_LON)
        nominal_km = (to_faf + faf_to_rwy - GOAL_MARGIN) * NM2KM
        return self.sim.distflown[:, 0] / M_PER_KM - nominal_km
