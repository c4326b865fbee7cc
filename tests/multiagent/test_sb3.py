"""The SB3 parameter-shared adapter, the reference policies and the evaluation."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from stable_baselines3 import PPO

from bluesky_gym.environments.horizontal_cr.multiagent import HorizontalCRMultiAgentTask
from bluesky_gym.multiagent.evaluation import evaluate, kpi_table, summarise
from bluesky_gym.multiagent.policies import GeometricCRPolicy, RandomPolicy, SB3Policy
from bluesky_gym.multiagent.sb3 import (
    LiveRowsRolloutBuffer,
    LiveRowsVecNormalize,
    SharedPolicyVecEnv,
    track_live_rows,
)
from bluesky_gym.tasks.geometry import point_at_distance


def test_rows_are_agent_slots() -> None:
    venv = SharedPolicyVecEnv("sector_cr_v0", n_episodes=3)
    task = venv.task
    assert venv.num_envs == 3 * task.n_agents
    venv.seed(5)
    obs = venv.reset()
    assert obs["x_r"].shape == (venv.num_envs, 4)
    live = task.sim.active.reshape(-1)
    assert np.all(obs["traffic_mask"][~live] == 0.0) and np.all(obs["traffic_mask"][live, 0] == 1.0)
    rng = np.random.default_rng(0)
    obs, reward, dones, infos = venv.step(rng.uniform(-1, 1, (venv.num_envs, 2)))
    assert np.array_equal(venv.live_rows, live)
    # Dummy rows: zero reward, done at every step, no bootstrapping, no episode statistics.
    assert np.all(reward[~live] == 0.0) and np.all(dones[~live])
    assert all(not infos[i]["TimeLimit.truncated"] and "episode" not in infos[i] for i in np.flatnonzero(~live))
    assert all(infos[i]["agent_active"] for i in np.flatnonzero(live))
    assert np.all(reward[live] < 0.0)  # drift / intrusion penalties
    # Row e * n_agents + k is aircraft k of episode e.
    assert np.allclose(reward.reshape(3, task.n_agents), task.agent_return, atol=1e-6)


def test_agents_leaving_and_episode_restart() -> None:
    venv = SharedPolicyVecEnv("horizontal_cr_v0", n_episodes=2, max_episode_steps=3)
    venv.seed(0)
    first = venv.reset()
    zeros = np.zeros((venv.num_envs, 1))
    for _ in range(2):
        obs, reward, dones, infos = venv.step(zeros)
        assert not dones.any()
    obs, reward, dones, infos = venv.step(zeros)
    # Time limit: every agent truncated (bootstrapped), with its final observation and statistics.
    assert dones.all()
    for info in infos:
        assert info["TimeLimit.truncated"] and info["episode"]["l"] == 3
        assert info["terminal_observation"]["waypoint_distance"].shape == (1,)
    assert venv.episodes_done == 2 and len(venv.episode_kpis) == 2
    assert {"return", "kpi_los_count", "kpi_completion_rate"} <= set(venv.episode_kpis[0])
    # The episodes restarted in the same step: new scenarios (the generator continues).
    assert not np.array_equal(obs["waypoint_distance"], first["waypoint_distance"])
    assert venv.task.stats.steps.tolist() == [0, 0]


def test_agent_done_mid_episode_becomes_a_dummy_row() -> None:
    task = HorizontalCRMultiAgentTask(1)
    venv = SharedPolicyVecEnv(task)
    venv.seed(1)
    venv.reset()
    # Aircraft 2's waypoint 5 km ahead: it arrives within the step (about 6 km flown in 50 s).
    s = task.sim
    task.wpt_lat[0, 2], task.wpt_lon[0, 2] = point_at_distance(s.lat[0, 2], s.lon[0, 2], 5.0, s.hdg[0, 2])
    obs, reward, dones, infos = venv.step(np.zeros((venv.num_envs, 1)))
    assert dones[2] and not infos[2]["TimeLimit.truncated"] and reward[2] > 0.5  # arrived: +1
    assert np.all(obs["intruder_distance"][2] == 0.0)  # its next observation is the dummy one
    assert not dones[[0, 1, 3, 4, 5]].any()
    obs, reward, dones, infos = venv.step(np.zeros((venv.num_envs, 1)))
    assert dones[2] and reward[2] == 0.0 and not infos[2]["agent_active"]


def test_ppo_trains_on_the_shared_adapter() -> None:
    venv = SharedPolicyVecEnv("sector_cr_v0", n_episodes=2)
    model = PPO("MultiInputPolicy", venv, n_steps=4, batch_size=76, n_epochs=1, seed=0, device="cpu")
    model.learn(total_timesteps=400)
    assert model.num_timesteps >= 400
    policy = SB3Policy(model)
    records = evaluate("sector_cr_v0", policy, 2, max_episode_steps=5)
    assert len(records) == 2 and all(np.isfinite(r["kpi_los_steps"]) for r in records)


def test_live_rows_buffer_and_normaliser() -> None:
    rows = SharedPolicyVecEnv("sector_cr_v0", n_episodes=2)
    venv = LiveRowsVecNormalize(rows)
    model = PPO("MultiInputPolicy", venv, n_steps=8, batch_size=76, n_epochs=1, seed=0, device="cpu", rollout_buffer_class=LiveRowsRolloutBuffer)
    track_live_rows(model, rows)
    live_seen: list[np.ndarray] = []
    original = rows.step_wait

    def spy():
        out = original()
        live_seen.append(rows.live_rows.copy())
        return out

    rows.step_wait = spy
    model.learn(total_timesteps=8 * rows.num_envs)
    buffer = model.rollout_buffer
    n_live = int(np.sum(live_seen[-8:]))
    assert 0 < n_live < buffer.buffer_size * buffer.n_envs
    assert np.array_equal(buffer.live, np.array(live_seen[-8:]))
    # Minibatches hold live transitions only: their observations have an own drift (cos^2 + sin^2 = 1).
    batches = list(buffer.get(76))
    assert sum(len(b.actions) for b in batches) == n_live
    for b in batches:
        obs = {k: v.numpy() for k, v in b.observations.items()}
        assert np.all(np.abs(obs["cos(drift)"]) + np.abs(obs["sin(drift)"]) > 0)
    # The running statistics only counted live rows: the first reset and every step's live rows.
    count = venv.obs_rms["airspeed"].count
    assert count < 0.7 * (9 * rows.num_envs)
    # The normaliser's statistics are frozen when evaluating.
    venv.training = False
    before = venv.obs_rms["x_r"].mean.copy()
    evaluate("sector_cr_v0", SB3Policy(model, normalizer=venv), 1, max_episode_steps=3)
    assert np.array_equal(before, venv.obs_rms["x_r"].mean)
    with pytest.raises(TypeError):
        track_live_rows(PPO("MultiInputPolicy", rows, n_steps=8, batch_size=76, device="cpu"), rows)


def test_evaluation_is_reproducible_and_classical_beats_random() -> None:
    random_1 = evaluate("sector_cr_v0", RandomPolicy(seed=0), 6)
    random_2 = evaluate("sector_cr_v0", RandomPolicy(seed=0), 6)
    assert random_1 == random_2
    classical = evaluate("sector_cr_v0", GeometricCRPolicy(), 6)
    r, c = summarise(random_1), summarise(classical)
    assert c["kpi_los_steps"][0] < 0.5 * r["kpi_los_steps"][0]
    assert c["kpi_mean_abs_drift_deg"][0] < r["kpi_mean_abs_drift_deg"][0]
    table = kpi_table({"random": random_1, "classical": classical})
    assert "LoS/ep" in table and "classical" in table


def test_classical_rule_turns_away_from_a_head_on_conflict() -> None:
    task = HorizontalCRMultiAgentTask(1)
    task.seed(task.all_envs, [np.random.default_rng(0)])
    task.reset()
    s = task.sim
    s.active[0, 2:] = False
    # Aircraft 1 straight ahead of aircraft 0, 20 NM north and 1 NM east, flying south.
    s.lat[0, 1] = s.lat[0, 0] + 20 / 60
    s.lon[0, 1] = s.lon[0, 0] + 1 / (60 * np.cos(np.radians(s.lat[0, 0])))
    s.hdg[0, :2] = s.trk[0, :2] = [0.0, 180.0]
    s.gs[0, 1] = s.gs[0, 0]
    policy = GeometricCRPolicy()
    policy.bind(task)
    a = policy.act(task.observation())
    # It passes on 0's right: 0 turns left; 0 passes on 1's right too (seen from 1): 1 turns left.
    assert a[0, 0, 0] == -1.0 and a[0, 1, 0] == -1.0
