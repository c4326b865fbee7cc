"""DescentEnv-v0: reach and hold a target altitude, then descend before the runway."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from bluesky_gym.core.jit import grid_range, jit, jit_inline
from bluesky_gym.core.units import NM2KM, VS_SELECT_EPS
from bluesky_gym.tasks.base import DEFAULT_TYPES, Array, BoolArray, BoxSpec, StepGeometry, Task, TaskConfig, check_int, check_range, typed
from bluesky_gym.tasks.compiled import IntArray, kwikdist_scalar

ALT_MEAN = 1500.0  # m
ALT_STD = 3000.0  # m
VZ_MEAN = 0.0  # m/s
VZ_STD = 5.0  # m/s
RWY_DIS_MEAN = 100.0  # km
RWY_DIS_STD = 200.0  # km
ACTION_2_MS = 12.5  # m/s of vertical speed per unit action
ALT_DIF_REWARD_SCALE = -5 / 3000  # per m off the target altitude
CRASH_PENALTY = -100.0
CRASH_FINAL_ALTITUDE = -100.0  # m: the final_altitude info of a crashed episode (the reference's marker)
RWY_ALT_DIF_REWARD_SCALE = -50 / 3000  # per m above the runway at its threshold
AC_SPD = 150.0  # m/s CAS
DEFAULT_RWY_DIS = 200.0  # km from the start point to the runway
RWY_LAT, RWY_LON = 52.0, 4.0  # deg: the start point the runway distance is measured from
CLIMB_TARGET = 1e6  # m: selected altitude for a climb (clipped by the ceiling)
# -v1 declared bounds of the normalised entries: altitudes within [0, 15000] m, |vz| <= 20 m/s
# (the A320's vsmax is 16 m/s), the runway at most one step past its threshold.
ALT_BOUNDS = (-1.0, 5.0)
VZ_BOUND = 4.0
RUNWAY_BOUND_LOW = -1.0


@dataclass(frozen=True)
class DescentMeasurement(StepGeometry):
    """One step's quantities of the descent task, for the rows (episodes) ``envs``.

    No traffic and no heading goal; ``goal_reached``: the runway has been reached.
    """

    alt: Array  # (rows,) m, ownship altitude
    vs: Array  # (rows,) m/s, ownship vertical speed
    runway_km: Array  # (rows,) km left to the runway


@dataclass(frozen=True)
class DescentConfig(TaskConfig):
    """Scenario options of the descent task (defaults: the paper's).

    Attributes:
        alt_min: Lowest initial altitude [m] (integer draw in [alt_min, alt_max)).
        alt_max: Upper bound of the initial altitude draw [m].
        target_alt_dif: Target altitude offset bound [m] (integer draw in [-dif, dif)).
        runway_distance_km: Distance from the start to the runway [km].
        hold_altitude_at_zero: ``-v1``: a vertical speed of at most 0.1 m/s in magnitude
            (|a| <= 0.008) holds the current altitude; ``-v0``: BlueSky then flies its default
            7.62 m/s, so a = 0 climbs (bluesky-gym #59).
    """

    alt_min: int = 2000
    alt_max: int = 4000
    target_alt_dif: int = 500
    runway_distance_km: float = DEFAULT_RWY_DIS
    hold_altitude_at_zero: bool = False

    def validate(self) -> None:
        """Check every option."""
        check_int("alt_min", self.alt_min, 1)
        check_int("alt_max", self.alt_max, self.alt_min + 1, 11000)
        check_int("target_alt_dif", self.target_alt_dif, 1, self.alt_min - 1)
        check_range("runway_distance_km", self.runway_distance_km, 0.0, 2000.0, strict_low=True)


class DescentTask(Task):
    """Batched descent task; see :class:`bluesky_gym.environments.descent.env.DescentEnv` for the MDP."""

    env_id: ClassVar[str] = "DescentEnv-v0"
    dt: ClassVar[float] = 1.0
    action_frequency: ClassVar[int] = 30
    max_episode_steps: ClassVar[int] = 300
    config_class: ClassVar[type[TaskConfig]] = DescentConfig
    info_keys: ClassVar[tuple[str, ...]] = ("total_reward", "final_altitude")
    route_km_array: ClassVar[str | None] = "route_km"
    config: DescentConfig

    def max_aircraft(self) -> int:
        """One aircraft: the ownship."""
        return 1

    def build_observation_spec(self) -> dict[str, BoxSpec]:
        """Four scalar entries (unbounded in ``-v0``)."""
        if not self.config.float32_spaces:
            return {k: BoxSpec((1,)) for k in ("altitude", "vz", "target_altitude", "runway_distance")}
        runway_high = (self.config.runway_distance_km - RWY_DIS_MEAN) / RWY_DIS_STD
        return {
            "altitude": BoxSpec((1,), *ALT_BOUNDS),
            "vz": BoxSpec((1,), -VZ_BOUND, VZ_BOUND),
            "target_altitude": BoxSpec((1,), *ALT_BOUNDS),
            "runway_distance": BoxSpec((1,), RUNWAY_BOUND_LOW, max(1.0, float(np.ceil(runway_high)))),
        }

    def build_action_spec(self) -> BoxSpec:
        """One normalised vertical-speed command."""
        return BoxSpec((1,), -1.0, 1.0)

    # --- generator ------------------------------------------------------------------------------
    def allocate(self) -> None:
        """Target and final altitude per episode."""
        self.target_alt = np.zeros(self.n_envs)  # (n_envs,) m
        self.final_altitude = np.zeros(self.n_envs)  # (n_envs,) m, 0 until the episode ends
        self.route_km = np.full(self.n_envs, float(self.config.runway_distance_km))  # (n_envs,) km: the runway leg (extra-track KPI)

    def generate(self, envs: NDArray[np.int64]) -> None:
        """Initial and target altitude (integer draws), then the ownship."""
        c = self.config
        alt_init = np.empty(envs.size)
        for k, e in enumerate(envs):
            rng = self.rngs[e]
            alt_init[k] = rng.integers(c.alt_min, c.alt_max)
            self.target_alt[e] = alt_init[k] + rng.integers(-c.target_alt_dif, c.target_alt_dif)
        self.final_altitude[envs] = 0.0
        self.sim.create(envs, 0, RWY_LAT, RWY_LON, 0.0, alt_init, AC_SPD, **typed(self.ownship_types(envs)))
        self.sim.set_autopilot(envs, 0, swvnav=False)

    def ownship_types(self, envs: NDArray[np.int64]) -> list[str]:
        """The ownship's aircraft type in each reset episode (the A320 here; tasks with a type option draw it)."""
        return [DEFAULT_TYPES[0]] * envs.size

    # --- action -------------------------------------------------------------------------------
    def apply_action(self, action: Array) -> None:
        """Vertical speed 12.5 a m/s: the reference's direct ``selalt``/``selvs`` writes (:func:`vertical_speed_targets`)."""
        selalt, selvs = np.empty(self.n_envs), np.empty(self.n_envs)
        a = np.ascontiguousarray(action, dtype=np.float64)
        vertical_speed_targets(self.all_envs, self.ownship, a, self.sim.alt, self.config.hold_altitude_at_zero, selalt, selvs)
        self.sim.set_autopilot(self.all_envs, 0, selalt=selalt, selvs=selvs)

    # --- measure --------------------------------------------------------------------------------
    def runway_distance(self, envs: NDArray[np.int64] | slice | None = None) -> Array:
        """Km left to the runway along the 200 km leg, of episodes ``envs`` (all when None)."""
        ids = self.all_envs[slice(None) if envs is None else envs]
        return self.measure(ids).runway_km

    def measure(self, envs: NDArray[np.int64] | None = None) -> DescentMeasurement:
        """Altitude, vertical speed and runway distance of episodes ``envs`` (all when None; :func:`descent_measure`)."""
        ids = self.all_envs if envs is None else np.asarray(envs, dtype=np.int64)
        s = self.sim
        p = ids.size
        alt, vs, runway_km, goal = np.empty(p), np.empty(p), np.empty(p), np.empty(p, bool)
        descent_measure(ids, self.ownship[ids], s.lat, s.lon, s.alt, s.vs, self.config.runway_distance_km, alt, vs, runway_km, goal)
        shape = (p, s.max_aircraft)
        return DescentMeasurement(
            envs=ids,
            separation_nm=np.full(shape, np.inf),
            los=np.zeros(shape, bool),
            drift_deg=None,
            goal_reached=goal,
            alt=alt,
            vs=vs,
            runway_km=runway_km,
        )

    # --- observation ----------------------------------------------------------------------------
    def observe(self, g: StepGeometry | None = None) -> dict[str, Array]:
        """Normalised altitude, vertical speed, target and runway distance of the rows ``g.envs`` (:func:`observation`)."""
        g = self.measure() if g is None else g
        assert isinstance(g, DescentMeasurement)
        return observation(g, self.target_alt)

    # --- reward and termination -----------------------------------------------------------------
    def reward(self, g: StepGeometry) -> tuple[Array, BoolArray, dict[str, Array]]:
        """Altitude tracking while flying, else the crash or runway term; records ``final_altitude`` (all episodes; :func:`descent_reward`)."""
        assert isinstance(g, DescentMeasurement)
        n = g.envs.size
        reward, terminated = np.empty(n), np.empty(n, bool)
        altitude, crash, runway = np.empty(n), np.empty(n), np.empty(n)
        descent_reward(g.envs, g.alt, g.runway_km, self.target_alt, self.final_altitude, reward, terminated, altitude, crash, runway)
        return reward, terminated, {"altitude": altitude, "crash": crash, "runway": runway}

    def episode_info(self) -> dict[str, Array]:
        """``total_reward`` and ``final_altitude``."""
        return {"total_reward": self.stats.total_reward.copy(), "final_altitude": self.final_altitude.copy()}


def observation(g: DescentMeasurement, target_alt: Array) -> dict[str, Array]:
    """The descent entries of rows ``g.envs`` from the measured values and the episodes' target altitudes [m].

    Elementwise scalings of the measurement: numpy arrays on the CPU, torch tensors in the device
    step (:mod:`bluesky_gym.environments.descent.device_step`), the same operations on both.
    """
    return {
        "altitude": ((g.alt - ALT_MEAN) / ALT_STD)[:, None],
        "vz": ((g.vs - VZ_MEAN) / VZ_STD)[:, None],
        "target_altitude": ((target_alt[g.envs] - ALT_MEAN) / ALT_STD)[:, None],
        "runway_distance": ((g.runway_km - RWY_DIS_MEAN) / RWY_DIS_STD)[:, None],
    }


# --- kernels: the task's rules, run by the CPU task and launched by the device step ------------------
@jit_inline
def _vertical_speed(a: float, alt: float, hold: bool) -> tuple[float, float]:
    """Selected altitude [m] and vertical speed [m/s] of the action ``a``, the ownship at altitude ``alt`` [m].

    v = 12.5 a m/s; the selected altitude is the climb target for v >= 0, else 0 m; with ``hold``
    (``-v1``'s ``hold_altitude_at_zero``) |v| <= 0.1 m/s selects the current altitude instead:
    BlueSky replaces such a vertical speed by its default 7.62 m/s towards the selected altitude.
    """
    v = a * ACTION_2_MS
    selalt = CLIMB_TARGET if v >= 0 else 0.0
    if hold and abs(v) <= VS_SELECT_EPS:
        selalt = alt
    return selalt, v


@jit
def vertical_speed_targets(envs: IntArray, own: IntArray, action: Array, alt: Array, hold: bool, selalt_out: Array, selvs_out: Array) -> None:
    """The selected altitude and vertical speed of the clipped ``action`` (p, 1) of each row (:func:`_vertical_speed`).

    Row ``r``: ownship slot ``own[r]`` of episode ``envs[r]``; ``alt`` (n, m) [m].
    """
    for r in grid_range(envs.shape[0]):
        e = envs[r]
        o = own[r]
        selalt_out[r], selvs_out[r] = _vertical_speed(action[r, 0], alt[e, o], hold)


@jit
def command_vertical_speed(envs: IntArray, own: IntArray, action: Array, alt: Array, hold: bool, selalt: Array, selvs: Array) -> None:
    """:func:`vertical_speed_targets` written into the autopilot's ``selalt``/``selvs`` (n, m), as :meth:`DescentTask.apply_action` does.

    The device step (:mod:`bluesky_gym.environments.descent.device_step`) launches it on the
    simulator's device state.
    """
    for r in grid_range(envs.shape[0]):
        e = envs[r]
        o = own[r]
        selalt[e, o], selvs[e, o] = _vertical_speed(action[r, 0], alt[e, o], hold)


@jit_inline
def _runway_km(lat: float, lon: float, runway_distance_km: float) -> float:
    """Km left to the runway: ``runway_distance_km`` minus the kwik distance from the start point (RWY_LAT, RWY_LON)."""
    return runway_distance_km - kwikdist_scalar(RWY_LAT, RWY_LON, lat, lon) * NM2KM


@jit_inline
def _measure_row(
    r: int,
    e: int,
    o: int,
    lat: Array,
    lon: Array,
    alt: Array,
    vs: Array,
    runway_distance_km: float,
    alt_out: Array,
    vs_out: Array,
    runway_out: Array,
    goal_out: BoolArray,
) -> None:
    """Row ``r`` of :func:`descent_measure`: ownship slot ``o`` of episode ``e``."""
    alt_out[r] = alt[e, o]
    vs_out[r] = vs[e, o]
    rk = _runway_km(lat[e, o], lon[e, o], runway_distance_km)
    runway_out[r] = rk
    goal_out[r] = rk <= 0


@jit
def descent_measure(
    envs: IntArray,
    own: IntArray,
    lat: Array,
    lon: Array,
    alt: Array,
    vs: Array,
    runway_distance_km: float,
    alt_out: Array,
    vs_out: Array,
    runway_out: Array,
    goal_out: BoolArray,
) -> None:
    """Altitude [m], vertical speed [m/s], km left to the runway and runway reached of ownship slot ``own[r]`` of episode ``envs[r]``."""
    for r in grid_range(envs.shape[0]):
        _measure_row(r, envs[r], own[r], lat, lon, alt, vs, runway_distance_km, alt_out, vs_out, runway_out, goal_out)


@jit_inline
def _descent_reward(alt: float, runway_km: float, target_alt: float, final_altitude: float) -> tuple[float, bool, float, float, float, float]:
    """One episode's descent step: reward, terminated, its components (altitude, crash, runway) and the new final altitude.

    Flying on (runway ahead and alt > 0): -(5/3000) |target - alt|; else crashed (alt <= 0):
    -100, the final altitude -100; else at the runway: -(50/3000) alt, the final altitude alt.
    The episode terminates when crashed or at the runway; each component is 0 where its case does
    not hold.
    """
    flying = runway_km > 0 and alt > 0
    crashed = not flying and alt <= 0
    at_runway = not flying and not crashed and runway_km <= 0
    altitude = abs(target_alt - alt) * ALT_DIF_REWARD_SCALE if flying else 0.0
    crash = CRASH_PENALTY if crashed else 0.0
    runway = alt * RWY_ALT_DIF_REWARD_SCALE if at_runway else 0.0
    if crashed:
        final_altitude = CRASH_FINAL_ALTITUDE
    elif at_runway:
        final_altitude = alt
    reward = altitude if flying else (crash if crashed else runway)
    return reward, crashed or at_runway, altitude, crash, runway, final_altitude


@jit
def descent_reward(
    envs: IntArray,
    alt: Array,
    runway_km: Array,
    target_alt: Array,
    final_altitude: Array,
    reward_out: Array,
    terminated_out: BoolArray,
    altitude_out: Array,
    crash_out: Array,
    runway_out: Array,
) -> None:
    """:func:`_descent_reward` of rows (episode ``envs[r]``) from the measured ``alt``/``runway_km`` (p,), ``final_altitude`` (n,) updated."""
    for r in grid_range(envs.shape[0]):
        e = envs[r]
        reward_out[r], terminated_out[r], altitude_out[r], crash_out[r], runway_out[r], final_altitude[e] = _descent_reward(
            alt[r], runway_km[r], target_alt[e], final_altitude[e]
        )
