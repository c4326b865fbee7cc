"""Deprecated wind wrappers: wind is the ``wind`` option of every environment.

``gym.make(id, wind=Wind(lat, lon, vnorth, veast, observe=True))`` (or ``gym.make_vec(...,
wind=...)``) gives an environment whose task installs the wind in every episode and, with
``observe``, observes it (:class:`~bluesky_gym.core.wind.Wind` describes both). The wind is part of
the task's configuration (``env.unwrapped.config.wind``) and of ``env.spec.kwargs``, so that an
environment made again from its spec has it.

:class:`WindFieldWrapper` and :class:`VectorWindFieldWrapper` are kept as thin aliases of that
option for existing code: they install the same wind in the wrapped environment's task
(:meth:`Task.add_wind <bluesky_gym.tasks.base.Task.add_wind>`, which the option calls), with the
same results bit for bit. They are not true wrappers (the wind lives in the task, so
``env.unwrapped`` still has it) and warn with a :class:`DeprecationWarning`.
"""

from __future__ import annotations

import warnings
from typing import Any

import gymnasium as gym
from gymnasium.vector import VectorEnv, VectorWrapper
from numpy.typing import ArrayLike

from bluesky_gym.core.wind import MAX_WIND, WIND_KEYS, Wind
from bluesky_gym.tasks.base import Task

__all__ = ["MAX_WIND", "WIND_KEYS", "VectorWindFieldWrapper", "Wind", "WindFieldWrapper"]

_DEPRECATED = "{name} is deprecated: pass wind=Wind(lat, lon, vnorth, veast, observe=...) to gym.make or gym.make_vec instead"


def _install(
    env: Any, name: str, lat: ArrayLike, lon: ArrayLike, vnorth: ArrayLike, veast: ArrayLike, alt: ArrayLike | None, augment_obs: bool
) -> None:
    """Warn that ``name`` is deprecated and add the wind to the task of ``env``, as the ``wind`` option does."""
    warnings.warn(_DEPRECATED.format(name=name), DeprecationWarning, stacklevel=3)
    task = getattr(env.unwrapped, "task", None)
    if not isinstance(task, Task):
        raise TypeError("the wind wrapper needs a BlueSky-Gym environment (an env with a .task)")
    wind = Wind.of({"lat": lat, "lon": lon, "vnorth": vnorth, "veast": veast, "alt": alt, "observe": augment_obs})
    assert wind is not None
    task.add_wind(wind)


class WindFieldWrapper(gym.Wrapper):
    """Deprecated: add wind to a single environment (use ``gym.make(id, wind=Wind(...))``).

    Args:
        env: A BlueSky-Gym environment.
        lat: Latitudes of the wind points [deg].
        lon: Longitudes of the wind points [deg].
        vnorth: North components [m/s] (the direction the wind blows to), any shape with one value per point.
        veast: East components [m/s].
        alt: Must be None (a 2-D field).
        augment_obs: Add ``wind_u`` and ``wind_v`` to the observation (the option's ``observe``).
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
        _install(env, "WindFieldWrapper", lat, lon, vnorth, veast, alt, augment_obs)


class VectorWindFieldWrapper(VectorWrapper):
    """Deprecated: add wind to every episode of a natively batched environment (use ``gym.make_vec(..., wind=Wind(...))``).

    Same arguments as :class:`WindFieldWrapper`.
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
        _install(env, "VectorWindFieldWrapper", lat, lon, vnorth, veast, alt, augment_obs)
