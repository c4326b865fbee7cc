"""Wind: a uniform wind or a field of wind points with BlueSky's interpolation [dynamics.md 6].

As in the reference wrapper, the wind is added right after every episode's scenario was
generated (so aircraft are created without wind and the wind acts from the first step on), and
``augment_obs`` adds the wind at the ownship in its heading frame:

* ``wind_u`` = (wn·cos h + we·sin h) / 50: along-heading component (tail wind positive);
* ``wind_v`` = (−wn·sin h + we·cos h) / 50: cross component (positive toward the right).

Wind acts only above 50 ft, so it has no effect in HorizontalCR and PlanWaypoint, whose
aircraft fly at altitude 0 (BlueSky physics, kept). Unlike the reference, the wrapper also works
on the terminal step and on natively batched environments (with autoreset).
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.vector import VectorEnv, VectorWrapper
from gymnasium.vector.utils import batch_space
from numpy.typing import ArrayLike, NDArray

from bluesky_gym.tasks.base import Task

MAX_WIND = 50.0  # m/s, normalisation of the wind observation


def _task_of(env: Any) -> Task:
    task = getattr(env.unwrapped, "task", None)
    if not isinstance(task, Task):
        raise TypeError("the wind wrapper needs a BlueSky-Gym environment (an env with a .task)")
    return task


class _Wind:
    """The wind definition and what both wrappers do with it."""

    def __init__(self, lat: ArrayLike, lon: ArrayLike, vnorth: ArrayLike, veast: ArrayLike, alt: ArrayLike | None) -> None:
        if alt is not None:
            raise ValueError("wind altitude profiles are not supported; pass alt=None for a 2-D field (the same wind at every altitude)")
        self.lat, self.lon, self.vnorth, self.veast = (np.atleast_1d(np.asarray(x, dtype=np.float64)).ravel() for x in (lat, lon, vnorth, veast))
        if not (self.lat.size == self.lon.size == self.vnorth.size == self.veast.size) or self.lat.size == 0:
            raise ValueError("wind: lat, lon, vnorth and veast must have the same, non-zero number of points")
        if not np.all(np.isfinite(np.concatenate([self.lat, self.lon, self.vnorth, self.veast]))):
            raise ValueError("wind: all values must be finite")

    def install(self, task: Task) -> None:
        def add_wind(t: Task, envs: NDArray[np.int64]) -> None:
            for e in envs:
                t.sim.wind.add_points(int(e), self.lat, self.lon, self.vnorth, self.veast)

        task.reset_hooks.append(add_wind)

    @staticmethod
    def observation(task: Task) -> dict[str, np.ndarray]:
        sim = task.sim
        wn, we = sim.wind.at(task.all_envs, sim.lat[:, 0], sim.lon[:, 0])
        h = np.deg2rad(sim.hdg[:, 0])
        u = (wn * np.cos(h) + we * np.sin(h)) / MAX_WIND
        v = (-wn * np.sin(h) + we * np.cos(h)) / MAX_WIND
        return {"wind_u": u[:, None], "wind_v": v[:, None]}


def _install(env: Any, lat: ArrayLike, lon: ArrayLike, vnorth: ArrayLike, veast: ArrayLike, alt: ArrayLike | None) -> Task:
    """Validate the wind definition and add it to every new episode of ``env``'s task."""
    task = _task_of(env)
    _Wind(lat, lon, vnorth, veast, alt).install(task)
    return task


def _augmented_space(space: gym.Space) -> spaces.Dict:
    if not isinstance(space, spaces.Dict):
        raise TypeError("augment_obs needs a Dict observation space")
    extra = {k: spaces.Box(-np.inf, np.inf, shape=(1,), dtype=np.float64) for k in ("wind_u", "wind_v")}
    return spaces.Dict({**space.spaces, **extra})


class WindFieldWrapper(gym.Wrapper):
    """Add wind to a single environment.

    Args:
        env: A BlueSky-Gym environment.
        lat: Latitudes of the wind points [deg].
        lon: Longitudes of the wind points [deg].
        vnorth: North components [m/s] (the direction the wind blows to), any shape with one value per point.
        veast: East components [m/s].
        alt: Must be None (a 2-D field).
        augment_obs: Add ``wind_u`` and ``wind_v`` to the observation.
    """

    def __init__(
        self,
        env: gym.Env,
        lat: ArrayLike,
        lon: ArrayLike,
        vnorth: ArrayLike,
        veast: ArrayLike,
        alt: ArrayLike | None = None,
        augment_obs: bool = False,
    ) -> None:
        super().__init__(env)
        self._task = _install(env, lat, lon, vnorth, veast, alt)
        self.augment_obs = augment_obs
        if augment_obs:
            self.observation_space = _augmented_space(env.observation_space)

    def _augment(self, obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        if not self.augment_obs:
            return obs
        return {**obs, **{k: v[0] for k, v in _Wind.observation(self._task).items()}}

    def reset(self, **kwargs: Any) -> tuple[Any, dict[str, Any]]:
        """Reset; the wind is in place before the first step."""
        obs, info = self.env.reset(**kwargs)
        return self._augment(obs), info

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        """Step and append the wind observation (also on the terminal step)."""
        obs, reward, terminated, truncated, info = self.env.step(action)
        return self._augment(obs), reward, terminated, truncated, info


class VectorWindFieldWrapper(VectorWrapper):
    """Add wind to every episode of a natively batched environment.

    Same arguments as :class:`WindFieldWrapper`. With autoreset, the returned first observation
    of a new episode and ``info["final_obs"]`` both carry the wind entries.
    """

    def __init__(
        self,
        env: VectorEnv,
        lat: ArrayLike,
        lon: ArrayLike,
        vnorth: ArrayLike,
        veast: ArrayLike,
        alt: ArrayLike | None = None,
        augment_obs: bool = False,
    ) -> None:
        super().__init__(env)
        self._task = _install(env, lat, lon, vnorth, veast, alt)
        self.augment_obs = augment_obs
        if augment_obs:
            self.single_observation_space = _augmented_space(env.single_observation_space)
            self.observation_space = batch_space(self.single_observation_space, env.num_envs)

    def reset(self, **kwargs: Any) -> tuple[Any, dict[str, Any]]:
        """Reset every episode."""
        obs, info = self.env.reset(**kwargs)
        if self.augment_obs:
            obs = {**obs, **_Wind.observation(self._task)}
        return obs, info

    def step(self, actions: Any) -> tuple[Any, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Step every episode."""
        if self.augment_obs:
            # Ended episodes are reset inside env.step (SAME_STEP autoreset), so the wind seen at
            # their final state is captured after the last physics sub-step.
            task = self._task
            hook_store: dict[str, np.ndarray] = {}

            def before_reset(t: Task, k: int) -> None:
                if k == t.action_frequency - 1:
                    hook_store.update(_Wind.observation(t))

            task.substep_hooks.append(before_reset)
            try:
                obs, reward, terminated, truncated, info = self.env.step(actions)
            finally:
                task.substep_hooks.remove(before_reset)
            obs = {**obs, **_Wind.observation(task)}
            if "final_obs" in info:
                info["final_obs"] = {**info["final_obs"], **hook_store}
            return obs, reward, terminated, truncated, info
        return self.env.step(actions)
