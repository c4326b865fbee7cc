"""Multi-agent DenseSectorCR: agents that enter mid-episode, the end of the episode and the KPIs."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("pettingzoo")

from bluesky_gym.multiagent import make_task, parallel_env


def test_entering_aircraft_appear_with_a_first_observation_and_act_from_the_next_step() -> None:
    env = parallel_env("dense_sector_cr_v0", spawn_rate_start=1800.0, spawn_rate_end=1800.0)
    obs, _ = env.reset(seed=1)
    seen, finished = set(env.agents), set()
    appeared_total = 0
    for _ in range(30):
        before = set(env.agents)
        obs, rew, term, trunc, infos = env.step({a: np.zeros(2) for a in env.agents})
        new = set(obs) - before
        appeared_total += len(new)
        for a in new:
            assert a not in seen, f"{a} named two aircraft"
            assert rew[a] == 0.0 and not term[a] and not trunc[a] and infos[a] == {}
            k = env.agent_name_mapping[a]
            assert env.task.sim.active[0, k]
            assert set(obs[a]) == set(env.observation_space(a).spaces) and all(np.isfinite(v).all() for v in obs[a].values())
            assert obs[a]["cos(drift)"] ** 2 + obs[a]["sin(drift)"] ** 2 == pytest.approx(1.0)  # a real first observation, not padding
        seen |= new
        finished |= {a for a in obs if term[a] or trunc[a]}
        assert set(env.agents) == {a for a in obs if not (term[a] or trunc[a])}
        assert not (set(env.agents) & finished)
    assert appeared_total == env.task.scenario.spawned[0] > 0
    # The new agents act: a heading action of one that appeared turns it.
    agent = next(a for a in env.agents if env.agent_name_mapping[a] >= env.task.scenario.num_ac[0])
    k = env.agent_name_mapping[agent]
    hdg = env.task.sim.hdg[0, k]
    env.step({agent: np.array([1.0, 0.0])})
    assert (env.task.sim.hdg[0, k] - hdg + 180.0) % 360.0 - 180.0 > 5.0


def test_the_episode_ends_at_the_time_limit_with_its_kpis() -> None:
    env = parallel_env("dense_sector_cr_v0", max_episode_steps=12, spawn_rate_start=900.0, spawn_rate_end=900.0)
    env.reset(seed=2)
    n_start = len(env.agents)
    for _ in range(12):
        assert env.agents
        obs, _, _, _, infos = env.step({a: np.zeros(2) for a in env.agents})
    assert env.agents == []
    task = env.task
    kpis = next(i for i in infos.values() if i)
    assert kpis["kpi_agents"] == n_start + task.scenario.spawned[0]
    assert kpis["kpi_aircraft_spawned"] == task.scenario.spawned[0] > 0
    hours = task.agent_steps[0].sum() * 5.0 / 3600.0
    assert kpis["kpi_los_per_flight_hour"] == pytest.approx(task.stats.los_count[0] / hours)
    # Aircraft that entered in the last step are not agents: not in the step's dicts.
    late = np.flatnonzero(task.sim.active[0] & ~task.acting[0])
    assert not ({env.possible_agents[k] for k in late} & set(obs))


def test_batched_multi_agent_episodes_equal_single_ones() -> None:
    batched = make_task("dense_sector_cr_v0", n_envs=2)
    batched.seed(batched.all_envs, [np.random.default_rng(s) for s in (3, 4)])
    batched.reset()
    singles = []
    for s in (3, 4):
        t = make_task("dense_sector_cr_v0")
        t.seed(t.all_envs, [np.random.default_rng(s)])
        t.reset()
        singles.append(t)
    rng = np.random.default_rng(0)
    for _ in range(25):
        a = rng.uniform(-1, 1, (2, batched.n_agents, 2))
        res = batched.step(a)
        for i, t in enumerate(singles):
            r = t.step(a[i : i + 1])
            np.testing.assert_array_equal(r.reward[0], res.reward[i])
            np.testing.assert_array_equal(r.appeared[0], res.appeared[i])
            for key, v in r.observation.items():
                np.testing.assert_array_equal(v[0], res.observation[key][i])
