"""Every task prints what it is: id, batch size, physics, time limit and every field of its frozen configuration."""

from __future__ import annotations

import dataclasses

import pytest

from bluesky_gym.environments.descent.task import DescentTask
from bluesky_gym.environments.horizontal_cr.task import HorizontalCRTask
from bluesky_gym.environments.merge.task import MergeTask
from bluesky_gym.environments.plan_waypoint.task import PlanWaypointTask
from bluesky_gym.environments.real_traffic.task import RealTrafficTask
from bluesky_gym.environments.sector_cr.task import SectorCRTask
from bluesky_gym.environments.static_obstacle.task import StaticObstacleTask
from bluesky_gym.environments.vertical_cr.task import VerticalCRTask

TASKS = [DescentTask, VerticalCRTask, HorizontalCRTask, PlanWaypointTask, SectorCRTask, StaticObstacleTask, MergeTask, RealTrafficTask]


@pytest.mark.parametrize("cls", TASKS, ids=[c.__name__ for c in TASKS])
def test_repr_prints_the_frozen_configuration(cls: type) -> None:
    task = cls(2)
    text = repr(task)
    assert text.startswith(f"{cls.__name__}(id={cls.env_id!r}, n_envs=2, physics={type(task.sim).__name__}, time_limit={task.time_limit}, config=")
    assert text.endswith(f"config={task.config!r})")
    fields = dataclasses.fields(task.config)
    assert len(fields) > 1
    for f in fields:
        assert f"{f.name}={getattr(task.config, f.name)!r}" in text


def test_repr_shows_a_changed_option_and_the_time_limit_given() -> None:
    task = HorizontalCRTask(1, HorizontalCRTask.config_class(num_intruders=3, float32_spaces=True), max_episode_steps=17)
    text = repr(task)
    assert "num_intruders=3," in text and "float32_spaces=True," in text and "time_limit=17," in text
    assert repr(HorizontalCRTask(1)) != text
