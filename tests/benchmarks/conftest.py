"""Interpreters for the optional tests that measure the real BlueSky and the reference package."""

from __future__ import annotations

import os

import pytest

from bluesky_gym.benchmarks.external import bluesky_python
from bluesky_gym.cli.bench import BLUESKY_PYTHON_VAR, REFERENCE_PYTHON_VAR


@pytest.fixture(scope="module")
def bluesky_interpreter() -> str:
    """An interpreter with BlueSky (``$BLUESKY_PYTHON``, or this one if it has BlueSky), else skip."""
    python = bluesky_python(os.environ.get(BLUESKY_PYTHON_VAR) or None)
    if python is None:
        pytest.skip(f"BlueSky is not importable here and ${BLUESKY_PYTHON_VAR} is not set")
    return python


@pytest.fixture(scope="module")
def reference_interpreter() -> str:
    """An interpreter with bluesky-gym 0.2.0 (``$BLUESKY_GYM_REFERENCE_PYTHON``), else skip."""
    python = os.environ.get(REFERENCE_PYTHON_VAR)
    if not python:
        pytest.skip(f"optional comparison with the reference package bluesky-gym 0.2.0: set ${REFERENCE_PYTHON_VAR} to an interpreter that has it")
    return python
