"""MergeEnv-v0: merge the ownship into a stream of arrivals via a final approach fix (docs/environments-v0.md §7)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar, cast

import numpy as np
from numpy.typing import NDArray

from bluesky_gym.core.physics import Physics
from bluesky_gym.core.units import NM2KM
from bluesky_gym.tasks import compiled
from bluesky_gym.tasks.base import (
    DEFAULT_TYPES,
    Array,
    BoolArray,
    BoxSpec,
    StepGeometry,
    Task,
    TaskConfig,
    TypeMix,
    check_int,
    check_pair,
    check_range,
    check_type_mix,
    command_heading_and_speed,
    draw_types,
    kwik_separation,
    typed,
)
from bluesky_gym.tasks.geometry import point_at_distance, ref_kwikdist

# Airspace (reference values).
RWY_LAT, RWY_LON = 52.36239301495972, 4.713195734579777  # deg: runway (Schiphol)
FAF_DISTANCE = 200.0  # km (the reference comments NM) due north of the runway
FAF_BEARING = 0.0  # deg
_faf = point_at_distance(RWY_LAT, RWY_LON, FAF_DISTANCE, FAF_BEARING)
FAF_LAT, FAF_LON = float(_faf[0]), float(_faf[1])  # deg: final approach fix (54.161036, 4.713196)
FAF_DISTANCE_NM = 200.0  # NM: -v1 FAF distance due north of the runway, the unit the reference meant
_faf_v1 = point_at_distance(RWY_LAT, RWY_LON, FAF_DISTANCE_NM * NM2KM, FAF_BEARING)
FAF_LAT_V1, FAF_LON_V1 = float(_faf_v1[0]), float(_faf_v1[1])  # deg

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
AVERAGE_DRIFT_EMPTY = 0.0  # rad: the average_drift info before the first step (the reference's mean of nothing is NaN)
INTRUSION_PENALTY = -1.0  # per intruder within INTRUSION_DISTANCE, per step
INTRUSION_DISTANCE = 4.0  # NM, horizontal only (all aircraft share one altitude)
D_HEADING = 15.0  # deg of heading change per unit action
D_SPEED = 20.0  # m/s of CAS change per unit action
NUM_AC_STATE = 5  # intruders in the observation (the closest ones)
WAYPOINT_DIST_SCALE = 250.0  # NM: waypoint_dist and distances are divided by 250
POSITION_SCALE = 1e6  # m: x_r, y_r
SPEED_SCALE = 150.0  # m/s: vx_r, vy_r
M_PER_KM = 1000.0

OBS_SCALES = (POSITION_SCALE, SPEED_SCALE, WAYPOINT_DIST_SCALE)  # for the compiled observation
_NO_ROWS = np.zeros(0, bool)  # an empty per-row flag array: -v0 has no faf_now
INTRUDER_KEYS = ("x_r", "y_r", "vx_r", "vy_r", "cos(track)", "sin(track)", "distances")
MAX_NUM_AC = 200  # largest supported traffic count
ALT_MAX = 11060.0  # m: the A320's altitude ceiling
CAS_RANGE = (67.0, 163.0)  # m/s: the A320's CAS envelope away from the ground
# -v1 (see MergeConfig).
DISTANCE_MARGIN_KM = 10.0  # km: FAF capture radius as the reference's comment states (goal: twice it)
MAX_EPISODE_STEPS_V1 = 100  # decision steps: start -> FAF at 200 NM -> runway takes up to ~66 at the initial TAS
# -v1 declared bounds: distances within 8 x 250 NM, positions within 4000 km, relative speeds
# within twice the fastest TAS.
WAYPOINT_DIST_BOUND = 8.0
POSITION_BOUND = 4.0
SPEED_BOUND = 4.0
AIRSPEED_BOUND = 1.0  # (TAS - 150) / 150: TAS within [0, 300] m/s


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
        faf_same_step: ``-v1``: the FAF reached in a step shows in that step's observation
            (``faf_reached`` 1, the target then the runway); ``-v0``: from the next one
            (bluesky-gym #13).
        faf_distance_in_nm: ``-v1``: the FAF is 200 NM north of the runway, the unit the
            reference's comment gives, and the episode limit is 100 steps so that the runway stays
            within reach; ``-v0``: 200 km, 50 steps.
        margins_in_km: ``-v1``: the FAF capture radius is 10 km and the runway goal 20 km, as the
            reference's comment states; ``-v0``: 10 and 20 NM (the "km" compared with NM).
        normalise_airspeed: ``-v1``: ``airspeed`` is (TAS - 150) / 150; ``-v0``: raw TAS [m/s]
            (about 168).
        intruder_types: Aircraft types of the intruders: a type name, names drawn with equal
            probability (e.g. ``("A320", "B744")``) or ``{name: weight}``. Default A320 only (the
            paper's fleet, no random draw). Types are BlueSky's OpenAP types (``bluesky_gym.core.aircraft.supported_types()``).
        ownship_types: Aircraft type(s) of the ownship, in the same form (default A320). Types
            are drawn after the spawn points. The observation's speed and altitude normalisation
            stays the A320's.

    """

    num_aircraft: int = NUM_AC
    spawn_distance_km: tuple[float, float] = SPAWN_DISTANCE
    intruder_distance_km: tuple[float, float] = INTRUDER_DISTANCE
    spawn_bearing_deg: float = SPAWN_BEARING
    ac_speed: float = AC_SPD
    altitude: float = AC_ALT
    faf_same_step: bool = False
    faf_distance_in_nm: bool = False
    margins_in_km: bool = False
    normalise_airspeed: bool = False
    intruder_types: TypeMix = DEFAULT_TYPES
    ownship_types: TypeMix = DEFAULT_TYPES

    def __post_init__(self) -> None:
        super().__post_init__()
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
        check_type_mix("intruder_types", self.intruder_types)
        check_type_mix("ownship_types", self.ownship_types)


