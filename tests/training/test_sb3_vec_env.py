"""SB3's VecEnv API over the native batched environment."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("stable_baselines3", reason="needs Stable-Baselines3 (the 'train' extra)")

from stable_baselines3 import PPO, SAC
from stable_baselines3.common.evaluation import evaluate_policy
from stable_baselines3.common.monitor import Monitor
from stable_baselines3.common.vec_env import DummyVecEnv, VecEnv

from bluesky_gym.envs.seeds import TRAIN_SEED_LIMIT, train_env_seeds
from bluesky_gym.training import make_vector_env
from bluesky_gym.training.sb3_vec_env import SB3VecEnv

ENV = "DescentEnv-v0"


def _rollout(venv: SB3VecEnv, steps: int, seed: int = 0) -> list:
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(steps):
        a = rng.uniform(-1, 1, (venv.num_envs, *venv.action_space.shape)).astype(np.float32)
        out.append(venv.step(a))
    return out


def test_is_an_sb3_vec_env_with_dict_spaces() -> None:
    venv = SB3VecEnv(ENV, num_envs=3)
    assert isinstance(venv, VecEnv)
    assert venv.num_envs == 3
    assert set(venv.observation_space.spaces) == {"altitude", "vz", "target_altitude", "runway_distance"}
    obs = venv.reset()
    assert all(v.shape == (3, 1) and v.dtype == np.float64 for v in obs.values())
    venv.close()


def test_step_outputs_and_terminal_observation() -> None:
    venv = SB3VecEnv(ENV, num_envs=4)
    venv.seed(3)
    venv.reset()
    returns = np.zeros(4)
    lengths = np.zeros(4, int)
    finished = 0
    for obs, rew, dones, infos in _rollout(venv, 60):
        assert rew.dtype == np.float32 and rew.shape == (4,)
        assert dones.dtype == bool and len(infos) == 4
        returns += rew
        lengths += 1
        for i, info in enumerate(infos):
            assert "TimeLimit.truncated" in info
            assert isinstance(info["total_reward"], float)
            if dones[i]:
                finished += 1
                term = info["terminal_observation"]
                assert set(term) == set(obs)
                # The returned observation is already the next episode's first one.
                assert any(not np.array_equal(term[k], obs[k][i]) for k in obs)
                assert info["episode"]["l"] == lengths[i]
                assert info["episode"]["r"] == pytest.approx(info["total_reward"])
                assert info["episode"]["r"] == pytest.approx(returns[i], abs=1e-3)
                assert 0.0 <= info["kpi_success"] <= 1.0
                assert set(info["episode_reward_components"]) == {"reward_altitude", "reward_crash", "reward_runway"}
                assert sum(info["episode_reward_components"].values()) == pytest.approx(info["episode"]["r"])
                returns[i] = 0.0
                lengths[i] = 0
            else:
                assert "terminal_observation" not in info and "episode" not in info
                assert not any(k.startswith("kpi_") for k in info)
    assert finished >= 4  # Descent episodes last about 40 steps


def test_time_limit_truncation_is_flagged() -> None:
    venv = SB3VecEnv(ENV, num_envs=2, max_episode_steps=3)
    venv.reset()
    results = _rollout(venv, 3)
    _, _, dones, infos = results[-1]
    assert dones.all()
    assert all(info["TimeLimit.truncated"] for info in infos)
    assert all(info["episode"]["l"] == 3 for info in infos)
    assert not any(info["TimeLimit.truncated"] for info in results[0][3])


def test_seed_reproduces_and_uses_training_range() -> None:
    venv = SB3VecEnv(ENV, num_envs=3)
    seeds = venv.seed(11)
    assert list(seeds) == train_env_seeds(11, 3)
    assert all(0 <= s < TRAIN_SEED_LIMIT for s in seeds)
    first = venv.reset()
    a = [r[0] for r in _rollout(venv, 5)]
    venv.seed(11)
    again = venv.reset()
    b = [r[0] for r in _rollout(venv, 5)]
    for k in first:
        np.testing.assert_array_equal(first[k], again[k])
        np.testing.assert_array_equal(a[-1][k], b[-1][k])
    venv.seed(12)
    other = venv.reset()
    assert any(not np.array_equal(first[k], other[k]) for k in first)
    # Environment i of the adapter is the single environment reset with the i-th seed.
    single = make_vector_env(ENV, 1)
    obs1, _ = single.reset(seed=[seeds[2]])
    for k in first:
        np.testing.assert_array_equal(obs1[k][0], first[k][2])


def test_attributes_methods_and_wrappers() -> None:
    venv = SB3VecEnv(ENV, num_envs=2)
    assert venv.get_attr("num_envs") == [2, 2]
    assert venv.get_attr("render_mode", indices=[1]) == [None]
    venv.set_attr("render_env", 1)
    assert venv.venv.render_env == 1
    assert venv.env_method("reset", seed=[1, 2], indices=[0, 1])[0][0]["altitude"].shape == (2, 1)
    assert venv.env_is_wrapped(Monitor) == [True, True]
    assert venv.env_is_wrapped(DummyVecEnv) == [False, False]
    with pytest.raises(TypeError):
        SB3VecEnv(make_vector_env(ENV, 2), num_envs=2, alt_min=2100)


def test_ppo_learns_on_the_batched_env() -> None:
    venv = SB3VecEnv(ENV, num_envs=4)
    model = PPO("MultiInputPolicy", venv, n_steps=32, batch_size=64, n_epochs=2, seed=0, device="cpu")
    model.learn(256)
    assert model.num_timesteps == 256
    assert len(model.ep_info_buffer) >= 1  # episode statistics reach SB3's logger
    mean, _ = evaluate_policy(model, venv, n_eval_episodes=4)
    assert np.isfinite(mean)


def test_sac_learns_on_the_batched_env() -> None:
    venv = SB3VecEnv(ENV, num_envs=4)
    model = SAC("MultiInputPolicy", venv, learning_starts=40, buffer_size=2000, batch_size=32, seed=0, device="cpu")
    model.learn(240)
    assert model.num_timesteps == 240
    assert model.replay_buffer.size() * venv.num_envs == 240
    # Terminal transitions store the real final observation (not the next episode's first);
    # the others store the observation the next transition starts from.
    rb = model.replay_buffer
    n = rb.size()
    keys = list(rb.observations)
    done_rows = 0
    for t in range(n - 1):
        for i in range(venv.num_envs):
            same = all(np.array_equal(rb.next_observations[k][t, i], rb.observations[k][t + 1, i]) for k in keys)
            if rb.dones[t, i] > 0:
                done_rows += 1
                assert not same
            else:
                assert same
    assert done_rows > 0
