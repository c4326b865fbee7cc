"""Gymnasium shells around a batched task: a single environment and a native vector environment.

The single environment *is* the batched task with one episode; there is no second copy of the
physics or of the MDP. Both shells only convert between numpy batches and Gymnasium's API.

The task owns the time limit: it truncates an episode after ``max_episode_steps`` decision steps
(``terminated`` wins over ``truncated`` on the same step), computes the KPIs of that last step,
and the shell refuses a step after the end. The limit is part of the MDP (a ``-v1`` reward can
count the steps left), so it is an ordinary constructor argument: ``max_episode_steps`` (as
``gym.make_vec``, PettingZoo and direct construction pass it) or its synonym ``time_limit``, which
``gym.make`` passes on (``gym.make`` keeps its own ``max_episode_steps`` for Gymnasium's
``TimeLimit`` wrapper and never tells the environment; see :func:`time_limit_of`). The ids are
registered without that wrapper, and ``env.spec.max_episode_steps`` reports the task's limit.
"""

from __future__ import annotations

import dataclasses
import tracemalloc
from collections.abc import Mapping
from types import TracebackType
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.envs.registration import EnvSpec
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from bluesky_gym.envs.device import TensorIO, check_device
from bluesky_gym.envs.registry import device_step_class, scene_builder
from bluesky_gym.tasks.base import BoxSpec, StepResult, Task, check_int, numeric_action

RENDER_MODES = ["rgb_array", "human"]
RENDER_FPS = 30


def _box(spec: BoxSpec, dtype: type[np.floating[Any]] = np.float64) -> spaces.Box:
    # bounds per entry in the space's dtype (Gymnasium warns when float64 bounds are cast to float32)
    low, high = (np.asarray(b, dtype=dtype) if isinstance(b, np.ndarray) else b for b in (spec.low, spec.high))
    return spaces.Box(low=low, high=high, shape=spec.shape, dtype=dtype)


def observation_space(task: Task) -> spaces.Dict:
    """The single-episode observation space of a task (float32 for a ``-v1`` configuration)."""
    return spaces.Dict({k: _box(v, task.space_dtype) for k, v in task.observation_spec.items()})


def _typed(task: Task, obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """``obs`` in the dtype of the task's observation space (a copy for float32, the arrays themselves for float64)."""
    dtype = task.space_dtype
    return obs if dtype is np.float64 else {k: v.astype(dtype) for k, v in obs.items()}


def _split_kwargs(task_class: type[Task], kwargs: dict[str, Any]) -> Any:
    return task_class.make_config(kwargs)


def _check_render_mode(render_mode: str | None) -> None:
    if render_mode is not None and render_mode not in RENDER_MODES:
        raise ValueError(f"render_mode must be one of {RENDER_MODES} or None, got {render_mode!r}")


def check_reset_options(options: Any, make: str) -> None:
    """Refuse ``reset`` options: the environments take none (scenario options go to ``make``).

    Args:
        options: ``reset``'s ``options`` argument.
        make: The call that takes scenario options, for the message (``"gym.make"``).

    Raises:
        ValueError: ``options`` is neither None nor a dict, or a non-empty dict.
    """
    if options is None:
        return
    if not isinstance(options, Mapping):
        raise ValueError(f"reset options must be a dict or None, got {type(options).__name__} {options!r}")
    if options:
        raise ValueError(f"reset options are not supported; got {sorted(map(str, options))} (pass scenario options to {make})")


def _is_seed(value: Any) -> bool:
    return isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_)) and bool(value >= 0)


