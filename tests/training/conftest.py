"""Shared fixtures of the benchmark tests."""

from __future__ import annotations

import pytest

pytest.importorskip("stable_baselines3")


@pytest.fixture(autouse=True)
def _one_torch_thread() -> None:
    """Keep PyTorch to one thread: the test machines have few cores."""
    import torch

    torch.set_num_threads(1)
