"""DescentEnv-v0 task: action, measurement, observation and reward written out by hand (docs/environments-v0.md §1)."""

from __future__ import annotations

import numpy as np
import pytest

from bluesky_gym.environments.descent.task import DescentTask
from bluesky_gym.environments.plan_waypoint.task import PlanWaypointTask
from bluesky_gym.environments.static_obstacle.task import StaticObstacleTask
from bluesky_gym.environments.vertical_cr.task import VerticalCRTask

from .conftest import R_EARTH


def _task(n_envs: int, task_class: type = DescentTask) -> DescentTask:
    task = task_class(n_envs)
    task.seed(task.all_envs, [np.random.default_rng(10 + i) for i in range(n_envs)])
    task.reset()
    return task


def test_action_selects_altitude_and_vertical_speed() -> None:
    task = _task(3)
    task.apply_action(np.array([[1.0], [-0.4], [0.0]]))
    np.testing.assert_array_equal(task.sim.selvs[:, 0], [12.5, -5.0, 0.0])
    np.testing.assert_array_equal(task.sim.selalt[:, 0], [1e6, 0.0, 1e6])  # v >= 0 climbs
    assert not task.sim.swvnav[:, 0].any()


def test_measurement_and_observation() -> None:
    task = _task(2)
    s = task.sim
    s.alt[:, 0], s.vs[:, 0] = [2500.0, 4000.0], [-5.0, 2.5]
    s.lat[:, 0] = 52.0 + np.degrees(np.array([50_000.0, 150_000.0]) / R_EARTH)  # 50 and 150 km north of the start
    s.lon[:, 0] = 4.0
    task.target_alt[:] = [3000.0, 1500.0]
    g = task.measure()
    np.testing.assert_allclose(g.runway_km, [150.0, 50.0], rtol=1e-12)
    np.testing.assert_array_equal(g.goal_reached, [False, False])
    assert g.drift_deg is None and np.isinf(g.separation_nm).all() and not g.los.any()
    obs = task.observe(g)
    np.testing.assert_allclose(obs["altitude"][:, 0], [(2500 - 1500) / 3000, (4000 - 1500) / 3000])
    np.testing.assert_allclose(obs["vz"][:, 0], [-1.0, 0.5])
    np.testing.assert_allclose(obs["target_altitude"][:, 0], [0.5, 0.0])
    np.testing.assert_allclose(obs["runway_distance"][:, 0], [(150 - 100) / 200, (50 - 100) / 200], rtol=1e-12)


def test_reward_flying_crash_and_runway() -> None:
    task = _task(3)
    s = task.sim
    task.target_alt[:] = 3000.0
    s.alt[:, 0] = [2700.0, -1.0, 600.0]
    s.lat[2, 0] = 52.0 + np.degrees(201_000.0 / R_EARTH)  # past the runway
    g = task.measure()
    reward, terminated, parts = task.reward(g)  # flying on, crashed, at the runway
    np.testing.assert_allclose(reward, [-(5 / 3000) * 300.0, -100.0, -(50 / 3000) * 600.0], rtol=1e-12)
    np.testing.assert_array_equal(terminated, [False, True, True])
    np.testing.assert_allclose(parts["altitude"], [-0.5, 0.0, 0.0], rtol=1e-12)
    np.testing.assert_array_equal(parts["crash"], [0.0, -100.0, 0.0])
    np.testing.assert_allclose(parts["runway"], [0.0, 0.0, -(50 / 3000) * 600.0], rtol=1e-12)
    np.testing.assert_array_equal(task.final_altitude, [0.0, -100.0, 600.0])
    np.testing.assert_array_equal(g.goal_reached, [False, False, True])


@pytest.mark.parametrize("task_class", [DescentTask, VerticalCRTask, PlanWaypointTask, StaticObstacleTask])
def test_measuring_some_rows_gives_those_rows_of_the_full_measurement(task_class: type) -> None:
    task = _task(5, task_class)
    for _ in range(3):
        task.step(np.random.default_rng(0).uniform(-1, 1, (5, *task.action_spec.shape)))
    rows = np.array([3, 1])
    full, part = task.observe(task.measure()), task.observe(task.measure(rows))
    assert full.keys() == part.keys()
    for k in full:
        np.testing.assert_array_equal(part[k], full[k][rows], err_msg=k, strict=True)
    np.testing.assert_array_equal(task.measure(rows).goal_reached, task.measure().goal_reached[rows])
