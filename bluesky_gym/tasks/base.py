"""The batched task: scenario generation, action mapping, an explicit step, observation, reward and KPIs.

A task runs ``n_envs`` episodes of one air-traffic problem on one physics backend (the native
:class:`~bluesky_gym.core.Simulator`, or the real BlueSky through the same interface). The
Gymnasium and PettingZoo classes are thin shells around it.

The step, written out (:meth:`Task.step`)::

    a = clip_action(action)            # validate and clip the batch of actions
    apply_action(a)                    # autopilot commands (physics commands only)
    advance()                          # action_frequency physics sub-steps (Simulator.run)
    g = measure()                      # this step's geometry, computed once
    obs = observe(g)                   # observation dict, key -> (rows, *shape)
    reward, terminated, parts = reward(g)
    record(g, reward)                  # episode statistics / KPIs from g
    truncated = truncation(terminated, g)   # the time limit or truncate(g), unless terminated; info

A concrete task supplies:

* :meth:`Task.generate`: the scenarios of the episodes being reset, drawn from their own generators;
* :meth:`Task.apply_action`: a batch of clipped actions -> autopilot commands;
* :meth:`Task.measure`: a :class:`StepGeometry` (usually a frozen subclass with the task's own
  quantities: intruder distances and bearings, drift, goal distance...). ``measure(envs)`` gives the
  rows ``envs`` only (``g.envs``). The common part the base reads for the KPIs is
  ``separation_nm`` and ``los`` (rows, max_aircraft), ``drift_deg`` (rows,) or None, and
  ``goal_reached`` (rows,). The default, for tasks without traffic, has no separation, no drift
  and no goal;
* :meth:`Task.observe` ``(g)``: the observation of the rows ``g.envs``, from ``g`` and the state;
* :meth:`Task.reward` ``(g)``: reward, termination and named reward components (all episodes).
  It may update the task's episode state (reach flags, counters); nothing it needs travels from
  ``observe`` through an attribute;
* optionally :meth:`Task.truncate` ``(g)``, :meth:`Task.episode_info`, :meth:`Task.extra_track_km`.

Without an argument, ``observe()`` measures first (e.g. after a reset). The base supplies
:meth:`Task.advance` (the physics sub-steps in one ``Physics.run`` call) and
:meth:`Task.record` (the statistics, from ``g`` only: the separation is never computed a second
time).

Tasks with traffic (SectorCR, Merge, HorizontalCR) write measure, observation and reward as
module functions of rows (episode ``envs[r]``, ownship slot ``own[r]``), e.g.
``sector_cr.measure(sim, task, envs, own)``, ``sector_cr.observation(g)``,
``sector_cr.reward(g)``: the single-agent task passes slot 0 of its episodes
(:attr:`Task.ownship`), the multi-agent tasks every active agent slot. Their geometry comes from
the compiled kernels of :mod:`bluesky_gym.tasks.compiled`, the only implementation.
"""

from __future__ import annotations

import abc
import dataclasses
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar, Protocol

import numpy as np
from numpy.typing import NDArray

from bluesky_gym.core.aircraft import DEFAULT_TYPE, check_types
from bluesky_gym.core.physics import Physics
from bluesky_gym.core.wind import WIND_KEYS, Wind, wind_at_ownship
from bluesky_gym.tasks import compiled
from bluesky_gym.tasks.geometry import ref_kwikqdrdist
from bluesky_gym.tasks.geometry import wrap180 as wrap180  # re-exported for the tasks

Array = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
_EMPTY = np.empty(0)
#: The KPIs of every task, in the order :func:`~bluesky_gym.tasks.compiled.episode_kpis` writes them.
KPI_KEYS = (
    "kpi_los_count",
    "kpi_los_steps",
    "kpi_min_separation_nm",
    "kpi_mean_abs_drift_deg",
    "kpi_track_distance_km",
    "kpi_fuel_kg",
    "kpi_episode_time_s",
)


