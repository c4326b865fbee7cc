"""Environment benchmark: every cell of the table, on tiny budgets (never speed)."""

from __future__ import annotations

import pytest

from bluesky_gym.benchmarks.env_bench import native_single_rate, native_vector_rate, run_envs
from bluesky_gym.registration import available_envs


@pytest.mark.parametrize("env_id", available_envs())
def test_native_single_and_vector_rates(env_id: str) -> None:
    single = native_single_rate(env_id, 0.02)
    batched = native_vector_rate(env_id, 4, 0.02)
    for res in (single, batched):
        assert 0 < res["rate_low"] <= res["rate"] <= res["rate_high"]
        assert isinstance(res["kernel"], str)
    assert batched["call_s"] == pytest.approx(4 / batched["rate"])


def test_run_envs_rows_and_missing_comparisons() -> None:
    out = run_envs(["DescentEnv-v0"], [2, 3], 0.02)
    (row,) = out["rows"]
    assert row["id"] == "DescentEnv-v0"
    assert set(row["batched"]) == {"2", "3"}
    assert row["bluesky"] is None and row["reference"] is None
    assert row["single_vs_reference"] is None and row["batched_vs_reference"] is None


def test_run_envs_rejects_unknown_ids() -> None:
    with pytest.raises(ValueError, match="NoSuchEnv-v0"):
        run_envs(["NoSuchEnv-v0"], [2], 0.02)


def test_failing_reference_interpreter_becomes_an_error_cell() -> None:
    out = run_envs(["DescentEnv-v0"], [2], 0.02, reference_python="no-such-python-interpreter")
    row = out["rows"][0]
    assert "interpreter not found" in row["reference"]["error"]
    assert row["single_vs_reference"] is None


@pytest.mark.bluesky
def test_bluesky_backend_cell(bluesky_interpreter: str) -> None:
    out = run_envs(["DescentEnv-v0"], [2], 0.05, bluesky_python=bluesky_interpreter)
    row = out["rows"][0]
    assert "error" not in row["bluesky"], row["bluesky"]
    assert row["single_vs_bluesky"] > 0


@pytest.mark.bluesky
def test_reference_cell(reference_interpreter: str) -> None:
    out = run_envs(["DescentEnv-v0"], [2], 0.05, reference_python=reference_interpreter)
    row = out["rows"][0]
    assert "error" not in row["reference"], row["reference"]
    assert row["reference"]["versions"]["bluesky-gym"] == "0.2.0"
    assert row["single_vs_reference"] > 0 and row["batched_vs_reference"] > 0
