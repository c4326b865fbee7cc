"""The multi-agent step is the single-agent one: physics in one Simulator.run call, the task functions per agent."""

from __future__ import annotations

import numpy as np
import pytest
from gymnasium.utils import seeding

from bluesky_gym.environments.horizontal_cr.multiagent import HorizontalCRMultiAgentTask
from bluesky_gym.environments.horizontal_cr.task import HorizontalCRTask
from bluesky_gym.environments.merge.multiagent import MergeMultiAgentTask
from bluesky_gym.environments.merge.task import MergeTask
from bluesky_gym.environments.sector_cr.multiagent import SectorCRMultiAgentTask
from bluesky_gym.environments.sector_cr.task import SectorCRTask


def _seeded(task, seed: int = 3):
    task.seed(task.all_envs, [seeding.np_random(seed + i)[0] for i in range(task.n_envs)])
    task.reset()
    return task


@pytest.mark.parametrize(
    "task_class", [SectorCRMultiAgentTask, MergeMultiAgentTask, HorizontalCRMultiAgentTask, SectorCRTask, MergeTask, HorizontalCRTask]
)
def test_a_step_runs_the_physics_sub_steps_in_one_run_call(task_class, monkeypatch) -> None:
    task = _seeded(task_class(2))
    calls: list[int] = []
    run = task.sim.run

    def counting_run(n_steps: int, *args, **kwargs):
        calls.append(n_steps)
        return run(n_steps, *args, **kwargs)

    def no_step() -> None:
        raise AssertionError("a sub-step outside Simulator.run")

    monkeypatch.setattr(task.sim, "run", counting_run)
    monkeypatch.setattr(task.sim, "step", no_step)
    shape = (2, task.n_agents, *task.action_spec.shape) if hasattr(task, "n_agents") else (2, *task.action_spec.shape)
    for _ in range(3):
        task.step(np.zeros(shape))
    assert calls == [task.action_frequency] * 3


@pytest.mark.parametrize(
    ("ma_class", "sa_class"),
    [(SectorCRMultiAgentTask, SectorCRTask), (MergeMultiAgentTask, MergeTask), (HorizontalCRMultiAgentTask, HorizontalCRTask)],
)
def test_agent_zero_has_the_single_agent_geometry_and_reward(ma_class, sa_class) -> None:
    """The same scenario seen by agent 0 and by the single-agent ownship: one geometry, one reward."""
    ma, sa = _seeded(ma_class(2), 11), _seeded(sa_class(2), 11)
    g_ma, g_sa = ma.measure(np.arange(2), np.zeros(2, np.int64)), sa.measure()
    for name in ("separation_nm", "los", "drift_deg", "goal_reached"):
        np.testing.assert_array_equal(getattr(g_ma, name), getattr(g_sa, name), err_msg=name)
    r_ma, _, comp_ma = ma.reward_rows(g_ma)
    r_sa, _, comp_sa = sa.reward(g_sa)
    np.testing.assert_array_equal(r_ma, r_sa)
    assert comp_ma.keys() == comp_sa.keys()
    for key in comp_ma:
        np.testing.assert_array_equal(comp_ma[key], comp_sa[key], err_msg=key)
