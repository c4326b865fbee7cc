"""Shared fixtures of the command-line tests."""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

#: For the commands that train (``list``, ``info``, the reference policies and the error messages need no SB3).
needs_sb3 = pytest.mark.skipif(importlib.util.find_spec("stable_baselines3") is None, reason="needs Stable-Baselines3 (the 'train' extra)")

ROOT = Path(__file__).resolve().parents[2]

#: Tiny budgets so that every subcommand runs in seconds.
TINY_CONFIG = {
    "run": {"checkpoint_freq": 100, "eval_episodes": 4},
    "algos": {
        "PPO": {"n_steps": 32, "batch_size": 64, "n_epochs": 2},
        "SAC": {"buffer_size": 5000, "learning_starts": 64, "batch_size": 32},
        "TD3": {"buffer_size": 5000, "batch_size": 32},
        "DDPG": {"buffer_size": 5000, "batch_size": 32},
    },
}


@pytest.fixture
def tiny_config(tmp_path: Path) -> Path:
    """A config file with tiny rollouts and buffers."""
    path = tmp_path / "tiny.json"
    path.write_text(json.dumps(TINY_CONFIG))
    return path


@pytest.fixture(autouse=True)
def _one_torch_thread() -> None:
    try:
        import torch
    except ImportError:
        return
    torch.set_num_threads(1)


def run_cli(*args: str, cwd: Path, timeout: float = 300, columns: int | None = None) -> subprocess.CompletedProcess[str]:
    """Run the installed ``bluesky-gym`` console script (importing this checkout) in ``cwd``."""
    script = Path(sys.executable).with_name("bluesky-gym")
    command = [str(script)] if script.exists() else [sys.executable, "-m", "bluesky_gym"]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    if columns is not None:
        env["COLUMNS"] = str(columns)
    return subprocess.run([*command, *args], cwd=cwd, capture_output=True, text=True, timeout=timeout, env=env, check=False)
