"""PettingZoo ``ParallelEnv`` shells: every aircraft is an agent.

Each environment is a :class:`~bluesky_gym.multiagent.base.MultiAgentTask` with one episode; the
shell only converts between the task's arrays and PettingZoo's per-agent dicts.

* ``possible_agents`` are ``"aircraft_0" .. "aircraft_{n-1}"``, one per aircraft slot of the
  scenario (SectorCR sizes its slots for the densest traffic its configuration allows, so most
  episodes use only some of them); ``agents`` are the aircraft of the current episode still flying.
* ``step(actions)`` takes a dict agent -> action. An agent of ``agents`` missing from the dict
  keeps its heading and speed (action 0); actions of agents that are not in ``agents`` are
  ignored; an unknown name raises ``KeyError``. An action that is not an array of real numbers
  of the agent's action shape (a string, a complex number, ``None``, another shape), or has NaN
  or infinite values, raises ``ValueError`` naming the agent; ``actions`` other than a dict
  raise ``TypeError``.
* An agent leaves ``agents`` in the step where it is terminated (goal reached) or truncated
  (SectorCR: it left the sector; every task: the time limit); the returned dicts hold exactly the
  agents that acted in that step (and, in a layout whose aircraft appear mid-episode, such as
  :mod:`~bluesky_gym.multiagent.real_traffic`, those that appeared, with their first observation).
* ``reset(seed=s)`` gives the episode of seed ``s`` (the single-agent scenario of that seed with
  every aircraft as an agent); ``reset()`` continues the environment's generator.
* ``state()`` is the global state for centralised training (see
  :meth:`~bluesky_gym.multiagent.base.MultiAgentTask.state`), ``state_space`` its Box.
* infos: per agent ``return``, ``intrusions`` and ``completed`` (exit / arrival); in the step
  that ends the episode, the agents of that step also get the episode's KPIs ``kpi_*`` (KPIs
  without a value, e.g. the time to complete when no agent completed, are left out).

PettingZoo is an optional dependency: ``pip install -e ".[multiagent]"``.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding

from bluesky_gym.envs.registry import multiagent_entry, resolve
from bluesky_gym.multiagent import make_task, require_pettingzoo
from bluesky_gym.multiagent.base import MultiAgentTask, agent_action, agent_actions
from bluesky_gym.multiagent.dense_sector_cr import DenseSectorCRMultiAgentTask
from bluesky_gym.multiagent.horizontal_cr import HorizontalCRMultiAgentTask
from bluesky_gym.multiagent.merge import MergeMultiAgentTask
from bluesky_gym.multiagent.render import agent_name
from bluesky_gym.multiagent.sector_cr import SectorCRMultiAgentTask
from bluesky_gym.tasks.base import BoxSpec

require_pettingzoo()  # a clear error naming the extra when PettingZoo is missing
from pettingzoo import ParallelEnv  # noqa: E402

RENDER_MODES = ["rgb_array", "human"]
RENDER_FPS = 30


def box(spec: BoxSpec, dtype: Any = np.float64) -> spaces.Box:
    """Return a ``Box`` (float64, or float32 for ``-v1``) from a task's :class:`~bluesky_gym.tasks.base.BoxSpec`."""
    low, high = (np.asarray(b, dtype=dtype) if isinstance(b, np.ndarray) else b for b in (spec.low, spec.high))  # bounds in the space's dtype
    return spaces.Box(low=low, high=high, shape=spec.shape, dtype=dtype)


def agent_observation_space(task: MultiAgentTask) -> spaces.Dict:
    """Return the observation space of one agent (in the task's space dtype)."""
    return spaces.Dict({k: box(v, task.space_dtype) for k, v in task.observation_spec.items()})


def state_box(task: MultiAgentTask) -> spaces.Box:
    """Return the Box of the global state: per aircraft slot, the task's state features (``base.STATE_FEATURES`` by default)."""
    return spaces.Box(-np.inf, np.inf, (task.state_size,), np.float64)


