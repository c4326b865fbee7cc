"""The batched task: scenario generation, action mapping, observation, reward and KPIs.

A task runs ``n_envs`` episodes of one air-traffic problem on one physics backend (the native
:class:`~bluesky_gym.core.Simulator`, or the real BlueSky through the same interface). It is pure
numpy: the Gymnasium and PettingZoo classes are thin shells around it.

A concrete task supplies four parts, in the spirit of a generator/dynamics/observation/reward
pipeline:

* :meth:`Task.generate` creates the scenario of the episodes being reset, drawing only from their
  own generators;
* :meth:`Task.apply_action` maps a batch of normalised actions to autopilot commands;
* :meth:`Task.observe` builds the observation dict from the simulator state;
* :meth:`Task.evaluate` returns reward, termination and named reward components.

The base class runs the physics sub-steps, the time limit, episode counters and KPIs.
"""

from __future__ import annotations

import abc
import dataclasses
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar, Protocol

import numpy as np
from numpy.typing import NDArray

from bluesky_gym.core import Simulator
from bluesky_gym.tasks.geometry import ref_kwikdist, ref_kwikqdrdist

Array = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


@dataclass(frozen=True)
class BoxSpec:
    """A numpy description of a Box space (converted to ``gymnasium.spaces.Box`` by the shells)."""

    shape: tuple[int, ...]
    low: float = -np.inf
    high: float = np.inf


@dataclass(frozen=True)
class TaskConfig:
    """Base of every task's frozen configuration (the paper's "boundary conditions")."""

    def replace(self, **changes: Any) -> TaskConfig:
        """A copy with ``changes`` applied, validated."""
        unknown = set(changes) - {f.name for f in dataclasses.fields(self)}
        if unknown:
            valid = ", ".join(sorted(f.name for f in dataclasses.fields(self)))
            raise TypeError(f"unknown option(s) {sorted(unknown)} for {type(self).__name__}; valid options: {valid}")
        new = dataclasses.replace(self, **changes)
        new.validate()
        return new

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first invalid field."""


def check_int(name: str, value: Any, low: int, high: int | None = None) -> None:
    """Validate an integer option in [low, high]."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ValueError(f"{name} must be an integer, got {value!r}")
    if value < low or (high is not None and value > high):
        rng = f"[{low}, {high}]" if high is not None else f">= {low}"
        raise ValueError(f"{name} must be in {rng}, got {value}")


def check_range(name: str, value: Any, low: float, high: float | None = None, *, strict_low: bool = False) -> None:
    """Validate a finite real option."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) or not np.isfinite(value):
        raise ValueError(f"{name} must be a finite number, got {value!r}")
    if (value <= low if strict_low else value < low) or (high is not None and value > high):
        raise ValueError(f"{name} must be {'>' if strict_low else '>='} {low}{f' and <= {high}' if high is not None else ''}, got {value}")


def check_pair(name: str, value: Any) -> tuple[float, float]:
    """Validate a (low, high) pair option of finite numbers."""
    if isinstance(value, (str, bytes)) or not isinstance(value, Sequence) or len(value) != 2:
        raise ValueError(f"{name} must be a (low, high) pair, got {value!r}")
    for v in value:
        check_range(name, v, -np.inf)
    return float(value[0]), float(value[1])


def wrap180(x: Array) -> Array:
    """The reference's single wrap: x > 180 -> x - 360; x < -180 -> x + 360 (once only)."""
    return np.where(x > 180, x - 360, np.where(x < -180, x + 360, x))