def episode_seeds(seed: Any, num_envs: int) -> list[int | None]:
    """The seed of each episode of a batched ``reset(seed=...)``.

    Args:
        seed: None (no seeds), a non-negative integer ``s`` (episode ``i`` gets ``s + i``) or a
            sequence of ``num_envs`` non-negative integers or None.
        num_envs: Number of episodes.

    Raises:
        ValueError: naming what is not a seed, or the number of seeds given.
    """
    if seed is None:
        return [None] * num_envs
    if _is_seed(seed):
        return [int(seed) + i for i in range(num_envs)]
    if not isinstance(seed, (list, tuple, np.ndarray)) or (isinstance(seed, np.ndarray) and seed.ndim != 1):
        raise ValueError(f"seed must be None, a non-negative integer or a list of {num_envs} seeds (integers or None), got {seed!r}")
    seeds = list(seed)
    if len(seeds) != num_envs:
        raise ValueError(f"got {len(seeds)} seeds for {num_envs} environments")
    for i, s in enumerate(seeds):
        if s is not None and not _is_seed(s):
            raise ValueError(f"seed[{i}] must be a non-negative integer or None, got {s!r}")
    return [None if s is None else int(s) for s in seeds]


def _bytes_per_episode(task_class: type[Task], config: Any) -> float:
    """Memory [bytes] one more episode of ``task_class`` takes at construction, from two small batches traced by :mod:`tracemalloc`."""
    task_class(1, config)  # load what every batch shares (compiled code, tables) before measuring
    sizes = []
    for n in (1, 17):
        started = not tracemalloc.is_tracing()
        if started:
            tracemalloc.start()
        before = tracemalloc.get_traced_memory()[0]
        task = task_class(n, config)
        sizes.append(tracemalloc.get_traced_memory()[0] - before)
        del task
        if started:
            tracemalloc.stop()
    return max(sizes[1] - sizes[0], 0) / 16


def _size(n_bytes: float) -> str:
    for unit, factor in (("PiB", 2**50), ("TiB", 2**40), ("GiB", 2**30), ("MiB", 2**20), ("KiB", 2**10)):
        if n_bytes >= factor:
            return f"{n_bytes / factor:.3g} {unit}"
    return f"{n_bytes:.0f} B"


def batch_memory_error(env_id: str, task_class: type[Task], config: Any, num_envs: int, exc: MemoryError) -> MemoryError:
    """The ``MemoryError`` of a batch that does not fit in memory, saying how much it would take.

    Args:
        env_id: The id, named first in the message.
        task_class: The environment's task.
        config: Its configuration.
        num_envs: The batch size asked for.
        exc: The error of the allocation that failed (numpy's names one array).
    """
    per_episode = _bytes_per_episode(task_class, config)
    return MemoryError(
        f"{env_id}: num_envs={num_envs} needs about {_size(per_episode * num_envs)} of memory ({_size(per_episode)} per episode) "
        f"to be built, more than this machine could allocate ({exc}); use fewer episodes per batch"
    )


def device_step_for(task: Task, io: TensorIO) -> Any:
    """The device step of ``task`` (its registry row's ``device_step``), or None where its step runs on the host (physics on the device)."""
    cls = device_step_class(type(task))
    if cls is None or not cls.supports(task):
        return None
    return cls(task, io)


def time_limit_of(max_episode_steps: int | None, time_limit: int | None) -> int | None:
    """The time limit an environment constructor gives its task: either argument, or None (the task's default).

    ``time_limit`` is the spelling for ``gym.make``: Gymnasium's ``make`` keeps an argument named
    ``max_episode_steps`` for its ``TimeLimit`` wrapper, which truncates from outside without telling
    the environment (the task then keeps its own limit, its KPIs do not come on the wrapper's last
    step, and a ``-v1`` reward counting the steps left counts them to the task's limit). So
    ``gym.make(id, time_limit=N)`` sets the environment's own limit, as ``max_episode_steps=N`` does
    for ``gym.make_vec``, PettingZoo and a directly constructed environment.

    Args:
        max_episode_steps: The constructor's ``max_episode_steps`` (None: not given).
        time_limit: The constructor's ``time_limit`` (None: not given).

    Raises:
        ValueError: Both are given and differ.
    """
    if max_episode_steps is not None and time_limit is not None and max_episode_steps != time_limit:
        raise ValueError(f"max_episode_steps={max_episode_steps!r} and time_limit={time_limit!r} are the same limit; give one")
    return time_limit if time_limit is not None else max_episode_steps


