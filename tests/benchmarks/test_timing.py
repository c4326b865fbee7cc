"""The measurement loop: structure and consistency of its results (never speed)."""

from __future__ import annotations

import gymnasium as gym
import pytest

import bluesky_gym  # noqa: F401
from bluesky_gym.benchmarks.timing import combine, env_step_rate, measure


def test_measure_counts_calls_and_reports_a_consistent_result() -> None:
    calls = {"n": 0, "between": 0}

    def call() -> None:
        calls["n"] += 1

    def between() -> None:
        calls["between"] += 1

    res = measure(call, 5.0, 0.02, between=between, warmup_calls=3, min_blocks=4)
    assert res["blocks"] >= 4
    assert calls["between"] == res["blocks"]
    assert calls["n"] > res["calls"] >= res["blocks"]  # warm-up and calibration calls are not timed
    assert 0 < res["rate_low"] <= res["rate"] <= res["rate_high"]
    assert res["call_s"] == pytest.approx(5.0 / res["rate"])
    assert res["seconds"] > 0


def test_measure_respects_max_blocks() -> None:
    res = measure(lambda: None, 1.0, 10.0, min_blocks=1, max_blocks=2)
    assert res["blocks"] == 2


@pytest.mark.parametrize("bad", [{"units_per_call": 0.0, "seconds": 1.0}, {"units_per_call": 1.0, "seconds": 0.0}])
def test_measure_rejects_non_positive_arguments(bad: dict[str, float]) -> None:
    with pytest.raises(ValueError):
        measure(lambda: None, **bad)


def test_env_step_rate_single_resets_ended_episodes() -> None:
    # Five decision steps per episode, so the measurement sees several episode ends.
    env = gym.make("DescentEnv-v0", time_limit=5)
    res = env_step_rate(env, 0.05, seed=1)
    env.close()
    assert res["episodes"] >= 1
    assert res["rate"] > 0 and res["calls"] >= 3


def test_env_step_rate_vector_counts_every_episode() -> None:
    env = gym.make_vec("DescentEnv-v0", num_envs=3, vectorization_mode="vector_entry_point", max_episode_steps=4)
    res = env_step_rate(env, 0.05, seed=2, num_envs=3)
    env.close()
    assert res["call_s"] == pytest.approx(3.0 / res["rate"])
    assert res["episodes"] >= 3


def test_combine_takes_medians_and_skips_failed_runs() -> None:
    runs = [
        {"rate": 10.0, "rate_low": 8.0, "rate_high": 12.0, "call_s": 0.1, "calls": 5.0, "blocks": 3.0, "seconds": 0.5, "kernel": "k"},
        {"error": "boom"},
        {"rate": 30.0, "rate_low": 20.0, "rate_high": 40.0, "call_s": 0.03, "calls": 7.0, "blocks": 4.0, "seconds": 0.2, "kernel": "k"},
        {"rate": 20.0, "rate_low": 15.0, "rate_high": 25.0, "call_s": 0.05, "calls": 1.0, "blocks": 3.0, "seconds": 0.3, "kernel": "k"},
    ]
    out = combine(runs)
    assert out["rate"] == 20.0 and out["call_s"] == 0.05
    assert (out["rate_low"], out["rate_high"]) == (8.0, 40.0)
    assert (out["calls"], out["blocks"]) == (13.0, 10.0)
    assert out["runs"] == [10.0, 30.0, 20.0]
    assert out["kernel"] == "k"
    assert combine([{"error": "a"}, {"error": "b"}]) == {"error": "a"}
