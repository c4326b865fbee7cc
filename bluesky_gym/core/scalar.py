"""Scalar arithmetic helpers shared by every kernel, with numpy's exact semantics.

The kernels reproduce results that BlueSky computes with numpy arrays, to the last bit. These
helpers give scalar code numpy's behaviour where Python's or C's differs: the float remainder
(sign of the divisor), ``np.sign`` and ``np.maximum`` (NaN propagates), division by zero (inf or
NaN, not an error), and numpy's own degree conversion factors.
"""

from __future__ import annotations

import math

import numpy as np

from bluesky_gym.core.jit import fmod, jit

RAD = np.pi / 180.0  # numpy's deg2rad factor
DEG = 180.0 / np.pi  # numpy's rad2deg factor


@jit
def mod(a: float, b: float) -> float:
    """numpy/Python float remainder (the result has the sign of ``b``)."""
    # Fast paths with the same result: fmod(a, b) is exactly a when |a| < |b|, and numpy then
    # adds b to a negative remainder. (Zero goes the long way: its sign is set below.)
    if b > 0.0:
        if 0.0 < a < b:
            return a
        if -b < a < 0.0:
            return a + b
    m = float(fmod(a, b))
    if m != 0.0:
        if (b < 0.0) != (m < 0.0):
            m += b
    else:
        m = math.copysign(0.0, b)
    return m


@jit
def sign(x: float) -> float:
    """``np.sign`` of a float (NaN stays NaN)."""
    if x > 0.0:
        return 1.0
    if x < 0.0:
        return -1.0
    if x == 0.0:
        return 0.0
    return x  # NaN


@jit
def maximum(a: float, b: float) -> float:
    """``np.maximum`` of two floats (NaN propagates)."""
    if a != a:
        return a
    if b != b:
        return b
    return a if a >= b else b


@jit
def minimum(a: float, b: float) -> float:
    """``np.minimum`` of two floats (NaN propagates)."""
    if a != a:
        return a
    if b != b:
        return b
    return a if a <= b else b


@jit
def clip(x: float, low: float, high: float) -> float:
    """``np.clip`` of a float: ``x`` within ``[low, high]``, NaN kept; a value equal to a bound gives the bound (its sign of zero)."""
    if not (x > low or x != x):
        x = low
    if not (x < high or x != x):
        x = high
    return x


@jit
def divide(a: float, b: float) -> float:
    """``a / b`` with numpy's IEEE semantics: a zero divisor gives +-inf (NaN for 0/0) instead of an error."""
    if b != 0.0:
        return a / b
    if a != a or a == 0.0:
        return math.nan
    return math.copysign(math.inf, a) * math.copysign(1.0, b)
