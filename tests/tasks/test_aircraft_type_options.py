"""The aircraft-type mix options of HorizontalCR, VerticalCR, SectorCR and Merge."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import bluesky_gym  # noqa: F401  (registers the environments)

ENVS = ["HorizontalCREnv-v0", "VerticalCREnv-v0", "SectorCREnv-v0", "MergeEnv-v0"]
MIX = {"intruder_types": {"A320": 0.4, "B744": 0.3, "E190": 0.3}, "ownship_types": ("C550", "GLF6")}


def _fleet(env: gym.Env, e: int = 0) -> list[str]:
    sim = env.unwrapped.task.sim
    return sim.aircraft_type(e, np.flatnonzero(sim.active[e]))


def _positions(env: gym.Env) -> np.ndarray:
    sim = env.unwrapped.task.sim
    act = sim.active[0]
    return np.stack([sim.lat[0, act], sim.lon[0, act], sim.hdg[0, act], sim.alt[0, act]])


@pytest.mark.parametrize("env_id", ENVS)
def test_type_mix_changes_the_fleet_reproducibly(env_id: str) -> None:
    default = gym.make(env_id)
    default.reset(seed=5)
    assert set(_fleet(default)) == {"A320"}
    one_type = gym.make(env_id, intruder_types=("a320",), ownship_types="A320")
    obs_one, _ = one_type.reset(seed=5)
    obs_default, _ = gym.make(env_id).reset(seed=5)
    for k in obs_default:  # a one-type mix draws nothing: the paper's episode
        np.testing.assert_array_equal(obs_one[k], obs_default[k])
    mixed = gym.make(env_id, **MIX)
    fleets = []
    for seed in (5, 6, 5):
        mixed.reset(seed=seed)
        fleets.append(_fleet(mixed))
        assert fleets[-1][0] in ("C550", "GLF6")
        assert set(fleets[-1][1:]) <= {"A320", "B744", "E190"}
    assert fleets[0] == fleets[2]  # same seed, same fleet
    assert len(set(fleets[0][1:])) > 1 or len(set(fleets[1][1:])) > 1
    again = gym.make(env_id, **MIX)
    again.reset(seed=5)
    assert _fleet(again) == fleets[0]
    for _ in range(3):
        mixed.step(mixed.action_space.sample())


@pytest.mark.parametrize("env_id", ["HorizontalCREnv-v0", "SectorCREnv-v0", "MergeEnv-v0"])
def test_types_are_drawn_after_the_scenario(env_id: str) -> None:
    """The positions, headings and altitudes of a seed do not depend on the type mix."""
    a, b = gym.make(env_id), gym.make(env_id, **MIX)
    a.reset(seed=11)
    b.reset(seed=11)
    np.testing.assert_array_equal(_positions(a), _positions(b))


def test_batched_episode_has_the_single_episode_fleet() -> None:
    venv = gym.make_vec("MergeEnv-v0", num_envs=3, vectorization_mode="vector_entry_point", **MIX)
    venv.reset(seed=20)
    for i in range(3):
        single = gym.make("MergeEnv-v0", **MIX)
        single.reset(seed=20 + i)
        sim = venv.unwrapped.task.sim
        assert sim.aircraft_type(i, np.flatnonzero(sim.active[i])) == _fleet(single)


@pytest.mark.parametrize(
    ("value", "message"),
    [
        (("A320", "XX99"), r"intruder_types: aircraft type 'XX99' is not supported; supported types: A124, .*B744"),
        ("EC35", "'EC35' is not supported"),
        ((), "at least one aircraft type"),
        ({"A320": -1.0}, "intruder_types weight must be >= 0.0"),
        ({"A320": 0.0}, "positive sum"),
        (("A320", "a320"), "names a type twice"),
        (320, "must be a type name"),
    ],
)
def test_bad_type_mix_is_refused(value: object, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        gym.make("HorizontalCREnv-v0", intruder_types=value)
