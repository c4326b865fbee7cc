"""Whole-number options accept the notations the help texts and README use (``2e6``)."""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

import pytest

from bluesky_gym.cli.arguments import non_negative_int, positive_int, whole_number


@pytest.mark.parametrize(("text", "value"), [("250000", 250000), ("2e6", 2_000_000), ("2_000_000", 2_000_000), ("1.5e3", 1500), ("100.0", 100)])
def test_whole_numbers_in_any_notation(text: str, value: int) -> None:
    assert whole_number(text) == value
    assert positive_int(text) == value
    assert non_negative_int(text) == value


@pytest.mark.parametrize("text", ["2.5", "1e-3", "two", "", "nan", "inf"])
def test_non_whole_numbers_are_refused_with_their_text(text: str) -> None:
    with pytest.raises(argparse.ArgumentTypeError, match="whole number"):
        whole_number(text)


def test_bounds_still_hold() -> None:
    with pytest.raises(argparse.ArgumentTypeError, match=">= 1"):
        positive_int("0e0")
    with pytest.raises(argparse.ArgumentTypeError, match=">= 0"):
        non_negative_int("-1e3")


def test_the_readme_sweep_estimate_command_parses_2e6(tmp_path: Path) -> None:
    pytest.importorskip("stable_baselines3", reason="the estimate times SB3 training (the 'train' extra)")
    script = Path(sys.executable).with_name("bluesky-gym")
    command = [str(script)] if script.exists() else [sys.executable, "-m", "bluesky_gym"]
    run = subprocess.run(
        [*command, "sweep", "--env", "DescentEnv-v0", "--algos", "PPO", "--steps", "2e6", "--estimate"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert run.returncode == 0, run.stderr
    assert "DescentEnv-v0" in run.stdout and "PPO" in run.stdout
