"""The tests write nothing to the home directory: BlueSky, Ray and Matplotlib are pointed elsewhere (tests/conftest.py)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def run_with_home(home: Path, args: list[str], **env: str) -> subprocess.CompletedProcess[str]:
    """Run ``python args`` in the project directory with ``HOME`` set to ``home``."""
    home.mkdir(exist_ok=True)
    environ = dict(os.environ, HOME=str(home), PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""), **env)
    return subprocess.run([sys.executable, *args], cwd=ROOT, env=environ, capture_output=True, text=True, timeout=900)


def written(home: Path) -> list[str]:
    return sorted(str(p.relative_to(home)) for p in home.rglob("*"))


def test_training_plotting_and_video_tests_leave_the_home_directory_alone(tmp_path: Path) -> None:
    for module, extra in (("stable_baselines3", "train"), ("matplotlib", "train"), ("moviepy", "render"), ("traffic", "realtraffic")):
        pytest.importorskip(module, reason=f"runs tests of the '{extra}' extra")
    selection = [
        "tests/training/test_runner.py::test_run_records_everything",
        "tests/training/test_plotting.py::test_plots_and_aggregate_from_run_dirs",
        "tests/render/test_render.py::test_record_video_wrapper",
        "tests/realtraffic/test_sources.py::test_table_is_cleaned_into_flights",
    ]
    home = tmp_path / "home"
    res = run_with_home(home, ["-m", "pytest", "-q", "-n", "0", "-p", "no:cacheprovider", *selection])
    assert res.returncode == 0, res.stdout + res.stderr
    assert "4 passed" in res.stdout
    assert written(home) == []


@pytest.mark.bluesky
def test_bluesky_keeps_its_working_directory_outside_the_home_directory(tmp_path: Path) -> None:
    pytest.importorskip("bluesky")
    home, workdir = tmp_path / "home", tmp_path / "bluesky"
    code = "from bluesky_gym.backends.bluesky_sim import load_bluesky; bs = load_bluesky(); print(bs.sim is not None)"
    res = run_with_home(home, ["-c", code], BLUESKY_GYM_BLUESKY_WORKDIR=str(workdir))
    assert res.returncode == 0 and res.stdout.strip() == "True", res.stderr
    assert written(home) == []
    assert (workdir / "settings.cfg").exists()
