"""RealTrafficCR's step on the device (:mod:`bluesky_gym.environments.real_traffic.device_step`).

Under numba-cuda's simulator every output must equal the CPU vector environment's bit for bit,
through recorded aircraft appearing and leaving mid-episode, time limits and autoresets; a step's
launches must not grow with the number of episodes.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import bluesky_gym
from bluesky_gym.core import cuda_target
from bluesky_gym.environments.real_traffic.device_step import RealTrafficDeviceStep
from bluesky_gym.realtraffic.scenario import WindowPlayer

from ..realtraffic.synthetic import joining_collection, save
from .conftest import ON, compare_device_step, needs_device

torch = pytest.importorskip("torch")
pytestmark = needs_device
bluesky_gym.register_envs()

#: Short windows: episodes reach their time limit within the steps and are reset.
_SHORT = {"window_s": 40.0, "min_traffic": 1, "max_traffic": 6}


@pytest.fixture(scope="module")
def joining(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """A collection where recorded aircraft appear and leave within every few minutes of the ownship's window (the options that play it)."""
    return {"collections": (save(joining_collection(), tmp_path_factory.mktemp("rt-device")),), **_SHORT}


@pytest.fixture
def events(monkeypatch: pytest.MonkeyPatch) -> dict[str, int]:
    """Counts of the recorded aircraft created and deleted mid-episode (not at an episode's start) by every player."""
    counts = {"created": 0, "deleted": 0}
    original = WindowPlayer.schedule

    def schedule(self: WindowPlayer, envs: Any = None) -> None:
        (ended_e, _), (due_e, _) = self.due(envs)
        started = self.elapsed[due_e] == 0.0
        counts["deleted"] += int(ended_e.size)
        counts["created"] += int((~started).sum())
        original(self, envs)

    monkeypatch.setattr(WindowPlayer, "schedule", schedule)
    return counts


@pytest.mark.parametrize(
    ("env_id", "extra"),
    [("RealTrafficCREnv-v0", {}), ("RealTrafficCREnv-v1", {}), ("RealTrafficCREnv-v0", {"altitude_action": True})],
)
def test_real_traffic_device_step_equals_the_cpu_vector_env_bit_for_bit(
    env_id: str, extra: dict[str, Any], joining: dict[str, Any], events: dict[str, int], monkeypatch: pytest.MonkeyPatch
) -> None:
    """Same seeds, same actions: the same outputs, every info entry and KPI included, through appearances, departures, time limits and autoresets."""
    options = {**joining, **extra}
    ended, terminated, cpu, dev = compare_device_step(env_id, options, RealTrafficDeviceStep, monkeypatch, steps=9, num_envs=3, seed=0)
    assert ended >= 6, "episodes must reach the time limit and be reset on the way"
    assert terminated == 0
    assert events["created"] > 0, "recorded aircraft must appear mid-episode"
    assert events["deleted"] > 0, "recorded aircraft must leave mid-episode"
    cpu.close()
    dev.close()


def _launches_per_step(options: dict[str, Any], num_envs: int, steps: int) -> list[tuple[int, bool]]:
    """The launches of each step of a device environment (zero actions, no episode ending), and whether aircraft entered or left in it."""
    env = gym.make_vec("RealTrafficCREnv-v0", num_envs=num_envs, device="cuda", **{**options, "window_s": 600.0})
    env.reset(seed=0)
    player = env.unwrapped.task.player
    out = []
    for _ in range(steps):
        clock = player.elapsed.copy()
        player.elapsed += 10.0  # what the step's clock will read: the events it will have
        (ended_e, _), (due_e, _) = player.due()
        player.elapsed[...] = clock
        before = cuda_target.launches()
        _, _, terminated, truncated, _ = env.step(torch.zeros(env.action_space.shape, device=ON))
        assert not bool((terminated | truncated).any())
        out.append((cuda_target.launches() - before, bool(ended_e.size or due_e.size)))
    env.close()
    return out


def test_a_step_is_a_fixed_number_of_launches_whatever_the_number_of_episodes(joining: dict[str, Any]) -> None:
    """Without an episode ending: one count for steps without traffic entering or leaving, one (larger) with, for 2 and 4 episodes."""
    counts: dict[bool, set[int]] = {False: set(), True: set()}
    for n in (2, 4):
        for launches, event in _launches_per_step(joining, n, 15):
            counts[event].add(launches)
    assert len(counts[False]) == 1 and len(counts[True]) == 1, counts
    assert min(counts[True]) > min(counts[False])


def test_the_multi_agent_task_and_wind_keep_their_step_on_the_host() -> None:
    """The all-agents task (every recorded aircraft an agent) and wind are not covered: the step runs on the host (the physics on the device)."""
    from bluesky_gym.environments.real_traffic.task import RealTrafficAllAgentsTask

    task = RealTrafficAllAgentsTask(1)
    assert not RealTrafficDeviceStep.supports(task)
    windy = gym.make_vec("RealTrafficCREnv-v0", num_envs=1, device="cuda", wind={"lat": [47.0], "lon": [8.0], "vnorth": [5.0], "veast": [0.0]})
    assert windy.unwrapped._device_step is None
    plain = gym.make_vec("RealTrafficCREnv-v1", num_envs=1, device="cuda")
    assert isinstance(plain.unwrapped._device_step, RealTrafficDeviceStep)
    windy.close()
    plain.close()
    np.testing.assert_equal(RealTrafficDeviceStep.task_class.env_id, "RealTrafficCREnv-v0")
