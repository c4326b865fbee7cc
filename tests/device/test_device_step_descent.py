"""Descent's step on the device (:mod:`bluesky_gym.environments.descent.device_step`).

Under numba-cuda's simulator every output (observations, reward, terminated, truncated, every
info entry, the final observations and infos of ended episodes) must equal the CPU vector
environment's bit for bit, through truncations, crashes, runways reached and autoresets; and a
step's launches must not grow with the number of episodes.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import bluesky_gym
from bluesky_gym.environments.descent.device_step import DescentDeviceStep

from .conftest import ON, compare_device_step, needs_device, same_tensor

torch = pytest.importorskip("torch")
pytestmark = needs_device
bluesky_gym.register_envs()

#: A short, low leg: random actions crash some episodes and bring others to the runway within a few steps.
SHORT_LOW_LEG = {"runway_distance_km": 12.0, "alt_min": 300, "alt_max": 400, "target_alt_dif": 100}


def episodes_with(infos: list[dict[str, Any]], component: str) -> int:
    """The episode-steps of the CPU environment's infos whose reward component ``component`` is not 0 (``crash``: crashed, ...)."""
    return sum(int((info[f"reward_{component}"] != 0).sum()) for info in infos)


@pytest.mark.parametrize(
    ("env_id", "options"),
    [
        ("DescentEnv-v0", {"max_episode_steps": 3}),
        ("DescentEnv-v1", {"max_episode_steps": 3}),
        ("DescentEnv-v0", {**SHORT_LOW_LEG, "max_episode_steps": 50}),
        ("DescentEnv-v1", {**SHORT_LOW_LEG, "max_episode_steps": 50}),
    ],
)
def test_device_step_episodes_equal_the_cpu_vector_env_bit_for_bit(env_id: str, options: dict[str, Any], monkeypatch: pytest.MonkeyPatch) -> None:
    """Same seeds, same actions: the same outputs, every info entry included, through truncations, crashes, runways and autoresets."""
    infos: list[dict[str, Any]] = []
    ended, terminated, cpu, dev = compare_device_step(env_id, options, DescentDeviceStep, monkeypatch, steps=10, cpu_infos=infos)
    if options["max_episode_steps"] == 3:
        assert ended >= 6 and terminated == 0, "every episode must be truncated at the time limit and reset, several times"
    else:
        assert terminated >= 3, "episodes must end on the short, low leg and be reset"
        assert episodes_with(infos, "crash") >= 1 and episodes_with(infos, "runway") >= 1, "some episodes must crash, others land"
    # The episodes' scenarios on the host are those of the CPU environment (drawn from the same generators).
    np.testing.assert_array_equal(dev.unwrapped.task.target_alt, cpu.unwrapped.task.target_alt)
    cpu.close()
    dev.close()


def test_v1_zero_action_holds_the_altitude_on_the_device_as_on_the_cpu() -> None:
    """``hold_altitude_at_zero``: a = 0 selects the current altitude (the command kernel's branch), as on the CPU."""
    cpu = gym.make_vec("DescentEnv-v1", num_envs=2)
    dev = gym.make_vec("DescentEnv-v1", num_envs=2, device="cuda")
    cpu.reset(seed=5)
    dev.reset(seed=5)
    for step in range(2):
        oc, *_ = cpu.step(np.zeros((2, 1), np.float32))
        od, *_ = dev.step(torch.zeros((2, 1), dtype=torch.float32, device=ON))
        for k in oc:
            same_tensor(od[k], oc[k], f"step {step} obs {k}")
    assert np.abs(oc["vz"]).max() < 0.05, "the altitude is held, not climbed at BlueSky's default 7.62 m/s"
    np.testing.assert_array_equal(dev.unwrapped.task.sim.selalt[:, 0], cpu.unwrapped.task.sim.selalt[:, 0])
    cpu.close()
    dev.close()


def test_wind_keeps_the_task_step_on_the_host() -> None:
    """An uncovered configuration (wind) falls back to the host step, the physics on the device."""
    windy = gym.make_vec("DescentEnv-v0", num_envs=2, device="cuda", wind={"lat": [52.0], "lon": [4.4], "vnorth": [5.0], "veast": [0.0]})
    assert windy.unwrapped._device_step is None
    assert not DescentDeviceStep.supports(windy.unwrapped.task)
    windy.close()
    calm = gym.make_vec("DescentEnv-v1", num_envs=2, device="cuda")
    assert isinstance(calm.unwrapped._device_step, DescentDeviceStep)
    calm.close()
