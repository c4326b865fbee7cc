"""Merge's step on the device (:mod:`bluesky_gym.environments.merge.device_step`).

Under numba-cuda's simulator every output must equal the CPU vector environment's bit for bit,
through FAF captures, runway arrivals (terminations), truncations and autoresets; a step's
launches must not grow with the number of episodes.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import bluesky_gym
from bluesky_gym.environments.merge.device_step import MergeDeviceStep

from .conftest import compare_device_step, needs_device

torch = pytest.importorskip("torch")
pytestmark = needs_device
bluesky_gym.register_envs()

#: Ownships spawned close to the FAF, few aircraft: FAF captures happen within the steps (-v1: in the
#: step they happen, measured again against the runway).
_NEAR_FAF = {"num_aircraft": 6, "spawn_distance_km": (5.0, 40.0), "intruder_distance_km": (2.0, 30.0)}


@pytest.mark.parametrize(
    ("env_id", "options"),
    [
        ("MergeEnv-v0", {"max_episode_steps": 2, **_NEAR_FAF}),
        ("MergeEnv-v1", {"max_episode_steps": 2, **_NEAR_FAF}),
    ],
)
def test_merge_device_step_equals_the_cpu_vector_env_bit_for_bit(env_id: str, options: dict[str, Any], monkeypatch: pytest.MonkeyPatch) -> None:
    """Same seeds, same actions: the same outputs, every info entry and KPI included, through FAF captures, time limits and autoresets.

    (A runway arrival takes tens of steps after the FAF, more than the simulator affords here: the
    goal's kernels run in every step, with their result False.)
    """
    infos: list[dict[str, Any]] = []
    ended, _, cpu, dev = compare_device_step(env_id, options, MergeDeviceStep, monkeypatch, steps=5, num_envs=2, cpu_infos=infos)
    assert ended >= 3, "episodes must reach the time limit and be reset on the way"
    assert any((info["reward_reach"] > 0).any() for info in infos), "an ownship must reach the FAF"
    cpu.close()
    dev.close()


def test_wind_keeps_merge_on_the_host() -> None:
    """A configuration the device step does not cover runs the task's step on the host (the physics on the device)."""
    windy = gym.make_vec("MergeEnv-v0", num_envs=1, device="cuda", wind={"lat": [53.0], "lon": [4.7], "vnorth": [5.0], "veast": [0.0]})
    assert windy.unwrapped._device_step is None
    plain = gym.make_vec("MergeEnv-v0", num_envs=1, device="cuda")
    assert isinstance(plain.unwrapped._device_step, MergeDeviceStep)
    windy.close()
    plain.close()
    np.testing.assert_equal(MergeDeviceStep.task_class.env_id, "MergeEnv-v0")
