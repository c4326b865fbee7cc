"""Argument types shared by the subcommands."""

from __future__ import annotations

import argparse


def whole_number(text: str) -> int:
    """Parse a whole number, also written as ``2e6``, ``2_000_000`` or ``100.0``."""
    try:
        return int(text)
    except ValueError:
        pass
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number (e.g. 250000 or 2e6), got {text!r}") from None
    if not value.is_integer():
        raise argparse.ArgumentTypeError(f"expected a whole number (e.g. 250000 or 2e6), got {text!r}")
    return int(value)


def positive_int(text: str) -> int:
    """Parse an integer >= 1 (``2e6`` is accepted)."""
    value = whole_number(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be >= 1, got {value}")
    return value


def non_negative_int(text: str) -> int:
    """Parse an integer >= 0 (``2e6`` is accepted)."""
    value = whole_number(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be >= 0, got {value}")
    return value


def positive_float(text: str) -> float:
    """Parse a number > 0."""
    value = float(text)
    if not value > 0:
        raise argparse.ArgumentTypeError(f"must be > 0, got {value}")
    return value
