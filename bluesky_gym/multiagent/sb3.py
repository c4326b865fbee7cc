"""Stable-Baselines3 ``VecEnv`` for a policy shared by all agents (parameter sharing).

:class:`SharedPolicyVecEnv` runs ``n_episodes`` multi-agent episodes of a batched task and shows
every agent slot of every episode as one row of an SB3 ``VecEnv``: row ``e * n_agents + k`` is
aircraft slot ``k`` of episode ``e``; ``num_envs = n_episodes * n_agents``. One SB3 model (e.g.
``PPO("MultiInputPolicy", venv)``) then learns a single policy from the experience of all agents,
each acting on its own observation (one agent's observation space and action space).

Row semantics:

* a row whose slot holds an aircraft at the start of a step is a *live* row: its reward is the
  agent's reward; it is done when the agent terminates (goal), is truncated (sector exit, time
  limit) or its episode ends. Its info then holds ``terminal_observation``,
  ``TimeLimit.truncated`` (truncated and not terminated: SB3 bootstraps the value of the final
  observation, as the single-agent environments' truncations) and ``episode = {"r": agent
  return, "l": agent steps, "t": seconds}``, so SB3 logs per-agent returns;
* a row whose slot is empty (the episode has fewer aircraft than slots, or the agent has left) is
  a *dummy* row: its observation is all zeros, its reward 0, and it is done at every step with
  ``TimeLimit.truncated`` False, i.e. a one-step episode of return 0 that bootstraps nothing. The
  policy's action for it is ignored. Dummy rows cost compute and enter the rollout buffer (with
  zero return, so their advantage is minus the value of the all-zeros observation, which the
  critic quickly learns to be 0). :attr:`SharedPolicyVecEnv.live_rows` tells which rows were live
  in the last step, and every row's info has ``agent_active``;
* :class:`LiveRowsRolloutBuffer` (``PPO(..., rollout_buffer_class=LiveRowsRolloutBuffer)``, then
  :func:`track_live_rows`) keeps the dummy transitions out of PPO's updates: advantages are
  computed on all rows as usual (a dummy transition is a finished one-step episode, so it never
  mixes with a live agent's), but the minibatches are drawn from the live transitions only. This
  removes their cost (most SectorCR slots are empty) and their noise from the gradient;
* :class:`LiveRowsVecNormalize` is SB3's observation normalisation (``VecNormalize``) with running
  statistics taken from the live rows only (the zeros of dummy rows would bias them);
* when an episode ends (no agent left, or the time limit), it restarts in the same step (the
  task's own autoreset, :attr:`~bluesky_gym.tasks.base.Task.autoreset`, which the adapter
  switches on): its rows' next observations are the first of the new episode. Its KPIs (``kpi_*`` of
  :meth:`~bluesky_gym.multiagent.base.MultiAgentTask.kpis`, plus the team return) are appended
  to :attr:`SharedPolicyVecEnv.episode_kpis`.

Stable-Baselines3 is optional: ``pip install -e ".[train]"``.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable, Generator, Iterable, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding

from bluesky_gym.core.extras import require_sb3
from bluesky_gym.envs.seeds import train_env_seeds
from bluesky_gym.multiagent import make_task
from bluesky_gym.multiagent.base import MultiAgentTask

require_sb3()

from stable_baselines3.common.buffers import DictRolloutBuffer  # noqa: E402
from stable_baselines3.common.type_aliases import DictRolloutBufferSamples  # noqa: E402
from stable_baselines3.common.vec_env import VecNormalize  # noqa: E402
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvIndices, VecEnvObs, VecEnvStepReturn  # noqa: E402

KPI_HISTORY = 1000  # episodes kept in :attr:`SharedPolicyVecEnv.episode_kpis`


class SharedPolicyVecEnv(VecEnv):
    """SB3 ``VecEnv`` whose rows are the agent slots of a batch of multi-agent episodes.

    Args:
        task: A batched multi-agent task, or a multi-agent environment name (``"sector_cr_v0"``,
            ``"merge_v0"``, ``"horizontal_cr_v0"``), then created with ``n_episodes`` episodes.
        n_episodes: Number of multi-agent episodes when ``task`` is a name.
        max_episode_steps: Time limit when ``task`` is a name.
        **options: Scenario options when ``task`` is a name.

    Example:
        >>> from stable_baselines3 import PPO
        >>> venv = SharedPolicyVecEnv("sector_cr_v0", n_episodes=8)
        >>> model = PPO("MultiInputPolicy", venv, seed=0).learn(50_000)
    """

    def __init__(self, task: MultiAgentTask | str, n_episodes: int = 8, max_episode_steps: int | None = None, **options: Any) -> None:
        if isinstance(task, str):
            self.task: MultiAgentTask = make_task(task, n_episodes, max_episode_steps, **options)
        elif options or max_episode_steps is not None:
            raise TypeError("scenario options and max_episode_steps are only accepted together with an environment name")
        else:
            self.task = task
        task = self.task
        task.autoreset = True  # an episode that ends restarts within its step
        self.n_episodes, self.n_agents = task.n_envs, task.n_agents
        self.render_mode = None
        obs_space = spaces.Dict({k: spaces.Box(v.low, v.high, v.shape, np.float64) for k, v in task.observation_spec.items()})
        spec = task.action_spec
        super().__init__(self.n_episodes * self.n_agents, obs_space, spaces.Box(spec.low, spec.high, spec.shape, np.float64))
        self._episode_seeds: list[int] | None = None
        self._actions: np.ndarray | None = None
        self._t0 = time.time()
        self._zero_obs = {k: np.zeros(v.shape) for k, v in task.observation_spec.items()}
        #: (num_envs,) rows that held a live agent at the start of the last step.
        self.live_rows = np.zeros(self.num_envs, bool)
        #: KPIs (and ``return``, the team return) of the latest finished episodes.
        self.episode_kpis: deque[dict[str, float]] = deque(maxlen=KPI_HISTORY)
        #: Number of multi-agent episodes finished since construction.
        self.episodes_done = 0

    # --- row layout ------------------------------------------------------------------------------
    def _rows(self, obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        return {k: v.reshape(self.num_envs, *v.shape[2:]) for k, v in obs.items()}

    # --- VecEnv API -----------------------------------------------------------------------------
    def reset(self) -> VecEnvObs:
        """Reset every episode (with the seeds set by :meth:`seed`, if any)."""
        if self._episode_seeds is not None:
            self.task.seed(self.task.all_envs, [seeding.np_random(s)[0] for s in self._episode_seeds])
            self._episode_seeds = None
        elif any(s is not None for s in self._seeds):
            raise ValueError("per-row seeds are not supported: seed the episodes with SharedPolicyVecEnv.seed(seed)")
        self.task.reset()
        self._reset_seeds()
        self._reset_options()
        self.reset_infos = [{} for _ in range(self.num_envs)]
        return self._rows(self.task.observation())

    def seed(self, seed: int | None = None) -> Sequence[int | None]:
        """Seed the episodes of the next :meth:`reset` from the training seed range.

        Args:
            seed: The run seed; ``None`` draws one at random.

        Returns:
            The scenario seed of each row's episode.
        """
        if seed is None:
            seed = int(np.random.randint(0, 2**31 - 1))
        self._episode_seeds = list(train_env_seeds(int(seed), self.n_episodes))
        return [s for s in self._episode_seeds for _ in range(self.n_agents)]

    def step_async(self, actions: np.ndarray) -> None:
        """Store the actions of the next :meth:`step_wait`."""
        self._actions = np.asarray(actions)

    def step_wait(self) -> VecEnvStepReturn:
        """Step every episode; finished episodes restart in the same call."""
        if self._actions is None:
            raise RuntimeError("step_wait() called without step_async()")
        task = self.task
        actions = self._actions.reshape(self.n_episodes, self.n_agents, *task.action_spec.shape)
        self._actions = None
        lengths = (task.agent_steps + (task.sim.active & ~task.finished[:, None])).reshape(-1)  # agent steps after this one
        res = task.step(actions)  # the task resets the episodes that ended (autoreset)
        live = res.acting.reshape(-1)
        ended_agent = (res.terminated | res.truncated).reshape(-1)
        dones = ~live | ended_agent
        reward = res.reward.reshape(-1).astype(np.float32)
        time_limit = (res.truncated & ~res.terminated).reshape(-1)
        final_obs = self._rows(res.observation)
        returns = res.agent_info["return"].reshape(-1)
        ended_episodes = np.flatnonzero(res.episode_done)
        for e in ended_episodes:
            rec = {"return": float(res.info["total_reward"][e])}
            rec.update({k: float(v[e]) for k, v in res.info.items() if k.startswith("kpi_")})
            self.episode_kpis.append(rec)
        self.episodes_done += int(ended_episodes.size)
        if ended_episodes.size:
            obs = self._rows(task.observation())
        else:
            keep = ~ended_agent
            obs = {k: np.where(keep.reshape(keep.shape + (1,) * (v.ndim - 1)), v, 0.0) for k, v in final_obs.items()}
        elapsed = round(time.time() - self._t0, 6)
        infos: list[dict[str, Any]] = []
        live_list, ended_list, tl_list = live.tolist(), ended_agent.tolist(), time_limit.tolist()
        for i in range(self.num_envs):
            if not live_list[i]:
                infos.append({"agent_active": False, "TimeLimit.truncated": False, "terminal_observation": self._zero_obs})
                continue
            info: dict[str, Any] = {"agent_active": True, "TimeLimit.truncated": tl_list[i]}
            if ended_list[i]:
                info["terminal_observation"] = {k: v[i].copy() for k, v in final_obs.items()}
                info["episode"] = {"r": float(returns[i]), "l": int(lengths[i]), "t": elapsed}
            infos.append(info)
        self.live_rows = live
        return obs, reward, dones, infos

    def close(self) -> None:
        """Nothing to release (the task owns no window)."""

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        """Return an attribute of this adapter (or of its task), once per index."""
        value = getattr(self, attr_name) if hasattr(self, attr_name) else getattr(self.task, attr_name)
        return [value for _ in self._indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        """Set an attribute of the task (shared by all rows)."""
        setattr(self.task, attr_name, value)

    def env_method(self, method_name: str, *method_args: Any, indices: VecEnvIndices = None, **method_kwargs: Any) -> list[Any]:
        """Call a method of the task once; its result is repeated per index."""
        result = getattr(self.task, method_name)(*method_args, **method_kwargs)
        return [result for _ in self._indices(indices)]

    def env_is_wrapped(self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None) -> list[bool]:
        """No row is wrapped (the episode statistics are provided by the adapter itself)."""
        return [False for _ in self._indices(indices)]

    def _indices(self, indices: VecEnvIndices) -> Iterable[int]:
        if indices is None:
            return range(self.num_envs)
        if isinstance(indices, (int, np.integer)):
            return [int(indices)]
        return list(indices)


class LiveRowsRolloutBuffer(DictRolloutBuffer):
    """PPO rollout buffer that trains on the live rows of a :class:`SharedPolicyVecEnv` only.

    Every transition is stored (so SB3's advantage computation is unchanged); :meth:`get` draws
    the minibatches from the transitions whose row held a live agent. The live mask of each step
    comes from :attr:`live_source` (set it with :func:`track_live_rows`); without a source every
    transition counts as live.
    """

    live_source: Callable[[], np.ndarray] | None = None

    def reset(self) -> None:
        """Empty the buffer."""
        super().reset()
        self.live = np.ones((self.buffer_size, self.n_envs), bool)

    def add(self, *args: Any, **kwargs: Any) -> None:
        """Store a transition and whether each row was live in it."""
        if self.live_source is not None:
            self.live[self.pos] = self.live_source()
        super().add(*args, **kwargs)

    def get(  # type: ignore[override]  # SB3 annotates its dict buffer's get with the plain sample type
        self, batch_size: int | None = None
    ) -> Generator[DictRolloutBufferSamples, None, None]:
        """Yield minibatches of live transitions, in random order."""
        assert self.full, "the rollout buffer is not full"
        if not self.generator_ready:
            # SB3's own preparation (flattening the stored arrays) runs on the first batch.
            next(super().get(self.buffer_size * self.n_envs))
        live = self.live.swapaxes(0, 1).reshape(-1)  # the flattened order: row-major over (env, step)
        indices = np.random.permutation(np.flatnonzero(live))
        if batch_size is None:
            batch_size = max(indices.size, 1)
        for start in range(0, indices.size, batch_size):
            yield self._get_samples(indices[start : start + batch_size])


def track_live_rows(model: Any, venv: SharedPolicyVecEnv) -> None:
    """Let a PPO model built with ``rollout_buffer_class=LiveRowsRolloutBuffer`` see ``venv``'s live rows.

    The link is not saved with the model; call this again after loading one for further training.
    """
    buffer = model.rollout_buffer
    if not isinstance(buffer, LiveRowsRolloutBuffer):
        raise TypeError("the model's rollout buffer is not a LiveRowsRolloutBuffer (pass rollout_buffer_class=LiveRowsRolloutBuffer)")
    buffer.live_source = lambda: venv.live_rows


class LiveRowsVecNormalize(VecNormalize):
    """Observation normalisation whose running mean and variance only see live rows.

    Rewards are not normalised. Dummy rows are normalised too (they are never trained on with
    :class:`LiveRowsRolloutBuffer`). Save and load the statistics with SB3's
    ``save(path)`` / ``VecNormalize.load(path, venv)``; set ``training = False`` to freeze them.

    Args:
        venv: The shared-policy adapter.
        clip_obs: Bound of the normalised observations.
    """

    def __init__(self, venv: SharedPolicyVecEnv, clip_obs: float = 10.0) -> None:
        super().__init__(venv, norm_obs=True, norm_reward=False, clip_obs=clip_obs)
        self.shared = venv

    def _update_obs_rms(self, obs: dict[str, np.ndarray]) -> None:
        live = self.shared.task.sim.active.reshape(-1)  # rows whose observation belongs to an agent
        if self.training and np.any(live):
            for key, rms in self.obs_rms.items():
                rms.update(obs[key][live])

    def reset(self) -> dict[str, np.ndarray]:
        """Reset the episodes; return the normalised first observations."""
        obs = self.venv.reset()
        assert isinstance(obs, dict)
        self.old_obs = obs
        self.returns = np.zeros(self.num_envs)
        self._update_obs_rms(obs)
        normalised = self.normalize_obs(obs)
        assert isinstance(normalised, dict)
        return normalised

    def step_wait(self) -> VecEnvStepReturn:
        """Step; update the statistics with the live rows and normalise the observations."""
        obs, rewards, dones, infos = self.venv.step_wait()
        assert isinstance(obs, dict)
        self.old_obs, self.old_reward = obs, rewards
        self._update_obs_rms(obs)
        for idx in np.flatnonzero(dones & self.shared.live_rows):
            infos[idx]["terminal_observation"] = self.normalize_obs(infos[idx]["terminal_observation"])
        return self.normalize_obs(obs), rewards, dones, infos