@dataclass(frozen=True)
class BoxSpec:
    """A numpy description of a Box space (converted to ``gymnasium.spaces.Box`` by the shells).

    ``low`` and ``high`` are one bound for every entry, or arrays of ``shape`` (a bound per entry).
    """

    shape: tuple[int, ...]
    low: float | Array = -np.inf
    high: float | Array = np.inf


@dataclass(frozen=True)
class TaskConfig:
    """Base of every task's frozen configuration (the paper's "boundary conditions").

    Attributes:
        float32_spaces: ``-v1``: float32 observation and action spaces with finite declared
            bounds, every observation entry clipped to its bound (``-v0``: float64, the
            reference's bounds, infinite for most entries).
        wind: Wind installed in every episode, and observed with ``observe``
            (:class:`~bluesky_gym.core.wind.Wind`, or a mapping of its fields); None: no wind.
    """

    float32_spaces: bool = False
    wind: Wind | None = None

    def __post_init__(self) -> None:
        # Aircraft-type mixes are stored hashable: a name -> (name,), a list -> tuple, a mapping
        # -> tuple of (name, weight) pairs (the order given is kept: it fixes the draws).
        for f in dataclasses.fields(self):
            if f.name in TYPE_MIX_OPTIONS:
                object.__setattr__(self, f.name, freeze_type_mix(getattr(self, f.name)))
            elif f.name == "wind":
                object.__setattr__(self, f.name, Wind.of(getattr(self, f.name)))
            elif f.type in ("bool", bool):
                # A switch (float32_spaces, the -v1 fixes): "no" or 0 would silently mean something else.
                value = getattr(self, f.name)
                if not isinstance(value, (bool, np.bool_)):
                    raise ValueError(f"{f.name} must be True or False, got {value!r}")
                object.__setattr__(self, f.name, bool(value))

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


def numeric_action(action: Any, expected: tuple[int, ...], what: str = "action") -> Array:
    """``action`` as a float64 array, refusing what is not real numbers.

    Strings, bytes, complex numbers, objects and ragged nestings are refused with a ``ValueError``
    naming the expected shape, instead of being converted (``'0.5'`` -> 0.5, the imaginary part
    dropped) or failing inside numpy.

    Args:
        action: The action as given.
        expected: The shape it should have (for the message).
        what: How the message calls the action (e.g. ``"action of aircraft_3"``).
    """
    try:
        raw = action if isinstance(action, np.ndarray) else np.asarray(action)
    except (TypeError, ValueError, OverflowError) as exc:
        raise ValueError(f"{what} must be an array of real numbers with shape {expected}, got {action!r}") from exc
    if raw.dtype.kind not in "biuf":
        raise ValueError(f"{what} must be an array of real numbers with shape {expected}, got {action!r} (dtype {raw.dtype})")
    return np.asarray(raw, dtype=np.float64)


def check_int(name: str, value: Any, low: int, high: int | None = None) -> None:
    """Validate an integer option in [low, high]."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ValueError(f"{name} must be an integer, got {value!r}")
    if not -(2**63) <= value < 2**63:
        raise ValueError(f"{name} must fit in a 64-bit integer, got {value}")
    if value < low or (high is not None and value > high):
        rng = f"[{low}, {high}]" if high is not None else f">= {low}"
        raise ValueError(f"{name} must be in {rng}, got {value}")


def check_range(name: str, value: Any, low: float, high: float | None = None, *, strict_low: bool = False) -> None:
    """Validate a finite real option."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) or not np.isfinite(value):
        raise ValueError(f"{name} must be a finite number, got {value!r}")
    if (value <= low if strict_low else value < low) or (high is not None and value > high):
        raise ValueError(f"{name} must be {'>' if strict_low else '>='} {low}{f' and <= {high}' if high is not None else ''}, got {value}")


