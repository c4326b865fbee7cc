"""The task's step on the device (:mod:`bluesky_gym.environments.sector_cr.device_step`).

It gives the CPU vector environment's episodes, in a fixed number of launches.

Under numba-cuda's simulator every output (observations, reward, terminated, truncated, every
info entry, the final observations and infos of ended episodes) must equal the CPU vector
environment's bit for bit, through several autoresets; the aircraft state must never travel
back to the host whole; and a step's launches must not grow with the number of episodes.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import bluesky_gym
from bluesky_gym.environments.sector_cr.device_step import SectorCRDeviceStep
from bluesky_gym.envs.registry import entry, env_ids

from .conftest import ON, compare_device_step, launches_of_step, needs_device

torch = pytest.importorskip("torch")
pytestmark = needs_device
bluesky_gym.register_envs()


@pytest.mark.parametrize(
    ("env_id", "options"),
    [
        ("SectorCREnv-v0", {}),
        ("SectorCREnv-v1", {}),
        ("SectorCREnv-v0", {"intruder_types": ("A320", "B744"), "ac_density_mode": "uniform"}),
        ("SectorCREnv-v1", {"poly_area_range": (40.0, 80.0), "max_episode_steps": 60}),  # small sectors: left, terminated
    ],
)
def test_device_step_episodes_equal_the_cpu_vector_env_bit_for_bit(env_id: str, options: dict[str, Any], monkeypatch: pytest.MonkeyPatch) -> None:
    """Same seeds, same actions: the same outputs, every info entry included, through terminations, truncations and autoresets."""
    options = {"max_episode_steps": 3, **options}
    ended, terminated, cpu, dev = compare_device_step(env_id, options, SectorCRDeviceStep, monkeypatch)
    if options["max_episode_steps"] > 9:
        assert terminated >= 1, "an agent must leave its small sector (-v1: terminated) and be reset"
    else:
        assert ended >= 4, "episodes must end (time limit 3, the sector left) and be reset on the way"
    # The episodes' scenarios on the host are those of the CPU environment (drawn from the same generators).
    np.testing.assert_array_equal(dev.unwrapped.task.wpt_lat, cpu.unwrapped.task.wpt_lat)
    cpu.close()
    dev.close()


#: Launches of a device step in which no episode ends, per id (docs/backends.md's table): -v1 adds
#: one clip per observation entry; StaticObstacle runs its ten sub-steps as separate launches.
STEP_LAUNCHES = {
    "SectorCREnv-v0": 11,
    "SectorCREnv-v1": 21,
    "MergeEnv-v0": 12,
    "MergeEnv-v1": 27,
    "HorizontalCREnv-v0": 12,
    "HorizontalCREnv-v1": 20,
    "DescentEnv-v0": 7,
    "DescentEnv-v1": 11,
    "VerticalCREnv-v0": 9,
    "VerticalCREnv-v1": 20,
    "PlanWaypointEnv-v0": 9,
    "PlanWaypointEnv-v1": 13,
    "StaticObstacleEnv-v0": 38,
    "StaticObstacleEnv-v1": 44,
    "DenseSectorCREnv-v0": 14,
    "DenseSectorCREnv-v1": 24,
    "RealTrafficCREnv-v0": 11,
    "RealTrafficCREnv-v1": 13,
}
#: Smaller scenarios where the default is slow under the simulator.
#: DenseSectorCR without entries (a step in which aircraft enter adds its fixed gather and scatter:
#: tests/device/test_device_step_dense_sector_cr.py).
_LAUNCH_OPTIONS: dict[str, dict[str, Any]] = {
    "MergeEnv-v0": {"num_aircraft": 6},
    "MergeEnv-v1": {"num_aircraft": 6},
    "DenseSectorCREnv-v0": {"spawn_rate_start": 0.0, "spawn_rate_end": 0.0},
    "DenseSectorCREnv-v1": {"spawn_rate_start": 0.0, "spawn_rate_end": 0.0},
}


def test_every_id_has_a_device_step_and_is_counted() -> None:
    assert sorted(STEP_LAUNCHES) == sorted(i for i in env_ids() if entry(i).device_step is not None) == sorted(env_ids())


@pytest.mark.parametrize("env_id", sorted(STEP_LAUNCHES))
def test_a_step_is_a_fixed_number_of_launches_whatever_the_number_of_episodes(env_id: str) -> None:
    options = _LAUNCH_OPTIONS.get(env_id, {})
    steady = launches_of_step(env_id, 2, False, **options)
    assert steady == launches_of_step(env_id, 4, False, **options) == STEP_LAUNCHES[env_id]
    assert launches_of_step(env_id, 2, True, **options) == launches_of_step(env_id, 4, True, **options) > steady


def test_wind_keeps_the_task_step_on_the_host() -> None:
    """A wind option runs the task's step on the host (the physics on the device)."""
    windy = gym.make_vec("SectorCREnv-v0", num_envs=2, device="cuda", wind={"lat": [52.0], "lon": [4.4], "vnorth": [5.0], "veast": [0.0]})
    assert windy.unwrapped._device_step is None
    windy.close()


@pytest.mark.parametrize(
    ("action", "message"),
    [
        (np.zeros((2, 3)), r"action has shape \(2, 3\), expected \(2, 2\)"),
        (np.full((2, 2), np.nan), "NaN or infinite"),
        ([["a", "b"], ["c", "d"]], "real numbers"),
    ],
)
def test_bad_actions_are_refused_in_one_line(action: Any, message: str) -> None:
    env = gym.make_vec("SectorCREnv-v0", num_envs=2, device="cuda")
    env.reset(seed=0)
    given = torch.as_tensor(action, device=ON) if isinstance(action, np.ndarray) else action
    with pytest.raises(ValueError, match=message):
        env.step(given)
    env.close()


def test_rendering_a_device_step_environment_shows_its_statistics() -> None:
    """The pictures read the task's host arrays: with a render mode the step copies its statistics there."""
    cpu = gym.make_vec("SectorCREnv-v0", num_envs=2, render_mode="rgb_array")
    dev = gym.make_vec("SectorCREnv-v0", num_envs=2, render_mode="rgb_array", device="cuda")
    cpu.reset(seed=4)
    dev.reset(seed=4)
    for _ in range(2):
        cpu.step(np.full((2, 2), 0.5))
        dev.step(torch.full((2, 2), 0.5, device=ON))
    for k in ("steps", "total_reward", "min_separation", "drift_sum"):
        np.testing.assert_array_equal(getattr(dev.unwrapped.task.stats, k), getattr(cpu.unwrapped.task.stats, k), err_msg=k)
    np.testing.assert_array_equal(dev.unwrapped.task.total_intrusions, cpu.unwrapped.task.total_intrusions)
    assert dev.render().shape == cpu.render().shape
    cpu.close()
    dev.close()