@dataclass
class EpisodeStats:
    """Per-episode accumulators shaped (n_envs,) (reset per episode)."""

    n_envs: int
    steps: NDArray[np.int64] = field(init=False)  # env steps taken
    total_reward: Array = field(init=False)
    los_count: NDArray[np.int64] = field(init=False)  # new losses of separation (pair events)
    los_steps: NDArray[np.int64] = field(init=False)  # env steps with the ownship in LoS
    min_separation: Array = field(init=False)  # NM, smallest ownship-intruder distance seen
    drift_sum: Array = field(init=False)  # deg, sum of |drift| over steps
    drift_n: NDArray[np.int64] = field(init=False)
    time_to_goal: Array = field(init=False)  # s, NaN until the goal is reached
    in_los: NDArray[np.bool_] = field(init=False)  # (n_envs, max_aircraft) pairs with the ownship

    def __post_init__(self) -> None:
        n = self.n_envs
        self.steps = np.zeros(n, np.int64)
        self.total_reward = np.zeros(n)
        self.los_count = np.zeros(n, np.int64)
        self.los_steps = np.zeros(n, np.int64)
        self.min_separation = np.full(n, np.inf)
        self.drift_sum = np.zeros(n)
        self.drift_n = np.zeros(n, np.int64)
        self.time_to_goal = np.full(n, np.nan)
        self.in_los = np.zeros((n, 1), bool)

    def clear(self, envs: NDArray[np.int64], max_aircraft: int) -> None:
        """Start new episodes in ``envs``."""
        if self.in_los.shape[1] != max_aircraft:
            self.in_los = np.zeros((self.n_envs, max_aircraft), bool)
        self.steps[envs] = 0
        self.total_reward[envs] = 0.0
        self.los_count[envs] = 0
        self.los_steps[envs] = 0
        self.min_separation[envs] = np.inf
        self.drift_sum[envs] = 0.0
        self.drift_n[envs] = 0
        self.time_to_goal[envs] = np.nan
        self.in_los[envs] = False


class Effect(Protocol):
    """Something added to every new episode of a task, e.g. wind (see :meth:`Task.add_effect`)."""

    def on_reset(self, task: Task, envs: NDArray[np.int64]) -> None:
        """Act on episodes ``envs`` right after their scenarios were generated (before the first observation)."""


@dataclass(frozen=True)
class ObservationTerms:
    """Extra observation entries of a task, computed together (see :meth:`Task.add_observation_terms`).

    Attributes:
        spec: Entry name -> its Box (shape of one episode's value, declared bounds).
        value: ``value(task, envs) -> {name: (len(envs), *shape) float64}`` for every name of
            ``spec``, from the current state of episodes ``envs``.
    """

    spec: Mapping[str, BoxSpec]
    value: Callable[[Task, NDArray[np.int64]], Mapping[str, Array]]


@dataclass
class StepResult:
    """What one batched step returns (all arrays over the batch)."""

    observation: dict[str, Array]  # key -> (n_envs, *shape)
    reward: Array  # (n_envs,)
    terminated: BoolArray  # (n_envs,)
    truncated: BoolArray  # (n_envs,)
    info: dict[str, Array]  # key -> (n_envs,)


