"""VerticalCR's step on the device (:mod:`bluesky_gym.environments.vertical_cr.device_step`).

Under numba-cuda's simulator every output (observations, reward, terminated, truncated, every
info entry, the final observations and infos of ended episodes) must equal the CPU vector
environment's bit for bit, through truncations, crashes, runways reached, intrusions and
autoresets; and a step's launches must not grow with the number of episodes.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import bluesky_gym
from bluesky_gym.environments.vertical_cr.device_step import VerticalCRDeviceStep

from .conftest import ON, compare_device_step, needs_device
from .test_device_step_descent import SHORT_LOW_LEG, episodes_with

torch = pytest.importorskip("torch")
pytestmark = needs_device
bluesky_gym.register_envs()

#: Descent's short, low leg with intruders that fit it: met within the first steps, near the ownship's level.
SHORT_LOW_CONFLICTS = {**SHORT_LOW_LEG, "late_dh_floor": 50, "early_dh_band": 100, "tlosh_min": 10, "num_intruders": 3}


@pytest.mark.parametrize(
    ("env_id", "options"),
    [
        ("VerticalCREnv-v0", {"max_episode_steps": 3}),
        ("VerticalCREnv-v1", {"max_episode_steps": 3, "intruder_types": ("A320", "B744")}),
        ("VerticalCREnv-v0", {**SHORT_LOW_CONFLICTS, "max_episode_steps": 50}),
        ("VerticalCREnv-v1", {**SHORT_LOW_CONFLICTS, "max_episode_steps": 50}),
    ],
)
def test_device_step_episodes_equal_the_cpu_vector_env_bit_for_bit(env_id: str, options: dict[str, Any], monkeypatch: pytest.MonkeyPatch) -> None:
    """Same seeds, same actions: the same outputs, every info entry included, through truncations, crashes, runways, intrusions and autoresets."""
    infos: list[dict[str, Any]] = []
    ended, terminated, cpu, dev = compare_device_step(env_id, options, VerticalCRDeviceStep, monkeypatch, steps=10, cpu_infos=infos)
    if options["max_episode_steps"] == 3:
        assert ended >= 6 and terminated == 0, "every episode must be truncated at the time limit and reset, several times"
    else:
        assert terminated >= 3, "episodes must end on the short, low leg and be reset"
        assert all(episodes_with(infos, c) >= 1 for c in ("crash", "runway", "intrusion")), "crashes, landings, intrusions"
    # The episodes' scenarios on the host are those of the CPU environment (drawn from the same generators).
    np.testing.assert_array_equal(dev.unwrapped.task.conflict_dh, cpu.unwrapped.task.conflict_dh)
    cpu.close()
    dev.close()


def test_wind_keeps_the_task_step_on_the_host() -> None:
    """An uncovered configuration (wind) falls back to the host step, the physics on the device."""
    windy = gym.make_vec("VerticalCREnv-v1", num_envs=2, device="cuda", wind={"lat": [52.0], "lon": [4.4], "vnorth": [5.0], "veast": [0.0]})
    assert windy.unwrapped._device_step is None
    assert not VerticalCRDeviceStep.supports(windy.unwrapped.task)
    windy.close()


def test_rendering_a_device_step_environment_shows_its_statistics() -> None:
    """The pictures read the task's host arrays: with a render mode the step copies them there."""
    cpu = gym.make_vec("VerticalCREnv-v0", num_envs=2, render_mode="rgb_array")
    dev = gym.make_vec("VerticalCREnv-v0", num_envs=2, render_mode="rgb_array", device="cuda")
    cpu.reset(seed=4)
    dev.reset(seed=4)
    for _ in range(2):
        cpu.step(np.full((2, 1), -0.5))
        dev.step(torch.full((2, 1), -0.5, device=ON))
    for k in ("steps", "total_reward", "min_separation"):
        np.testing.assert_array_equal(getattr(dev.unwrapped.task.stats, k), getattr(cpu.unwrapped.task.stats, k), err_msg=k)
    for k in ("target_alt", "final_altitude", "total_intrusions"):
        np.testing.assert_array_equal(getattr(dev.unwrapped.task, k), getattr(cpu.unwrapped.task, k), err_msg=k)
    assert dev.render().shape == cpu.render().shape
    cpu.close()
    dev.close()
