"""The centralised alternative: one Gymnasium agent controls every aircraft.

A centralised environment is a :class:`~bluesky_gym.multiagent.base.MultiAgentTask` with one
episode seen as a single-agent MDP:

* observation: ``Dict`` of
  ``local`` - ``Box((n_agents, D))``: row ``k`` is aircraft slot ``k``'s own observation (the
  multi-agent observation of agent ``k`` flattened in key order, ``D`` values), zeros for an empty
  slot; and ``state`` - ``Box((n_agents, F))``: the global state rows (``F`` features, see
  :data:`~bluesky_gym.multiagent.base.STATE_FEATURES`; the first is the slot's active flag);
* action: ``Box(-1, 1, (n_agents * d,))``, the joint action: entries ``k*d .. k*d + d - 1`` are
  aircraft slot ``k``'s action (as in the multi-agent environment); entries of empty slots are
  ignored;
* reward: the sum of the rewards of the aircraft that acted;
* ``terminated`` when every aircraft has left before the time limit, ``truncated`` at the time
  limit; info: ``total_reward`` (team return), ``agents_active``, ``agents_completed``,
  ``total_intrusions``, ``average_drift`` and at the end of the episode the KPIs ``kpi_*``.

The ids ``SectorCRCentralised-v0``, ``MergeCentralised-v0``, ``HorizontalCRCentralised-v0`` and
``DenseSectorCRCentralised-v0`` are registered by :func:`bluesky_gym.multiagent.register_envs`.
"""

from __future__ import annotations

from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from bluesky_gym.envs.shell import TaskSpecMixin, check_reset_options, time_limit_of
from bluesky_gym.multiagent.base import STATE_FEATURES, MultiAgentTask, flatten_observation
from bluesky_gym.multiagent.dense_sector_cr import DenseSectorCRMultiAgentTask
from bluesky_gym.multiagent.horizontal_cr import HorizontalCRMultiAgentTask
from bluesky_gym.multiagent.merge import MergeMultiAgentTask
from bluesky_gym.multiagent.sector_cr import SectorCRMultiAgentTask
from bluesky_gym.tasks.base import numeric_action

RENDER_MODES = ["rgb_array", "human"]
RENDER_FPS = 30


def local_bounds(task: MultiAgentTask) -> tuple[np.ndarray, np.ndarray]:
    """Per-element (low, high) of one agent's flattened observation, in key order."""
    low = np.concatenate([np.full(int(np.prod(v.shape)), v.low) for v in task.observation_spec.values()])
    high = np.concatenate([np.full(int(np.prod(v.shape)), v.high) for v in task.observation_spec.values()])
    return low, high


class CentralisedEnv(TaskSpecMixin, gym.Env):
    """Base of the centralised environments (subclasses set ``task_class``).

    Args:
        render_mode: ``None``, ``"rgb_array"`` or ``"human"``.
        max_episode_steps: Time limit in decision steps (default: the single-agent environment's).
        time_limit: ``max_episode_steps`` under the name ``gym.make`` passes on
            (:func:`~bluesky_gym.envs.shell.time_limit_of`).
        **options: Scenario options of the single-agent task.

    """

    task_class: ClassVar[type[MultiAgentTask]]
    metadata: dict[str, Any] = {"render_modes": RENDER_MODES, "render_fps": RENDER_FPS}  # noqa: RUF012 - Gymnasium declares it an instance attribute

    def __init__(self, render_mode: str | None = None, max_episode_steps: int | None = None, time_limit: int | None = None, **options: Any) -> None:
        if render_mode is not None and render_mode not in RENDER_MODES:
            raise ValueError(f"render_mode must be one of {RENDER_MODES} or None, got {render_mode!r}")
        self.render_mode = render_mode
        self.task = self.task_class(1, self.task_class.make_config(options), max_episode_steps=time_limit_of(max_episode_steps, time_limit))
        m = self.task.n_agents
        low, high = local_bounds(self.task)
        self.observation_space = spaces.Dict(
            {
                "local": spaces.Box(np.broadcast_to(low, (m, low.size)), np.broadcast_to(high, (m, high.size)), dtype=np.float64),
                "state": spaces.Box(-np.inf, np.inf, (m, len(STATE_FEATURES)), np.float64),
            }
        )
        spec = self.task.action_spec
        self.action_space = spaces.Box(spec.low, spec.high, (m * int(np.prod(spec.shape)),), np.float64)
        self._needs_reset = True
        self._renderer: Any = None
        self._last_reward = 0.0
        self._last_info: dict[str, Any] = {}

    def _observation(self) -> dict[str, np.ndarray]:
        return {"local": flatten_observation(self.task.observation())[0], "state": self.task.state_rows()[0]}

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """Start a new episode; ``seed`` seeds the scenario generator (``self.np_random``)."""
        super().reset(seed=seed)
        check_reset_options(options, "gym.make")
        self.task.seed(np.array([0]), [self.np_random])
        self.task.reset()
        self._needs_reset = False
        info = {k: v[0].item() for k, v in self.task.episode_info().items()}
        self._last_reward, self._last_info = 0.0, info
        if self.render_mode == "human":
            self.render()
        return self._observation(), info

    def step(self, action: Any) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]:
        """Apply the joint action (out-of-range values are clipped)."""
        if self._needs_reset:
            raise RuntimeError("step() called before reset() or after the episode ended; call reset() first")
        a = numeric_action(action, self.action_space.shape or ())
        if a.size != int(np.prod(self.action_space.shape or ())):
            raise ValueError(f"action has shape {a.shape}, expected {self.action_space.shape}")
        res = self.task.step(a.reshape(1, self.task.n_agents, *self.task.action_spec.shape))
        reward = float(res.reward[0].sum())
        ended = bool(res.episode_done[0])
        time_up = bool(self.task.stats.steps[0] >= self.task.time_limit)
        terminated, truncated = ended and not time_up, ended and time_up
        info = {k: v[0].item() for k, v in res.info.items()}
        self._needs_reset = ended
        self._last_reward, self._last_info = reward, info
        if self.render_mode == "human":
            self.render()
        return self._observation(), reward, terminated, truncated, info

    def render(self) -> np.ndarray | None:
        """Draw the current state: an RGB frame (``rgb_array``) or the window (``human``)."""
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode='rgb_array' or 'human' to gym.make")
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


class SectorCRCentralisedEnv(CentralisedEnv):
    """SectorCRCentralised-v0: one agent steers every aircraft of the sector (see the module docstring)."""

    task_class = SectorCRMultiAgentTask


class MergeCentralisedEnv(CentralisedEnv):
    """MergeCentralised-v0: one agent steers every arrival (see the module docstring)."""

    task_class = MergeMultiAgentTask


class HorizontalCRCentralisedEnv(CentralisedEnv):
    """HorizontalCRCentralised-v0: one agent steers the ownship and its intruders (see the module docstring)."""

    task_class = HorizontalCRMultiAgentTask


class DenseSectorCRCentralisedEnv(CentralisedEnv):
    """DenseSectorCRCentralised-v0: one agent steers every aircraft of the sector, those that enter during the episode included."""

    task_class = DenseSectorCRMultiAgentTask
