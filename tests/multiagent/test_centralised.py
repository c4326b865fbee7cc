"""The centralised environments: one Gymnasium agent for every aircraft."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import bluesky_gym.multiagent as ma
from bluesky_gym.multiagent.base import STATE_FEATURES
from bluesky_gym.multiagent.centralised import HorizontalCRCentralisedEnv

IDS = ma.centralised_ids()
LIMITS = {"SectorCRCentralised-v0": 200, "MergeCentralised-v0": 50, "HorizontalCRCentralised-v0": 300, "DenseSectorCRCentralised-v0": 200}


@pytest.fixture(autouse=True)
def _registered() -> None:
    ma.register_envs()
    ma.register_envs()  # idempotent


@pytest.mark.parametrize("env_id", IDS)
def test_check_env(env_id: str) -> None:
    env = gym.make(env_id)
    check_env(env.unwrapped, skip_render_check=True)
    assert gym.registry[env_id].max_episode_steps is None  # the task owns the time limit
    assert env.spec.max_episode_steps == LIMITS[env_id]
    env.close()


@pytest.mark.parametrize("env_id", IDS)
def test_spaces_and_seeding(env_id: str) -> None:
    env = gym.make(env_id)
    task = env.unwrapped.task
    m = task.n_agents
    assert env.observation_space["local"].shape == (m, task.observation_size)
    assert env.observation_space["state"].shape == (m, len(STATE_FEATURES))
    assert env.action_space.shape == (m * int(np.prod(task.action_spec.shape)),)
    obs1, _ = env.reset(seed=3)
    obs2, _ = env.reset(seed=3)
    obs3, _ = env.reset(seed=4)
    assert all(np.array_equal(obs1[k], obs2[k]) for k in obs1)
    assert not np.array_equal(obs1["state"], obs3["state"])
    # Empty slots: all zeros in both parts.
    empty = obs3["state"][:, 0] == 0.0
    assert np.all(obs3["local"][empty] == 0.0) and np.all(obs3["state"][empty] == 0.0)


def test_joint_action_layout_and_team_reward() -> None:
    env = gym.make("SectorCRCentralised-v0")
    env.reset(seed=1)
    task = env.unwrapped.task
    hdg0 = task.sim.hdg[0].copy()
    action = np.zeros(env.action_space.shape)
    action[1 * 2 + 0] = 1.0  # slot 1 turns right, everyone else holds its heading
    _, reward, terminated, truncated, info = env.step(action)
    turn = (task.sim.hdg[0] - hdg0 + 180.0) % 360.0 - 180.0
    assert turn[1] > 5.0
    others = np.flatnonzero(task.sim.active[0])
    others = others[others != 1]
    assert np.allclose(turn[others], 0.0, atol=1e-6)
    # The team reward is the sum of the agents' rewards (here drift and intrusion penalties).
    assert reward == pytest.approx(info["reward_drift"] + info["reward_intrusion"])
    assert reward == pytest.approx(info["total_reward"])
    assert not terminated and not truncated


def test_same_episode_as_the_parallel_env() -> None:
    pytest.importorskip("pettingzoo")
    central = gym.make("MergeCentralised-v0")
    par = ma.parallel_env("merge_v0")
    obs_c, _ = central.reset(seed=9)
    obs_p, _ = par.reset(seed=9)
    rng = np.random.default_rng(0)
    for _ in range(4):
        joint = rng.uniform(-1, 1, (central.unwrapped.task.n_agents, 2))
        obs_c, r_c, *_ = central.step(joint.ravel())
        obs_p, r_p, *_ = par.step({a: joint[par.agent_name_mapping[a]] for a in par.agents})
        assert r_c == pytest.approx(sum(r_p.values()))
    assert np.allclose(obs_c["state"].ravel(), par.state())


def test_episode_end_and_kpis() -> None:
    # The environment's own time limit (gym.make's max_episode_steps only adds a TimeLimit wrapper).
    env = HorizontalCRCentralisedEnv(max_episode_steps=2)
    env.reset(seed=0)
    env.step(env.action_space.sample())
    _, _, terminated, truncated, info = env.step(env.action_space.sample())
    assert truncated and not terminated
    assert "kpi_los_count" in info and info["kpi_agents"] == 6.0
    with pytest.raises(RuntimeError):
        env.step(env.action_space.sample())


def test_render_rgb_array(monkeypatch: pytest.MonkeyPatch) -> None:
    pytest.importorskip("pygame")
    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")
    env = gym.make("MergeCentralised-v0", render_mode="rgb_array")
    env.reset(seed=0)
    frame = env.render()
    assert frame.dtype == np.uint8 and frame.shape[2] == 3
    env.close()


@pytest.mark.parametrize("bad", ["0.5", b"1", None])
def test_joint_actions_that_are_not_real_numbers_are_refused(bad: object) -> None:
    env = gym.make("HorizontalCRCentralised-v0").unwrapped
    env.reset(seed=0)
    with pytest.raises(ValueError, match="real numbers"):
        env.step(bad)
    task = ma.task_class("sector_cr_v0")(1)
    with pytest.raises(ValueError, match="real numbers"):
        task.step(np.full((1, task.n_agents, *task.action_spec.shape), 0.5 + 1j))


@pytest.mark.parametrize(
    ("options", "message"),
    [(5, r"^reset options must be a dict or None, got int 5$"), ({"seed": 1}, r"^reset options are not")],
)
def test_reset_options_are_refused_with_their_reason(options: object, message: str) -> None:
    env = gym.make("HorizontalCRCentralised-v0").unwrapped
    with pytest.raises(ValueError, match=message):
        env.reset(options=options)
