"""Running the worker script in a separate interpreter (here: this one)."""

from __future__ import annotations

import os
import sys
from pathlib import Path

from bluesky_gym.benchmarks import worker
from bluesky_gym.benchmarks.external import _clean_environment, bluesky_python, run_worker


def test_bluesky_python_choice() -> None:
    assert bluesky_python("/some/python") == "/some/python"
    assert bluesky_python("/some/python", disabled=True) is None
    assert bluesky_python(None) in (None, sys.executable)


def test_reference_mode_refuses_an_interpreter_without_the_reference_package() -> None:
    out = run_worker(sys.executable, "reference-env", {"env_id": "DescentEnv-v0", "seconds": 0.01, "seed": 0}, timeout=120)
    assert "bluesky-gym==0.2.0" in out["error"]
    assert out["pid"] != os.getpid()  # measured in another process


def test_unknown_mode_is_an_error() -> None:
    out = run_worker(sys.executable, "no-such-mode", {}, timeout=60)
    assert "exited with code 2" in out["error"]


def test_an_interpreter_path_relative_to_the_current_directory_is_found(monkeypatch) -> None:
    here = Path(sys.executable).parent.parent  # the environment's root: bin/python below it
    monkeypatch.chdir(here)
    relative = os.path.relpath(sys.executable, here)
    assert not Path(relative).is_absolute()
    out = run_worker(relative, "no-such-mode", {}, timeout=60)
    assert "exited with code 2" in out["error"]  # it started; not "interpreter not found"
    assert "interpreter not found: no/such/python" in run_worker("no/such/python", "no-such-mode", {}, timeout=60)["error"]


def test_timeout_is_reported(tmp_path: Path) -> None:
    # No interpreter starts within a millisecond, so the timeout always expires.
    out = run_worker(sys.executable, "bluesky-core", {"sets": [], "seconds": 0.01, "dt": 1.0}, timeout=1e-3)
    assert "timed out" in out["error"]


def test_clean_environment_drops_checkouts_of_this_project(monkeypatch, tmp_path: Path) -> None:
    checkout = tmp_path / "checkout"
    (checkout / "bluesky_gym").mkdir(parents=True)
    (checkout / "bluesky_gym" / "__init__.py").write_text("")
    other = tmp_path / "other"
    other.mkdir()
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(checkout), str(other)]))
    assert _clean_environment()["PYTHONPATH"] == str(other)
    monkeypatch.setenv("PYTHONPATH", str(checkout))
    assert "PYTHONPATH" not in _clean_environment()


def test_worker_main_usage_error() -> None:
    assert worker.main([]) == 2
