"""Run summaries: a finished run reduced to its results stays a finished, intact run that the results read."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("stable_baselines3", reason="needs Stable-Baselines3 (the 'train' extra)")

from bluesky_gym.training.hyperparams import PAPER, merge
from bluesky_gym.training.io import read_csv_rows, read_json
from bluesky_gym.training.plotting import load_run
from bluesky_gym.training.runner import inspect_run, make_run_spec, run_status, run_training
from bluesky_gym.training.summary import summarise_run

CONFIG = merge(PAPER, {"run": {"trainer": "fast"}, "algos": {"PPO": {"n_steps": 32, "batch_size": 64, "n_epochs": 1}}})


def test_a_summarised_run_is_finished_intact_and_plotted_from_its_curve(tmp_path: Path) -> None:
    spec = make_run_spec(CONFIG, "DescentEnv-v0", "PPO", 0, n_envs=4, total_timesteps=1024, checkpoint_freq=256, eval_episodes=3)
    d = tmp_path / "run"
    run_training(spec, d, verbose=0)
    header, rows = read_csv_rows(d / "episodes.csv")
    log = np.array([[float(x) if x else np.nan for x in r] for r in rows])
    record = summarise_run(d, bins=8)
    assert set(record["removed"]) == {"checkpoints", "checkpoint.json", "tensorboard", "episodes.csv", "model.zip"}
    assert sorted(p.name for p in d.iterdir()) == ["config.json", "curve.csv", "eval.json", "eval_episodes.csv", "result.json", "run.json"]
    assert inspect_run(d).problems == [] and run_status(d) == "finished"
    assert run_training(spec, d, verbose=0)["skipped"] is True  # a rerun of the sweep skips it
    run = load_run(d)
    result = read_json(d / "result.json")
    assert run.columns["episodes"].sum() == result["episodes"] == len(rows)
    assert np.all(np.diff(run.timesteps) > 0) and run.timesteps[-1] <= result["timesteps"]
    # Each row is the mean of the episodes that ended in its span.
    steps, returns = log[:, header.index("timesteps")], log[:, header.index("return")]
    edges = np.linspace(0, result["timesteps"], 9)
    for end, mean in zip(run.timesteps, run.columns["return"], strict=True):
        span = (steps > edges[np.searchsorted(edges, end) - 1]) & (steps <= end)
        assert mean == float(f"{returns[span].mean():.6g}")  # six significant digits
    assert summarise_run(d) == record  # again: nothing more to do


def test_runs_command_summarises_finished_runs_and_leaves_the_others(tmp_path: Path) -> None:
    spec = make_run_spec(CONFIG, "DescentEnv-v0", "PPO", 0, n_envs=2, total_timesteps=64, eval_episodes=0)
    run_training(spec, tmp_path / "done", verbose=0, tensorboard=False)
    (tmp_path / "open").mkdir()
    (tmp_path / "open" / "config.json").write_text("{}")
    out = subprocess.run([sys.executable, "-m", "bluesky_gym", "runs", str(tmp_path), "--summarise", "--keep-model"], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert "open: not finished" in out.stdout and "done: summarised" in out.stdout
    assert (tmp_path / "done" / "model.zip").exists() and not (tmp_path / "done" / "episodes.csv").exists()
    assert inspect_run(tmp_path / "done").problems == []