#: An aircraft-type mix option: type names drawn with equal probability, or {type name: weight}.
TypeMix = tuple[str, ...] | Mapping[str, float]
#: The mix of the paper's environments: A320 only (no random draw is made for a one-type mix).
DEFAULT_TYPES: tuple[str, ...] = (DEFAULT_TYPE,)


#: The options that hold an aircraft-type mix.
TYPE_MIX_OPTIONS = ("intruder_types", "ownship_types")


def freeze_type_mix(value: Any) -> Any:
    """A type-mix option in its stored, hashable form (other values unchanged, for validation to report)."""
    if isinstance(value, str):
        return (value,)
    if isinstance(value, Mapping):
        return tuple(value.items())
    if isinstance(value, list):
        return tuple(value)
    return value


def check_type_mix(name: str, value: Any, rotorcraft: bool = False) -> tuple[tuple[str, ...], Array]:
    """Validate an aircraft-type mix option and give its types (upper case) and their probabilities.

    Args:
        name: The option's name (for the message).
        value: A type name, a sequence of names (equally likely) or a mapping name -> weight
            (weights >= 0 with a positive sum), also as a sequence of (name, weight) pairs. Only
            types BlueSky flies with their own data (:func:`bluesky_gym.core.aircraft.supported_types`)
            are accepted.
        rotorcraft: Whether the task accepts BlueSky's rotorcraft too
            (:data:`bluesky_gym.core.aircraft.ROTORCRAFT_TYPES`).

    Raises:
        ValueError: Naming the option and the bad value (an unknown type lists the supported ones).
    """
    value = freeze_type_mix(value)
    pairs = isinstance(value, tuple) and bool(value) and all(isinstance(v, tuple) and len(v) == 2 for v in value)
    if pairs:
        names, weights = [v[0] for v in value], [v[1] for v in value]
        for w in weights:
            check_range(f"{name} weight", w, 0.0)
    elif isinstance(value, tuple):
        names, weights = list(value), [1.0] * len(value)
    else:
        raise ValueError(f"{name} must be a type name, a sequence of type names or a mapping type -> weight, got {value!r}")
    if not names:
        raise ValueError(f"{name} must name at least one aircraft type, got {value!r}")
    plain = all(isinstance(t, str) for t in names)
    upper = (
        tuple(t.upper() for t in names)
        if plain and [t.upper() for t in names] == [DEFAULT_TYPE]
        else check_types(names, what=f"{name}: aircraft type", rotorcraft=rotorcraft)
    )
    if len(set(upper)) != len(upper):
        raise ValueError(f"{name} names a type twice: {value!r}")
    total = float(sum(weights))
    if not total > 0:
        raise ValueError(f"{name} weights must have a positive sum, got {value!r}")
    return upper, np.asarray(weights, dtype=np.float64) / total


def draw_types(rng: np.random.Generator, mix: tuple[tuple[str, ...], Array], n: int) -> list[str]:
    """``n`` aircraft types drawn from a checked mix with the episode's generator (no draw for one type)."""
    names, p = mix
    if len(names) == 1:
        return [names[0]] * n
    return [names[i] for i in rng.choice(len(names), size=n, p=p)]


def typed(types: list[str]) -> dict[str, list[str]]:
    """``{"actype": types}`` for ``Physics.create``/``creconfs``, or nothing when every type is the default (the A320 path)."""
    return {} if all(t == DEFAULT_TYPE for t in types) else {"actype": types}


def check_pair(name: str, value: Any) -> tuple[float, float]:
    """Validate a (low, high) pair option of finite numbers."""
    if isinstance(value, (str, bytes)) or not isinstance(value, Sequence) or len(value) != 2:
        raise ValueError(f"{name} must be a (low, high) pair, got {value!r}")
    for v in value:
        check_range(name, v, -np.inf)
    return float(value[0]), float(value[1])


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


