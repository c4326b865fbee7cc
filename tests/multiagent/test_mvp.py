"""The multi-agent ``mvp`` policy: agents resolve a head-on conflict that they fly into without action."""

from __future__ import annotations

import numpy as np
import pytest
from gymnasium.utils import seeding

from bluesky_gym.core.geo import kwikdist
from bluesky_gym.environments.horizontal_cr.multiagent import HorizontalCRMultiAgentTask
from bluesky_gym.environments.merge.multiagent import MergeMultiAgentTask
from bluesky_gym.environments.sector_cr.multiagent import SectorCRMultiAgentTask
from bluesky_gym.multiagent.base import Array, MultiAgentTask
from bluesky_gym.multiagent.evaluation import evaluate
from bluesky_gym.multiagent.policies import MVPPolicy, Policy

#: Task -> (decision steps flown, time to loss of separation of the head-on pair [s]).
CASES = {SectorCRMultiAgentTask: (40, 60.0), MergeMultiAgentTask: (8, 150.0), HorizontalCRMultiAgentTask: (8, 150.0)}


class NoAction(Policy):
    """Every agent keeps its heading and speed (zero actions)."""

    name = "no action"

    def bind(self, env: MultiAgentTask) -> None:
        self.task = env

    def act(self, obs: dict[str, Array]) -> Array:
        task = self.task
        assert task.heading_step > 0.0
        return np.zeros((task.n_envs, task.n_agents, *task.action_spec.shape))


def _head_on(task_class: type[MultiAgentTask], policy: Policy, n: int = 2) -> np.ndarray:
    """Smallest horizontal separation [protected-zone radii] of agents 0 and 1, put on a head-on course."""
    steps, tlosh = CASES[task_class]
    task = task_class(n)
    task.seed(task.all_envs, [seeding.np_random(s)[0] for s in range(n)])
    task.reset()
    sim = task.sim
    for e in range(n):
        sim.delete(e, 1)
        sim.creconfs(e, 0, 1, 180.0, 0.0, tlosh)
    policy.bind(task)
    policy.reset()
    obs = task.observation()
    worst = np.full(n, np.inf)
    for _ in range(steps):
        res = task.step(policy.act(obs))
        obs = res.observation
        both = sim.active[:, 0] & sim.active[:, 1]
        d = kwikdist(sim.lat[:, 0], sim.lon[:, 0], sim.lat[:, 1], sim.lon[:, 1]) / task.intrusion_distance
        worst = np.where(both, np.minimum(worst, d), worst)
    assert np.isfinite(worst).all()
    return worst


@pytest.mark.parametrize("task_class", list(CASES), ids=lambda c: c.name)
def test_mvp_resolves_a_head_on_conflict_between_agents(task_class: type[MultiAgentTask]) -> None:
    with_mvp = _head_on(task_class, MVPPolicy())
    without = _head_on(task_class, NoAction())
    assert np.all(with_mvp >= 1.0), with_mvp
    assert np.all(with_mvp > without), (with_mvp, without)


def test_batched_mvp_equals_single_episodes() -> None:
    """Three multi-agent episodes played together equal the same episodes played one by one."""
    batched = evaluate("sector_cr_v0", MVPPolicy(), 3, max_episode_steps=30)
    assert len(batched) == 3
    for j, rec in enumerate(batched):
        (single,) = evaluate("sector_cr_v0", MVPPolicy(), 1, seed_offset=j, max_episode_steps=30)
        assert rec.keys() == single.keys()
        for k, v in rec.items():
            assert v == single[k] or (v != v and single[k] != single[k]), (j, k, v, single[k])  # equal, or both NaN
