"""The contributor guide docs/adding-a-task.md runs: its code blocks make a working, tested environment."""

from __future__ import annotations

import re
import sys
import types
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

GUIDE = Path(__file__).resolve().parents[2] / "docs" / "adding-a-task.md"
MODULE = "adding_a_task_example"


@pytest.fixture(scope="module")
def guide() -> types.ModuleType:
    """The guide's python code blocks, in order, executed as one module."""
    blocks = re.findall(r"```python\n(.*?)```", GUIDE.read_text(encoding="utf-8"), flags=re.DOTALL)
    assert len(blocks) >= 5
    module = types.ModuleType(MODULE)
    module.__file__ = str(GUIDE)
    sys.modules[MODULE] = module  # dataclasses resolve their annotations through sys.modules
    try:
        exec(compile("\n\n".join(blocks), str(GUIDE), "exec"), module.__dict__)  # noqa: S102 - the project's own document
        yield module
    finally:
        del sys.modules[MODULE]
        gym.registry.pop(module.HoldTask.env_id, None)


def test_the_guides_own_tests_pass(guide: types.ModuleType) -> None:
    tests = [getattr(guide, name) for name in dir(guide) if name.startswith("test_")]
    assert {t.__name__ for t in tests} == {"test_same_seed_same_episode", "test_batched_equals_single"}
    for test in tests:
        test()


def test_the_example_task_reaches_its_targets_and_ends(guide: types.ModuleType) -> None:
    """A simple controller reaches the target; episodes end by termination, with KPIs."""
    env = gym.make(guide.HoldTask.env_id)
    obs, _ = env.reset(seed=1)
    task = env.unwrapped.task
    for _ in range(guide.HoldTask.max_episode_steps):
        err = guide.wrap180(task.target_hdg[0] - task.sim.hdg[0, 0])
        action = np.clip([err / 15.0, obs["speed_error"][0] * 20.0 / 5.0], -1.0, 1.0)
        obs, reward, terminated, truncated, info = env.step(action)
        if terminated or truncated:
            break
    assert terminated and not truncated and info["reward_on_target"] == 10.0 and info["kpi_success"] == 1.0


def test_the_example_stages_are_plain_functions(guide: types.ModuleType) -> None:
    """Set a state, measure, and check observation and reward by hand."""
    task = guide.HoldTask(2)
    task.seed(task.all_envs, [np.random.default_rng(0), np.random.default_rng(1)])
    task.reset()
    task.target_hdg[:] = [10.0, 350.0]
    task.target_cas[:] = task.sim.cas[:, 0] + np.array([0.5, -10.0])
    task.sim.hdg[:, 0] = [10.5, 20.0]  # within 1 deg; 30 deg off across north
    g = task.measure()
    np.testing.assert_allclose(g.heading_error, [-0.5, -30.0])
    np.testing.assert_array_equal(g.goal_reached, [True, False])
    obs = task.observe(g)
    np.testing.assert_allclose(obs["heading_error"][1], [np.cos(np.radians(-30.0)), np.sin(np.radians(-30.0))])
    np.testing.assert_allclose(obs["speed_error"][:, 0], [0.5 / 20.0, -10.0 / 20.0], rtol=1e-9)
    reward, terminated, parts = task.reward(g)
    np.testing.assert_allclose(reward, [10.0 - 0.5 / 180.0 - 0.5 / 50.0, -(30.0 / 180.0 + 10.0 / 50.0)], rtol=1e-9)
    np.testing.assert_array_equal(terminated, [True, False])
    assert set(parts) == {"error", "on_target"}
    rows = task.measure(np.array([1]))
    np.testing.assert_array_equal(task.observe(rows)["speed_error"], obs["speed_error"][1:])


def test_the_rows_classical_controller_reaches_the_target(guide: types.ModuleType) -> None:
    """The guide's row names its pieces by import path; its classical controller flies the example to the target."""
    from bluesky_gym.envs.registry import resolve

    row = guide.HOLD_ROW
    assert row.reference_policies == ("random", "classical") and row.vector_env_class() is guide.HoldVectorEnv
    controller = resolve(row.classical)()
    env = gym.make(row.id)
    obs, _ = env.reset(seed=1)
    for _ in range(guide.HoldTask.max_episode_steps):
        action = controller.act({k: v[None] for k, v in obs.items()})[0]
        obs, _, terminated, truncated, info = env.step(action)
        if terminated or truncated:
            break
    assert terminated and not truncated and info["kpi_success"] == 1.0
    v1 = guide.HoldTask.make_config(dict(row.v1))
    assert v1.float32_spaces


def test_the_guides_folder_table_is_the_layering_rule() -> None:
    """The guide's table of an environment folder's files names the roles and layers tests/test_layering.py ranks them by."""
    from tests.test_layering import ROLES

    text = GUIDE.read_text(encoding="utf-8")
    table = text[text.index("| file | holds | builds on | layer |") :].split("\n\n")[0]
    rows = re.findall(r"^\| `(\w+)\.py` \|.*\| (\w+) \|$", table, flags=re.MULTILINE)
    assert dict(rows) == ROLES