class BlueSkyParallelEnv(ParallelEnv):
    """Base of the multi-agent PettingZoo environments (subclasses set ``task_class``).

    Args:
        render_mode: ``None``, ``"rgb_array"`` or ``"human"``.
        max_episode_steps: Time limit in decision steps (default: the single-agent environment's).
        name: The environment name, ``_v0`` (default) or ``_v1`` (the configuration of the
            ``-v1`` contract: float32 spaces with finite bounds; :func:`parallel_env` passes it).
        **options: Scenario options of the single-agent task (see its config dataclass).

    """

    task_class: ClassVar[type[MultiAgentTask]]
    metadata: dict[str, Any] = {"render_modes": RENDER_MODES, "render_fps": RENDER_FPS, "is_parallelizable": True}  # noqa: RUF012 - per instance: the name (_v0 or _v1) is set by __init__
    #: Whether the infos of the step that ends the episode carry its KPIs ``kpi_*``.
    kpis_in_infos: ClassVar[bool] = True
    #: The task's per-agent infos shown in the agents' infos (None: all).
    agent_info_keys: ClassVar[tuple[str, ...] | None] = None

    def __init__(self, render_mode: str | None = None, max_episode_steps: int | None = None, name: str | None = None, **options: Any) -> None:
        modes = self.metadata["render_modes"]
        if render_mode is not None and render_mode not in modes:
            raise ValueError(f"render_mode must be one of {modes} or None, got {render_mode!r}")
        self.render_mode = render_mode
        name = self.task_class.name if name is None else name
        self.task = self.make_task(name, max_episode_steps, options)
        self.metadata = {**self.metadata, "name": name}
        self._dtype = self.task.space_dtype
        self.possible_agents: list[str] = self.all_agents()
        self.agents: list[str] = []
        self._build_spaces()
        self.state_space = state_box(self.task)
        self._np_random: np.random.Generator | None = None
        self._np_random_seed: int | None = None
        self._renderer: Any = None
        self._last_reward = 0.0
        self._last_info: dict[str, Any] = {}

    # --- what a layout changes ----------------------------------------------------------------------
    def make_task(self, name: str, max_episode_steps: int | None, options: dict[str, Any]) -> MultiAgentTask:
        """The task of environment ``name`` (one episode)."""
        if multiagent_entry(name).task_class() is not self.task_class:
            raise ValueError(f"{name} is not a form of {self.task_class.name}")
        task: MultiAgentTask = make_task(name, 1, max_episode_steps, **options)
        return task

    def all_agents(self) -> list[str]:
        """``possible_agents``: one name per aircraft slot, ``aircraft_k``."""
        names = [agent_name(k) for k in range(self.task.n_agents)]
        self.agent_name_mapping: dict[str, int] = {a: k for k, a in enumerate(names)}
        return names

    def _build_spaces(self) -> None:
        self._observation_spaces = {a: agent_observation_space(self.task) for a in self.possible_agents}
        self._action_spaces = {a: box(self.task.action_spec, self._dtype) for a in self.possible_agents}

    def agent_names(self, slots: np.ndarray) -> list[str]:
        """The names of the agents of aircraft ``slots`` (episode 0)."""
        return [self.possible_agents[k] for k in slots]

    def action_slot(self, agent: Any) -> int | None:
        """The aircraft slot whose action ``agent`` gives (``KeyError`` for an unknown name), or None to ignore it."""
        return self.agent_name_mapping[agent]

    def seed_episode(self, seed: int | None) -> None:
        """Give the next episode its generator (``seed``: a new one; else the environment's own, continued)."""
        if seed is not None or self._np_random is None:
            self._np_random, self._np_random_seed = seeding.np_random(seed)
        self.task.seed(np.array([0]), [self._np_random])

    # --- the PettingZoo API -------------------------------------------------------------------------
    def observation_space(self, agent: str) -> spaces.Dict:
        """Return the observation space of ``agent`` (the same object at every call)."""
        return self._observation_spaces[agent]

    def action_space(self, agent: str) -> spaces.Box:
        """Return the action space of ``agent`` (the same object at every call)."""
        return self._action_spaces[agent]

    @property
    def np_random(self) -> np.random.Generator:
        """The scenario generator (seeded by ``reset(seed=...)``)."""
        if self._np_random is None:
            self._np_random, self._np_random_seed = seeding.np_random()
        return self._np_random

    def reset(self, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[dict[str, Any], dict[str, dict[str, Any]]]:
        """Start a new episode; ``seed`` seeds the scenario generator. ``options`` are not used."""
        self.seed_episode(seed)
        self.task.reset()
        active = np.flatnonzero(self.task.sim.active[0])
        self.agents = self.agent_names(active)
        obs = self.task.observation()
        observations = {a: {key: v[0, k].astype(self._dtype) for key, v in obs.items()} for a, k in zip(self.agents, active, strict=True)}
        infos: dict[str, dict[str, Any]] = {a: {} for a in self.agents}
        self._last_reward = 0.0
        self._last_info = {k: v[0].item() for k, v in self.task.episode_info().items()}
        if self.render_mode == "human":
            self.render()
        return observations, infos

    def step(self, actions: dict[str, Any]) -> tuple[dict[str, Any], dict[str, float], dict[str, bool], dict[str, bool], dict[str, dict[str, Any]]]:
        """Advance every agent one decision step; report the agents that acted and those that appeared."""
        if not self.agents:
            raise RuntimeError("step() called without agents: call reset() first (the episode has ended or never started)")
        task = self.task
        joint = np.zeros((1, task.n_agents, *task.action_spec.shape))
        for agent, action in agent_actions(actions).items():
            k = self.action_slot(agent)
            if k is not None:
                joint[0, k] = agent_action(agent, action, task.action_spec.shape)
        res = task.step(joint)
        shown = res.acting[0] if res.appeared is None else res.acting[0] | res.appeared[0]
        slots = np.flatnonzero(shown)
        names = self.agent_names(slots)
        rows = list(zip(names, slots.tolist(), strict=True))
        observations = {a: {key: v[0, k].astype(self._dtype) for key, v in res.observation.items()} for a, k in rows}
        rewards = {a: float(res.reward[0, k]) for a, k in rows}
        terminations = {a: bool(res.terminated[0, k]) for a, k in rows}
        truncations = {a: bool(res.truncated[0, k]) for a, k in rows}
        informed = res.acting[0] if res.measured is None else res.measured[0]
        kpis = {}
        if res.episode_done[0] and self.kpis_in_infos:
            kpis = {key: float(v[0]) for key, v in res.info.items() if key.startswith("kpi_") and np.isfinite(v[0])}
        agent_info = res.agent_info if self.agent_info_keys is None else {k: res.agent_info[k] for k in self.agent_info_keys}
        infos: dict[str, dict[str, Any]] = {a: {} for a, _ in rows}
        for name, slot in rows:
            if informed[slot]:
                infos[name] = {key: v[0, slot].item() for key, v in agent_info.items()}
                infos[name].update(kpis)
        self.agents = [a for a in names if not (terminations[a] or truncations[a])]
        self._last_reward = float(res.reward[0].sum())
        self._last_info = {key: v[0].item() for key, v in res.info.items()}
        if self.render_mode == "human":
            self.render()
        return observations, rewards, terminations, truncations, infos

    def state(self) -> np.ndarray:
        """Return the global state of the episode (see :meth:`MultiAgentTask.state`)."""
        return self.task.state()[0].copy()

    def kpis(self) -> dict[str, float]:
        """Return the KPIs of the current episode so far."""
        return {k: float(v[0]) for k, v in self.task.kpis().items()}

    def render(self) -> np.ndarray | None:
        """Draw the current state: an RGB frame (``rgb_array``) or the window (``human``)."""
        if self.render_mode is None:
            return None
        if self._renderer is None:
            from bluesky_gym.multiagent.render import make_renderer

            self._renderer = make_renderer(self.task, self.render_mode, RENDER_FPS)
        return self._renderer.render(0, reward=self._last_reward, info=self._last_info)

    def close(self) -> None:
        """Close the window, if one was opened."""
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None


class SectorCRParallelEnv(BlueSkyParallelEnv):
    """Multi-agent SectorCR: every aircraft in the sector is an agent.

    See :class:`~bluesky_gym.multiagent.sector_cr.SectorCRMultiAgentTask` for the observation,
    action and reward of each agent. Scenario options are SectorCREnv-v0's (``ac_density_mode``, ...).
    """

    task_class = SectorCRMultiAgentTask
    metadata: dict[str, Any] = {**BlueSkyParallelEnv.metadata, "name": SectorCRMultiAgentTask.name}  # noqa: RUF012 - per instance: the name (_v0 or _v1) is set by __init__


class MergeParallelEnv(BlueSkyParallelEnv):
    """Multi-agent Merge: every arrival is an agent.

    See :class:`~bluesky_gym.multiagent.merge.MergeMultiAgentTask`. Scenario options are
    MergeEnv-v0's (``num_aircraft``, ...).
    """

    task_class = MergeMultiAgentTask
    metadata: dict[str, Any] = {**BlueSkyParallelEnv.metadata, "name": MergeMultiAgentTask.name}  # noqa: RUF012 - per instance: the name (_v0 or _v1) is set by __init__


class HorizontalCRParallelEnv(BlueSkyParallelEnv):
    """Multi-agent HorizontalCR: the ownship and its intruders are all agents.

    See :class:`~bluesky_gym.multiagent.horizontal_cr.HorizontalCRMultiAgentTask`. Scenario
    options are HorizontalCREnv-v0's (``num_intruders``, ...).
    """

    task_class = HorizontalCRMultiAgentTask
    metadata: dict[str, Any] = {**BlueSkyParallelEnv.metadata, "name": HorizontalCRMultiAgentTask.name}  # noqa: RUF012 - per instance: the name (_v0 or _v1) is set by __init__


class DenseSectorCRParallelEnv(BlueSkyParallelEnv):
    """Multi-agent DenseSectorCR: every aircraft in the sector is an agent, and agents keep entering.

    See :class:`~bluesky_gym.multiagent.dense_sector_cr.DenseSectorCRMultiAgentTask`. An aircraft
    that enters during a step appears in that step's dicts with its first observation (reward 0,
    neither terminated nor truncated, an empty info) and is in ``agents`` from then on. Scenario
    options are DenseSectorCREnv-v0's (``spawn_rate_start``, ...).
    """

    task_class = DenseSectorCRMultiAgentTask
    metadata: dict[str, Any] = {**BlueSkyParallelEnv.metadata, "name": DenseSectorCRMultiAgentTask.name}  # noqa: RUF012 - per instance: the name (_v0 or _v1) is set by __init__


def parallel_env(name: str, **kwargs: Any) -> BlueSkyParallelEnv:
    """Create a multi-agent environment by name (``"sector_cr_v0"``, ``"merge_v0"``, ``"horizontal_cr_v0"``, and their ``_v1``).

    Args:
        name: Environment name (the multi-agent names of the environment table).
        **kwargs: ``render_mode``, ``max_episode_steps`` and scenario options.

    """
    cls: type[BlueSkyParallelEnv] = resolve(multiagent_entry(name).parallel_env)
    return cls(name=name, **kwargs)