# --- the step's geometry, observation and reward, for a set of ownship slots ----------------------
@dataclass(frozen=True)
class MergeGeometry(StepGeometry):
    """Merge's geometry of (episode, ownship slot) rows (see :func:`measure`).

    Attributes:
        own: (rows,) ownship slot of each row.
        after_faf: (rows,) whether the ownship had passed the FAF before this step's reward (its
            target is then the runway).
        target_nm: (rows,) kwik distance to the current target [NM].
        features: (rows, 4) drift [deg], target distance [NM], cos(drift), sin(drift).
        airspeed: (rows,) TAS [m/s].
        intruders: (rows, 7, NUM_AC_STATE) the observed closest other aircraft (:data:`INTRUDER_KEYS`).
        n_others: (rows,) other active aircraft (fewer than NUM_AC_STATE: the last entries are padding).
    """

    own: NDArray[np.int64]
    after_faf: BoolArray
    target_nm: Array
    features: Array
    airspeed: Array
    intruders: Array
    n_others: NDArray[np.int64]
    faf_now: BoolArray | None = None  # (rows,) -v1: the FAF reached in this step (then already in after_faf)


@dataclass(frozen=True)
class Airspace:
    """Where Merge's fixes are and how close counts as reached (``-v0``: the reference's values).

    Attributes:
        faf_lat: FAF latitude [deg].
        faf_lon: FAF longitude [deg].
        faf_margin_nm: FAF capture radius [NM].
        goal_margin_nm: Distance from the runway, after the FAF, that ends the episode [NM].
    """

    faf_lat: float = FAF_LAT
    faf_lon: float = FAF_LON
    faf_margin_nm: float = DISTANCE_MARGIN
    goal_margin_nm: float = GOAL_MARGIN


AIRSPACE_V0 = Airspace()


def airspace(config: MergeConfig) -> Airspace:
    """The fixes and margins of ``config``."""
    faf = (FAF_LAT_V1, FAF_LON_V1) if config.faf_distance_in_nm else (FAF_LAT, FAF_LON)
    margin = DISTANCE_MARGIN_KM / NM2KM if config.margins_in_km else DISTANCE_MARGIN
    return Airspace(faf[0], faf[1], margin, 2 * margin)


def nominal_route_km(start_lat: Array, start_lon: Array, space: Airspace = AIRSPACE_V0) -> Array:
    """The nominal route of ownships starting at (``start_lat``, ``start_lon``) [deg]: start -> FAF -> the goal margin before the runway [km].

    Kwik distances [NM] from the start to the FAF and from the FAF to the runway, less the goal margin.
    """
    to_faf = ref_kwikdist(start_lat, start_lon, space.faf_lat, space.faf_lon)
    faf_to_rwy = ref_kwikdist(space.faf_lat, space.faf_lon, RWY_LAT, RWY_LON)
    return np.asarray((to_faf + faf_to_rwy - space.goal_margin_nm) * NM2KM)


