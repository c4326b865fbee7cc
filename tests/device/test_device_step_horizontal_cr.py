"""HorizontalCR's step on the device (:mod:`bluesky_gym.environments.horizontal_cr.device_step`).

It gives the CPU vector environment's episodes, in a fixed number of launches.

Under numba-cuda's simulator every output (observations, reward, terminated, truncated, every
info entry, the final observations and infos of ended episodes) must equal the CPU vector
environment's bit for bit, through truncations, waypoints reached and several autoresets; the
aircraft state must never travel back to the host whole; and a step's launches must not grow
with the number of episodes.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import bluesky_gym
from bluesky_gym.environments.horizontal_cr.device_step import HorizontalCRDeviceStep

from .conftest import compare_device_step, needs_device

torch = pytest.importorskip("torch")
pytestmark = needs_device
bluesky_gym.register_envs()

#: Conflicts within 2 minutes (losses of separation within the first steps), and waypoints near enough
#: that some are reached (terminated) within the time limit of 4 steps while others are not (truncated).
CONFLICTS = {"tlosh_min": 10, "tlosh_max": 120, "max_episode_steps": 4}
#: Two intruders of two types (another physics path on the device).
TWO_TYPES = {"num_intruders": 2, "intruder_types": ("A320", "B744")}


@pytest.mark.parametrize(
    ("env_id", "options"),
    [
        ("HorizontalCREnv-v0", {"max_episode_steps": 3}),
        ("HorizontalCREnv-v1", {"max_episode_steps": 3, "num_intruders": 3}),
        ("HorizontalCREnv-v0", {**CONFLICTS, "waypoint_distance_min": 12, "waypoint_distance_max": 20}),  # ground phase: 4.5 km per step
        ("HorizontalCREnv-v1", {**CONFLICTS, "waypoint_distance_min": 20, "waypoint_distance_max": 30, **TWO_TYPES}),  # FL100: 8.7 km per step
    ],
)
def test_device_step_episodes_equal_the_cpu_vector_env_bit_for_bit(env_id: str, options: dict[str, Any], monkeypatch: pytest.MonkeyPatch) -> None:
    """Same seeds, same actions: the same outputs, every info entry included, through terminations, truncations and autoresets."""
    infos: list[dict[str, Any]] = []
    ended, terminated, cpu, dev = compare_device_step(env_id, options, HorizontalCRDeviceStep, monkeypatch, cpu_infos=infos)
    if options["max_episode_steps"] == 3:
        assert ended >= 6 and terminated == 0, "episodes must be truncated at the time limit 3, twice each, and be reset"
    else:
        reason = "some waypoints must be reached (terminated), others not (truncated), and the episodes reset"
        assert terminated >= 2 and ended - terminated >= 2, reason
        assert sum(int((i["reward_intrusion"] < 0).sum()) for i in infos) >= 2, "intruders must come within 5 NM (the intrusion penalty)"
        assert sum(int((i["reward_reach"] > 0).sum()) for i in infos) == terminated, "each waypoint reached pays the reach reward once"
    # The episodes' scenarios on the host are those of the CPU environment (drawn from the same generators).
    np.testing.assert_array_equal(dev.unwrapped.task.wpt_lat, cpu.unwrapped.task.wpt_lat)
    np.testing.assert_array_equal(dev.unwrapped.task.conflict_tlosh, cpu.unwrapped.task.conflict_tlosh)
    cpu.close()
    dev.close()


def test_wind_keeps_the_task_step_on_the_host() -> None:
    """A configuration the device step does not cover (wind) falls back to the task's step on the host, the physics on the device."""
    wind = {"lat": [52.0], "lon": [4.0], "vnorth": [5.0], "veast": [0.0]}
    windy = gym.make_vec("HorizontalCREnv-v0", num_envs=2, device="cuda", wind=wind)
    assert not HorizontalCRDeviceStep.supports(windy.unwrapped.task)
    assert windy.unwrapped._device_step is None
    windy.reset(seed=0)
    windy.step(np.zeros((2, 1)))
    still = gym.make_vec("HorizontalCREnv-v0", num_envs=2, device="cuda")
    assert HorizontalCRDeviceStep.supports(still.unwrapped.task)
    windy.close()
    still.close()