#: The ``wind_u`` and ``wind_v`` observation entries of a task with observed wind.
WIND_OBSERVATION = ObservationTerms(spec={k: BoxSpec((1,)) for k in WIND_KEYS}, value=wind_at_ownship)


@dataclass(frozen=True)
class StepGeometry:
    """One step's geometry of rows ``envs``, computed once by :meth:`Task.measure`.

    Tasks subclass it (frozen) with their own quantities. The base reads the common part below
    for the episode statistics and KPIs. Arrays are not copied: treat them as read-only.

    Attributes:
        envs: (rows,) the episodes the rows belong to.
        separation_nm: (rows, max_aircraft) distance from the ownship to every aircraft slot [NM]
            (inf for the ownship itself and empty slots).
        los: (rows, max_aircraft) loss-of-separation flags of those pairs.
        drift_deg: (rows,) signed drift to the current goal [deg], or None without a heading goal.
        goal_reached: (rows,) whether the episode's goal is reached after this step.
    """

    envs: NDArray[np.int64]
    separation_nm: Array
    los: BoolArray
    drift_deg: Array | None
    goal_reached: BoolArray


def flat_bounds(box: BoxSpec) -> tuple[Array, Array]:
    """A Box's (low, high) as :func:`~bluesky_gym.tasks.compiled.clip_to_bounds` takes them: one float64 value per element, flat."""
    low, high = (np.array(np.broadcast_to(np.asarray(b, dtype=np.float64), box.shape)).reshape(-1) for b in (box.low, box.high))
    return low, high


def clipped(values: Array, low: Array, high: Array) -> Array:
    """``values`` (rows, *shape) clipped to a Box's :func:`flat_bounds`: ``np.minimum(np.maximum(values, low), high)``, a new float64 array.

    The kernel :func:`~bluesky_gym.tasks.compiled.clip_to_bounds`, with one row's elements as its columns.
    """
    out = np.empty(np.shape(values))
    if out.size:
        compiled.clip_to_bounds(values.reshape(-1, low.size), low, high, out.reshape(-1, low.size))
    return out


def kwik_separation(
    sim: Physics, envs: NDArray[np.int64], own: NDArray[np.int64], intrusion_nm: float, vertical_m: float | None = None
) -> tuple[Array, BoolArray]:
    """Reference kwik distance [NM] from ownship slots to every other active aircraft, and the intrusion flags.

    Args:
        sim: The physics.
        envs: (p,) episode of each row.
        own: (p,) ownship slot of each row (0 for the single-agent tasks).
        intrusion_nm: Horizontal intrusion distance [NM].
        vertical_m: Vertical margin [m], or None for a purely horizontal intrusion test.

    Returns:
        Distances (inf for the ownship and empty slots) and intrusion flags, (p, max_aircraft).
    """
    shape = (len(envs), sim.lat.shape[1])
    dist = np.empty(shape)
    los = np.empty(shape, bool)
    compiled.kwik_separation(envs, own, sim.lat, sim.lon, sim.alt, sim.active, intrusion_nm, np.nan if vertical_m is None else vertical_m, dist, los)
    return dist, los


