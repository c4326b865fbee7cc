"""Helpers of the core tests."""

from __future__ import annotations

import numpy as np


def bits(a: np.ndarray, active: np.ndarray | None = None) -> np.ndarray:
    """The bit patterns of the values (float64 as int64), in the occupied slots where ``active`` is given (empty slots carry no meaning)."""
    a = np.ascontiguousarray(a)
    a = a.view(np.int64) if a.dtype == np.float64 else a
    return a if active is None else a[active]
