"""PlanWaypoint's step on the device (:mod:`bluesky_gym.environments.plan_waypoint.device_step`).

Under numba-cuda's simulator every output (observations, reward, terminated, truncated, every
info entry, the final observations and infos of ended episodes) must equal the CPU vector
environment's bit for bit, through goals reached (terminations), time limits (truncations) and
several autoresets; the aircraft state must never travel back to the host whole; and a step's
launches must not grow with the number of episodes.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import bluesky_gym
from bluesky_gym.environments.plan_waypoint.device_step import PlanWaypointDeviceStep

from .conftest import ON, compare_device_step, needs_device

torch = pytest.importorskip("torch")
pytestmark = needs_device
bluesky_gym.register_envs()


@pytest.mark.parametrize(
    ("env_id", "options", "goals"),
    [
        ("PlanWaypointEnv-v0", {"max_episode_steps": 3}, False),
        ("PlanWaypointEnv-v1", {"max_episode_steps": 3}, False),
        # Waypoints within a few km: some episodes reach them all (terminated), the others hit the time limit.
        ("PlanWaypointEnv-v0", {"num_waypoints": 2, "waypoint_distance_max": 8, "max_episode_steps": 4}, True),
        ("PlanWaypointEnv-v1", {"num_waypoints": 3, "waypoint_distance_max": 9, "max_episode_steps": 4}, True),
    ],
)
def test_device_step_episodes_equal_the_cpu_vector_env_bit_for_bit(
    env_id: str, options: dict[str, Any], goals: bool, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Same seeds, same actions: the same outputs, every info entry included, through terminations, truncations and autoresets."""
    infos: list[dict[str, Any]] = []
    ended, terminated, cpu, dev = compare_device_step(env_id, options, PlanWaypointDeviceStep, monkeypatch, num_envs=4, cpu_infos=infos)
    assert ended >= 8, "episodes must end (time limit 3 or 4, goals reached) and be reset on the way"
    if goals:
        assert terminated >= 2, "some episodes must reach every waypoint (terminated) and be reset"
        assert ended > terminated, "and some must hit the time limit"
        successes = sum(int(i["final_info"]["kpi_success"][i["_final_info"]].sum()) for i in infos if "final_info" in i)
        assert successes == terminated, "every terminated episode reached its goal (kpi_success 1)"
    else:
        assert terminated == 0
    # The episodes' scenarios on the host are those of the CPU environment (drawn from the same generators),
    # and the reach flags and statistics the device kept come back to the host as the CPU's.
    dev.unwrapped._device_step.sync_host()
    for name in ("wpt_lat", "wpt_lon", "wpt_reached", "tour_km"):
        np.testing.assert_array_equal(getattr(dev.unwrapped.task, name), getattr(cpu.unwrapped.task, name), err_msg=name)
    np.testing.assert_array_equal(dev.unwrapped.task.stats.total_reward, cpu.unwrapped.task.stats.total_reward)
    cpu.close()
    dev.close()


def test_goals_reached_give_the_goal_kpis() -> None:
    """An episode that reaches every waypoint ends terminated with success 1, its time to the goal and its extra track."""
    env = gym.make_vec("PlanWaypointEnv-v0", num_envs=3, device="cuda", num_waypoints=1, waypoint_distance_max=4)
    env.reset(seed=0)
    obs, reward, terminated, truncated, info = env.step(torch.zeros((3, 1), device=ON))
    assert bool(terminated.all()) and not bool(truncated.any())  # every waypoint within the 5 km capture radius
    assert reward.tolist() == [1.0, 1.0, 1.0]
    final = info["final_info"]
    assert final["kpi_success"].tolist() == [1.0, 1.0, 1.0]
    assert final["kpi_time_to_goal_s"].tolist() == [10.0, 10.0, 10.0]
    assert final["waypoints_completed"].tolist() == [1, 1, 1]
    assert bool(torch.isfinite(final["kpi_extra_track_km"]).all())
    assert info["final_obs"]["waypoint_reached"].tolist() == [[0.0]] * 3  # -v0: shown one step late
    assert obs["waypoint_reached"].tolist() == [[0.0]] * 3  # the new episodes' first observation
    assert env.unwrapped._device_step.arrays["wpt_reached"].tolist() == [[False]] * 3
    env.close()


def test_wind_keeps_the_task_step_on_the_host() -> None:
    """A configuration the device step does not cover (wind) runs the task's step on the host, the physics on the device."""
    windy = gym.make_vec("PlanWaypointEnv-v0", num_envs=2, device="cuda", wind={"lat": [52.0], "lon": [4.4], "vnorth": [5.0], "veast": [0.0]})
    assert windy.unwrapped._device_step is None
    assert not PlanWaypointDeviceStep.supports(windy.unwrapped.task)
    windy.close()
    calm = gym.make_vec("PlanWaypointEnv-v1", num_envs=2, device="cuda")
    assert isinstance(calm.unwrapped._device_step, PlanWaypointDeviceStep)
    calm.close()
