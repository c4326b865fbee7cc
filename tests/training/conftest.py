"""Shared fixtures of the benchmark tests."""

from __future__ import annotations

import csv
import importlib.util
from pathlib import Path

import pytest

#: For the tests that train or load models (the reference policies, evaluation, seeds and configs need no SB3).
needs_sb3 = pytest.mark.skipif(importlib.util.find_spec("stable_baselines3") is None, reason="needs Stable-Baselines3 (the 'train' extra)")


@pytest.fixture(autouse=True)
def _one_torch_thread() -> None:
    """Keep PyTorch to one thread: the test machines have few cores."""
    try:
        import torch
    except ImportError:
        return
    torch.set_num_threads(1)


def csv_rows(path: Path) -> list[list[str]]:
    """Every row of a CSV file, the header first, as strings."""
    with open(path, newline="") as f:
        return list(csv.reader(f))
