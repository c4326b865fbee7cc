"""``bluesky-gym bench scale``: the traffic, the table and the JSON rows, on tiny sizes (never speed)."""

from __future__ import annotations

import json
import math
import shlex
from pathlib import Path

import numpy as np
import pytest

from bluesky_gym.benchmarks.scale_bench import AREA_PER_AIRCRAFT, MAX_LATITUDE, core_flight, scale_scenario
from bluesky_gym.cli import main
from bluesky_gym.core.units import R_EARTH

ROW_KEYS = {"aircraft", "cdr", "sim_time_s", "core_wall_s", "bluesky_wall_s"}


def test_scenario_is_seeded_and_keeps_its_density() -> None:
    a, b = scale_scenario(500), scale_scenario(500)
    for field in ("lat", "lon", "hdg", "alt", "cas"):
        np.testing.assert_array_equal(getattr(a, field), getattr(b, field))
    assert not np.array_equal(scale_scenario(500, seed=1).lat, a.lat)
    for n in (100, 100_000):
        sc = scale_scenario(n)
        assert sc.lat.shape == (n,) and np.abs(sc.lat).max() <= MAX_LATITUDE
        half = np.radians(np.abs(sc.lat).max())
        width = np.radians(np.ptp(sc.lon))
        area = R_EARTH**2 * width * 2.0 * math.sin(half)
        assert area / n == pytest.approx(AREA_PER_AIRCRAFT, rel=0.05)
    assert len(a.rows()) == 500 and len(a.rows()[0]) == 5
    with pytest.raises(ValueError, match="n_aircraft must be >= 1"):
        scale_scenario(0)
    with pytest.raises(ValueError, match="do not fit"):
        scale_scenario(10_000_000)


def test_core_flight_resolves_conflicts_the_same_with_either_pair_search() -> None:
    sc = scale_scenario(300)
    grid = core_flight(sc, 60.0, True, "grid")
    every = core_flight(sc, 60.0, True, "all-pairs")
    assert grid["pair_search"] == "grid" and every["pair_search"] == "all-pairs"
    assert grid["conflicts"] == every["conflicts"] > 0
    assert core_flight(sc, 5.0, False)["conflicts"] == 0


def test_bench_scale_table_and_json(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "scale.json"
    assert main(["bench", "scale", "--aircraft", "20", "300", "--sim-time", "4", "--no-bluesky", "--quiet", "--json", str(out)]) == 0
    text = capsys.readouterr().out
    assert "core/BlueSky" in text and "targets:" in text
    rows = json.loads(out.read_text())["rows"]
    assert [(r["aircraft"], r["cdr"]) for r in rows] == [(20, False), (20, True), (300, False), (300, True)]
    for r in rows:
        assert ROW_KEYS <= set(r)
        assert r["sim_time_s"] == 4.0 and r["core_wall_s"] > 0.0 and r["bluesky_wall_s"] is None
    assert [r["pair_search"] for r in rows] == ["all-pairs", "all-pairs", "grid", "grid"]


@pytest.mark.bluesky
def test_bench_scale_flies_bluesky_side_by_side(bluesky_interpreter: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "scale.json"
    argv = ["bench", "scale", "--aircraft", "30", "60", "--sim-time", "3", "--bluesky-max-aircraft", "30", "--quiet", "--json", str(out)]
    assert main([*argv, "--bluesky-python", bluesky_interpreter]) == 0
    rows = json.loads(out.read_text())["rows"]
    assert [(r["aircraft"], r["cdr"]) for r in rows] == [(30, False), (30, True), (60, False), (60, True)]
    assert all(r["bluesky_wall_s"] > 0.0 for r in rows[:2]) and all(r["bluesky_wall_s"] is None for r in rows[2:])
    assert all(r["bluesky_error"] is None for r in rows)
    assert "30" in capsys.readouterr().out


def test_the_scale_table_of_the_docs_is_the_committed_measurement() -> None:
    from bluesky_gym.benchmarks.scale_bench import format_scale_markdown
    from bluesky_gym.cli import build_parser

    root = Path(__file__).resolve().parents[2]
    page = (root / "docs" / "backends.md").read_text(encoding="utf-8")
    measured = [json.loads((root / "results" / "bench" / name).read_text(encoding="utf-8")) for name in ("scale-1000.json", "scale.json")]
    assert format_scale_markdown(measured) in page
    rows = [r for m in measured for r in m["rows"]]
    assert {(r["aircraft"], r["sim_time_s"]) for r in rows if r["cdr"]} >= {(1000, 600.0), (10000, 3600.0), (100_000, 3600.0)}
    assert all(r["bluesky_wall_s"] for r in measured[0]["rows"])
    for out in ("results/bench/scale-1000.json", "results/bench/scale.json"):
        line = next(line for line in page.splitlines() if line.startswith("bluesky-gym bench scale") and line.endswith(out))
        args = build_parser().parse_args(shlex.split(line)[1:])
        assert args.func.__name__ == "run_scale_command"
