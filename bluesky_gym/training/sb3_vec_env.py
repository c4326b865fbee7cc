"""Stable-Baselines3's ``VecEnv`` API over the native batched environment.

:class:`SB3VecEnv` lets SB3 train directly on :class:`~bluesky_gym.envs.shell.BlueSkyVectorEnv`:
all ``num_envs`` episodes advance in one array operation per step, instead of SB3's
``DummyVecEnv`` looping over ``num_envs`` single environments.

It converts Gymnasium's vector conventions to SB3's:

* ``step`` returns ``dones = terminated | truncated`` and one info dict per environment. For an
  episode that ended, the observation returned is the first of the next episode (both APIs
  auto-reset), and its info holds ``terminal_observation`` (the final observation),
  ``TimeLimit.truncated`` (truncated and not terminated), the final step's info values, the
  episode KPIs ``kpi_*`` and ``episode = {"r": return, "l": length, "t": seconds}`` as SB3's
  ``Monitor`` would write (so SB3 logs ``rollout/ep_rew_mean`` and :func:`evaluate_policy` uses
  whole episodes), and ``episode_reward_components``, the episode's sum of every reward
  component ``reward_*``. Unfinished episodes get the step's info values and ``TimeLimit.truncated``.
* observations are dicts of ``(num_envs, *shape)`` float64 arrays, as SB3's
  ``MultiInputPolicy`` expects.
* :meth:`SB3VecEnv.seed` (called by SB3 when a model has a ``seed``) seeds the next ``reset``
  with training-range scenario seeds (see :mod:`bluesky_gym.envs.seeds`).
* ``get_attr``, ``set_attr`` and ``env_method`` act on the one shared batched environment: every
  index sees the same attribute, and a method is called once, its result repeated per index.

The episode statistics follow the vector environment, so this adapter is a drop-in for
``VecMonitor(DummyVecEnv([...]))``; do not wrap it in ``VecMonitor`` again.
"""

from __future__ import annotations

import time
from collections.abc import Iterable, Sequence
from typing import Any

import gymnasium as gym
import numpy as np

from bluesky_gym.core.extras import require_sb3
from bluesky_gym.envs.seeds import train_env_seeds
from bluesky_gym.training import make_vector_env

require_sb3()

from stable_baselines3.common.monitor import Monitor  # noqa: E402
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvIndices, VecEnvObs, VecEnvStepReturn  # noqa: E402

# Info entries of the vector environment that are not per-episode scalars.
_VECTOR_ONLY_KEYS = ("final_obs", "final_info", "_final_obs", "_final_info")


