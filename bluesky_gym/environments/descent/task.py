"""DescentEnv-v0: reach and hold a target altitude, then descend before the runway."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from bluesky_gym.core.units import NM2KM, VS_SELECT_EPS
from bluesky_gym.tasks.base import DEFAULT_TYPES, Array, BoolArray, BoxSpec, StepGeometry, Task, TaskConfig, check_int, check_range, typed
from bluesky_gym.tasks.geometry import ref_kwikdist

ALT_MEAN = 1500.0  # m
ALT_STD = 3000.0  # m
VZ_MEAN = 0.0  # m/s
VZ_STD = 5.0  # m/s
RWY_DIS_MEAN = 100.0  # km
RWY_DIS_STD = 200.0  # km
ACTION_2_MS = 12.5  # m/s of vertical speed per unit action
ALT_DIF_REWARD_SCALE = -5 / 3000  # per m off the target altitude
CRASH_PENALTY = -100.0
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
        """Vertical speed 12.5 a m/s: the reference's direct ``selalt``/``selvs`` writes."""
        v = action[:, 0] * ACTION_2_MS
        selalt = np.where(v >= 0, CLIMB_TARGET, 0.0)
        if self.config.hold_altitude_at_zero:
            # BlueSky replaces |selvs| <= 0.1 m/s by its default 7.62 m/s towards selalt: select
            # the current altitude instead, so that such an action holds it.
            selalt = np.where(np.abs(v) <= VS_SELECT_EPS, self.sim.alt[:, 0], selalt)
        self.sim.set_autopilot(self.all_envs, 0, selalt=selalt, selvs=v)

    # --- measure --------------------------------------------------------------------------------
    def runway_distance(self, envs: NDArray[np.int64] | slice | None = None) -> Array:
        """Km left to the runway along the 200 km leg, of episodes ``envs`` (all when None)."""
        rows = slice(None) if envs is None else envs
        d = ref_kwikdist(RWY_LAT, RWY_LON, self.sim.lat[rows, 0], self.sim.lon[rows, 0])
        return self.config.runway_distance_km - d * NM2KM

    def measure(self, envs: NDArray[np.int64] | None = None) -> DescentMeasurement:
        """Altitude, vertical speed and runway distance of episodes ``envs`` (all when None)."""
        ids = self.all_envs if envs is None else np.asarray(envs, dtype=np.int64)
        rows: NDArray[np.int64] | slice = slice(None) if envs is None else ids  # a slice: views, no copies
        s = self.sim
        runway_km = self.runway_distance(rows)
        shape = (ids.size, s.max_aircraft)
        return DescentMeasurement(
            envs=ids,
            separation_nm=np.full(shape, np.inf),
            los=np.zeros(shape, bool),
            drift_deg=None,
            goal_reached=runway_km <= 0,
            alt=s.alt[rows, 0],
            vs=s.vs[rows, 0],
            runway_km=runway_km,
        )

    # --- observation ----------------------------------------------------------------------------
    def observe(self, g: StepGeometry | None = None) -> dict[str, Array]:
        """Normalised altitude, vertical speed, target and runway distance of the rows ``g.envs``."""
        g = self.measure() if g is None else g
        assert isinstance(g, DescentMeasurement)
        return {
            "altitude": ((g.alt - ALT_MEAN) / ALT_STD)[:, None],
            "vz": ((g.vs - VZ_MEAN) / VZ_STD)[:, None],
            "target_altitude": ((self.target_alt[g.envs] - ALT_MEAN) / ALT_STD)[:, None],
            "runway_distance": ((g.runway_km - RWY_DIS_MEAN) / RWY_DIS_STD)[:, None],
        }

    # --- reward and termination -----------------------------------------------------------------
    def reward(self, g: StepGeometry) -> tuple[Array, BoolArray, dict[str, Array]]:
        """Altitude tracking while flying, else the crash or runway term; records ``final_altitude`` (all episodes)."""
        assert isinstance(g, DescentMeasurement)
        flying, crashed, at_runway = descent_outcome(g)
        altitude = np.where(flying, np.abs(self.target_alt - g.alt) * ALT_DIF_REWARD_SCALE, 0.0)
        crash = np.where(crashed, CRASH_PENALTY, 0.0)
        runway = np.where(at_runway, g.alt * RWY_ALT_DIF_REWARD_SCALE, 0.0)
        self.final_altitude = np.where(crashed, -100.0, np.where(at_runway, g.alt, self.final_altitude))
        reward = np.where(flying, altitude, np.where(crashed, crash, runway))
        return reward, crashed | at_runway, {"altitude": altitude, "crash": crash, "runway": runway}

    def episode_info(self) -> dict[str, Array]:
        """``total_reward`` and ``final_altitude``."""
        return {"total_reward": self.stats.total_reward.copy(), "final_altitude": self.final_altitude.copy()}

    def extra_track_km(self) -> Array:
        """Distance flown beyond the runway leg [km]."""
        return self.sim.distflown[:, 0] / 1000.0 - self.config.runway_distance_km


def descent_outcome(g: DescentMeasurement) -> tuple[BoolArray, BoolArray, BoolArray]:
    """(n_envs,) flags of a step, exactly one set per episode: flying on, crashed (alt <= 0), at the runway."""
    flying = (g.runway_km > 0) & (g.alt > 0)
    crashed = ~flying & (g.alt <= 0)
    return flying, crashed, ~flying & ~crashed & (g.runway_km <= 0)
