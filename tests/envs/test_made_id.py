"""Errors and pictures name the id the user made: a -v1 id is named as itself, a -v0 id's messages stay as they were.

A -v1 id is its -v0 task configured (same task and configuration classes), so without care its
messages named the -v0 id or no id at all. Every check compares the -v1 message with the -v0
message of the same mistake: the -v1 one is exactly the -v0 one naming the -v1 id.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import bluesky_gym  # noqa: F401 - registers the ids
from bluesky_gym.envs.registry import ENVIRONMENTS, entry

V1 = [e.id for e in ENVIRONMENTS if e.id.endswith("-v1")]


#: What gymnasium.make appends to a TypeError of the constructor (it names the id and the keyword arguments).
GYMNASIUM_SUFFIX = " was raised from the environment creator for "


def _message(make: object) -> tuple[type[BaseException], str]:
    """The type and message of the error ``make()`` raises (without Gymnasium's suffix)."""
    with pytest.raises((ValueError, TypeError, RuntimeError)) as info:
        make()  # type: ignore[operator]
    return info.type, str(info.value).partition(GYMNASIUM_SUFFIX)[0]


def _named(v1: str, v0_message: str, v1_message: str) -> None:
    """``v1_message`` is ``v0_message`` naming ``v1`` (in place of the -v0 id, or in front)."""
    v0 = v1.replace("-v1", "-v0")
    assert v1 in v1_message and v0 not in v1_message, v1_message
    expected = v0_message.replace(v0, v1) if v0 in v0_message else f"{v1}: {v0_message}"
    assert v1_message == expected
    assert not v0_message.startswith(f"{v0}: "), "a -v0 message is left as it was"


def _both(v1: str, make: object) -> None:
    """``make(id)`` fails on the -v0 and the -v1 id in the same way, the -v1 message naming its id."""
    v0 = v1.replace("-v1", "-v0")
    kind0, text0 = _message(lambda: make(v0))  # type: ignore[operator]
    kind1, text1 = _message(lambda: make(v1))  # type: ignore[operator]
    assert kind0 is kind1
    _named(v1, text0, text1)


@pytest.mark.parametrize("env_id", V1)
def test_bad_options_name_the_v1_id(env_id: str) -> None:
    _both(env_id, lambda i: gym.make(i, not_an_option=3))
    _both(env_id, lambda i: gym.make(i, float32_spaces="yes"))
    _both(env_id, lambda i: gym.make(i, render_mode="ascii"))
    _both(env_id, lambda i: gym.make(i, backend="xplane"))
    _both(env_id, lambda i: gym.make_vec(i, num_envs=2, vectorization_mode="vector_entry_point", not_an_option=3))
    _both(env_id, lambda i: gym.make_vec(i, num_envs=2, vectorization_mode="vector_entry_point", max_episode_steps=-1))
    fix = dict(entry(env_id).options)
    # one of the id's own fixes (RealTrafficCREnv-v1 has none but float32_spaces), given a non-switch value
    name = next((k for k in fix if k != "float32_spaces"), "float32_spaces")
    with pytest.raises(ValueError, match=f"^{env_id}: {name} must be True or False, got 'no'"):
        gym.make(env_id, **{name: "no"})


@pytest.mark.parametrize("env_id", V1)
def test_bad_actions_name_the_v1_id(env_id: str) -> None:
    def env(i: str) -> gym.Env:
        e = gym.make(i).unwrapped
        e.reset(seed=0)
        return e

    def venv(i: str) -> gym.vector.VectorEnv:
        v = gym.make_vec(i, num_envs=2, vectorization_mode="vector_entry_point")
        v.reset(seed=0)
        return v

    shape = gym.make(env_id).action_space.shape
    _both(env_id, lambda i: env(i).step(np.zeros(shape[0] + 1)))
    _both(env_id, lambda i: env(i).step(np.full(shape, np.nan)))
    _both(env_id, lambda i: env(i).step("0.5"))
    _both(env_id, lambda i: gym.make(i).unwrapped.step(np.zeros(shape)))  # before reset
    _both(env_id, lambda i: env(i).reset(options={"seed": 1}))
    _both(env_id, lambda i: venv(i).step(np.zeros((3, *shape))))
    _both(env_id, lambda i: venv(i).step(np.full((2, *shape), np.inf)))
    _both(env_id, lambda i: venv(i).reset(seed=[1, 2, 3]))


@pytest.mark.parametrize("env_id", V1)
def test_the_task_runs_as_the_made_id(env_id: str) -> None:
    v0 = env_id.replace("-v1", "-v0")
    assert gym.make(env_id).unwrapped.task.id == env_id
    assert gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point").unwrapped.task.id == env_id
    assert gym.make_vec(env_id, num_envs=2, vectorization_mode="sync").env_fns[0]().unwrapped.task.id == env_id
    assert gym.make(v0).unwrapped.task.id == v0
    # The class made directly (no id): the task's own id; the -v1 options alone do not make it -v1.
    cls = entry(env_id).env_class()
    direct = cls(**dict(entry(env_id).options))
    assert direct.task.id == direct.task.env_id == v0
    with pytest.raises(ValueError, match=r"^action contains NaN"):
        direct.reset(seed=0)
        direct.step(np.full(direct.action_space.shape, np.nan))


def test_the_picture_names_the_made_id() -> None:
    """The same episode made under two ids: the frames differ only in the title of the panel."""
    pytest.importorskip("pygame")
    other = "SectorCRTitleCheck-v9"
    gym.register(id=other, entry_point=entry("SectorCREnv-v0").env, max_episode_steps=None)
    try:
        frames = []
        for env_id in ("SectorCREnv-v0", other):
            env = gym.make(env_id, render_mode="rgb_array")
            env.reset(seed=0)
            env.step(np.zeros(env.action_space.shape))
            frames.append(env.render())
            env.close()
    finally:
        gym.registry.pop(other)
    rows = np.flatnonzero((frames[0] != frames[1]).any(axis=(1, 2)))
    assert rows.size, "the title does not show the id"
    assert rows.max() < 40, f"rows {rows.min()}..{rows.max()} differ: more than the title"


def test_the_example_of_the_v1_page() -> None:
    """docs/environments-v1.md: the error of a switch given 'no'."""
    with pytest.raises(ValueError) as info:
        gym.make("SectorCREnv-v1", exit_ends_episode="no")
    assert str(info.value) == "SectorCREnv-v1: exit_ends_episode must be True or False, got 'no'"


@pytest.mark.parametrize("env_id", V1)
def test_gymnasium_errors_inside_the_environment_name_the_v1_id(env_id: str) -> None:
    """Gymnasium's own errors raised while the environment runs (a seed that is not a seed) name the -v1 id too."""
    for make in (lambda i: gym.make(i), lambda i: gym.make(i).unwrapped):
        with pytest.raises(gym.error.Error, match=rf"^{env_id}: Seed must be a python integer"):
            make(env_id).reset(seed=1.5)
        with pytest.raises(gym.error.Error, match=r"^Seed must be a python integer"):
            make(env_id.replace("-v1", "-v0")).reset(seed=1.5)


@pytest.mark.parametrize("env_id", V1)
def test_a_step_before_reset_as_the_v1_page_says(env_id: str) -> None:
    """docs/environments-v1.md: gym.make's order wrapper answers with Gymnasium's message; the environment itself names the id."""
    env = gym.make(env_id)
    shape = env.action_space.shape
    with pytest.raises(gym.error.ResetNeeded) as info:
        env.step(np.zeros(shape))
    assert env_id not in str(info.value)
    with pytest.raises(RuntimeError, match=rf"^{env_id}: step\(\) called before reset\(\)"):
        env.unwrapped.step(np.zeros(shape))
    venv = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point")
    with pytest.raises(RuntimeError, match=rf"^{env_id}: step\(\) called before reset\(\)"):
        venv.step(np.zeros((2, *shape)))
