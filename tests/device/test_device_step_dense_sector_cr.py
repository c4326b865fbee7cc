"""DenseSectorCR's step on the device (:mod:`bluesky_gym.environments.dense_sector_cr.device_step`).

It gives the CPU vector environment's episodes, in a fixed number of launches, with its traffic
flow: the aircraft that leave the sector are deleted on the device, those that enter are drawn on
the host from each episode's generator and only they cross to the device.

Under numba-cuda's simulator every output (observations, reward, terminated, truncated, every
info entry, the final observations and infos of ended episodes) must equal the CPU vector
environment's bit for bit, through entries, exits, dropped entries, losses of separation and
autoresets; the aircraft state must never travel back to the host whole.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import bluesky_gym
from bluesky_gym.core import DeviceSimulator
from bluesky_gym.environments.dense_sector_cr.device_step import DenseSectorCRDeviceStep

from .conftest import ON, compare_device_step, launches_of_step, needs_device

torch = pytest.importorskip("torch")
pytestmark = needs_device
bluesky_gym.register_envs()

#: A busy flow through a small sector (aircraft cross it within a few steps) in few slots (entries dropped once
#: they are full), and short episodes (several autoresets).
BUSY = {
    "spawn_rate_start": 1800.0,
    "spawn_rate_end": 3600.0,
    "rise_time_s": 120.0,
    "max_spawned": 10,
    "max_episode_steps": 8,
    "poly_area_range": (10.0, 20.0),
}
#: No traffic enters: a step without entries.
NO_FLOW = {"spawn_rate_start": 0.0, "spawn_rate_end": 0.0}


def _flow_events(infos: list[dict[str, Any]]) -> dict[str, bool]:
    """Which flow events the CPU environment's infos show: entries, exits (traffic falling within an episode), drops, first losses."""
    events = {"entered": False, "left": False, "dropped": False, "first_loss": False}
    for before, after in zip(infos, infos[1:]):
        same_episode = after["spawned"] >= before["spawned"]
        grew = after["spawned"] > before["spawned"]
        events["entered"] |= bool(grew.any())
        # fewer aircraft than before plus those that entered: some left
        events["left"] |= bool((same_episode & (after["traffic"] < before["traffic"] + (after["spawned"] - before["spawned"]))).any())
    for info in infos:
        events["dropped"] |= bool((info["spawns_dropped"] > 0).any())
        final = info.get("final_info")
        if final is not None:
            events["first_loss"] |= bool(np.isfinite(final["kpi_time_to_first_los_s"][info["_final_info"]]).any())
    return events


@pytest.mark.parametrize("env_id", ["DenseSectorCREnv-v0", "DenseSectorCREnv-v1"])
def test_device_step_equals_the_cpu_through_entries_exits_and_autoresets(env_id: str, monkeypatch: pytest.MonkeyPatch) -> None:
    infos: list[dict[str, Any]] = []
    ended, _terminated, cpu, dev = compare_device_step(env_id, BUSY, DenseSectorCRDeviceStep, monkeypatch, steps=14, cpu_infos=infos)
    assert ended >= 3, "several autoresets"
    events = _flow_events(infos)
    assert all(events.values()), events
    # The state brought back (as for a picture): the aircraft deleted on the device are gone on the host too.
    np.testing.assert_array_equal(dev.unwrapped.task.sim.active, cpu.unwrapped.task.sim.active)
    cpu.close()
    dev.close()


def test_default_slots_run_on_the_device(monkeypatch: pytest.MonkeyPatch) -> None:
    """The default flow's 158 slots (157 aircraft beside the ownship) fit the device's per-airspace capacity."""
    _ended, _terminated, cpu, dev = compare_device_step("DenseSectorCREnv-v0", {}, DenseSectorCRDeviceStep, monkeypatch, steps=2, num_envs=2)
    assert dev.unwrapped.task.sim.max_aircraft == 158
    cpu.close()
    dev.close()


def test_a_step_with_entries_is_a_fixed_number_of_launches(monkeypatch: pytest.MonkeyPatch) -> None:
    """Entries in every episode add the same launches at 2 and 4 episodes (the new aircraft cross in one gather and scatter)."""
    created: list[int] = []
    original = DeviceSimulator.create
    monkeypatch.setattr(
        DeviceSimulator, "create", lambda self, env, slot, *a, **k: (created.append(np.size(env)), original(self, env, slot, *a, **k))[1]
    )
    busy = {"spawn_rate_start": 3600.0, "spawn_rate_end": 3600.0}
    with_entries = [launches_of_step("DenseSectorCREnv-v0", n, False, **busy) for n in (2, 4)]
    assert created and min(created) >= 2, "aircraft entered in the stepped episodes"
    assert with_entries[0] == with_entries[1] > launches_of_step("DenseSectorCREnv-v0", 2, False, **NO_FLOW)


def test_traffic_flow_never_brings_the_state_back_whole(monkeypatch: pytest.MonkeyPatch) -> None:
    env = gym.make_vec("DenseSectorCREnv-v0", num_envs=2, device="cuda", **BUSY)
    env.reset(seed=3)
    pulls: list[int] = []
    original = DeviceSimulator._to_host
    monkeypatch.setattr(DeviceSimulator, "_to_host", lambda self: (pulls.append(1), original(self))[1])
    for _ in range(4):
        _, _, _, _, info = env.step(torch.zeros(env.action_space.shape, device=ON))
    assert not pulls
    assert int(info["spawned"].sum()) > 0
    env.close()
