"""``bluesky-gym bench gpu``'s device check, end to end at tiny sizes (under the simulator, it measures nothing but runs every part)."""

from __future__ import annotations

import pytest

from bluesky_gym.benchmarks import gpu_bench

from .conftest import needs_device

pytestmark = needs_device


def test_the_device_check_runs_every_part_and_prints_its_table(monkeypatch: pytest.MonkeyPatch) -> None:
    for name, value in {"FIDELITY_SAMPLE": (2, 3, 4), "PHYSICS_AIRCRAFT": 3, "CPU_BATCH": 2, "DEVICE_BATCHES": (2,), "SUBSTEPS": 2,
                        "TASK_ROWS": (3,), "TASK_ROWS_CPU": 3, "TASK_INTRUDERS": 2}.items():  # fmt: skip
        monkeypatch.setattr(gpu_bench, name, value)
    monkeypatch.setattr(gpu_bench, "device_refusal", lambda: None)  # the simulator is no device, but runs the same code
    monkeypatch.setattr(gpu_bench, "_device_name", lambda: "numba-cuda simulator")
    result = gpu_bench.device_check(budget=600.0)
    assert result["fidelity"]["within_tolerances"]
    assert [p["target"] for p in result["physics"]] == ["cpu (1 core)", "cuda"]
    assert all(p["run_rate"] > 0 and p["step_rate"] > 0 for p in result["physics"])
    assert [t["target"] for t in result["tasks"]] == ["cpu (1 core)", "cuda"]
    assert all(t["sector_observe"] > 0 and t["merge_observe"] > 0 for t in result["tasks"])
    text = gpu_bench.format_device_check(result)
    assert "Device check on numba-cuda simulator" in text and "sector_observe" in text and "lat" in text


def test_a_device_check_out_of_budget_skips_the_rest(monkeypatch: pytest.MonkeyPatch) -> None:
    for name, value in {"FIDELITY_SAMPLE": (2, 3, 2), "PHYSICS_AIRCRAFT": 3, "CPU_BATCH": 2, "DEVICE_BATCHES": (2, 4), "TASK_ROWS": (3,),
                        "TASK_ROWS_CPU": 3, "TASK_INTRUDERS": 2}.items():  # fmt: skip
        monkeypatch.setattr(gpu_bench, name, value)
    monkeypatch.setattr(gpu_bench, "device_refusal", lambda: None)
    monkeypatch.setattr(gpu_bench, "_device_name", lambda: "numba-cuda simulator")
    result = gpu_bench.device_check(budget=0.0)
    assert [p.get("skipped") for p in result["physics"][1:]] == ["time budget", "time budget"]
    assert "skipped: time budget" in gpu_bench.format_device_check(result)


def test_the_vector_env_check_compares_and_times_every_id(monkeypatch: pytest.MonkeyPatch) -> None:
    pytest.importorskip("torch")
    for name, value in {"ENV_SAMPLE": (2, 2), "ENV_BATCHES": (2,), "ENV_CPU_BATCH": 2, "ENV_STEPS": 1}.items():
        monkeypatch.setattr(gpu_bench, name, value)
    monkeypatch.setattr(gpu_bench, "env_check_ids", lambda: ["HorizontalCREnv-v0", "DescentEnv-v1"])
    monkeypatch.setattr(gpu_bench, "device_refusal", lambda: None)
    monkeypatch.setattr(gpu_bench, "_device_name", lambda: "numba-cuda simulator")
    result = gpu_bench.device_envs(budget=600.0)
    assert [s["id"] for s in result["samples"]] == ["HorizontalCREnv-v0", "DescentEnv-v1"]
    for s in result["samples"]:  # the simulator runs the CPU's arithmetic: the same episodes, bit for bit
        assert s["obs_max_diff"] == 0.0 and s["reward_max_diff"] == 0.0 and s["obs_bit_identical"] == 1.0 and s["ended_differ"] == 0
    assert [(r["id"], r["target"]) for r in result["rates"]] == [
        (i, t) for i in ("HorizontalCREnv-v0", "DescentEnv-v1") for t in ("cpu (1 process)", "cuda")
    ]
    assert all(r["rate"] > 0 for r in result["rates"])
    text = gpu_bench.format_device_envs(result)
    assert "Vector environments on numba-cuda simulator" in text and "DescentEnv-v1" in text and "env-steps/s" in text
    skipped = gpu_bench.device_envs(budget=0.0)
    assert [s.get("skipped") for s in skipped["samples"]] == ["time budget", "time budget"]


def test_the_ppo_check_trains_on_device_environments_and_times_them(monkeypatch: pytest.MonkeyPatch) -> None:
    pytest.importorskip("stable_baselines3")
    monkeypatch.setattr(gpu_bench, "PPO_BATCHES", (("cpu", 2), ("cuda", 3)))
    monkeypatch.setattr(gpu_bench, "PPO_SETTINGS", (2, 1, 2))
    monkeypatch.setattr(gpu_bench, "PPO_ROLLOUTS", 1)
    monkeypatch.setattr(gpu_bench, "device_refusal", lambda: None)
    monkeypatch.setattr(gpu_bench, "_device_name", lambda: "numba-cuda simulator")
    result = gpu_bench.device_ppo(budget=600.0)
    assert [(r["env"], r["episodes"]) for r in result["rates"]] == [("cpu env (1 process)", 2), ("cuda env", 3)]
    assert all(r["rate"] > 0 for r in result["rates"])
    assert result["rates"][1]["hyperparams"]["batch_size"] == 3  # 3 episodes x 2 steps in 2 minibatches
    text = gpu_bench.format_device_ppo(result)
    assert "PPO end to end on numba-cuda simulator: SectorCREnv-v1" in text and "env-steps/s" in text
    skipped = gpu_bench.device_ppo(budget=0.0)
    assert [r.get("skipped") for r in skipped["rates"]] == ["time budget", "time budget"]


def test_the_device_step_ids_are_checked_first() -> None:
    from bluesky_gym.envs.registry import entry

    ids = gpu_bench.env_check_ids()
    on_device = [entry(i).device_step is not None for i in ids]
    assert on_device == sorted(on_device, reverse=True), "the ids whose step runs on the device come first"
    assert {
        "SectorCREnv-v0",
        "SectorCREnv-v1",
        "MergeEnv-v0",
        "MergeEnv-v1",
        "PlanWaypointEnv-v0",
        "PlanWaypointEnv-v1",
        "HorizontalCREnv-v0",
        "HorizontalCREnv-v1",
    } <= set(ids[: sum(on_device)])
