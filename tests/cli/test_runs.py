"""Failed starts leave nothing behind, ``plot`` copes with runs without episodes, ``runs`` lists run status (console script)."""

from __future__ import annotations

import json
import os
import shutil
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from bluesky_gym.cli import main
from bluesky_gym.training.io import read_json
from bluesky_gym.training.status import STATUSES

from .conftest import ROOT, needs_sb3

ENV = "DescentEnv-v0"
TINY = {"run": {"n_envs": 2, "checkpoint_freq": 64, "eval_episodes": 2}, "algos": {"PPO": {"n_steps": 32, "batch_size": 64, "n_epochs": 1}}}


def cli(tmp_path: Path, *args: str) -> subprocess.CompletedProcess[str]:
    """Run the installed ``bluesky-gym`` script in ``tmp_path`` (this checkout first on the path)."""
    script = Path(sys.executable).with_name("bluesky-gym")
    command = [str(script)] if script.exists() else [sys.executable, "-m", "bluesky_gym"]
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    return subprocess.run([*command, *args], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)


def one_line_error(res: subprocess.CompletedProcess[str]) -> str:
    assert res.returncode == 2, res.stderr
    assert res.stderr.count("\n") == 1 and "Traceback" not in res.stderr, res.stderr
    return res.stderr


@needs_sb3
def test_failed_starts_leave_no_run_directory_and_plot_skips_runs_without_episodes(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "typo.toml").write_text("[algos.PPO]\nlearning_rat = 0.1\n")
    err = one_line_error(cli(tmp_path, "train", "--env", ENV, "--config", "typo.toml"))
    assert "typo.toml:2" in err and "'learning_rat'" in err and "did you mean 'learning_rate'" in err and "n_steps" in err
    (tmp_path / "options.toml").write_text(f'[env_options."{ENV}"]\nalt_mn = 3000\n')
    # the other failed starts in-process (each console-script start costs seconds)
    assert main(["train", "--env", ENV, "--config", "options.toml"]) == 2
    assert main(["train", "--env", "NoSuchEnv-v0"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 2 and "alt_mn" in err and "NoSuchEnv-v0" in err
    assert not (tmp_path / "runs").exists()

    # A directory left by a failed start of an older version (only config.json) does not block the corrected run.
    leftover = tmp_path / "runs" / ENV / "PPO" / "seed_0"
    leftover.mkdir(parents=True)
    (leftover / "config.json").write_text(json.dumps({"env_id": ENV, "algo": "PPO", "seed": 0, "total_timesteps": 5, "identity": {"n_envs": 9}}))
    (tmp_path / "tiny.json").write_text(json.dumps(TINY))
    res = cli(tmp_path, "train", "--env", ENV, "--steps", "128", "--config", "tiny.json", "--no-progress")
    assert res.returncode == 0, res.stderr
    assert "failed" in res.stdout and read_json(leftover / "result.json")["timesteps"] == 128

    # plot: a run that has not logged an episode is skipped with a message; with nothing to plot, one line.
    starting = tmp_path / "runs" / ENV / "SAC" / "seed_0"
    starting.mkdir(parents=True)
    shutil.copy(leftover / "config.json", starting / "config.json")
    res = cli(tmp_path, "plot", "runs", "--out", "figures", "--reference-episodes", "2")
    assert res.returncode == 0, res.stderr
    assert f"skipping {Path('runs') / ENV / 'SAC' / 'seed_0'}" in res.stderr and (tmp_path / "figures" / "learning_curves.png").exists()
    assert main(["plot", str(starting)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "has logged an episode yet" in err


@needs_sb3
def test_runs_lists_every_run_with_status_steps_and_score(tmp_path: Path) -> None:
    (tmp_path / "tiny.json").write_text(json.dumps(TINY))
    res = cli(tmp_path, "train", "--env", ENV, "--steps", "128", "--config", "tiny.json", "--no-progress", "--out", "sweep")
    assert res.returncode == 0, res.stderr
    done = tmp_path / "sweep" / ENV / "PPO" / "seed_0"
    assert list((done / "tensorboard" / "PPO_1").glob("events.out.tfevents.*"))  # SB3's TensorBoard log

    def variant(seed: int) -> Path:
        d = done.parent / f"seed_{seed}"
        shutil.copytree(done, d)
        return d

    stopped = variant(1)
    for name in ("result.json", "model.zip", "eval.json"):
        (stopped / name).unlink()
    failed = variant(2)
    (failed / "result.json").unlink()
    run = read_json(failed / "run.json")
    run["processes"][-1]["error"] = "RuntimeError: out of memory"
    (failed / "run.json").write_text(json.dumps(run))
    damaged = variant(3)
    (damaged / read_json(damaged / "checkpoint.json")["dir"] / "model.zip").unlink()
    running = variant(4)
    (running / "result.json").unlink()
    (running / ".lock").write_text(f"{socket.gethostname()} {os.getpid()}\n")
    new = variant(5)
    for name in ("run.json", "result.json", "episodes.csv", "checkpoint.json", "model.zip", "eval.json", "eval_episodes.csv"):
        (new / name).unlink()
    shutil.rmtree(new / "checkpoints")

    res = cli(tmp_path, "runs", "sweep")
    assert res.returncode == 0, res.stderr
    lines = {line.split()[0]: line for line in res.stdout.splitlines() if line.startswith(ENV)}
    status = {Path(k).name: next(w for w in line.split() if w in STATUSES) for k, line in lines.items()}
    assert status == {"seed_0": "finished", "seed_1": "interrupted", "seed_2": "failed", "seed_3": "damaged", "seed_4": "running", "seed_5": "new"}
    assert "128/128 (100%)" in lines[str(Path(ENV) / "PPO" / "seed_0")] and "(held-out)" in lines[str(Path(ENV) / "PPO" / "seed_0")]
    assert "(training)" in lines[str(Path(ENV) / "PPO" / "seed_1")]
    assert "model.zip is missing" in res.stdout and "out of memory" in res.stdout
    listed = json.loads(cli(tmp_path, "runs", "sweep", "--json").stdout)
    finished = next(r for r in listed if r["status"] == "finished")
    assert finished["score"] == pytest.approx(read_json(done / "eval.json")["summary"]["return"]["mean"])
    assert finished["steps_done"] == finished["steps_total"] == 128 and finished["seed"] == 0
