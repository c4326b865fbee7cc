"""The fuel KPI of the multi-agent environments: the fuel burned by all agents of an episode."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bluesky_gym.multiagent import names, task_class
from bluesky_gym.multiagent.evaluation import evaluate
from bluesky_gym.multiagent.policies import RandomPolicy


@pytest.mark.parametrize("name", names())
def test_fuel_kpi_is_positive_and_finite_at_every_episode_end(name: str) -> None:
    records = evaluate(name, RandomPolicy(seed=1), 2, max_episode_steps=20)
    assert len(records) == 2
    for rec in records:
        assert math.isfinite(rec["kpi_fuel_kg"]) and rec["kpi_fuel_kg"] > 0.0, rec


def test_fuel_kpi_is_the_sum_over_the_agents() -> None:
    """Each agent's fuel burned when it leaves the simulation (done agents are deleted), summed: the episode's kpi_fuel_kg."""
    cls = task_class(names()[0])
    task = cls(1, cls.make_config({}), max_episode_steps=15)
    task.seed(task.all_envs, [np.random.default_rng(3)])
    task.reset()
    left: list[float] = []
    delete = task.sim.delete

    def spy(env: np.ndarray, slot: np.ndarray) -> None:
        left.extend(task.sim.fuelburn[env, slot].tolist())
        delete(env, slot)

    task.sim.delete = spy  # type: ignore[method-assign]
    policy = RandomPolicy(seed=2)
    policy.bind(task)
    policy.reset()
    obs = task.observation()
    res = None
    while not task.finished.all():
        res = task.step(policy.act(obs))
        obs = res.observation
    assert res is not None and res.episode_done.all()
    assert len(left) == int(res.info["kpi_agents"][0]) >= 2
    assert min(left) > 0.0
    assert res.info["kpi_fuel_kg"][0] == pytest.approx(sum(left), rel=1e-12)
