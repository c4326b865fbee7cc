"""The task owns the time limit, however the environment is made.

``gym.make`` keeps its own ``max_episode_steps`` for Gymnasium's ``TimeLimit`` wrapper and never
passes it on, so the environment's limit goes through ``gym.make`` as ``time_limit``; everywhere
else (``gym.make_vec``, direct construction) it is ``max_episode_steps``.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import bluesky_gym  # noqa: F401
from bluesky_gym.registration import available_envs

from .expected_spaces import MAX_EPISODE_STEPS

IDS = available_envs()


def _run_single(env: gym.Env, seed: int, limit: int) -> tuple[int, bool, bool, dict]:
    env.reset(seed=seed)
    for t in range(1, limit + 1):
        _, _, te, tr, info = env.step(np.zeros(env.action_space.shape))
        if te or tr:
            return t, te, tr, info
    raise AssertionError(f"episode did not end within {limit} steps")


def _assert_ended_with_kpis_and_refuses_more(env: gym.Env, info: dict) -> None:
    assert any(k.startswith("kpi_") for k in info), "KPIs missing on the last step"
    with pytest.raises(RuntimeError, match="ended"):
        env.step(np.zeros(env.action_space.shape))


@pytest.mark.parametrize("env_id", IDS)
def test_gym_make_limit_shorter_than_default(env_id: str) -> None:
    env = gym.make(env_id, time_limit=7)
    assert env.spec.max_episode_steps == 7 and env.unwrapped.spec.max_episode_steps == 7
    steps, te, tr, info = _run_single(env, seed=0, limit=50)
    assert (steps, te, tr) == (7, False, True)
    _assert_ended_with_kpis_and_refuses_more(env, info)


def test_gym_make_limit_longer_than_default() -> None:
    env = gym.make("PlanWaypointEnv-v0", time_limit=500)
    assert env.unwrapped.task.time_limit == 500
    steps, te, tr, info = _run_single(env, seed=0, limit=600)
    assert (steps, te, tr) == (500, False, True)
    _assert_ended_with_kpis_and_refuses_more(env, info)


def test_default_limit_ends_the_episode_itself() -> None:
    env = gym.make("PlanWaypointEnv-v0")
    steps, te, tr, info = _run_single(env, seed=1, limit=400)
    assert (steps, te, tr) == (MAX_EPISODE_STEPS["PlanWaypointEnv-v0"], False, True)
    _assert_ended_with_kpis_and_refuses_more(env, info)


@pytest.mark.parametrize("limit", [5, 400])
def test_make_vec_limit(limit: int) -> None:
    venv = gym.make_vec("PlanWaypointEnv-v0", num_envs=3, vectorization_mode="vector_entry_point", max_episode_steps=limit)
    assert venv.spec.max_episode_steps == limit
    venv.reset(seed=1)
    for t in range(1, limit + 1):
        _, _, te, tr, info = venv.step(np.zeros((3, *venv.single_action_space.shape)))
        if t < limit:
            assert not tr.any()
    assert tr.all() and not te.any()
    assert info["_kpi_success"].all()


def test_termination_on_the_last_allowed_step_is_not_truncation() -> None:
    # StaticObstacle seed 204: the aircraft enters a restricted area on step 100, the last one.
    env = gym.make("StaticObstacleEnv-v0")
    assert _run_single(env, seed=204, limit=100)[:3] == (100, True, False)
    venv = gym.make_vec("StaticObstacleEnv-v0", num_envs=2, vectorization_mode="vector_entry_point")
    venv.reset(seed=[204, 0])
    for _ in range(100):
        _, _, te, tr, _ = venv.step(np.zeros((2, 2)))
    assert (bool(te[0]), bool(tr[0])) == (True, False)


def test_centralised_limit_from_gym_make() -> None:
    env = gym.make("MergeCentralised-v0", time_limit=4)
    assert env.spec.max_episode_steps == 4
    env.reset(seed=0)
    for _ in range(4):
        _, _, te, tr, info = env.step(np.zeros(env.action_space.shape))
    assert (te, tr) == (False, True)
    _assert_ended_with_kpis_and_refuses_more(env, info)


def test_sync_make_vec_limit_reaches_every_copy() -> None:
    venv = gym.make_vec("PlanWaypointEnv-v0", num_envs=2, vectorization_mode="sync", time_limit=5)
    venv.reset(seed=1)
    for _ in range(5):
        _, _, te, tr, info = venv.step(np.zeros((2, *venv.single_action_space.shape)))
    assert tr.all() and not te.any()
    assert info["_kpi_success"].all()


def test_gym_make_without_time_limit_keeps_the_task_limit() -> None:
    env = gym.make("MergeEnv-v0", max_episode_steps=-1)  # Gymnasium: no TimeLimit wrapper
    assert env.unwrapped.task.time_limit == MAX_EPISODE_STEPS["MergeEnv-v0"]


@pytest.mark.parametrize("limit", [5, 400])
def test_make_vec_takes_time_limit_too(limit: int) -> None:
    venv = gym.make_vec("PlanWaypointEnv-v0", num_envs=2, vectorization_mode="vector_entry_point", time_limit=limit)
    assert venv.spec.max_episode_steps == limit and venv.unwrapped.task.time_limit == limit


def test_gym_make_max_episode_steps_is_gymnasiums_outer_wrapper() -> None:
    # Gymnasium's own TimeLimit truncates from outside; the environment keeps its limit and its MDP.
    env = gym.make("SectorCREnv-v1", max_episode_steps=6)
    assert isinstance(env, gym.wrappers.TimeLimit) and env.spec.max_episode_steps == 6
    assert env.unwrapped.task.time_limit == MAX_EPISODE_STEPS["SectorCREnv-v0"] == env.unwrapped.spec.max_episode_steps
    steps, te, tr, info = _run_single(env, seed=0, limit=50)
    assert (steps, te, tr) == (6, False, True)
    assert not any(k.startswith("kpi_") for k in info), "the environment cannot see the wrapper's last step"


def test_both_names_must_agree() -> None:
    SectorCREnv = type(gym.make("SectorCREnv-v0").unwrapped)
    assert SectorCREnv(max_episode_steps=9, time_limit=9).task.time_limit == 9
    with pytest.raises(ValueError, match="same limit; give one"):
        SectorCREnv(max_episode_steps=9, time_limit=10)
    with pytest.raises(ValueError, match="max_episode_steps"):
        gym.make("SectorCREnv-v0", time_limit=0)
