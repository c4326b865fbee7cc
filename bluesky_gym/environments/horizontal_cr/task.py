"""HorizontalCREnv-v0: reach a waypoint due north, avoiding intruders by heading (docs/environments-v0.md §3)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from bluesky_gym.core.aircraft import aircraft_performance, is_rotorcraft
from bluesky_gym.core.jit import grid_range, jit
from bluesky_gym.core.physics import Physics
from bluesky_gym.core.units import FL, NM2KM
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
    check_type_mix,
    draw_types,
    kwik_separation,
    typed,
)
from bluesky_gym.tasks.compiled import DEG2RAD
from bluesky_gym.tasks.geometry import point_at_distance, ref_kwikdist

DISTANCE_MARGIN = 5.0  # km: waypoint capture radius
REACH_REWARD = 1.0
NOT_REACHED_REWARD = 0.0  # the reach term of a step that does not first reach the waypoint
DRIFT_PENALTY = -0.1  # per rad of |drift|, per step
INTRUSION_PENALTY = -1.0  # per intruder within INTRUSION_DISTANCE, per step
INTRUSION_DISTANCE = 5.0  # NM, horizontal only
AVERAGE_DRIFT_EMPTY = 0.0  # rad: the average_drift info before the first step (the reference's mean of nothing is NaN)
D_HEADING = 45.0  # deg of heading change per unit action
AC_SPD = 150.0  # m/s CAS at creation (the ground phase then limits it to 89 m/s)
DISTANCE_SCALE = 150.0  # km: intruder and waypoint distances are divided by 150 (WAYPOINT_DISTANCE_MAX)
SPEED_SCALE = AC_SPD  # m/s: x/y_difference_speed are divided by 150
START_LAT, START_LON = 52.0, 4.0  # deg: BlueSky's default creation position
START_HDG = 0.0  # deg: BlueSky's default creation heading (north)
START_ALT = 0.0  # m: no altitude is given to ``cre``, so the ownship is in the ground phase
WAYPOINT_BEARING = 0.0  # deg: the waypoint is due north of the start
AIRBORNE_ALT = 100 * FL  # m: -v1 start altitude (FL100), above the ground phase, so CAS 150 m/s holds
# -v1 declared bounds: distances within 40 x 150 km (300 steps of 50 s at twice the TAS), speed
# differences within twice the fastest TAS.
DISTANCE_BOUND = 40.0
SPEED_DIFFERENCE_BOUND = 4.0


@dataclass(frozen=True)
class HorizontalCRConfig(TaskConfig):
    """Scenario options of the horizontal conflict-resolution task (defaults: the paper's).

    Integer draws are uniform over ``[min, max)``, as the reference's ``randint``.

    Attributes:
        num_intruders: Number of intruders (observation vectors have this length).
        dpsi_min: Lowest intruder track offset from the ownship track [deg].
        dpsi_max: Upper bound of the track offset draw [deg].
        dcpa_min: Lowest predicted distance at the closest point of approach [NM].
        dcpa_max: Upper bound of the dcpa draw [NM].
        tlosh_min: Lowest time to horizontal loss of separation [s].
        tlosh_max: Upper bound of the tlosh draw [s].
        waypoint_distance_min: Lowest distance of the waypoint from the start [km].
        waypoint_distance_max: Upper bound of the waypoint distance draw [km]. The observation's
            distance normalisation stays 150 km whatever this value.
        airborne_start: ``-v1``: every aircraft starts at FL100, where it flies the CAS 150 m/s
            of the scenario; ``-v0``: at altitude 0, in BlueSky's ground phase, capped at 89 m/s.
        intruder_types: Aircraft types of the intruders: a type name, names drawn with equal
            probability (e.g. ``("A320", "B744")``) or ``{name: weight}``. Default A320 only (the
            paper's fleet, no random draw). Types are BlueSky's OpenAP types (``bluesky_gym.core.aircraft.supported_types()``)
            and its rotorcraft (``bluesky_gym.core.aircraft.ROTORCRAFT_TYPES``), which fly BlueSky's
            rotor model; with ``airborne_start`` only rotorcraft whose ceiling is at least FL100.
        ownship_types: Aircraft type(s) of the ownship, in the same form (default A320).

    """

    num_intruders: int = 5
    dpsi_min: int = 45
    dpsi_max: int = 315
    dcpa_min: int = 0
    dcpa_max: int = 5
    tlosh_min: int = 100
    tlosh_max: int = 1000
    waypoint_distance_min: int = 100
    waypoint_distance_max: int = 150
    airborne_start: bool = False
    intruder_types: TypeMix = DEFAULT_TYPES
    ownship_types: TypeMix = DEFAULT_TYPES

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first invalid option."""
        check_int("num_intruders", self.num_intruders, 1, 50)
        check_int("dpsi_min", self.dpsi_min, 0, 359)
        check_int("dpsi_max", self.dpsi_max, self.dpsi_min + 1, 360)
        check_int("dcpa_min", self.dcpa_min, 0)
        check_int("dcpa_max", self.dcpa_max, self.dcpa_min + 1)
        check_int("tlosh_min", self.tlosh_min, 1)
        check_int("tlosh_max", self.tlosh_max, self.tlosh_min + 1)
        # The waypoint must start outside its capture radius, or the episode would end at once.
        check_int("waypoint_distance_min", self.waypoint_distance_min, int(DISTANCE_MARGIN) + 1, 5000)
        check_int("waypoint_distance_max", self.waypoint_distance_max, self.waypoint_distance_min + 1, 5000)
        for option, mix in (("intruder_types", self.intruder_types), ("ownship_types", self.ownship_types)):
            names, _ = check_type_mix(option, mix, rotorcraft=True)
            rotors = [(t, aircraft_performance(t).hmax) for t in names if self.airborne_start and is_rotorcraft(t)]
            for t, ceiling in rotors:
                if ceiling < AIRBORNE_ALT:
                    raise ValueError(
                        f"{option}: rotorcraft {t} cannot fly the airborne start at FL100 ({AIRBORNE_ALT:g} m): its ceiling is {ceiling:g} m"
                    )


# --- kernels: the task's rules, one source for the CPU and the device (bluesky_gym.core.jit) ---------
@jit
def waypoint_progress(envs, own, hdg, drift, dist_nm, reached, margin_km, km_out, heading_out, cos_out, sin_out, newly_out, goal_out):
    """The rest of the waypoint side of :func:`measure`, per row (slot ``own[r]`` of episode ``envs[r]``).

    From the row's drift [deg] and kwik distance to its waypoint [NM]
    (:func:`~bluesky_gym.tasks.compiled.goal_geometry`): the distance [km], the heading [deg],
    cos and sin of the drift, whether the waypoint is reached now for the first time (within
    ``margin_km``, not ``reached[r]`` before) and whether it is reached at all.
    """
    for r in grid_range(envs.shape[0]):
        km = dist_nm[r] * NM2KM
        rad = drift[r] * DEG2RAD
        newly = km < margin_km and not reached[r]
        km_out[r] = km
        heading_out[r] = hdg[envs[r], own[r]]
        cos_out[r] = math.cos(rad)
        sin_out[r] = math.sin(rad)
        newly_out[r] = newly
        goal_out[r] = reached[r] or newly


@jit
def row_reward(newly, drift, los, reach_reward, drift_penalty, intrusion_penalty, reward_out, reach_out, drift_out, intrusion_out, count_out):
    """The reward of each row: ``reach_reward`` on first reaching the waypoint, ``drift_penalty`` |drift| [rad], ``intrusion_penalty`` per intruder.

    ``newly`` (p,), ``drift`` (p,) [deg] and ``los`` (p, m) are the row's :func:`waypoint_progress`
    and :func:`~bluesky_gym.tasks.compiled.kwik_separation` results; out: the reward, its three
    components and the intruder count.
    """
    for r in grid_range(drift.shape[0]):
        count = 0
        for j in range(los.shape[1]):
            if los[r, j]:
                count += 1
        reach = reach_reward if newly[r] else NOT_REACHED_REWARD
        d = abs(drift[r] * DEG2RAD) * drift_penalty
        intrusion = count * intrusion_penalty
        reach_out[r] = reach
        drift_out[r] = d
        intrusion_out[r] = intrusion
        count_out[r] = count
        reward_out[r] = reach + d + intrusion


@jit
def episode_reward(envs, drift, count, goal, wpt_reach, drift_rad_sum, drift_rad_n, total_intrusions, terminated_out):
    """The episode side of the reward of rows ``envs`` (the ownship, slot 0): the reach flag, the info sums, the termination.

    The waypoint reached (``goal``) is remembered (it shows from the next observation on) and
    terminates; |drift| [rad] and the intruder count are added to the episode sums.
    """
    for r in grid_range(envs.shape[0]):
        e = envs[r]
        wpt_reach[e] = goal[r]
        drift_rad_sum[e] += abs(drift[r] * DEG2RAD)
        drift_rad_n[e] += 1
        total_intrusions[e] += count[r]
        terminated_out[r] = goal[r]


# --- the step's geometry, observation and reward, for a set of ownship slots ----------------------
INTRUDER_KEYS = ("intruder_distance", "cos_difference_pos", "sin_difference_pos", "x_difference_speed", "y_difference_speed")


@dataclass(frozen=True)
class HorizontalCRGeometry(StepGeometry):
    """HorizontalCR's geometry of (episode, ownship slot) rows (see :func:`measure`).

    Its arrays are numpy arrays on the CPU, torch tensors in the device step.

    Attributes:
        own: (rows,) ownship slot of each row.
        intruders: (5, rows, k) dist_km, cos_bearing, sin_bearing, x_dif, y_dif of the observed
            other aircraft (:func:`bluesky_gym.tasks.compiled.intruder_relative_state`).
        n_others: (rows,) other active aircraft.
        heading: (rows,) the ownship's heading [deg].
        waypoint_km: (rows,) kwik distance to the own waypoint [km].
        cos_drift: (rows,) cosine of the drift.
        sin_drift: (rows,) sine of the drift.
        newly_reached: (rows,) the waypoint is reached now for the first time.
    """

    own: NDArray[np.int64]
    intruders: Array
    n_others: NDArray[np.int64]
    heading: Array
    waypoint_km: Array
    cos_drift: Array
    sin_drift: Array
    newly_reached: BoolArray


def measure(
    sim: Physics,
    envs: NDArray[np.int64],
    own: NDArray[np.int64],
    wpt_lat: Array,
    wpt_lon: Array,
    reached: BoolArray,
    nearest: bool = False,
    k: int | None = None,
) -> HorizontalCRGeometry:
    """Intruder geometry, waypoint distance and drift, separation and the reach test of each row.

    The kernels :func:`~bluesky_gym.tasks.compiled.intruder_relative_state`,
    :func:`~bluesky_gym.tasks.compiled.goal_geometry`, :func:`waypoint_progress` and
    :func:`~bluesky_gym.tasks.compiled.kwik_separation`.

    Args:
        sim: The physics.
        envs: (rows,) episode of each row.
        own: (rows,) ownship slot of each row.
        wpt_lat: (rows,) latitude of each row's waypoint [deg].
        wpt_lon: (rows,) its longitude [deg].
        reached: (rows,) whether the waypoint was reached before this step.
        nearest: Observe the ``k`` nearest other aircraft (True) or the other slots in slot order
            (False: the single-agent creation order).
        k: Observed other aircraft (default: all other slots).
    """
    n, m = len(envs), sim.lat.shape[1]
    k = m - 1 if k is None else k
    intruders = np.empty((5, n, k))
    n_others = np.empty(n, np.int64)
    compiled.intruder_relative_state(envs, own, sim.lat, sim.lon, sim.hdg, sim.gs, sim.active, nearest, intruders, n_others)
    drift, dist_nm, waypoint_km, heading, cos_drift, sin_drift = (np.empty(n) for _ in range(6))
    newly, goal = np.empty(n, bool), np.empty(n, bool)
    compiled.goal_geometry(envs, own, sim.lat, sim.lon, sim.hdg, wpt_lat, wpt_lon, drift, dist_nm)
    waypoint_progress(envs, own, sim.hdg, drift, dist_nm, reached, DISTANCE_MARGIN, waypoint_km, heading, cos_drift, sin_drift, newly, goal)
    separation, los = kwik_separation(sim, envs, own, INTRUSION_DISTANCE)
    return HorizontalCRGeometry(envs, separation, los, drift, goal, own, intruders, n_others, heading, waypoint_km, cos_drift, sin_drift, newly)


def observation(g: HorizontalCRGeometry) -> dict[str, Array]:
    """HorizontalCREnv-v0's observation of every row: the geometry's entries scaled (numpy arrays or torch tensors alike)."""
    dist_km, cos_b, sin_b, x_dif, y_dif = g.intruders
    return {
        "intruder_distance": dist_km / DISTANCE_SCALE,
        "cos_difference_pos": cos_b,
        "sin_difference_pos": sin_b,
        "x_difference_speed": x_dif / SPEED_SCALE,
        "y_difference_speed": y_dif / SPEED_SCALE,
        "waypoint_distance": (g.waypoint_km / DISTANCE_SCALE)[:, None],
        "cos_drift": g.cos_drift[:, None],
        "sin_drift": g.sin_drift[:, None],
    }


def reward(g: HorizontalCRGeometry) -> tuple[Array, NDArray[np.int64], dict[str, Array]]:
    """Per row: +1 on first reaching the waypoint, -0.1 |drift| [rad], -1 per other aircraft within 5 NM; and the intrusion count.

    The kernel :func:`row_reward`.
    """
    assert g.drift_deg is not None
    n = len(g.drift_deg)
    r, reach, drift_reward, intrusion, count = np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(n, np.int64)
    row_reward(g.newly_reached, g.drift_deg, g.los, REACH_REWARD, DRIFT_PENALTY, INTRUSION_PENALTY, r, reach, drift_reward, intrusion, count)
    return r, count, {"reach": reach, "drift": drift_reward, "intrusion": intrusion}


def bounds_v1(key: str) -> tuple[float, float]:
    """The ``-v1`` declared (low, high) of an observation entry of HorizontalCR (its multi-agent form too)."""
    if key in ("intruder_distance", "waypoint_distance"):
        return 0.0, DISTANCE_BOUND
    if key in ("x_difference_speed", "y_difference_speed"):
        return -SPEED_DIFFERENCE_BOUND, SPEED_DIFFERENCE_BOUND
    return -1.0, 1.0


class HorizontalCRTask(Task):
    """Batched horizontal CR task; see :class:`bluesky_gym.environments.horizontal_cr.env.HorizontalCREnv`."""

    env_id: ClassVar[str] = "HorizontalCREnv-v0"
    dt: ClassVar[float] = 5.0
    action_frequency: ClassVar[int] = 10
    max_episode_steps: ClassVar[int] = 300
    config_class: ClassVar[type[TaskConfig]] = HorizontalCRConfig
    info_keys: ClassVar[tuple[str, ...]] = ("total_reward", "total_intrusions", "average_drift")
    #: The extra track is measured from the shortest path to the capture circle.
    route_km_array: ClassVar[str | None] = "route_km"
    config: HorizontalCRConfig

    def max_aircraft(self) -> int:
        """Aircraft slots: the ownship plus ``num_intruders`` intruders."""
        return 1 + self.config.num_intruders

    def build_observation_spec(self) -> dict[str, BoxSpec]:
        """Observation keys, shapes and bounds, in the reference's key order."""
        n = self.config.num_intruders
        spec = {
            k: BoxSpec((n,)) for k in ("intruder_distance", "cos_difference_pos", "sin_difference_pos", "x_difference_speed", "y_difference_speed")
        }
        spec.update({k: BoxSpec((1,)) for k in ("waypoint_distance", "cos_drift", "sin_drift")})
        if self.config.float32_spaces:
            for k in spec:
                spec[k] = BoxSpec(spec[k].shape, *bounds_v1(k))
        return spec

    def build_action_spec(self) -> BoxSpec:
        """Heading change, one value in [-1, 1]."""
        return BoxSpec((1,), -1.0, 1.0)

    # --- generator ------------------------------------------------------------------------------
    def allocate(self) -> None:
        """Allocate the per-episode arrays."""
        n = self.n_envs
        self.wpt_lat = np.zeros(n)  # deg
        self.wpt_lon = np.zeros(n)  # deg
        self.wpt_reach = np.zeros(n, bool)  # set by reward(), after the observation (one-step lag)
        self.ac_hdg = np.zeros(n)  # deg: ownship heading at the last observation (the action's reference)
        self.start_wpt_dist_km = np.zeros(n)  # kwik distance start -> waypoint [km]
        self.route_km = np.zeros(n)  # the shortest path to the capture circle: that distance less the capture radius [km]
        self.total_intrusions = np.zeros(n, np.int64)
        self.drift_rad_sum = np.zeros(n)  # sum of |drift| [rad] over the steps (average_drift)
        self.drift_rad_n = np.zeros(n, np.int64)
        # The scenario draws of the current episodes.
        shape = (n, self.config.num_intruders)
        self.conflict_dpsi = np.zeros(shape)  # deg
        self.conflict_dcpa = np.zeros(shape)  # NM
        self.conflict_tlosh = np.zeros(shape)  # s
        self.wpt_distance_drawn = np.zeros(n)  # km

    def generate(self, envs: NDArray[np.int64]) -> None:
        """Create the scenarios of the episodes ``envs``, drawing from their generators only."""
        c = self.config
        n = c.num_intruders
        imix = check_type_mix("intruder_types", c.intruder_types, rotorcraft=True)
        omix = check_type_mix("ownship_types", c.ownship_types, rotorcraft=True)
        own_types: list[str] = []
        intruder_types: list[str] = []
        dpsi = np.empty((envs.size, n))
        dcpa = np.empty((envs.size, n))
        tlosh = np.empty((envs.size, n))
        wpt_dist = np.empty(envs.size)
        for k, e in enumerate(envs):
            rng = self.rngs[e]
            for i in range(n):
                dpsi[k, i] = rng.integers(c.dpsi_min, c.dpsi_max)
                dcpa[k, i] = rng.integers(c.dcpa_min, c.dcpa_max)
                tlosh[k, i] = rng.integers(c.tlosh_min, c.tlosh_max)
            wpt_dist[k] = rng.integers(c.waypoint_distance_min, c.waypoint_distance_max)
            # Aircraft types last (no draw for a one-type mix): the rest of the scenario does not depend on them.
            own_types += draw_types(rng, omix, 1)
            intruder_types += draw_types(rng, imix, n)
        self.sim.create(envs, 0, START_LAT, START_LON, START_HDG, AIRBORNE_ALT if c.airborne_start else START_ALT, AC_SPD, **typed(own_types))
        self.conflict_dpsi[envs], self.conflict_dcpa[envs], self.conflict_tlosh[envs] = dpsi, dcpa, tlosh
        self.wpt_distance_drawn[envs] = wpt_dist
        # No dH: intruders at the ownship's altitude (0, ground phase) with its ground speed.
        self.sim.creconfs(
            np.repeat(envs, n), 0, np.tile(np.arange(1, n + 1), envs.size), dpsi.ravel(), dcpa.ravel(), tlosh.ravel(), **typed(intruder_types)
        )
        lat, lon = point_at_distance(self.sim.lat[envs, 0], self.sim.lon[envs, 0], wpt_dist, WAYPOINT_BEARING)
        self.wpt_lat[envs] = lat
        self.wpt_lon[envs] = lon
        self.wpt_reach[envs] = False
        self.ac_hdg[envs] = self.sim.hdg[envs, 0]
        self.start_wpt_dist_km[envs] = ref_kwikdist(self.sim.lat[envs, 0], self.sim.lon[envs, 0], lat, lon) * NM2KM
        self.route_km[envs] = self.start_wpt_dist_km[envs] - DISTANCE_MARGIN
        self.total_intrusions[envs] = 0
        self.drift_rad_sum[envs] = 0.0
        self.drift_rad_n[envs] = 0

    # --- dynamics interface ---------------------------------------------------------------------
    def apply_action(self, action: Array) -> None:
        """Command the heading: HDG = heading at the last observation + 45 a (the kernel :func:`~bluesky_gym.tasks.compiled.heading_targets`)."""
        # Values outside [0, 360) are passed on unchanged, as the reference's stack command does.
        target = np.empty(self.n_envs)
        compiled.heading_targets(self.ac_hdg, action, D_HEADING, target)
        self.sim.cmd_heading(self.all_envs, 0, target)

    def waypoint_geometry(self) -> tuple[Array, Array]:
        """(n_envs,) kwik distance to the waypoint [km] and drift wrap180(hdg - qdr) [deg] now (:meth:`measure`'s)."""
        g = self.measure()
        assert g.drift_deg is not None
        return g.waypoint_km, g.drift_deg

    # --- the step -----------------------------------------------------------------------------
    def measure(self, envs: NDArray[np.int64] | None = None) -> HorizontalCRGeometry:
        """The ownship's (slot 0) geometry of episodes ``envs`` (all when None): :func:`measure`."""
        envs = self.all_envs if envs is None else np.asarray(envs, dtype=np.int64)
        return measure(self.sim, envs, self.ownship[: len(envs)], self.wpt_lat[envs], self.wpt_lon[envs], self.wpt_reach[envs])

    def observe(self, g: StepGeometry | None = None) -> dict[str, Array]:
        """Intruders in creation order (slots 1..n, no sorting, docs/environments-v0.md §3) and the waypoint.

        Stores the observed heading: the next action's reference.
        """
        g = self.measure() if g is None else g
        self.ac_hdg[g.envs] = g.heading  # type: ignore[attr-defined]
        return observation(g)  # type: ignore[arg-type]

    def reward(self, g: StepGeometry) -> tuple[Array, BoolArray, dict[str, Array]]:
        """Reach, drift and intrusion terms; terminated once the waypoint is reached.

        Evaluated on the state of the observation just built; the reach flag therefore only
        shows from the next observation on (docs/environments-v0.md §3-4, one-step lag).
        """
        r, count, components = reward(g)  # type: ignore[arg-type]
        assert isinstance(g, HorizontalCRGeometry) and g.drift_deg is not None
        terminated = np.empty(self.n_envs, bool)
        sums = (self.drift_rad_sum, self.drift_rad_n, self.total_intrusions)
        episode_reward(g.envs, g.drift_deg, count, g.goal_reached, self.wpt_reach, *sums, terminated)
        return r, terminated, components

    def episode_info(self) -> dict[str, Array]:
        """Info keys of the reference, (n_envs,) each."""
        # The reference's mean of an empty array is NaN at reset; v0 reports 0.0 until a sample exists.
        average_drift = np.empty(self.n_envs)  # mean |drift| [rad] of the episode's steps
        compiled.sample_means(self.drift_rad_sum, self.drift_rad_n, AVERAGE_DRIFT_EMPTY, average_drift)
        return {
            "total_reward": self.stats.total_reward.copy(),
            "total_intrusions": self.total_intrusions.copy(),  # type: ignore[dict-item]  # a count among the float entries
            "average_drift": average_drift,
        }

    # --- KPIs -----------------------------------------------------------------------------------
