"""Shared fixtures of the command-line tests."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

pytest.importorskip("stable_baselines3")

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
    import torch

    torch.set_num_threads(1)
