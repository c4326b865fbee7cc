"""The deprecated ``python -m bluesky_gym.multiagent.train`` is a hand-off to ``bluesky-gym train-ma``: one parser, one run."""

from __future__ import annotations

import ast
import os
import subprocess
import sys
from pathlib import Path

import pytest

from bluesky_gym.multiagent import train

ROOT = Path(__file__).resolve().parents[2]


def test_old_option_names_become_the_train_ma_ones() -> None:
    old = ["--env", "merge_v0", "--timesteps", "2000", "--episodes=4", "--eval-episodes", "3", "--seed", "1"]
    assert train.train_ma_arguments(old) == ["--env", "merge_v0", "--steps", "2000", "--num-envs=4", "--eval-episodes", "3", "--seed", "1"]


def test_the_module_keeps_no_parser_of_its_own() -> None:
    tree = ast.parse(Path(train.__file__).read_text(encoding="utf-8"))
    imported = {a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
    imported |= {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) and n.module}
    assert "argparse" not in imported
    assert not hasattr(train, "build_parser")


def test_main_hands_its_arguments_to_train_ma(capfd: pytest.CaptureFixture[str]) -> None:
    # Checked by train-ma's parser: the renamed option reaches it as --steps.
    assert train.main(["--timesteps", "0", "--episodes=2"]) == 2
    err = capfd.readouterr().err
    assert "deprecated; use `bluesky-gym train-ma --steps 0 --num-envs=2`" in err
    assert "bluesky-gym train-ma: error: argument --steps: must be >= 1, got '0'" in err
    assert train.main(["--env", "no_such_env"]) == 2
    assert "argument --env: must be one of" in capfd.readouterr().err


def test_python_dash_m_entry_shows_the_train_ma_command() -> None:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    res = subprocess.run([sys.executable, "-m", "bluesky_gym.multiagent.train", "--help"], env=env, capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    assert res.stdout.startswith("usage: bluesky-gym train-ma")
    assert "--num-envs" in res.stdout and "--timesteps" not in res.stdout
    assert "deprecated" in res.stderr
