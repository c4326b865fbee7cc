"""Noisy observations: i.i.d. Gaussian noise on every observation entry.

As the reference ``NoisyObservationWrapper``, but drawn from a generator the wrapper owns.

The noise generator is seeded from the seed given to ``reset`` on its own stream, so adding the
wrapper does not change the scenarios an environment generates, and the same seed gives the same
noise. Reach flags are perturbed too, as in the reference. The observation space is unchanged.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import VectorEnv, VectorWrapper

NOISE_STREAM = 0x6E6F697365  # separates the noise stream from the scenario stream of a seed


def _check_level(noise_level: float) -> float:
    if isinstance(noise_level, bool) or not isinstance(noise_level, (int, float)) or not np.isfinite(noise_level) or noise_level < 0:
        raise ValueError(f"noise_level must be a finite number >= 0, got {noise_level!r}")
    return float(noise_level)


def _noisy(obs: Any, rng: np.random.Generator, level: float) -> Any:
    if isinstance(obs, np.ndarray):
        return obs + rng.normal(0.0, level, size=obs.shape)
    if isinstance(obs, dict):
        return {k: (v + rng.normal(0.0, level, size=v.shape) if isinstance(v, np.ndarray) else v) for k, v in obs.items()}
    raise TypeError(f"observation must be an array or a dict of arrays, got {type(obs).__name__}")


def _generator(seed: int | None) -> np.random.Generator:
    return np.random.default_rng(None if seed is None else [int(seed), NOISE_STREAM])


class NoisyObservationWrapper(gym.ObservationWrapper):
    """Add N(0, noise_level) noise to every observation of a single environment.

    Args:
        env: The environment.
        noise_level: Standard deviation of the noise (in normalised observation units).
    """

    def __init__(self, env: gym.Env, noise_level: float = 0.1) -> None:
        super().__init__(env)
        self.noise_level = _check_level(noise_level)
        self._rng = _generator(None)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        """Reset; a seed also seeds the noise."""
        if seed is not None:
            self._rng = _generator(seed)
        return super().reset(seed=seed, options=options)

    def observation(self, observation: Any) -> Any:
        """The noisy observation."""
        return _noisy(observation, self._rng, self.noise_level)


class VectorNoisyObservationWrapper(VectorWrapper):
    """Add N(0, noise_level) noise to every observation of a batched environment.

    ``info["final_obs"]`` of ended episodes is perturbed too.
    """

    def __init__(self, env: VectorEnv, noise_level: float = 0.1) -> None:
        super().__init__(env)
        self.noise_level = _check_level(noise_level)
        self._rng = _generator(None)

    def reset(self, *, seed: int | list[int | None] | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        """Reset every episode; an int seed also seeds the noise."""
        if isinstance(seed, (int, np.integer)):
            self._rng = _generator(int(seed))
        # Gymnasium's VectorEnv annotates an int seed only; BlueSky-Gym's vector envs also take one per environment.
        obs, info = self.env.reset(seed=seed, options=options)  # type: ignore[arg-type]
        return _noisy(obs, self._rng, self.noise_level), info

    def step(self, actions: Any) -> tuple[Any, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Step every episode."""
        obs, reward, terminated, truncated, info = self.env.step(actions)
        if "final_obs" in info:
            info = {**info, "final_obs": _noisy(info["final_obs"], self._rng, self.noise_level)}
        return _noisy(obs, self._rng, self.noise_level), reward, terminated, truncated, info