def made_as(env_id: str | None, task_class: type[Task]) -> str:
    """The id an environment is made as: its ``env_id`` argument, else its task's own id.

    Registration passes ``env_id`` to the environments of an id that configures another id's task
    (a ``-v1``), so that errors of the constructor already name it; Gymnasium sets the
    environment's ``spec`` (and with it the id) only after the constructor has returned.

    Raises:
        ValueError: ``env_id`` is not a string.
    """
    if env_id is None:
        return task_class.env_id
    if not isinstance(env_id, str):
        raise ValueError(f"env_id must be an environment id (a string), got {env_id!r}")
    return env_id


def _renderer_of(task: Any, render_mode: str, fps: float) -> Any:
    """The renderer of a shell's task: its environment's scene, titled with the id the user made (render is imported lazily)."""
    from bluesky_gym.render import make_renderer

    return make_renderer(task, render_mode, fps, scene=scene_builder(task.env_id), title=task.id)


class ErrorsNameTheId:
    """Context in which a ``ValueError``, ``TypeError``, ``RuntimeError`` or Gymnasium error names the id the environment was made with.

    A ``-v1`` id (or any id registered with another configuration of a task) shares its task and
    configuration classes with the task's own id, whose messages would otherwise be all the user
    sees; its messages start with ``"<id>: "`` unless they name the id already. The messages of
    the task's own id (the paper's ``-v0``) are left as they are.

    Args:
        env_id: The id the environment was made with.
        own_id: The task's own id (:attr:`~bluesky_gym.tasks.base.Task.env_id`).
    """

    __slots__ = ("env_id", "own_id")

    def __init__(self, env_id: str, own_id: str) -> None:
        self.env_id, self.own_id = env_id, own_id

    def __enter__(self) -> None:
        """Enter the context."""

    def __exit__(self, kind: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None) -> None:
        """Name the id in the message of an error leaving the context (the error itself propagates)."""
        named = (ValueError, TypeError, RuntimeError, gym.error.Error)
        if isinstance(exc, named) and self.env_id != self.own_id and exc.args and isinstance(exc.args[0], str):
            if self.env_id not in exc.args[0]:
                exc.args = (f"{self.env_id}: {exc.args[0]}", *exc.args[1:])


class TaskSpecMixin:
    """``spec`` as Gymnasium sets it, with ``max_episode_steps`` the task's own limit."""

    task: Any
    _spec: EnvSpec | None = None

    @property
    def spec(self) -> EnvSpec | None:
        """Gymnasium's description of how this environment was made; ``max_episode_steps`` is the task's limit."""
        if self._spec is None:
            return None
        return dataclasses.replace(self._spec, max_episode_steps=int(self.task.time_limit))

    @spec.setter
    def spec(self, value: EnvSpec | None) -> None:
        self._spec = value
        if value is not None:
            self._run_as(value.id)

    def _run_as(self, env_id: str) -> None:
        """Called with the id of the spec Gymnasium sets once the environment is made (nothing to do by default)."""


class MadeIdMixin(TaskSpecMixin):
    """The task runs as the id the environment was made with: its messages, its pictures and the environment's errors name that id."""

    _errors: ErrorsNameTheId

    def _run_as(self, env_id: str) -> None:
        """Name ``env_id`` in the task's messages and pictures and in this environment's errors."""
        self.task.id = env_id
        self._errors.env_id = env_id