class Task(abc.ABC):
    """Base class of every batched task.

    Args:
        n_envs: Number of episodes simulated together.
        config: The task's configuration (a frozen dataclass); defaults are the paper's.
        backend: ``"native"`` (the batched core) or ``"bluesky"`` (the real simulator, one
            airspace per process), or a ready physics object with the :class:`Simulator` interface.
        max_episode_steps: Truncate episodes after this many decision steps (default: the
            reference's limit).
    """

    #: Gymnasium id of the single-agent environment.
    env_id: ClassVar[str]
    #: Simulation time step [s] and physics sub-steps per action (reference values).
    dt: ClassVar[float]
    action_frequency: ClassVar[int]
    max_episode_steps: ClassVar[int]
    config_class: ClassVar[type[TaskConfig]]
    #: Info keys of the reference implementation, always present.
    info_keys: ClassVar[tuple[str, ...]]
    #: Whether the task has a goal (for the success / time-to-goal KPIs).
    has_goal: ClassVar[bool] = True

    def __init__(
        self, n_envs: int = 1, config: TaskConfig | None = None, backend: str | Simulator = "native", max_episode_steps: int | None = None
    ) -> None:
        if isinstance(n_envs, bool) or not isinstance(n_envs, (int, np.integer)) or n_envs < 1:
            raise ValueError(f"n_envs must be a positive integer, got {n_envs!r}")
        self.n_envs = int(n_envs)
        if max_episode_steps is not None:
            check_int("max_episode_steps", max_episode_steps, 1)
        #: Decision steps after which an episode is truncated (the reference's limit by default).
        self.time_limit = int(max_episode_steps) if max_episode_steps is not None else self.max_episode_steps
        self.config = config if config is not None else self.config_class()
        if not isinstance(self.config, self.config_class):
            raise TypeError(f"config must be a {self.config_class.__name__}, got {type(self.config).__name__}")
        self.config.validate()
        if isinstance(backend, str):
            from bluesky_gym.backends import make_physics

            backend = make_physics(backend, type(self), self.n_envs, self.max_aircraft(), self.max_waypoints())
        self.sim = backend
        if self.sim.n_envs != self.n_envs:
            raise ValueError(f"physics backend has {self.sim.n_envs} airspaces, the task {self.n_envs}")
        #: Whether observation and reward geometry run compiled (:mod:`bluesky_gym.tasks.compiled`):
        #: always, the compiled kernels are the production path (plain Python without numba).
        self.compiled = True
        #: The compiled functions (the module :mod:`bluesky_gym.tasks.compiled`), or None.
        self.kernels: Any = None
        if self.compiled:
            from bluesky_gym.tasks import compiled

            self.kernels = compiled
        self.rngs: list[np.random.Generator] = [np.random.default_rng() for _ in range(self.n_envs)]
        self.stats = EpisodeStats(self.n_envs)
        self.all_envs = np.arange(self.n_envs)
        self.observation_spec = self.build_observation_spec()
        self.action_spec = self.build_action_spec()
        #: Per-episode effects (:meth:`add_effect`) and extra observation entries (:meth:`add_observation_terms`).
        self.effects: list[Effect] = []
        self.observation_terms: list[ObservationTerms] = []
        self.allocate()

    # --- what a task defines --------------------------------------------------------------------
    def allocate(self) -> None:  # noqa: B027 - optional hook
        """Allocate the task's own per-episode arrays (called once by ``__init__``)."""

    @abc.abstractmethod
    def max_aircraft(self) -> int:
        """Aircraft slots per airspace for this configuration."""

    def max_waypoints(self) -> int:
        """Route capacity per aircraft."""
        return 2

    @abc.abstractmethod
    def build_observation_spec(self) -> dict[str, BoxSpec]:
        """Observation keys, shapes and declared bounds (in the reference's key order)."""

    @abc.abstractmethod
    def build_action_spec(self) -> BoxSpec:
        """The action Box."""

    @abc.abstractmethod
    def generate(self, envs: NDArray[np.int64]) -> None:
        """Create the scenarios of the episodes ``envs`` (their airspaces are empty)."""

    @abc.abstractmethod
    def apply_action(self, action: Array) -> None:
        """Turn a batch of clipped actions (n_envs, dim) into autopilot commands."""

    @abc.abstractmethod
    def observe(self) -> dict[str, Array]:
        """Observation of every episode: key -> (n_envs, *shape), float64."""

    def observe_envs(self, envs: NDArray[np.int64]) -> dict[str, Array]:
        """Observation of episodes ``envs`` only: key -> (len(envs), *shape) (e.g. after resetting them).

        The same values as :meth:`observe` gives for those rows. By default it is that
        observation, indexed; tasks with a cheaper per-episode form override it.
        """
        return {k: v[envs] for k, v in self.observe().items()}

    @abc.abstractmethod
    def evaluate(self) -> tuple[Array, BoolArray, dict[str, Array]]:
        """Reward (n_envs,), termination (n_envs,) and named reward components, after a step."""

    def episode_info(self) -> dict[str, Array]:
        """The reference info keys, (n_envs,) each."""
        return {"total_reward": self.stats.total_reward.copy()}

    def ownship_separation(self) -> tuple[Array, BoolArray]:
        """Ownship-to-aircraft distances [NM] and LoS flags, (n_envs, max_aircraft) each.

        Slot 0 is the ownship. Tasks with traffic override this (default: no traffic).
        """
        n = self.sim.max_aircraft
        return np.full((self.n_envs, n), np.inf), np.zeros((self.n_envs, n), bool)

    def kwik_separation(self, intrusion_nm: float, vertical_m: float | None = None) -> tuple[Array, BoolArray]:
        """Reference kwik distance [NM] from the ownship (slot 0) to every other active aircraft.

        Args:
            intrusion_nm: Horizontal intrusion distance [NM].
            vertical_m: Vertical margin [m], or None for a purely horizontal intrusion test.

        Returns:
            Distances (inf for the ownship and empty slots) and intrusion flags, (n_envs, max_aircraft).
        """
        s = self.sim
        if self.compiled:
            dist = np.empty(s.lat.shape)
            los = np.empty(s.lat.shape, bool)
            self.kernels.kwik_separation(s.lat, s.lon, s.alt, s.active, intrusion_nm, np.nan if vertical_m is None else vertical_m, dist, los)
            return dist, los
        dist = ref_kwikdist(s.lat[:, :1], s.lon[:, :1], s.lat, s.lon)
        other = s.active.copy()
        other[:, 0] = False
        dist = np.where(other, dist, np.inf)
        los = other & (dist < intrusion_nm)
        if vertical_m is not None:
            los &= np.abs(s.alt[:, :1] - s.alt) < vertical_m
        return dist, los

    def drift_deg(self) -> Array | None:
        """(n_envs,) current |drift| [deg] to the goal, or None if the task has no heading goal."""
        return None

    def goal_reached(self) -> BoolArray:
        """(n_envs,) whether the episode's goal has been reached."""
        return np.zeros(self.n_envs, bool)

    def truncate(self) -> BoolArray:
        """(n_envs,) task-specific truncation after a step, OR-ed with the time limit (default: none).

        Called once per step, after :meth:`evaluate`; a terminated episode is never reported as
        truncated.
        """
        return np.zeros(self.n_envs, bool)

    # --- effects and extra observation terms -----------------------------------------------------
    def add_effect(self, effect: Effect) -> None:
        """Apply ``effect.on_reset(task, envs)`` to every new episode from the next reset on.

        An effect changes the episodes' setting (e.g. installs wind in ``task.sim.wind``); it runs
        right after :meth:`generate`, so aircraft are created without it and it acts from the first
        step on. There are no per-sub-step effects: the physics sub-steps of a decision step run in
        one :meth:`~bluesky_gym.core.Simulator.run` call.
        """
        if not callable(getattr(effect, "on_reset", None)):
            raise TypeError(f"an effect needs an on_reset(task, envs) method, got {type(effect).__name__}")
        self.effects.append(effect)

    def add_observation_terms(self, terms: ObservationTerms) -> None:
        """Add entries to the observation (and to :attr:`observation_spec`), after the task's own.

        Every observation the task gives from then on (:meth:`observation`, the step's, the final
        one of an ended episode) carries them.

        Raises:
            ValueError: If a name is already an observation key.
        """
        clash = sorted(set(terms.spec) & set(self.observation_spec))
        if clash:
            raise ValueError(f"observation already has the key(s) {clash}")
        self.observation_terms = [*self.observation_terms, terms]
        self.observation_spec = {**self.observation_spec, **terms.spec}

    def observation(self, envs: NDArray[np.int64] | None = None) -> dict[str, Array]:
        """The observation the environments return: :meth:`observe` (or :meth:`observe_envs`) and the extra terms.

        Args:
            envs: Episodes to observe (all when None); rows follow ``envs``.
        """
        obs = self.observe() if envs is None else self.observe_envs(envs)
        return self.with_observation_terms(obs, envs)

    def with_observation_terms(self, obs: dict[str, Array], envs: NDArray[np.int64] | None = None) -> dict[str, Array]:
        """``obs`` (the task's own entries for ``envs``, all when None) followed by the extra terms' current values."""
        if not self.observation_terms:
            return obs
        rows = self.all_envs if envs is None else np.asarray(envs, dtype=np.int64)
        obs = dict(obs)
        for terms in self.observation_terms:
            values = terms.value(self, rows)
            obs.update((name, values[name]) for name in terms.spec)
        return obs

    # --- the episode loop ------------------------------------------------------------------------
    def seed(self, envs: NDArray[np.int64], generators: list[np.random.Generator]) -> None:
        """Give episodes ``envs`` their own random generators."""
        for e, g in zip(envs, generators):
            self.rngs[int(e)] = g

    def reset(self, envs: NDArray[np.int64] | None = None) -> None:
        """Start new episodes in ``envs`` (all when None)."""
        envs = self.all_envs if envs is None else np.asarray(envs, dtype=np.int64)
        if envs.size == 0:
            return
        self.sim.reset_envs(envs)
        self.stats.clear(envs, self.sim.max_aircraft)
        self.generate(envs)
        for effect in self.effects:
            effect.on_reset(self, envs)
        self._track_separation(envs, count_steps=False)

    def clip_action(self, action: Any) -> Array:
        """Validate a batch of actions and clip it to the action space."""
        spec = self.action_spec
        try:
            a = np.asarray(action, dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"action must be numeric with shape {(self.n_envs, *spec.shape)}, got {action!r}") from exc
        if a.shape != (self.n_envs, *spec.shape):
            raise ValueError(f"action has shape {a.shape}, expected {(self.n_envs, *spec.shape)} for {self.env_id}")
        if not np.isfinite(a).all():
            raise ValueError(f"action contains NaN or infinite values: {a.tolist()}")
        return np.minimum(np.maximum(a, spec.low), spec.high)  # np.clip's result, for finite values

    def step(self, action: Any) -> StepResult:
        """Apply a batch of actions, run the physics sub-steps and evaluate every episode."""
        a = self.clip_action(action)
        self.apply_action(a)
        reward, terminated, components, obs = self.transition()
        obs = self.with_observation_terms(obs)
        self.stats.steps += 1
        self.stats.total_reward += reward
        self._track_separation(slice(None), count_steps=True)
        drift = self.drift_deg()
        if drift is not None:
            self.stats.drift_sum += drift
            self.stats.drift_n += 1
        reached = self.goal_reached() & np.isnan(self.stats.time_to_goal)
        if reached.any():
            self.stats.time_to_goal[reached] = self.stats.steps[reached] * self.dt * self.action_frequency
        truncated = ~terminated & ((self.stats.steps >= self.time_limit) | self.truncate())
        info = self.episode_info()
        info.update({f"reward_{k}": v for k, v in components.items()})
        done = terminated | truncated
        if done.any():
            info.update(self.kpis())
        return StepResult(obs, reward, terminated, truncated, info)

    def transition(self) -> tuple[Array, BoolArray, dict[str, Array], dict[str, Array]]:
        """Run ``action_frequency`` physics sub-steps, then evaluate.

        As in the reference, the observation is built before the reward is evaluated (reach
        flags updated by the reward therefore show in the next observation).

        Returns:
            Reward, termination, reward components and the observation.
        """
        self.sim.run(self.action_frequency)
        obs = self.observe()
        reward, terminated, components = self.evaluate()
        return reward, terminated, components, obs

    def _track_separation(self, envs: NDArray[np.int64] | slice, count_steps: bool) -> None:
        dist, los = self.ownship_separation()
        if not isinstance(envs, slice):
            dist, los = dist[envs], los[envs]
        st = self.stats
        st.min_separation[envs] = np.minimum(st.min_separation[envs], dist.min(axis=1))
        new = los & ~st.in_los[envs]
        st.los_count[envs] += new.sum(axis=1)
        if count_steps:
            st.los_steps[envs] += los.any(axis=1)
        st.in_los[envs] = los

    def kpis(self) -> dict[str, Array]:
        """Air-traffic KPIs of the current episodes, (n_envs,) each."""
        st = self.stats
        with np.errstate(invalid="ignore"):
            avg_drift = np.where(st.drift_n > 0, st.drift_sum / np.maximum(st.drift_n, 1), np.nan)
        reached = ~np.isnan(st.time_to_goal)
        out = {
            "kpi_los_count": st.los_count.astype(np.float64),
            "kpi_los_steps": st.los_steps.astype(np.float64),
            "kpi_min_separation_nm": st.min_separation.copy(),
            "kpi_mean_abs_drift_deg": avg_drift,
            "kpi_track_distance_km": self.sim.distflown[:, 0] / 1000.0,
            "kpi_episode_time_s": st.steps * self.dt * self.action_frequency,
        }
        if self.has_goal:
            out["kpi_success"] = reached.astype(np.float64)
            out["kpi_time_to_goal_s"] = st.time_to_goal.copy()
            out["kpi_extra_track_km"] = self.extra_track_km()
        return out

    def extra_track_km(self) -> Array:
        """(n_envs,) distance flown minus the direct distance from the start to the goal [km]."""
        return np.full(self.n_envs, np.nan)

    # --- helpers for subclasses -----------------------------------------------------------------
    def kwik_from_ownship(self, lat: Array, lon: Array) -> tuple[Array, Array]:
        """Reference kwik (qdr deg in [0, 360), dist NM) from each ownship (slot 0) to points (n_envs, k)."""
        return ref_kwikqdrdist(self.sim.lat[:, :1], self.sim.lon[:, :1], lat, lon)

    @classmethod
    def make_config(cls, options: Mapping[str, Any] | None = None) -> TaskConfig:
        """The default configuration with ``options`` applied and validated."""
        return cls.config_class().replace(**dict(options or {}))
