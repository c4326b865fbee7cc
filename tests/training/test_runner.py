"""Training runs: recorded, resumable after an interruption, never half-written."""

from __future__ import annotations

import os
import pickle
import socket
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("stable_baselines3", reason="needs Stable-Baselines3 (the 'train' extra)")

from stable_baselines3.common.callbacks import BaseCallback

from bluesky_gym.training.hyperparams import PAPER, merge
from bluesky_gym.training.io import latest_checkpoint, read_json
from bluesky_gym.training.runner import (
    RunConfigMismatch,
    RunLock,
    RunLocked,
    make_run_spec,
    run_status,
    run_training,
)

from .conftest import csv_rows

ENV = "DescentEnv-v0"
TINY = merge(
    PAPER,
    {
        "algos": {
            "PPO": {"n_steps": 32, "batch_size": 64, "n_epochs": 2},
            "SAC": {"buffer_size": 4000, "learning_starts": 64, "batch_size": 32},
            "TD3": {"buffer_size": 4000, "batch_size": 32},
            "DDPG": {"buffer_size": 4000, "batch_size": 32},
        }
    },
)


class Interrupt(Exception):
    """Stands for a crash."""


class CrashAfterCheckpoints(BaseCallback):
    """Raise once ``n`` checkpoints have been committed and ``extra`` more steps were taken."""

    def __init__(self, run_dir: Path, n: int, extra: int) -> None:
        super().__init__()
        self.run_dir, self.n, self.extra = run_dir, n, extra
        self.seen: int | None = None

    def _on_step(self) -> bool:
        ckpt = latest_checkpoint(self.run_dir)
        if ckpt is not None and self.seen is None and ckpt[0]["timesteps"] >= self.n:
            self.seen = self.model.num_timesteps
        if self.seen is not None and self.model.num_timesteps >= self.seen + self.extra:
            raise Interrupt
        return True


def test_run_records_everything(tmp_path: Path) -> None:
    spec = make_run_spec(TINY, ENV, "PPO", 3, n_envs=4, total_timesteps=300, checkpoint_freq=100, eval_episodes=4)
    d = tmp_path / "run"
    assert run_status(d) == "new"
    result = run_training(spec, d, verbose=0)
    assert run_status(d) == "finished"
    assert result["timesteps"] == 384  # PPO finishes its rollout: 3 x 32 steps x 4 envs
    cfg = read_json(d / "config.json")
    assert cfg["identity"] == spec.identity() and cfg["hyperparams"]["n_steps"] == 32 and cfg["seed"] == 3
    assert cfg["seeds"]["eval_seed_base"] == 2**31 and all(s < 2**31 for s in cfg["seeds"]["train_env_seeds_at_start"])
    versions = read_json(d / "run.json")["processes"][0]["versions"]
    assert {"python", "numpy", "gymnasium", "stable_baselines3", "torch", "bluesky_gym"} <= set(versions)
    rows = csv_rows(d / "episodes.csv")
    header, data = rows[0], rows[1:]
    assert header[:7] == ["episode", "timesteps", "wall_time_s", "env_index", "return", "length", "terminated"]
    assert {"total_reward", "final_altitude", "reward_altitude", "kpi_success", "kpi_min_separation_nm"} <= set(header)
    assert [int(r[0]) for r in data] == list(range(len(data))) and len(data) == result["episodes"] > 0
    steps = [int(r[1]) for r in data]
    assert steps == sorted(steps) and steps[-1] <= 384
    col = header.index
    for r in data:
        assert float(r[col("return")]) == pytest.approx(float(r[col("total_reward")]))
        parts = sum(float(r[col(k)]) for k in ("reward_altitude", "reward_crash", "reward_runway"))
        assert parts == pytest.approx(float(r[col("return")]))
    assert (d / "model.zip").exists() and read_json(d / "eval.json")["episodes"] == 4
    assert latest_checkpoint(d)[0]["timesteps"] == 384
    record = latest_checkpoint(d)[0]
    kept = sorted(p.name for p in (d / "checkpoints").iterdir())
    assert kept == sorted(p.split("/")[1] for p in (record["previous"]["dir"], record["dir"]))  # the latest two; older ones removed
    assert set(record["files"]) == {"model.zip"} and record["files"]["model.zip"]["bytes"] > 0
    # Rerunning skips the finished run; another configuration is refused.
    assert run_training(spec, d, verbose=0)["skipped"] is True
    other = make_run_spec(TINY, ENV, "PPO", 3, n_envs=4, total_timesteps=600, checkpoint_freq=100, eval_episodes=4)
    with pytest.raises(RunConfigMismatch, match="total_timesteps"):
        run_training(other, d, verbose=0)


def test_a_run_without_tensorboard_leaves_nothing_in_the_temporary_directory(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import tempfile

    temp = tmp_path / "temp"
    temp.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(temp))
    monkeypatch.delenv("SB3_LOGDIR", raising=False)
    for algo in ("PPO", "SAC"):
        spec = make_run_spec(TINY, ENV, algo, 0, n_envs=2, total_timesteps=128, checkpoint_freq=64, eval_episodes=0)
        d = tmp_path / algo
        with pytest.raises(Interrupt):  # interrupted and resumed: both processes log through SB3's logger
            run_training(spec, d, verbose=0, tensorboard=False, callbacks=[CrashAfterCheckpoints(d, 64, 2)])
        assert run_training(spec, d, verbose=0, tensorboard=False)["resumed_from"] is not None
        assert not (d / "tensorboard").exists()
    fast = make_run_spec(merge(TINY, {"run": {"trainer": "fast"}}), ENV, "PPO", 0, n_envs=2, total_timesteps=128, checkpoint_freq=64, eval_episodes=0)
    run_training(fast, tmp_path / "fast", verbose=0, tensorboard=False)
    assert not list(temp.glob("SB3-*"))  # SB3 makes an empty SB3-<date> folder there unless given a logger


