"""StaticObstacle's step on the device (:mod:`bluesky_gym.environments.static_obstacle.device_step`).

Under numba-cuda's simulator every output (observations, reward, terminated, truncated, every
info entry, the final observations and infos of ended episodes) must equal the CPU vector
environment's bit for bit, through obstacles entered within a decision step (the episode stops
at that sub-step), waypoints reached, truncations and autoresets; and a step's launches must not
grow with the number of episodes.
"""

from __future__ import annotations

from collections import Counter
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import bluesky_gym
from bluesky_gym.environments.static_obstacle import task as so
from bluesky_gym.environments.static_obstacle.device_step import StaticObstacleDeviceStep

from .conftest import compare_device_step, needs_device

torch = pytest.importorskip("torch")
pytestmark = needs_device
bluesky_gym.register_envs()

#: Many small obstacles close to the start: the aircraft enters them within decision steps.
CROWDED = {"num_obstacles": 50, "obstacle_distance_min": 5, "obstacle_distance_max": 15, "obstacle_area_min": 3, "obstacle_area_max": 20}
CROWDED_V1 = {"num_obstacles": 50, "obstacle_distance_min": 2, "obstacle_distance_max": 20, "obstacle_area_min": 10, "obstacle_area_max": 100}
#: Near waypoints with a wide capture radius: goals reached.
NEAR_GOALS = {
    "distance_margin_km": 40.0,
    "waypoint_distance_min": 30,
    "waypoint_distance_max": 50,
    "num_obstacles": 20,
    "obstacle_distance_min": 5,
    "obstacle_distance_max": 40,
}


@pytest.mark.parametrize(
    ("env_id", "options", "mid_step_ends", "goals", "truncations"),
    [
        ("StaticObstacleEnv-v0", {"max_episode_steps": 5, **CROWDED}, 4, 0, 1),
        ("StaticObstacleEnv-v1", {"max_episode_steps": 4, **CROWDED_V1}, 2, 0, 2),
        ("StaticObstacleEnv-v0", {"max_episode_steps": 5, **NEAR_GOALS}, 0, 5, 0),
        ("StaticObstacleEnv-v1", {"max_episode_steps": 5, **NEAR_GOALS}, 0, 5, 0),
    ],
)
def test_device_step_episodes_equal_the_cpu_vector_env_bit_for_bit(
    env_id: str, options: dict[str, Any], mid_step_ends: int, goals: int, truncations: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Same seeds, same actions: the same outputs, every info entry included, through terminations, truncations and autoresets.

    The CPU environment's sub-step ends and waypoints reached are counted, so that the branches
    compared are known to have run: episodes stopped within a decision step (the device holds
    and restores their state), waypoints reached (``-v0``: at sub-step 1 by the last
    observation's distance; ``-v1``: the same step).
    """
    ends: Counter[int] = Counter()
    reached = [0]
    stop, reward = so.SubstepEnd.__call__, so.StaticObstacleTask.reward

    def counted_stop(self: so.SubstepEnd, track: np.ndarray) -> Any:
        out = stop(self, track)
        ends.update(out.tolist())
        return out

    def counted_reward(self: so.StaticObstacleTask, g: Any) -> Any:
        reached[0] += int(np.sum(g.newly_reached))
        return reward(self, g)

    monkeypatch.setattr(so.SubstepEnd, "__call__", counted_stop)
    monkeypatch.setattr(so.StaticObstacleTask, "reward", counted_reward)
    ended, terminated, cpu, dev = compare_device_step(env_id, options, StaticObstacleDeviceStep, monkeypatch)
    substeps = so.StaticObstacleTask.action_frequency
    within = sum(count for k, count in ends.items() if 1 < k < substeps)
    assert within >= mid_step_ends, f"episodes must end within a decision step (sub-steps at which they ended: {dict(ends)})"
    assert reached[0] >= goals, f"waypoints must be reached ({reached[0]})"
    assert terminated >= max(mid_step_ends, goals), "episodes must terminate and be reset"
    assert ended - terminated >= truncations, "episodes must reach the time limit and be reset"
    # The episodes' scenarios on the host are those of the CPU environment (drawn from the same generators).
    np.testing.assert_array_equal(dev.unwrapped.task.wpt_lat, cpu.unwrapped.task.wpt_lat)
    cpu.close()
    dev.close()


def test_wind_keeps_the_task_step_on_the_host() -> None:
    """A configuration the device step does not cover (wind) runs the task's step on the host, the physics on the device."""
    windy = gym.make_vec("StaticObstacleEnv-v1", num_envs=2, device="cuda", wind={"lat": [52.0], "lon": [4.0], "vnorth": [5.0], "veast": [0.0]})
    assert windy.unwrapped._device_step is None
    assert not StaticObstacleDeviceStep.supports(windy.unwrapped.task)
    calm = gym.make_vec("StaticObstacleEnv-v1", num_envs=2, device="cuda")
    assert isinstance(calm.unwrapped._device_step, StaticObstacleDeviceStep)
    windy.close()
    calm.close()
