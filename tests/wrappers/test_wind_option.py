"""Wind as an environment option: ``gym.make(id, wind=...)`` gives, bit for bit, what the wind wrappers gave.

The wrappers' earlier implementation (a ``WindEffect`` adding the points at every reset, and the
wind observation terms, installed in the wrapped environment's task) is reproduced here as
``OldWindEffect`` and ``old_wind_observation``, so that the option is compared with what the
wrappers did, not only with the deprecated aliases that now call the option's code.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import bluesky_gym  # noqa: F401
from bluesky_gym.core.wind import Wind
from bluesky_gym.tasks.base import BoxSpec, ObservationTerms
from bluesky_gym.wrappers import VectorWindFieldWrapper, WindFieldWrapper

#: Two wind points (a 2-D field), with their observation.
POINTS = {"lat": [51.5, 52.5], "lon": [4.0, 4.5], "vnorth": [-10.0, 3.0], "veast": [15.0, -7.5]}
IDS = ["DescentEnv-v0", "VerticalCREnv-v0", "MergeEnv-v0", "StaticObstacleEnv-v0", "SectorCREnv-v1"]


class OldWindEffect:
    """The wind wrappers' effect as it was: the points, as float64 arrays, added to every new episode."""

    def __init__(self, lat: list[float], lon: list[float], vnorth: list[float], veast: list[float]) -> None:
        self.lat, self.lon, self.vnorth, self.veast = (np.atleast_1d(np.asarray(x, dtype=np.float64)).ravel() for x in (lat, lon, vnorth, veast))

    def on_reset(self, task, envs) -> None:  # type: ignore[no-untyped-def]
        for e in envs:
            task.sim.wind.add_points(int(e), self.lat, self.lon, self.vnorth, self.veast)


def old_wind_observation(task, envs):  # type: ignore[no-untyped-def]
    """The wrappers' wind_u and wind_v as they were."""
    sim = task.sim
    wn, we = sim.wind.at(envs, sim.lat[envs, 0], sim.lon[envs, 0])
    h = np.deg2rad(sim.hdg[envs, 0])
    u = (wn * np.cos(h) + we * np.sin(h)) / 50.0
    v = (-wn * np.sin(h) + we * np.cos(h)) / 50.0
    return {"wind_u": u[:, None], "wind_v": v[:, None]}


def old_wrapper(env, observe: bool):  # type: ignore[no-untyped-def]
    """What ``WindFieldWrapper(env, **POINTS, augment_obs=observe)`` did to the environment's task."""
    task = env.unwrapped.task
    task.add_effect(OldWindEffect(**POINTS))
    if observe:
        task.add_observation_terms(ObservationTerms({k: BoxSpec((1,)) for k in ("wind_u", "wind_v")}, old_wind_observation))
    return env


def _bits(x) -> bytes:  # type: ignore[no-untyped-def]
    return np.asarray(x).tobytes()


def _episode(env: gym.Env, steps: int, seed: int) -> list[bytes]:
    """Everything the environment returns over ``steps`` random steps (resetting when an episode ends), as bytes."""
    out: list[bytes] = []
    obs, info = env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    for _ in range(steps):
        out += [_bits(obs[k]) for k in sorted(obs)] + [repr(sorted(info.items())).encode()]
        obs, reward, te, tr, info = env.step(rng.uniform(-1, 1, env.action_space.shape))
        out.append(_bits([reward, te, tr]))
        if te or tr:
            obs, info = env.reset()
    return out


@pytest.mark.parametrize("observe", [False, True])
@pytest.mark.parametrize("env_id", IDS)
def test_the_option_gives_the_wrappers_results_bit_for_bit(env_id: str, observe: bool) -> None:
    option = _episode(gym.make(env_id, wind=Wind(**POINTS, observe=observe)), 60, seed=3)
    assert option == _episode(old_wrapper(gym.make(env_id), observe), 60, seed=3)
    with pytest.warns(DeprecationWarning, match="pass wind=Wind"):
        alias = WindFieldWrapper(gym.make(env_id), **POINTS, augment_obs=observe)
    assert option == _episode(alias, 60, seed=3)
    assert option != _episode(gym.make(env_id), 60, seed=3)  # the wind changes the episodes


def test_the_vector_option_gives_the_vector_wrappers_results_bit_for_bit() -> None:
    def run(venv: gym.vector.VectorEnv) -> list[bytes]:
        obs, _ = venv.reset(seed=[4, 9, 11])
        out = []
        rng = np.random.default_rng(0)
        for _ in range(80):
            obs, reward, te, tr, info = venv.step(rng.uniform(-1, 1, (3, 1)))
            out += [_bits(obs[k]) for k in sorted(obs)] + [_bits(reward), _bits(te), _bits(tr)]
            out += [_bits(info["final_obs"][k]) for k in sorted(info.get("final_obs", {}))]
        return out

    def make(**kw) -> gym.vector.VectorEnv:  # type: ignore[no-untyped-def]
        return gym.make_vec("DescentEnv-v0", num_envs=3, vectorization_mode="vector_entry_point", **kw)

    option = run(make(wind=Wind(**POINTS, observe=True)))
    assert option == run(old_wrapper(make(), True))
    with pytest.warns(DeprecationWarning):
        assert option == run(VectorWindFieldWrapper(make(), **POINTS, augment_obs=True))


def test_the_wind_is_the_tasks_configuration() -> None:
    """The wind is part of the environment, not of a wrapper: the unwrapped environment, its spec and a copy made from it have it."""
    env = gym.make("DescentEnv-v0", wind={**POINTS, "observe": True})
    wind = env.unwrapped.config.wind
    assert wind == Wind(**POINTS, observe=True) and wind.lat == (51.5, 52.5)
    assert hash(env.unwrapped.config) == hash(env.unwrapped.config)  # still hashable
    again = gym.make(env.spec)
    assert again.unwrapped.config == env.unwrapped.config
    assert _episode(again, 20, seed=1) == _episode(env, 20, seed=1)
    assert gym.make("DescentEnv-v0").unwrapped.config.wind is None
    assert "wind_u" in env.unwrapped.observation_space.spaces and "wind_u" not in gym.make("DescentEnv-v0").observation_space.spaces