def target(after_faf: BoolArray, space: Airspace = AIRSPACE_V0) -> tuple[Array, Array]:
    """Lat, lon [deg] of the current target: the FAF, then the runway once the FAF was reached (:func:`~bluesky_gym.tasks.compiled.merge_targets`)."""
    after = np.ascontiguousarray(after_faf, dtype=bool)
    lat, lon = np.empty(after.shape), np.empty(after.shape)
    compiled.merge_targets(after.reshape(-1), space.faf_lat, space.faf_lon, RWY_LAT, RWY_LON, lat.reshape(-1), lon.reshape(-1))
    return lat, lon


def measure(
    sim: Physics, envs: NDArray[np.int64], own: NDArray[np.int64], after_faf: BoolArray, space: Airspace = AIRSPACE_V0, faf_same_step: bool = False
) -> MergeGeometry:
    """Drift and distance to the current target, the 5 closest other aircraft and the separation of each row.

    BlueSky's Python kwik forms (bearing mod 360, degrees subtracted first), which the reference
    runs use; intruders sorted by ``kwikdist_matrix``; separation by kwik distance, 4 NM.
    With ``faf_same_step`` (``-v1``) a row within the FAF's capture radius is measured again
    against the runway, its next target, and flagged in ``faf_now``
    (:func:`~bluesky_gym.tasks.compiled.merge_faf_now`); the runway goal is
    :func:`~bluesky_gym.tasks.compiled.merge_goal`.
    """
    n = len(envs)
    tlat, tlon = target(after_faf, space)
    features = np.empty((n, 4))
    intruders = np.empty((n, 7, NUM_AC_STATE))
    n_others = np.empty(n, np.int64)
    compiled.merge_observe(envs, own, sim.lat, sim.lon, sim.hdg, sim.tas, sim.active, tlat, tlon, OBS_SCALES, features, intruders, n_others)
    faf_now = None
    if faf_same_step:
        faf_now, after_now = np.empty(n, bool), np.empty(n, bool)
        compiled.merge_faf_now(after_faf, features, space.faf_margin_nm, faf_now, after_now)
        after_faf = after_now
        if faf_now.any():
            tlat, tlon = target(after_faf, space)
            compiled.merge_observe(envs, own, sim.lat, sim.lon, sim.hdg, sim.tas, sim.active, tlat, tlon, OBS_SCALES, features, intruders, n_others)
    separation, los = kwik_separation(sim, envs, own, INTRUSION_DISTANCE)
    reached = np.empty(n, bool)
    compiled.merge_goal(after_faf, features, _NO_ROWS if faf_now is None else faf_now, space.goal_margin_nm, reached)
    return MergeGeometry(
        envs, separation, los, features[:, 0], reached, own, after_faf, features[:, 1], features, sim.tas[envs, own], intruders, n_others, faf_now
    )


def observation(g: MergeGeometry) -> dict[str, Array]:
    """MergeEnv-v0's observation of every row (the reference's padding when fewer intruders are active).

    Views and arithmetic of the geometry's arrays, numpy's or the device step's tensors alike.
    """
    f = g.features
    obs = {
        "cos(drift)": f[:, 2:3],
        "sin(drift)": f[:, 3:4],
        "airspeed": g.airspeed[:, None],  # m/s, not normalised (reference)
        "waypoint_dist": f[:, 1:2] / WAYPOINT_DIST_SCALE,
        # The reach flag as it was before this step's reward (one-step lag, docs/environments-v0.md §7);
        # 0 or 1 (exact in any float dtype).
        "faf_reached": cast(Array, g.after_faf[:, None] * 1.0),
    }
    obs.update({key: g.intruders[:, i] for i, key in enumerate(INTRUDER_KEYS)})
    return obs


def normalised_airspeed(airspeed: Array) -> Array:
    """``-v1``'s airspeed observation: (TAS - 150) / 150 (numpy's arrays or tensors alike)."""
    return (airspeed - SPEED_SCALE) / SPEED_SCALE


def reward(g: MergeGeometry, space: Airspace = AIRSPACE_V0) -> tuple[Array, BoolArray, BoolArray, NDArray[np.int64], dict[str, Array]]:
    """FAF reach reward, drift and intrusion penalties of every row (:func:`~bluesky_gym.tasks.compiled.merge_reward`).

    Returns:
        Reward, FAF reached now, runway goal reached now (termination), intrusion count, components.
    """
    n = len(g.envs)
    r, reach, drift_reward, intrusion = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    reach_faf, near_runway, count = np.empty(n, bool), np.empty(n, bool), np.empty(n, np.int64)
    compiled.merge_reward(
        g.features,
        g.after_faf,
        _NO_ROWS if g.faf_now is None else g.faf_now,
        g.goal_reached,
        g.los,
        space.faf_margin_nm,
        REACH_REWARD,
        DRIFT_PENALTY,
        INTRUSION_PENALTY,
        r,
        reach,
        drift_reward,
        intrusion,
        reach_faf,
        near_runway,
        count,
    )
    return r, reach_faf, near_runway, count, {"reach": reach, "drift": drift_reward, "intrusion": intrusion}