class BlueSkyEnv(MadeIdMixin, gym.Env):
    """Base of the single-episode environments (subclasses set ``task_class``).

    Args:
        render_mode: ``None``, ``"rgb_array"`` or ``"human"``.
        backend: ``"native"`` or ``"bluesky"``.
        max_episode_steps: Truncation limit in decision steps (default: the reference's).
        env_id: The id the environment is made as, named by its errors and pictures (registration
            passes it for a ``-v1`` id; default: the task's own id).
        time_limit: ``max_episode_steps`` under the name ``gym.make`` passes on (see
            :func:`time_limit_of`).
        **options: Scenario options of the task (see its config dataclass).
    """

    task_class: ClassVar[type[Task]]
    metadata: dict[str, Any] = {"render_modes": RENDER_MODES, "render_fps": RENDER_FPS}  # noqa: RUF012 - Gymnasium declares it an instance attribute

    def __init__(
        self,
        render_mode: str | None = None,
        backend: str = "native",
        max_episode_steps: int | None = None,
        env_id: str | None = None,
        time_limit: int | None = None,
        **options: Any,
    ) -> None:
        env_id = made_as(env_id, self.task_class)
        self._errors = ErrorsNameTheId(env_id, self.task_class.env_id)
        with self._errors:
            _check_render_mode(render_mode)
            self.render_mode = render_mode
            self.backend = backend
            limit = time_limit_of(max_episode_steps, time_limit)
            self.task = self.task_class(1, _split_kwargs(self.task_class, options), backend=backend, max_episode_steps=limit)
            self._observation_space = (self.task.observation_spec, observation_space(self.task))
            self.action_space = _box(self.task.action_spec, self.task.space_dtype)
            self._renderer: Any = None
            self._needs_reset = True
            self._reset_once = False
            self._last_reward = 0.0
            self._last_info: dict[str, Any] = {}
        self._run_as(env_id)

    @property
    def config(self) -> Any:
        """The task configuration (frozen dataclass)."""
        return self.task.config

    @property
    def observation_space(self) -> spaces.Dict:  # type: ignore[override]
        """The observation space: the task's observation, with any terms added to it (e.g. wind)."""
        spec, space = self._observation_space
        if spec is not self.task.observation_spec:
            self._observation_space = (self.task.observation_spec, observation_space(self.task))
            space = self._observation_space[1]
        return space

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """Start a new episode; ``seed`` seeds the episode generator (``self.np_random``)."""
        with self._errors:
            super().reset(seed=seed)
            check_reset_options(options, "gym.make")
            self.task.seed(np.array([0]), [self.np_random])
            self.task.reset()
            self._needs_reset = False
            self._reset_once = True
            self._last_reward = 0.0
            obs = {k: v[0].copy() for k, v in _typed(self.task, self.task.observation()).items()}
            info = {k: _scalar(v[0]) for k, v in self.task.episode_info().items()}
            self._last_info = info
            if self.render_mode == "human":
                self.render()
            return obs, info

    def step(self, action: Any) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]:
        """Advance one decision step. Out-of-range actions are clipped to the action space."""
        with self._errors:
            if self._needs_reset:
                raise RuntimeError("step() called before reset() or after the episode ended (terminated or truncated); call reset() first")
            a = numeric_action(action, self.task.action_spec.shape)
            if a.shape != self.action_space.shape:
                if a.size == int(np.prod(self.task.action_spec.shape)) and a.ndim <= 1:
                    a = a.reshape(self.action_space.shape)
                else:
                    raise ValueError(f"action has shape {a.shape}, expected {self.action_space.shape} for {self.task.id}")
            res = self.task.step(a[None])
            obs = {k: v[0].copy() for k, v in _typed(self.task, res.observation).items()}
            terminated, truncated = bool(res.terminated[0]), bool(res.truncated[0])
            info = {k: _scalar(v[0]) for k, v in res.info.items()}
            self._needs_reset = terminated or truncated
            self._last_reward = float(res.reward[0])
            self._last_info = info
            if self.render_mode == "human":
                self.render()
            return obs, float(res.reward[0]), terminated, truncated, info

    def render(self) -> np.ndarray | None:
        """Draw the current state: an RGB frame (``rgb_array``) or the window (``human``)."""
        with self._errors:
            if self.render_mode is None:
                gym.logger.warn("render() called without a render_mode; pass render_mode='rgb_array' or 'human' to gym.make")
                return None
            if not self._reset_once:
                raise RuntimeError("render() called before reset(): there is no state to draw yet; call reset() first")
            if self._renderer is None:
                self._renderer = _renderer_of(self.task, self.render_mode, self.metadata["render_fps"])
            frame: np.ndarray | None = self._renderer.render(0, reward=self._last_reward, info=self._last_info)
            return frame

    def close(self) -> None:
        """Release this environment's window (and its BlueSky backend, if any)."""
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        close = getattr(self.task.sim, "close", None)
        if close is not None:
            close()


