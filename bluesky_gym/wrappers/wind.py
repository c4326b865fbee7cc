"""Wind: a uniform wind or a field of wind points with BlueSky's interpolation [docs/dynamics.md §6].

As in the reference wrapper, the wind is added right after every episode's scenario was
generated (so aircraft are created without wind and the wind acts from the first step on), and
``augment_obs`` adds the wind at the ownship in its heading frame:

* ``wind_u`` = (wn·cos h + we·sin h) / 50: along-heading component (tail wind positive);
* ``wind_v`` = (−wn·sin h + we·cos h) / 50: cross component (positive toward the right).

Wind acts only above 50 ft, so it has no effect in HorizontalCR and PlanWaypoint, whose
aircraft fly at altitude 0 (BlueSky physics, kept). Unlike the reference, the wrapper also works
on the terminal step and on natively batched environments (with autoreset).

The wrappers hand the wind to the task: a :class:`WindEffect` (:meth:`Task.add_effect
<bluesky_gym.tasks.base.Task.add_effect>`) installs it in every new episode, and with
``augment_obs`` the two entries become observation terms of the task
(:meth:`~bluesky_gym.tasks.base.Task.add_observation_terms`), so they are in every observation
the environment returns, the final observation of an ended episode included. Nothing runs per
physics sub-step, so a decision step stays one :meth:`~bluesky_gym.core.Simulator.run` call.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import VectorEnv, VectorWrapper
from numpy.typing import ArrayLike, NDArray

from bluesky_gym.tasks.base import Array, BoxSpec, ObservationTerms, Task

MAX_WIND = 50.0  # m/s, normalisation of the wind observation
WIND_KEYS = ("wind_u", "wind_v")


def _task_of(env: Any) -> Task:
    task = getattr(env.unwrapped, "task", None)
    if not isinstance(task, Task):
        raise TypeError("the wind wrapper needs a BlueSky-Gym environment (an env with a .task)")
    return task


class WindEffect:
    """A wind field (uniform or from definition points), installed in every new episode of a task.

    Args:
        lat: Latitudes of the wind points [deg].
        lon: Longitudes of the wind points [deg].
        vnorth: North components [m/s] (the direction the wind blows to).
        veast: East components [m/s].
        alt: Must be None (a 2-D field, the same wind at every altitude).
    """

    def __init__(self, lat: ArrayLike, lon: ArrayLike, vnorth: ArrayLike, veast: ArrayLike, alt: ArrayLike | None = None) -> None:
        if alt is not None:
            raise ValueError("wind altitude profiles are not supported; pass alt=None for a 2-D field (the same wind at every altitude)")
        self.lat, self.lon, self.vnorth, self.veast = (np.atleast_1d(np.asarray(x, dtype=np.float64)).ravel() for x in (lat, lon, vnorth, veast))
        if not (self.lat.size == self.lon.size == self.vnorth.size == self.veast.size) or self.lat.size == 0:
            raise ValueError("wind: lat, lon, vnorth and veast must have the same, non-zero number of points")
        if not np.all(np.isfinite(np.concatenate([self.lat, self.lon, self.vnorth, self.veast]))):
            raise ValueError("wind: all values must be finite")

    def on_reset(self, task: Task, envs: NDArray[np.int64]) -> None:
        """Add the wind points to the airspaces of the new episodes ``envs``."""
        for e in envs:
            task.sim.wind.add_points(int(e), self.lat, self.lon, self.vnorth, self.veast)


def wind_at_ownship(task: Task, envs: NDArray[np.int64]) -> dict[str, Array]:
    """``wind_u``, ``wind_v``: the wind at the ownship in its heading frame / 50, (len(envs), 1) each."""
    sim = task.sim
    wn, we = sim.wind.at(envs, sim.lat[envs, 0], sim.lon[envs, 0])
    h = np.deg2rad(sim.hdg[envs, 0])
    u = (wn * np.cos(h) + we * np.sin(h)) / MAX_WIND
    v = (-wn * np.sin(h) + we * np.cos(h)) / MAX_WIND
    return {"wind_u": u[:, None], "wind_v": v[:, None]}


#: The ``wind_u`` and ``wind_v`` observation entries.
WIND_OBSERVATION = ObservationTerms(spec={k: BoxSpec((1,)) for k in WIND_KEYS}, value=wind_at_ownship)


def add_wind(task: Task, wind: WindEffect, augment_obs: bool) -> None:
    """Install ``wind`` in every new episode of ``task``; with ``augment_obs`` also observe it."""
    if augment_obs and set(WIND_KEYS) & set(task.observation_spec):
        raise ValueError("the environment already observes the wind (wind_u, wind_v); wrap it with augment_obs=True only once")
    task.add_effect(wind)
    if augment_obs:
        task.add_observation_terms(WIND_OBSERVATION)


class WindFieldWrapper(gym.Wrapper):
    """Add wind to a single environment.

    The observation space of the environment (and of this wrapper) gains ``wind_u`` and
    ``wind_v`` with ``augment_obs``.

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
        self.augment_obs = augment_obs
        add_wind(_task_of(env), WindEffect(lat, lon, vnorth, veast, alt), augment_obs)


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
        self.augment_obs = augment_obs
        add_wind(_task_of(env), WindEffect(lat, lon, vnorth, veast, alt), augment_obs)
