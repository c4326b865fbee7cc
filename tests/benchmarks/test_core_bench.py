"""Core benchmark: scenario, native measurement and the BlueSky worker (never speed)."""

from __future__ import annotations

import numpy as np
import pytest

from bluesky_gym.benchmarks.core_bench import (
    TURN_ANGLE,
    available_kernels,
    bluesky_core_rates,
    core_scenario,
    make_simulator,
    native_core_rate,
    populate,
    run_core,
)


def test_scenario_mixed_altitudes_and_every_third_aircraft_turning() -> None:
    sc = core_scenario(4, 7)
    for field in (sc.lat, sc.lon, sc.hdg, sc.alt, sc.cas, sc.turn):
        assert field.shape == (4, 7)
    assert np.all((sc.alt >= 1000) & (sc.alt <= 11000)) and np.ptp(sc.alt) > 1000
    assert np.all((sc.cas >= 120) & (sc.cas <= 140))
    turning = sc.turn != 0
    assert np.array_equal(turning[0], np.arange(7) % 3 == 0)
    assert set(np.abs(sc.turn[turning])) == {TURN_ANGLE}
    assert set(np.sign(sc.turn[0][turning[0]])) == {-1.0, 1.0}  # left and right turns
    again = core_scenario(4, 7)
    assert np.array_equal(sc.alt, again.alt)  # deterministic


def test_populated_simulator_turns_the_turning_aircraft() -> None:
    sim = make_simulator(3, 4, "compiled")
    env, slot, _turn = populate(sim, core_scenario(3, 4))
    assert np.all(sim.active)
    hdg0 = sim.hdg.copy()
    for _ in range(5):
        sim.step()
    dh = np.abs((sim.hdg - hdg0 + 180) % 360 - 180)
    turning = np.zeros((3, 4), bool)
    turning[env, slot] = True
    assert np.all(dh[turning] > 1.0)
    assert np.all(dh[~turning] < 1e-9)


def test_available_kernels_are_the_compiled_one() -> None:
    kernels = available_kernels()
    assert kernels == ["compiled"]


@pytest.mark.parametrize("kernel", available_kernels())
def test_native_rate_reports_kernel_and_size(kernel: str) -> None:
    res = native_core_rate(2, 3, 0.02, kernel)
    assert res["kernel"] == kernel
    assert (res["envs"], res["aircraft"]) == (2, 3)
    assert 0 < res["rate_low"] <= res["rate"] <= res["rate_high"]


def test_run_core_without_bluesky_has_no_ratio() -> None:
    out = run_core([1, 2], [1, 2], ["compiled"], 0.02, None)
    assert [(r["envs"], r["aircraft"]) for r in out["native"]] == [(1, 1), (1, 2), (2, 1), (2, 2)]
    assert out["bluesky"] is None
    assert all(r["vs_bluesky"] is None for r in out["native"])
    assert out["target"]["rate"] == 1e7


def test_bluesky_worker_failure_is_reported_not_raised() -> None:
    out = bluesky_core_rates("no-such-python-interpreter", [1], 0.02)
    assert "interpreter not found" in out["error"]


@pytest.mark.bluesky
def test_bluesky_core_rates(bluesky_interpreter: str) -> None:
    out = bluesky_core_rates(bluesky_interpreter, [1, 3], 0.05)
    assert "error" not in out, out.get("traceback", out.get("error"))
    assert [r["aircraft"] for r in out["results"]] == [1, 3]
    assert out["versions"]["bluesky-simulator"] == "1.1.1"
    assert all(r["rate"] > 0 for r in out["results"])


@pytest.mark.bluesky
def test_run_core_with_bluesky_gives_ratios(bluesky_interpreter: str) -> None:
    out = run_core([2], [1], ["compiled"], 0.02, bluesky_interpreter)
    assert out["native"][0]["vs_bluesky"] > 0


@pytest.mark.bluesky
def test_run_core_repeat_with_bluesky_uses_same_run_ratios(bluesky_interpreter: str) -> None:
    out = run_core([2], [1], ["compiled"], 0.02, bluesky_interpreter, repeats=2)
    row = out["native"][0]
    assert len(row["vs_bluesky_runs"]) == 2
    assert min(row["vs_bluesky_runs"]) <= row["vs_bluesky"] <= max(row["vs_bluesky_runs"])
    assert len(out["bluesky"]["results"][0]["runs"]) == 2