def bounds_v1(key: str) -> tuple[float, float]:
    """The ``-v1`` declared (low, high) of an observation entry of Merge."""
    return {
        "airspeed": (-AIRSPEED_BOUND, AIRSPEED_BOUND),
        "waypoint_dist": (0.0, WAYPOINT_DIST_BOUND),
        "faf_reached": (0.0, 1.0),
        "x_r": (-POSITION_BOUND, POSITION_BOUND),
        "y_r": (-POSITION_BOUND, POSITION_BOUND),
        "vx_r": (-SPEED_BOUND, SPEED_BOUND),
        "vy_r": (-SPEED_BOUND, SPEED_BOUND),
        "distances": (0.0, WAYPOINT_DIST_BOUND),
    }.get(key, (-1.0, 1.0))


class MergeTask(Task):
    """Batched merge task; see :class:`bluesky_gym.environments.merge.env.MergeEnv` for the MDP."""

    env_id: ClassVar[str] = "MergeEnv-v0"
    dt: ClassVar[float] = 5.0
    action_frequency: ClassVar[int] = 10
    max_episode_steps: ClassVar[int] = 50
    config_class: ClassVar[type[TaskConfig]] = MergeConfig
    info_keys: ClassVar[tuple[str, ...]] = ("total_reward", "faf_reach", "average_drift", "total_intrusions")
    route_km_array: ClassVar[str | None] = "route_km"
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
        if self.config.float32_spaces:
            spec = {k: BoxSpec(v.shape, *bounds_v1(k)) for k, v in spec.items()}
        return spec

    @classmethod
    def episode_limit(cls, config: TaskConfig) -> int:
        """50 steps; 100 with the FAF at 200 NM (``-v1``), so that the runway stays within reach."""
        assert isinstance(config, MergeConfig)
        return MAX_EPISODE_STEPS_V1 if config.faf_distance_in_nm else int(cls.max_episode_steps)

    def build_action_spec(self) -> BoxSpec:
        """Heading change and speed change, each in [-1, 1]."""
        return BoxSpec((2,), -1.0, 1.0)

    # --- generator ------------------------------------------------------------------------------
    def allocate(self) -> None:
        """Per-episode arrays."""
        n = self.n_envs
        self.wpt_reach = np.zeros(n, np.int64)  # 0 before the FAF, 1 after (the observed flag)
        self.faf_reached = np.zeros(n, np.int64)  # 0, 1 (FAF) or 2 (near the runway): info faf_reach
        self.total_intrusions = np.zeros(n, np.int64)
        self.drift_rad_sum = np.zeros(n)  # sum of |drift| [rad] (average_drift)
        self.drift_rad_n = np.zeros(n, np.int64)
        self.start_lat = np.zeros(n)  # deg, ownship start
        self.start_lon = np.zeros(n)
        #: (n_envs,) the nominal route start -> FAF -> goal margin before the runway [km] (extra-track KPI).
        self.route_km = np.zeros(n)
        #: The fixes and margins of the configuration.
        self.airspace = airspace(self.config)

    def generate(self, envs: NDArray[np.int64]) -> None:
        """Ownship north of the FAF, intruders on the same radial sector flying LNAV FAF -> runway."""
        c = self.config
        n_int = c.num_aircraft - 1
        b = c.spawn_bearing_deg
        own = np.empty((envs.size, 2))  # (bearing from the FAF, distance km)
        intr = np.empty((envs.size, n_int, 2))
        omix, imix = check_type_mix("ownship_types", c.ownship_types), check_type_mix("intruder_types", c.intruder_types)
        own_types: list[str] = []
        intruder_types: list[str] = []
        for k, e in enumerate(envs):
            rng = self.rngs[e]
            # The reference's Python ``random.uniform`` draws, from the episode generator, in its
            # order: ownship bearing, distance, then bearing and distance of each intruder.
            own[k] = rng.uniform((-b, c.spawn_distance_km[0]), (b, c.spawn_distance_km[1]))
            intr[k] = rng.uniform((-b, c.intruder_distance_km[0]), (b, c.intruder_distance_km[1]), size=(n_int, 2))
            own_types += draw_types(rng, omix, 1)  # types last (no draw for a one-type mix)
            intruder_types += draw_types(rng, imix, n_int)
        faf_lat, faf_lon = self.airspace.faf_lat, self.airspace.faf_lon
        lat, lon = point_at_distance(faf_lat, faf_lon, own[:, 1], own[:, 0])
        # Heading b - 180 points back at the FAF; it is stored unwrapped (e.g. -170), as BlueSky does.
        self.sim.create(envs, 0, lat, lon, own[:, 0] - 180, c.altitude, c.ac_speed, **typed(own_types))
        self.start_lat[envs] = lat
        self.start_lon[envs] = lon
        self.route_km[envs] = nominal_route_km(lat, lon, self.airspace)
        env = np.repeat(envs, n_int)
        slot = np.tile(np.arange(1, n_int + 1), envs.size)
        ilat, ilon = point_at_distance(faf_lat, faf_lon, intr[..., 1].ravel(), intr[..., 0].ravel())
        self.sim.create(env, slot, ilat, ilon, intr[..., 0].ravel() - 180, c.altitude, c.ac_speed, **typed(intruder_types))
        # "INTi addwpt FAF" then "INTi dest RWY": LNAV direct to the FAF, then the runway; VNAV stays off.
        self.sim.add_waypoint(env, slot, faf_lat, faf_lon)
        self.sim.set_destination(env, slot, RWY_LAT, RWY_LON)
        self.wpt_reach[envs] = 0
        self.faf_reached[envs] = 0
        self.total_intrusions[envs] = 0
        self.drift_rad_sum[envs] = 0.0
        self.drift_rad_n[envs] = 0

    # --- dynamics interface ---------------------------------------------------------------------
    def apply_action(self, action: Array) -> None:
        """HDG wrap180(hdg + 15 a0); SPD (CAS + 20 a1) * 1.94384 kt (docs/environments-v0.md §7)."""
        command_heading_and_speed(self.sim, self.all_envs, self.ownship, action, D_HEADING, D_SPEED)

    # --- the step -----------------------------------------------------------------------------
    def target(self) -> tuple[Array, Array]:
        """(n_envs,) lat, lon [deg] of the current target: the FAF, then the runway once reached."""
        return target(self.wpt_reach != 0, self.airspace)

    def measure(self, envs: NDArray[np.int64] | None = None) -> MergeGeometry:
        """The ownship's (slot 0) geometry of episodes ``envs`` (all when None): :func:`measure`."""
        envs = self.all_envs if envs is None else np.asarray(envs, dtype=np.int64)
        return measure(self.sim, envs, self.ownship[: len(envs)], self.wpt_reach[envs] != 0, self.airspace, self.config.faf_same_step)

    def observe(self, g: StepGeometry | None = None) -> dict[str, Array]:
        """Ownship drift, airspeed and target distance, and the 5 closest intruders by kwik distance."""
        obs = observation(self.measure() if g is None else g)  # type: ignore[arg-type]
        if self.config.normalise_airspeed:
            obs["airspeed"] = normalised_airspeed(obs["airspeed"])
        return obs

    def reward(self, g: StepGeometry) -> tuple[Array, BoolArray, dict[str, Array]]:
        """FAF reach reward, runway goal, drift and intrusion penalties."""
        assert isinstance(g, MergeGeometry)
        r, reach_faf, near_runway, count, components = reward(g, self.airspace)
        compiled.merge_episode_sums(
            g.envs,
            g.features,
            reach_faf,
            near_runway,
            count,
            self.wpt_reach,
            self.faf_reached,
            self.drift_rad_sum,
            self.drift_rad_n,
            self.total_intrusions,
        )
        return r, near_runway, components

    def episode_info(self) -> dict[str, Array]:
        """Info keys of the reference, (n_envs,) each."""
        # The reference's mean of an empty list is NaN at reset; v0 reports 0.0 until a sample exists.
        average_drift = np.empty(self.n_envs)
        compiled.sample_means(self.drift_rad_sum, self.drift_rad_n, AVERAGE_DRIFT_EMPTY, average_drift)
        return {
            "total_reward": self.stats.total_reward.copy(),
            "faf_reach": self.faf_reached.copy(),  # type: ignore[dict-item]  # counts among the float entries
            "average_drift": average_drift,
            "total_intrusions": self.total_intrusions.copy(),  # type: ignore[dict-item]
        }