class CrashAfterCheckpointHooks:
    """The fast trainer's form of :class:`CrashAfterCheckpoints`: hooks that raise at the same point."""

    def __init__(self, run_dir: Path, n: int, extra: int) -> None:
        self.run_dir, self.n, self.extra = run_dir, n, extra
        self.seen: int | None = None

    def on_rollout_start(self, trainer: object) -> None:
        self._check(trainer)

    def on_episodes(self, trainer: object, records: list) -> None:
        self._check(trainer)

    def _check(self, trainer: object) -> None:
        steps = trainer.num_timesteps  # type: ignore[attr-defined]
        ckpt = latest_checkpoint(self.run_dir)
        if ckpt is not None and self.seen is None and ckpt[0]["timesteps"] >= self.n:
            self.seen = steps
        if self.seen is not None and steps >= self.seen + self.extra:
            raise Interrupt


def _replay_size(ckpt_dir: Path) -> int:
    """Transitions in a checkpoint's replay buffer (SB3's pickle or the fast trainer's tensors)."""
    if (ckpt_dir / "replay_buffer.pkl").exists():
        with open(ckpt_dir / "replay_buffer.pkl", "rb") as f:
            return int(pickle.load(f).size()) * 2  # per environment
    import torch

    return int(torch.load(ckpt_dir / "replay_buffer.pt", weights_only=True)["size"])


@pytest.mark.parametrize(
    ("trainer", "algo"), [("sb3", "PPO"), ("sb3", "SAC"), ("sb3", "TD3"), ("fast", "PPO"), ("fast", "SAC"), ("fast", "TD3"), ("fast", "DDPG")]
)
def test_interrupted_run_resumes_without_loss_or_repeat(tmp_path: Path, trainer: str, algo: str) -> None:
    total = 512 if algo == "PPO" else 300
    spec = make_run_spec(TINY, ENV, algo, 1, n_envs=2, total_timesteps=total, checkpoint_freq=100, eval_episodes=0, trainer=trainer)
    d = tmp_path / algo
    crash = CrashAfterCheckpoints(d, 100, 60) if trainer == "sb3" else CrashAfterCheckpointHooks(d, 100, 60)
    with pytest.raises(Interrupt):
        run_training(spec, d, verbose=0, callbacks=[crash])
    ckpt, ckpt_dir = latest_checkpoint(d)
    assert run_status(d) == "checkpointed" and 100 <= ckpt["timesteps"] < total
    before = csv_rows(d / "episodes.csv")
    assert len(before) - 1 > ckpt["episodes_logged"]  # rows were logged after the checkpoint
    assert not (d / ".lock").exists()

    result = run_training(spec, d, verbose=0)
    assert result["resumed_from"] == ckpt["timesteps"]
    assert result["timesteps"] == total
    after = csv_rows(d / "episodes.csv")
    kept = ckpt["episodes_logged"] + 1
    assert after[:kept] == before[:kept]  # rows up to the checkpoint are untouched
    assert [int(r[0]) for r in after[1:]] == list(range(len(after) - 1))  # no row lost or repeated
    steps = [int(r[1]) for r in after[1:]]
    assert steps == sorted(steps) and all(s > ckpt["timesteps"] for s in steps[kept - 1 :])
    procs = read_json(d / "run.json")["processes"]
    assert [s["start_timesteps"] for s in procs] == [0, ckpt["timesteps"]]
    final, final_dir = latest_checkpoint(d)
    assert final["timesteps"] == total
    if algo != "PPO":
        assert _replay_size(final_dir) == total  # every transition once: none lost, none twice


def test_lock_refuses_a_live_owner_and_takes_over_a_dead_one(tmp_path: Path) -> None:
    lock = tmp_path / ".lock"
    lock.write_text(f"{socket.gethostname()} {os.getppid()}\n")  # a live process
    with pytest.raises(RunLocked), RunLock(tmp_path):
        pass
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True, check=True)
    lock.write_text(f"{socket.gethostname()} {int(dead.stdout)}\n")
    with RunLock(tmp_path):
        assert lock.read_text().split()[1] == str(os.getpid())
    assert not lock.exists()


def test_run_json_records_the_command_by_the_program_name_not_its_path() -> None:
    from bluesky_gym.training.runner import recorded_command

    assert recorded_command(["/some/dir/bluesky_gym/__main__.py", "train", "--env", "DescentEnv-v0"]) == [
        "bluesky-gym",
        "train",
        "--env",
        "DescentEnv-v0",
    ]
    assert recorded_command(["/opt/venv/bin/bluesky-gym", "sweep"]) == ["bluesky-gym", "sweep"]
    assert recorded_command(["/x/y/train_script.py", "--seed", "1"]) == ["train_script.py", "--seed", "1"]
    assert recorded_command([]) == []