def _scalar(v: Any) -> Any:
    if isinstance(v, np.generic):
        return v.item()
    return v


class BlueSkyVectorEnv(MadeIdMixin, VectorEnv):
    """Native batched environment: ``num_envs`` episodes stepped with array operations.

    Autoreset is ``SAME_STEP``: when an episode ends, the returned observation is the first of
    the next episode and the final observation and info are in ``info["final_obs"]`` and
    ``info["final_info"]`` (with masks ``info["_final_obs"]``, ``info["_final_info"]``).
    Episode ``i`` after ``reset(seed=s)`` is identical to a single environment reset with seed
    ``s + i``.

    With ``device="cuda"`` the physics runs on a CUDA GPU (:class:`~bluesky_gym.core.DeviceSimulator`)
    and the batches are torch tensors on it: observations, rewards, ``terminated``, ``truncated``
    and ``info["final_obs"]``; actions may be tensors on the device. The other info entries stay
    numpy arrays on the host. The task's own side (actions to commands, resets with their random
    draws, observation, reward) runs on the host as with ``device="cpu"``, so episode ``i`` draws
    the same scenarios as a single environment with seed ``s + i``; its physics agrees with the
    CPU's within the GPU's rounding (docs/backends.md). For a task whose
    registry row names a ``device_step`` (a :class:`~bluesky_gym.envs.device.DeviceStep`: every
    single-agent task, without wind) the whole step runs on the device instead, every info entry
    is a tensor there, and only the random draws (resets, DenseSectorCR's entering aircraft) and
    RealTrafficCR's recorded aircraft entering and leaving run on the host.

    Args:
        num_envs: Number of episodes simulated together.
        render_mode: ``None``, ``"rgb_array"`` (frame of ``render_env``, or a grid of the first
            ``render_grid`` episodes) or ``"human"``.
        render_env: Episode drawn by :meth:`render`.
        render_grid: If > 1, draw a grid of the first ``render_grid`` episodes instead.
        backend: ``"native"`` only (BlueSky has one simulator per process).
        max_episode_steps: Truncation limit in decision steps (default: the reference's).
        env_id: The id the environment is made as (see :class:`BlueSkyEnv`).
        device: ``"cpu"`` (numpy arrays) or ``"cuda"`` (the physics on a CUDA GPU, torch tensors on
            it; needs the ``gpu`` and ``train`` extras).
        time_limit: ``max_episode_steps`` under another name (see :func:`time_limit_of`).
        **options: Scenario options of the task.
    """

    task_class: ClassVar[type[Task]]
    metadata: dict[str, Any] = {  # noqa: RUF012 - Gymnasium declares it an instance attribute
        "render_modes": RENDER_MODES,
        "render_fps": RENDER_FPS,
        "autoreset_mode": AutoresetMode.SAME_STEP,
    }

    def __init__(
        self,
        num_envs: int = 1,
        render_mode: str | None = None,
        render_env: int = 0,
        render_grid: int = 1,
        backend: str = "native",
        max_episode_steps: int | None = None,
        env_id: str | None = None,
        device: str = "cpu",
        time_limit: int | None = None,
        **options: Any,
    ) -> None:
        env_id = made_as(env_id, self.task_class)
        self._errors = ErrorsNameTheId(env_id, self.task_class.env_id)
        with self._errors:
            _check_render_mode(render_mode)
            check_int("num_envs", num_envs, 1)
            self.device = check_device(device)
            self._io: TensorIO | None = None
            if self.device == "cuda":
                if backend != "native":
                    raise ValueError(f"device='cuda' runs the native core on the GPU; backend must be 'native', got {backend!r}")
                self._io, backend = TensorIO(), "cuda"
            check_int("render_env", render_env, 0)
            check_int("render_grid", render_grid, 1)
            self.num_envs = int(num_envs)
            self.autoreset_mode = AutoresetMode.SAME_STEP  # as Gymnasium's own vector envs say it (and in metadata)
            self.render_mode = render_mode
            self.render_env = int(render_env)
            self.render_grid = int(render_grid)
            limit = time_limit_of(max_episode_steps, time_limit)
            config = _split_kwargs(self.task_class, options)
            try:
                self.task = self.task_class(self.num_envs, config, backend=backend, max_episode_steps=limit)
            except MemoryError as exc:
                raise batch_memory_error(env_id, self.task_class, config, self.num_envs, exc) from exc
            if not 0 <= self.render_env < self.num_envs:
                raise ValueError(f"render_env must be in [0, {self.num_envs}), got {render_env}")
            single = observation_space(self.task)
            self._observation_spaces: tuple[dict[str, BoxSpec], spaces.Dict, gym.Space[Any]] = (
                self.task.observation_spec,
                single,
                batch_space(single, self.num_envs),
            )
            self.single_action_space = _box(self.task.action_spec, self.task.space_dtype)
            self.action_space = batch_space(self.single_action_space, self.num_envs)
            #: The task's step on the device (``device="cuda"``, where the task has one), else None.
            self._device_step = None if self._io is None else device_step_for(self.task, self._io)
            self._renderer: Any = None
            self._reset_once = False
            self._last_reward = np.zeros(self.num_envs)
            self._last_info: dict[str, Any] = {}
        self._run_as(env_id)

    @property
    def config(self) -> Any:
        """The task configuration (frozen dataclass)."""
        return self.task.config

    def _spaces(self) -> tuple[spaces.Dict, gym.Space[Any]]:
        spec, single, batched = self._observation_spaces
        if spec is not self.task.observation_spec:
            single = observation_space(self.task)
            batched = batch_space(single, self.num_envs)
            self._observation_spaces = (self.task.observation_spec, single, batched)
        return single, batched

    @property
    def single_observation_space(self) -> spaces.Dict:  # type: ignore[override]
        """One episode's observation space: the task's observation, with any terms added to it (e.g. wind)."""
        return self._spaces()[0]

    @property
    def observation_space(self) -> gym.Space[Any]:  # type: ignore[override]
        """The batched observation space."""
        return self._spaces()[1]

    def reset(self, *, seed: int | list[int | None] | None = None, options: dict[str, Any] | None = None) -> tuple[dict[str, Any], dict[str, Any]]:
        """Reset every episode. ``seed`` int s seeds episode i with s + i; a list seeds each (numpy arrays, or tensors with ``device="cuda"``)."""
        with self._errors:
            check_reset_options(options, "gym.make_vec")
            seeds = episode_seeds(seed, self.num_envs)
            gens = [seeding.np_random(s)[0] for s in seeds]
            self.task.seed(self.task.all_envs, gens)
            self._reset_once = True
            self._last_reward = np.zeros(self.num_envs)
            if self._device_step is not None:
                obs_d, info_d = self._device_step.reset()
                self._last_info = {}
                if self.render_mode is not None:
                    self._device_step.sync_host()
                if self.render_mode == "human":
                    self.render()
                return obs_d, info_d
            self.task.reset()
            info = self.task.episode_info()
            self._last_info = info
            if self.render_mode == "human":
                self.render()
            obs = _typed(self.task, self.task.observation())
            return (obs if self._io is None else self._io.upload_all(obs)), info

    def step(self, actions: Any) -> tuple[dict[str, Any], Any, Any, Any, dict[str, Any]]:
        """Step every episode; ended episodes are reset in the same call (SAME_STEP). numpy arrays, or tensors with ``device="cuda"``."""
        with self._errors:
            if not self._reset_once:
                raise RuntimeError("step() called before reset(); call reset() first")
            if self._device_step is not None:
                return self._step_on_device(actions)
            if self._io is not None:
                actions = self._io.to_host(actions)
            res: StepResult = self.task.step(actions)
            done = res.terminated | res.truncated
            info: dict[str, Any] = dict(res.info)
            for k in res.info:
                if k.startswith("kpi_"):
                    info[f"_{k}"] = done.copy()
            obs = _typed(self.task, res.observation)
            if done.any():
                ended = np.flatnonzero(done)
                final_obs = {k: v.copy() for k, v in obs.items()}
                final_info = {k: v.copy() for k, v in res.info.items()}
                self.task.reset(ended)
                new_obs = _typed(self.task, self.task.observation(ended))
                obs = {k: v.copy() for k, v in obs.items()}
                for k, v in obs.items():
                    v[ended] = new_obs[k]
                info["final_obs"] = final_obs
                info["_final_obs"] = done.copy()
                info["final_info"] = final_info
                info["_final_info"] = done.copy()
            self._last_reward = res.reward
            self._last_info = res.info
            if self.render_mode == "human":
                self.render()
            if self._io is not None:
                return self._on_device(obs, res, info)
            return obs, res.reward, res.terminated, res.truncated, info

    def _step_on_device(self, actions: Any) -> tuple[dict[str, Any], Any, Any, Any, dict[str, Any]]:
        """A step with the task on the device (:class:`~bluesky_gym.envs.device.DeviceStep`): tensors in, tensors out."""
        assert self._device_step is not None
        obs, reward, terminated, truncated, info, _ended = self._device_step.step(actions)
        if self.render_mode is not None:  # the pictures read the host (copies made for them only)
            self._device_step.sync_host()
            self._last_reward = reward.cpu().numpy()
            self._last_info = {k: v.cpu().numpy() for k, v in info.items() if not k.startswith(("final", "_final"))}
            if self.render_mode == "human":
                self.render()
        return obs, reward, terminated, truncated, info

    def _on_device(self, obs: dict[str, np.ndarray], res: StepResult, info: dict[str, Any]) -> tuple[dict[str, Any], Any, Any, Any, dict[str, Any]]:
        """A step's outputs as tensors on the device (``device="cuda"``): one upload per array."""
        io = self._io
        assert io is not None
        if "final_obs" in info:
            info["final_obs"] = io.upload_all(info["final_obs"])
        return io.upload_all(obs), io.upload(res.reward), io.upload(res.terminated), io.upload(res.truncated), info

    def state_tensors(self, *names: str) -> tuple[Any, ...]:
        """The simulator's state arrays ``names`` (``lat``, ``tas``, ..., ``active``) as tensors on the device, (num_envs, max_aircraft) each.

        Only with ``device="cuda"``. The tensors share the device memory of the simulator's state
        (no copy; the state first goes to the device if the host holds it, and the next step
        starts from there). They show the state of this moment: the next step or command
        leaves them behind.

        Raises:
            RuntimeError: The environment was made with ``device="cpu"``.
        """
        with self._errors:
            if self._io is None:
                raise RuntimeError("state_tensors() needs an environment made with device='cuda'")
            return tuple(self._io.tensor(a) for a in self.task.sim.device_arrays(*names))

    def render(self) -> np.ndarray | None:  # type: ignore[override]  # one frame, not Gymnasium's tuple of sub-environment frames
        """A frame of episode ``render_env`` (or a grid of the first ``render_grid`` episodes)."""
        with self._errors:
            if self.render_mode is None:
                gym.logger.warn("render() called without a render_mode")
                return None
            if not self._reset_once:
                raise RuntimeError("render() called before reset(): there is no state to draw yet; call reset() first")
            if self._renderer is None:
                self._renderer = _renderer_of(self.task, self.render_mode, self.metadata["render_fps"])
            frame: np.ndarray | None
            if self.render_grid > 1:
                frame = self._renderer.render_grid(min(self.render_grid, self.num_envs), rewards=self._last_reward, info=self._last_info)
            else:
                reward = float(self._last_reward[self.render_env])
                frame = self._renderer.render(self.render_env, reward=reward, info=_pick(self._last_info, self.render_env))
            return frame

    def close_extras(self, **kwargs: Any) -> None:
        """Release the window."""
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None


def _pick(info: dict[str, Any], i: int) -> dict[str, Any]:
    return {k: _scalar(v[i]) for k, v in info.items() if isinstance(v, np.ndarray) and v.ndim == 1}