class SB3VecEnv(VecEnv):
    """SB3 ``VecEnv`` over a native batched BlueSky-Gym environment.

    Args:
        env: A batched environment (``gym.make_vec(..., vectorization_mode="vector_entry_point")``)
            or an environment id, which is then created with ``num_envs`` and ``env_kwargs``.
        num_envs: Number of environments when ``env`` is an id.
        **env_kwargs: Scenario options, ``max_episode_steps`` or ``render_mode`` when ``env`` is
            an id.

    Example:
        >>> from stable_baselines3 import PPO
        >>> venv = SB3VecEnv("DescentEnv-v0", num_envs=8)
        >>> model = PPO("MultiInputPolicy", venv, seed=0).learn(10_000)

    """

    def __init__(self, env: gym.vector.VectorEnv | str, num_envs: int = 1, **env_kwargs: Any) -> None:
        if not isinstance(env, str) and env_kwargs:
            raise TypeError("env_kwargs are only accepted together with an environment id")
        venv = make_vector_env(env, num_envs, **env_kwargs) if isinstance(env, str) else env
        autoreset = venv.metadata.get("autoreset_mode")
        if autoreset is not None and autoreset != gym.vector.AutoresetMode.SAME_STEP:
            raise ValueError(f"SB3VecEnv needs a SAME_STEP autoreset vector environment, got {autoreset}")
        self.venv: gym.vector.VectorEnv = venv
        self.env_id = venv.spec.id if venv.spec is not None else type(venv).__name__
        super().__init__(venv.num_envs, venv.single_observation_space, venv.single_action_space)
        self._actions: np.ndarray | None = None
        self._returns = np.zeros(self.num_envs)
        self._lengths = np.zeros(self.num_envs, dtype=np.int64)
        self._components: dict[str, np.ndarray] = {}
        self._t0 = time.time()
        #: Number of episodes finished since construction.
        self.episodes_done = 0

    # --- VecEnv API -----------------------------------------------------------------------------
    def reset(self) -> VecEnvObs:
        """Reset every environment (with the seeds set by :meth:`seed`, if any)."""
        seeds: list[int | None] | None = None if all(s is None for s in self._seeds) else list(self._seeds)
        if any(self._options):
            raise ValueError("reset options are not supported by BlueSky-Gym environments (pass scenario options at creation)")
        # Gymnasium's VectorEnv annotates an int seed only; its vector envs, like ours, take one per environment.
        obs, info = self.venv.reset(seed=seeds)  # type: ignore[arg-type]
        self.reset_infos = _split_info(info, self.num_envs)
        self._reset_seeds()
        self._reset_options()
        self._returns[:] = 0.0
        self._lengths[:] = 0
        self._components.clear()
        return obs

    def seed(self, seed: int | None = None) -> Sequence[int | None]:
        """Seed the scenarios of the next :meth:`reset` from the training range.

        Args:
            seed: The run seed; ``None`` draws one at random.

        Returns:
            The per-environment scenario seeds (all below ``2**31``).

        """
        if seed is None:
            seed = int(np.random.randint(0, 2**31 - 1))
        self._seeds = list(train_env_seeds(int(seed), self.num_envs))
        return self._seeds

    def step_async(self, actions: np.ndarray) -> None:
        """Store the actions of the next :meth:`step_wait`."""
        self._actions = np.asarray(actions)

    def step_wait(self) -> VecEnvStepReturn:
        """Step every environment; ended episodes restart in the same call."""
        if self._actions is None:
            raise RuntimeError("step_wait() called without step_async()")
        actions = self._actions.reshape((self.num_envs, *(self.action_space.shape or ())))
        self._actions = None
        obs, reward, terminated, truncated, info = self.venv.step(actions)
        reward = np.asarray(reward, dtype=np.float64)
        terminated = np.asarray(terminated, dtype=bool)
        truncated = np.asarray(truncated, dtype=bool)
        dones = terminated | truncated
        self._returns += reward
        self._lengths += 1
        for k, v in info.items():
            if k.startswith("reward_") and _per_env(v, self.num_envs):
                self._components.setdefault(k, np.zeros(self.num_envs))
                self._components[k] += v

        infos = _split_info(info, self.num_envs, masked=True)
        time_limit = (truncated & ~terminated).tolist()
        for i in range(self.num_envs):
            infos[i]["TimeLimit.truncated"] = time_limit[i]
        if np.any(dones):
            final_obs = info.get("final_obs")
            final_info = info.get("final_info", {})
            elapsed = round(time.time() - self._t0, 6)
            for i in np.flatnonzero(dones).tolist():
                d = infos[i]
                d.update({k: _scalar(v[i]) for k, v in final_info.items() if _per_env(v, self.num_envs)})
                d["terminal_observation"] = {k: v[i].copy() for k, v in final_obs.items()} if final_obs is not None else None
                d["episode"] = {"r": float(self._returns[i]), "l": int(self._lengths[i]), "t": elapsed}
                d["episode_reward_components"] = {k: float(v[i]) for k, v in self._components.items()}
            self._returns[dones] = 0.0
            self._lengths[dones] = 0
            for v in self._components.values():
                v[dones] = 0.0
            self.episodes_done += int(dones.sum())
        return obs, reward.astype(np.float32), dones, infos

    def close(self) -> None:
        """Close the batched environment."""
        self.venv.close()

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        """Return the attribute of the shared batched environment, once per index."""
        value = getattr(self.venv, attr_name)
        return [value for _ in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        """Set an attribute of the shared batched environment (for all indices)."""
        setattr(self.venv, attr_name, value)

    def env_method(self, method_name: str, *method_args: Any, indices: VecEnvIndices = None, **method_kwargs: Any) -> list[Any]:
        """Call a method of the shared batched environment once; its result is repeated per index."""
        result = getattr(self.venv, method_name)(*method_args, **method_kwargs)
        return [result for _ in self._get_indices(indices)]

    def env_is_wrapped(self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None) -> list[bool]:
        """Tell whether environments are wrapped: only ``Monitor`` reports True.

        No Gymnasium wrapper is applied, but the episode statistics ``Monitor`` would add are
        provided (``info["episode"]``).
        """
        wrapped = isinstance(wrapper_class, type) and issubclass(Monitor, wrapper_class)
        return [wrapped for _ in self._get_indices(indices)]

    def get_images(self) -> Sequence[np.ndarray | None]:
        """One RGB frame per environment (``render_mode="rgb_array"``)."""
        if self.render_mode != "rgb_array":
            return [None for _ in range(self.num_envs)]
        venv: Any = self.venv  # a BlueSky-Gym vector env: it renders the episode ``render_env``
        keep = venv.render_env
        try:
            frames: list[np.ndarray | None] = []
            for i in range(self.num_envs):
                venv.render_env = i
                frames.append(venv.render())
        finally:
            venv.render_env = keep
        return frames

    def _get_indices(self, indices: VecEnvIndices) -> Iterable[int]:
        if indices is None:
            return range(self.num_envs)
        if isinstance(indices, (int, np.integer)):
            return [int(indices)]
        return list(indices)


def _per_env(v: Any, n: int) -> bool:
    return isinstance(v, np.ndarray) and v.ndim == 1 and v.shape[0] == n


def _scalar(v: Any) -> Any:
    return v.item() if isinstance(v, np.generic) else v


def _split_info(info: dict[str, Any], n: int, masked: bool = False) -> list[dict[str, Any]]:
    """Per-environment info dicts from a vector info (array per key).

    With ``masked``, keys with a Gymnasium mask ``_key`` appear only where the mask is set (e.g.
    ``kpi_*`` at the end of an episode).
    """
    out: list[dict[str, Any]] = [{} for _ in range(n)]
    for k, v in info.items():
        if k in _VECTOR_ONLY_KEYS or k.startswith("_") or not _per_env(v, n):
            continue
        values = v.tolist()
        mask = info.get(f"_{k}") if masked else None
        if mask is None:
            for i in range(n):
                out[i][k] = values[i]
        else:
            for i in np.flatnonzero(mask).tolist():
                out[i][k] = values[i]
    return out
