"""``bluesky-gym bench``: runs on tiny sizes and prints sane tables and JSON (never speed)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from bluesky_gym.benchmarks.core_bench import available_kernels
from bluesky_gym.cli import main


def test_bench_core_table_and_json(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out_json = tmp_path / "core.json"
    code = main(["bench", "core", "--envs", "1", "2", "--aircraft", "1", "3", "--seconds", "0.02", "--no-bluesky", "--json", str(out_json)])
    assert code == 0
    text = capsys.readouterr().out
    assert "aircraft-sub-steps per second" in text
    assert "ac-sub-steps/s" in text
    assert "BlueSky: not measured" in text
    rows = [line.split() for line in text.splitlines() if line.split()[:1] and line.split()[0] in available_kernels()]
    assert len(rows) == (4 + 2) * len(available_kernels())  # 2 x 2 A320 cells, 2 mixed-fleet cells at the largest batch
    assert sum("mixed (10 types)" in line for line in text.splitlines()) == 2 * len(available_kernels())
    data = json.loads(out_json.read_text())
    assert data["meta"]["numpy"]
    assert {(r["kernel"], r["envs"], r["aircraft"]) for r in data["core"]["native"]} == {
        (k, e, a) for k in available_kernels() for e in (1, 2) for a in (1, 3)
    }
    assert {(r["fleet"], r["envs"], r["aircraft"]) for r in data["core"]["mixed"]} == {("mixed (10 types)", 2, a) for a in (1, 3)}


def test_bench_core_prints_the_target_next_to_its_cell(capsys: pytest.CaptureFixture[str]) -> None:
    # The target cell is 4096 x 20; a one-kernel run of only that cell on a tiny budget.
    kernel = available_kernels()[0]
    assert main(["bench", "core", "--envs", "4096", "--aircraft", "20", "--kernel", kernel, "--seconds", "0.01", "--no-bluesky"]) == 0
    text = capsys.readouterr().out
    target_line = next(line for line in text.splitlines() if "target >=" in line)
    assert target_line.startswith(kernel) and "4096" in target_line
    assert target_line.endswith(": met") or target_line.endswith(": NOT MET")


def test_bench_core_unknown_kernel_exits(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit, match="not available"):
        main(["bench", "core", "--kernel", "no-such-kernel", "--no-bluesky"])


def test_bench_envs_table(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out_json = tmp_path / "envs.json"
    args = ["bench", "envs", "--ids", "DescentEnv-v0", "--batch", "2", "5", "--seconds", "0.02", "--no-bluesky", "--json", str(out_json)]
    code = main(args)
    assert code == 0
    text = capsys.readouterr().out
    header = next(line for line in text.splitlines() if line.startswith("env "))
    for column in ("single", "x2", "x5", "BlueSky", "reference", "single/ref (>=30x)", "x5/ref"):
        assert column in header
    assert any(line.startswith("DescentEnv-v0") for line in text.splitlines())
    assert "not measured" in text
    data = json.loads(out_json.read_text())
    assert data["envs"]["rows"][0]["batched"]["5"]["rate"] > 0


def test_bench_envs_failed_cell_sets_exit_code(capsys: pytest.CaptureFixture[str]) -> None:
    args = "bench envs --ids DescentEnv-v0 --batch 2 --seconds 0.02 --no-bluesky --reference-python no-such-python-interpreter --quiet"
    code = main(args.split())
    assert code == 1
    text = capsys.readouterr().out
    assert "errors:" in text and "interpreter not found" in text


def test_bench_envs_unknown_id_exits() -> None:
    with pytest.raises(SystemExit, match="NoSuchEnv-v0"):
        main(["bench", "envs", "--ids", "NoSuchEnv-v0", "--no-bluesky"])


def test_bench_all(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out_json = tmp_path / "all.json"
    args = f"bench all --envs 1 --aircraft 2 --kernel {available_kernels()[0]} --core-seconds 0.02 --ids DescentEnv-v0 --batch 2 --env-seconds 0.02"
    code = main([*args.split(), "--no-bluesky", "--quiet", "--json", str(out_json)])
    assert code == 0
    text = capsys.readouterr().out
    assert text.index("aircraft-sub-steps per second") < text.index("Environment steps per second")
    assert set(json.loads(out_json.read_text())) == {"meta", "core", "envs"}


def test_bench_profile(capsys: pytest.CaptureFixture[str]) -> None:
    kernel = available_kernels()[0]
    assert main(["bench", "profile", "--envs", "8", "--aircraft", "2", "--kernel", kernel, "--steps", "2", "--top", "5", "--quiet"]) == 0
    text = capsys.readouterr().out
    assert f"Profile of Simulator.step, {kernel} kernel, 8 airspaces x 2 aircraft" in text
    table = text.split("\n\n")[1].splitlines()
    assert table[0].split()[:2] == ["function", "calls/step"]
    assert 2 + 1 <= len(table) <= 2 + 5  # at most --top rows (a compiled step has few Python-level functions)


def test_bench_repeat_reports_medians_of_runs(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out_json = tmp_path / "repeat.json"
    kernel = available_kernels()[0]
    args = f"bench all --envs 2 --aircraft 1 --kernel {kernel} --core-seconds 0.02 --ids DescentEnv-v0 --batch 2 --env-seconds 0.02 --repeat 2"
    assert main([*args.split(), "--no-bluesky", "--quiet", "--json", str(out_json)]) == 0
    text = capsys.readouterr().out
    assert text.count("median over 2 runs") == 2
    data = json.loads(out_json.read_text())
    assert len(data["core"]["native"]) == 1 and len(data["core"]["native"][0]["runs"]) == 2
    row = data["envs"]["rows"][0]
    assert len(row["single"]["runs"]) == 2 and len(row["batched"]["2"]["runs"]) == 2