def command_heading_and_speed(sim: Physics, envs: NDArray[np.int64], own: NDArray[np.int64], action: Array, d_heading: float, d_speed: float) -> None:
    """SectorCR's and Merge's action of rows (episode ``envs[r]``, ownship slot ``own[r]``), ``action`` (rows, 2).

    HDG wrap180(hdg + d_heading a0); SPD (CAS + d_speed a1) * 1.94384 kt: the reference adds the
    step to CAS in m/s, converts the sum to knots and stacks SPD, which BlueSky converts back with
    1 kt = 0.514444 m/s.
    """
    heading_new, speed = np.empty(len(envs)), np.empty(len(envs))
    compiled.heading_speed_targets(envs, own, np.ascontiguousarray(action), sim.hdg, sim.cas, d_heading, d_speed, heading_new, speed)
    sim.cmd_heading(envs, own, heading_new)
    sim.cmd_speed(envs, own, speed)


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

    #: Gymnasium id of the single-agent environment of the task's default configuration (its ``-v0`` id).
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
    #: The name of the task's (n_envs,) array holding each episode's nominal route [km] (set when the
    #: episode is generated), from which :meth:`extra_track_km` measures the extra track; None: no route.
    route_km_array: ClassVar[str | None] = None
    #: Reset the episodes that ended at the end of :meth:`step` (the step's result keeps their
    #: final observation; :meth:`observation` then gives the first of the new episodes). The
    #: Gymnasium shells reset themselves; the shared-policy SB3 adapter sets it.
    autoreset: bool = False

    def __init__(
        self, n_envs: int = 1, config: TaskConfig | None = None, backend: str | Physics = "native", max_episode_steps: int | None = None
    ) -> None:
        if isinstance(n_envs, bool) or not isinstance(n_envs, (int, np.integer)) or n_envs < 1:
            raise ValueError(f"n_envs must be a positive integer, got {n_envs!r}")
        #: The id this task runs as, named by its messages and pictures: :attr:`env_id`, or the id
        #: its environment was made with (a ``-v1`` id is this task configured; the shells set it).
        self.id: str = type(self).env_id
        self.n_envs = int(n_envs)
        if max_episode_steps is not None:
            check_int("max_episode_steps", max_episode_steps, 1)
        self.config = config if config is not None else self.config_class()
        if not isinstance(self.config, self.config_class):
            raise TypeError(f"config must be a {self.config_class.__name__}, got {type(self.config).__name__}")
        self.config.validate()
        #: Decision steps after which an episode is truncated (the configuration's limit by default).
        self.time_limit = int(max_episode_steps) if max_episode_steps is not None else self.episode_limit(self.config)
        self.sim: Physics
        if isinstance(backend, str):
            from bluesky_gym.backends import make_physics

            self.sim = make_physics(backend, self.dt, self.n_envs, self.max_aircraft(), self.max_waypoints())
        else:
            self.sim = backend
        if self.sim.n_envs != self.n_envs:
            raise ValueError(f"physics backend has {self.sim.n_envs} airspaces, the task {self.n_envs}")
        self.rngs: list[np.random.Generator] = [np.random.default_rng() for _ in range(self.n_envs)]
        self.stats = EpisodeStats(self.n_envs)
        self.all_envs = np.arange(self.n_envs)
        #: Ownship slot of every episode (0), for the functions written for sets of ownship slots.
        self.ownship = np.zeros(self.n_envs, np.int64)
        self.observation_spec = self.build_observation_spec()
        self.action_spec = self.build_action_spec()
        #: Per-episode effects (:meth:`add_effect`) and extra observation entries (:meth:`add_observation_terms`).
        self.effects: list[Effect] = []
        self.observation_terms: list[ObservationTerms] = []
        self._observation_bounds: tuple[dict[str, BoxSpec], dict[str, tuple[Array, Array]]] | None = None
        self._action_bounds: tuple[BoxSpec, tuple[Array, Array]] | None = None
        self.allocate()
        if self.config.wind is not None:
            self.add_wind(self.config.wind)

    def __repr__(self) -> str:
        """The task as it was made: its id, batch size, physics, time limit and its frozen configuration, every field.

        For example ``HorizontalCRTask(id='HorizontalCREnv-v0', n_envs=1, physics=Simulator,
        time_limit=300, config=HorizontalCRConfig(float32_spaces=False, num_intruders=5, ...))``.
        """
        return (
            f"{type(self).__name__}(id={self.id!r}, n_envs={self.n_envs}, physics={type(self.sim).__name__}, "
            f"time_limit={self.time_limit}, config={self.config!r})"
        )

    def wrap_physics(self, wrapper: Callable[[Physics], Physics]) -> Physics:
        """Put a wrapper around the physics, e.g. a :class:`~bluesky_gym.scenarios.export.ScenarioRecorder`.

        Call it before the first reset; every later physics call of the task goes through the wrapper.

        Args:
            wrapper: Called with the current physics, returns the physics to use from now on.

        Returns:
            The new physics.
        """
        wrapped = wrapper(self.sim)
        if wrapped.n_envs != self.n_envs:
            raise ValueError(f"the wrapped physics has {wrapped.n_envs} airspaces, the task {self.n_envs}")
        self.sim = wrapped
        return wrapped

    # --- what a task defines --------------------------------------------------------------------
    @classmethod
    def episode_limit(cls, config: TaskConfig) -> int:
        """Default episode limit in decision steps for ``config`` (the reference's :attr:`max_episode_steps`)."""
        return int(cls.max_episode_steps)

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

    def measure(self, envs: NDArray[np.int64] | None = None) -> StepGeometry:
        """This step's geometry of episodes ``envs`` (all when None); the default: no traffic, no drift, no goal."""
        envs = self.all_envs if envs is None else np.asarray(envs, dtype=np.int64)
        shape = (len(envs), self.sim.max_aircraft)
        return StepGeometry(envs, np.full(shape, np.inf), np.zeros(shape, bool), None, np.zeros(len(envs), bool))

    @abc.abstractmethod
    def observe(self, g: StepGeometry | None = None) -> dict[str, Array]:
        """Observation of the rows ``g.envs``: key -> (rows, *shape), float64 (``g`` None: measure all now)."""

    def observe_envs(self, envs: NDArray[np.int64]) -> dict[str, Array]:
        """Observation of episodes ``envs`` only: key -> (len(envs), *shape) (e.g. after resetting them)."""
        return self.observe(self.measure(np.asarray(envs, dtype=np.int64)))

    @abc.abstractmethod
    def reward(self, g: StepGeometry) -> tuple[Array, BoolArray, dict[str, Array]]:
        """Reward (n_envs,), termination (n_envs,) and named reward components from a full-batch geometry."""

    def episode_info(self) -> dict[str, Array]:
        """The reference info keys, (n_envs,) each."""
        return {"total_reward": self.stats.total_reward.copy()}

    def ownship_separation(self) -> tuple[Array, BoolArray]:
        """Ownship-to-aircraft distances [NM] and LoS flags now, (n_envs, max_aircraft) each (for pictures and tests).

        The step itself reads them from its :class:`StepGeometry`.
        """
        g = self.measure()
        return g.separation_nm, g.los

    def truncate(self, g: StepGeometry) -> BoolArray:
        """(n_envs,) task-specific truncation after a step, OR-ed with the time limit (default: none).

        Called once per step, after :meth:`reward`; a terminated episode is never reported as
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

    def add_wind(self, wind: Wind) -> None:
        """Install ``wind`` in every new episode (an effect) and, with ``wind.observe``, observe it.

        The ``wind`` option does this when the task is built.

        Raises:
            ValueError: ``wind.observe`` and the task observes a wind already.
        """
        if wind.observe and set(WIND_KEYS) & set(self.observation_spec):
            raise ValueError("the environment already observes the wind (wind_u, wind_v); observe it only once")
        self.add_effect(wind)
        if wind.observe:
            self.add_observation_terms(WIND_OBSERVATION)

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
        """``obs`` (the task's own entries for ``envs``, all when None) followed by the extra terms' current values.

        With ``config.float32_spaces`` every entry is clipped to its declared bound (:meth:`bounded`).
        """
        if self.observation_terms:
            rows = self.all_envs if envs is None else np.asarray(envs, dtype=np.int64)
            obs = dict(obs)
            for terms in self.observation_terms:
                values = terms.value(self, rows)
                obs.update((name, values[name]) for name in terms.spec)
        return self.bounded(obs) if self.config.float32_spaces else obs

    def bounded(self, obs: dict[str, Array]) -> dict[str, Array]:
        """``obs`` with every entry clipped to the finite bounds of :attr:`observation_spec` (the ``-v1`` contract).

        The bounds are chosen to hold for the task's reachable states; the clip keeps the
        contract for the rare state beyond them (an aircraft far outside the scenario's area).
        Each entry is clipped by the kernel :func:`~bluesky_gym.tasks.compiled.clip_to_bounds`
        (the values of one row as its columns, against :meth:`observation_bounds`).
        """
        bounds = self.observation_bounds()
        return {k: clipped(v, *bounds[k]) for k, v in obs.items()}

    def observation_bounds(self) -> dict[str, tuple[Array, Array]]:
        """The declared bounds of every observation entry (:func:`flat_bounds`), computed again when :attr:`observation_spec` changes."""
        spec = self.observation_spec
        if self._observation_bounds is None or self._observation_bounds[0] is not spec:
            self._observation_bounds = (spec, {k: flat_bounds(box) for k, box in spec.items()})
        return self._observation_bounds[1]

    def action_bounds(self) -> tuple[Array, Array]:
        """The bounds of the action space (:func:`flat_bounds`), computed again when :attr:`action_spec` changes."""
        if self._action_bounds is None or self._action_bounds[0] is not self.action_spec:
            self._action_bounds = (self.action_spec, flat_bounds(self.action_spec))
        return self._action_bounds[1]

    @property
    def space_dtype(self) -> type[np.floating[Any]]:
        """The dtype of the observation and action spaces: float32 with ``config.float32_spaces`` (``-v1``), else float64."""
        return np.float32 if self.config.float32_spaces else np.float64

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
        self.record(self.measure(envs), None)

    def clip_action(self, action: Any) -> Array:
        """Validate a batch of actions and clip it to the action space."""
        spec = self.action_spec
        a = numeric_action(action, (self.n_envs, *spec.shape))
        if a.shape != (self.n_envs, *spec.shape):
            raise ValueError(f"action has shape {a.shape}, expected {(self.n_envs, *spec.shape)} for {self.id}")
        if not np.isfinite(a).all():
            raise ValueError(f"action contains NaN or infinite values: {a.tolist()}")
        return clipped(a, *self.action_bounds())  # np.clip's result, for finite values

    def step(self, action: Any) -> Any:
        """Apply a batch of actions, run the physics sub-steps and evaluate the controlled rows.

        This is the one step pipeline of every agent layout. Its rows are (episode, aircraft
        slot) pairs: slot 0 of every episode here (:attr:`ownship`); every acting aircraft in the
        multi-agent layout (:class:`~bluesky_gym.multiagent.base.MultiAgentTask`, which supplies
        the same hooks over its rows). As in the reference, the observation is built before the
        reward is evaluated (reach flags updated by the reward therefore show in the next
        observation). With :attr:`autoreset`, the episodes that ended are reset at the end of the
        step (:meth:`end_step`).
        """
        a = self.clip_action(action)
        self.apply_action(a)
        self.advance()
        g = self.measure()
        obs = self.with_observation_terms(self.observe(g))
        reward, terminated, components = self.reward(g)
        self.record(g, reward)
        truncated = self.truncation(terminated, g)
        ended = self.end_step(terminated, truncated)
        info = self.episode_info()
        info.update({f"reward_{k}": v for k, v in components.items()})
        if ended.any():
            info.update(self.kpis())
        result = self.step_result(obs, reward, terminated, truncated, ended, info)
        if self.autoreset and ended.any():
            self.reset(np.flatnonzero(ended))
        return result

    def truncation(self, terminated: BoolArray, g: StepGeometry) -> BoolArray:
        """(n_envs,) episodes truncated by this step: at the time limit or cut by :meth:`truncate`, unless terminated.

        The kernel :func:`~bluesky_gym.tasks.compiled.truncation`, after this step's :meth:`record`
        (the time limit counts the step).
        """
        out = np.empty(self.n_envs, bool)
        compiled.truncation(self.stats.steps, self.time_limit, terminated, self.truncate(g), out)
        return out

    def end_step(self, terminated: BoolArray, truncated: BoolArray) -> BoolArray:
        """Close the step (the multi-agent layout removes the agents that left); return the (n_envs,) episodes that ended."""
        return terminated | truncated

    def step_result(
        self, obs: dict[str, Array], reward: Array, terminated: BoolArray, truncated: BoolArray, ended: BoolArray, info: dict[str, Array]
    ) -> Any:
        """What :meth:`step` returns: a :class:`StepResult` here."""
        return StepResult(obs, reward, terminated, truncated, info)

    def advance(self) -> None:
        """Run the ``action_frequency`` physics sub-steps in one :meth:`~bluesky_gym.core.physics.Physics.run` call."""
        self.sim.run(self.action_frequency)

    def record(self, g: StepGeometry, reward: Array | None) -> None:
        """Update the episode statistics of rows ``g.envs`` from the geometry (``reward`` None: at a reset, no step)."""
        st = self.stats
        stepped = reward is not None
        compiled.record_step(
            g.envs,
            g.separation_nm,
            g.los,
            stepped,
            reward if stepped else _EMPTY,
            _EMPTY if g.drift_deg is None else g.drift_deg,
            g.goal_reached,
            self.dt,
            self.action_frequency,
            st.in_los,
            st.min_separation,
            st.los_count,
            st.los_steps,
            st.steps,
            st.total_reward,
            st.drift_sum,
            st.drift_n,
            st.time_to_goal,
        )

    def kpis(self) -> dict[str, Array]:
        """Air-traffic KPIs of the current episodes, (n_envs,) each.

        The common ones (:data:`KPI_KEYS`) come from the kernel :func:`~bluesky_gym.tasks.compiled.episode_kpis`;
        a task with a goal adds ``kpi_success``, ``kpi_time_to_goal_s`` and ``kpi_extra_track_km``.
        """
        st = self.stats
        out = {key: np.empty(self.n_envs) for key in KPI_KEYS}
        compiled.episode_kpis(
            st.steps,
            st.los_count,
            st.los_steps,
            st.min_separation,
            st.drift_sum,
            st.drift_n,
            self.sim.distflown,
            self.sim.fuelburn,
            self.dt,
            self.action_frequency,
            *out.values(),
        )
        if self.has_goal:
            success, time_to_goal = np.empty(self.n_envs), np.empty(self.n_envs)
            compiled.goal_kpis(st.time_to_goal, success, time_to_goal)
            out.update({"kpi_success": success, "kpi_time_to_goal_s": time_to_goal, "kpi_extra_track_km": self.extra_track_km()})
        return out

    def extra_track_km(self) -> Array:
        """(n_envs,) the ownship's distance flown beyond its episode's nominal route [km]; NaN for a task without one.

        The kernel :func:`~bluesky_gym.tasks.compiled.extra_track` with the task's array named by
        :attr:`route_km_array`.
        """
        if self.route_km_array is None:
            return np.full(self.n_envs, np.nan)
        out = np.empty(self.n_envs)
        compiled.extra_track(self.sim.distflown, getattr(self, self.route_km_array), out)
        return out

    # --- helpers for subclasses -----------------------------------------------------------------
    def kwik_from_ownship(self, lat: Array, lon: Array) -> tuple[Array, Array]:
        """Reference kwik (qdr deg in [0, 360), dist NM) from each ownship (slot 0) to points (n_envs, k)."""
        return ref_kwikqdrdist(self.sim.lat[:, :1], self.sim.lon[:, :1], lat, lon)

    @classmethod
    def make_config(cls, options: Mapping[str, Any] | None = None) -> TaskConfig:
        """The default configuration with ``options`` applied and validated."""
        return cls.config_class().replace(**dict(options or {}))
