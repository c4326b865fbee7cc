"""Runs of the fast trainer: the same run directory as SB3's, resumable, reproducible, its models SB3 models."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("stable_baselines3", reason="needs Stable-Baselines3 (the 'train' extra)")

import torch

from bluesky_gym.training.evaluation import evaluate, load_policy
from bluesky_gym.training.hyperparams import PAPER, merge
from bluesky_gym.training.io import latest_checkpoint, read_json
from bluesky_gym.training.runner import make_run_spec, resolve_compile, run_status, run_training

from .conftest import csv_rows

ENV = "DescentEnv-v0"
TINY = merge(
    PAPER,
    {
        "run": {"trainer": "fast"},
        "algos": {
            "PPO": {"n_steps": 32, "batch_size": 64, "n_epochs": 2},
            "SAC": {"buffer_size": 4000, "learning_starts": 64, "batch_size": 32},
            "TD3": {"buffer_size": 4000, "batch_size": 32},
            "DDPG": {"buffer_size": 4000, "batch_size": 32},
        },
    },
)


def test_fast_run_writes_the_run_directory_of_an_sb3_run(tmp_path: Path) -> None:
    spec = make_run_spec(TINY, ENV, "PPO", 3, n_envs=4, total_timesteps=300, checkpoint_freq=100, eval_episodes=4)
    assert spec.trainer == "fast" and spec.compile is False  # "auto" does not compile a run this short
    sb3 = make_run_spec(merge(TINY, {"run": {"trainer": "sb3"}}), ENV, "PPO", 3, n_envs=4, total_timesteps=300, checkpoint_freq=100)
    assert spec.identity()["trainer"] == "fast" and "trainer" not in sb3.identity()  # SB3 identities are those of older runs
    d = tmp_path / "fast"
    result = run_training(spec, d, verbose=0)
    assert run_status(d) == "finished" and result["timesteps"] == 384 and result["trainer"] == "fast"
    ref = tmp_path / "sb3"
    run_training(sb3, ref, verbose=0)
    header, sb3_header = csv_rows(d / "episodes.csv")[0], csv_rows(ref / "episodes.csv")[0]
    assert header == sb3_header  # the same columns, in the same order
    data = csv_rows(d / "episodes.csv")[1:]
    assert [int(r[0]) for r in data] == list(range(len(data))) and len(data) == result["episodes"] > 0
    col = header.index
    for r in data:
        assert float(r[col("return")]) == pytest.approx(float(r[col("total_reward")]))
        parts = sum(float(r[col(k)]) for k in ("reward_altitude", "reward_crash", "reward_runway"))
        assert parts == pytest.approx(float(r[col("return")]))
    record, ckpt_dir = latest_checkpoint(d)
    assert set(record["files"]) == {"model.zip", "trainer.pt"} and record["timesteps"] == 384
    assert (d / "tensorboard" / "PPO_1").is_dir() and any((d / "tensorboard" / "PPO_1").iterdir())
    # The model file is an SB3 model: SB3 loads it, evaluation reads it as any run's.
    from stable_baselines3 import PPO

    model = PPO.load(d / "model.zip")
    assert model.num_timesteps == 384
    policy = load_policy(d, env_id=ENV)
    assert policy.name.startswith("PPO")
    assert evaluate(ENV, policy, 4).mean_return == pytest.approx(read_json(d / "eval.json")["summary"]["return"]["mean"])


def test_same_seed_same_run_other_seed_another(tmp_path: Path) -> None:
    def run(seed: int, name: str) -> tuple[dict[str, torch.Tensor], list[list[str]]]:
        spec = make_run_spec(TINY, ENV, "PPO", seed, n_envs=3, total_timesteps=192, checkpoint_freq=10_000, eval_episodes=0)
        run_training(spec, tmp_path / name, verbose=0, tensorboard=False)
        from stable_baselines3 import PPO

        weights = PPO.load(tmp_path / name / "model.zip").policy.state_dict()
        log = [r[:2] + r[3:] for r in csv_rows(tmp_path / name / "episodes.csv")]  # without the wall time
        return weights, log

    a, log_a = run(5, "a")
    b, log_b = run(5, "b")
    c, log_c = run(6, "c")
    assert all(torch.equal(a[k], b[k]) for k in a) and log_a == log_b
    assert not all(torch.equal(a[k], c[k]) for k in a) and log_a != log_c


def test_the_fast_trainer_refuses_what_it_does_not_implement() -> None:
    with pytest.raises(ValueError, match="'use_sde' is not supported by the fast trainer"):
        make_run_spec(merge(TINY, {"algos": {"PPO": {"use_sde": True}}}), ENV, "PPO", 0)
    with pytest.raises(ValueError, match="'action_noise' is not supported by the fast trainer"):
        make_run_spec(merge(TINY, {"algos": {"TD3": {"action_noise": None}}}), ENV, "TD3", 0)
    with pytest.raises(ValueError, match="unknown trainer 'jax'"):
        make_run_spec(TINY, ENV, "PPO", 0, trainer="jax")
    with pytest.raises(ValueError, match="compile must be"):
        make_run_spec(TINY, ENV, "PPO", 0, compile="yes")
    # SB3 keeps every name of its constructor.
    assert make_run_spec(merge(PAPER, {"algos": {"PPO": {"use_sde": True}}}), ENV, "PPO", 0).hyperparams["use_sde"] is True


def test_auto_compile_is_for_long_runs_of_small_ppo_minibatches() -> None:
    paper = {"n_steps": 128, "batch_size": 64, "n_epochs": 10}
    assert resolve_compile("auto", "fast", "PPO", paper, 16, 2_000_000) is True
    assert resolve_compile("auto", "fast", "PPO", paper, 16, 100_000) is False  # 1,600 updates: compiling does not pay
    assert resolve_compile("auto", "fast", "PPO", {"n_steps": 16, "batch_size": 4096, "n_epochs": 10}, 1024, 20_000_000) is False
    assert resolve_compile("auto", "sb3", "PPO", paper, 16, 2_000_000) is False
    assert resolve_compile("auto", "fast", "SAC", {}, 1, 2_000_000) is False
    assert resolve_compile(True, "fast", "PPO", paper, 16, 10) is True


def test_train_command_with_the_fast_trainer(tmp_path: Path) -> None:
    config = tmp_path / "tiny.toml"
    config.write_text("[algos.PPO]\nn_steps = 16\nbatch_size = 32\nn_epochs = 1\n")
    base = [sys.executable, "-m", "bluesky_gym", "train", "--env", ENV, "--algo", "PPO", "--trainer", "fast", "--num-envs", "4"]
    common = ["--config", str(config), "--eval-episodes", "1", "--no-progress", "--quiet", "--no-tensorboard", "--out", str(tmp_path / "runs")]
    done = subprocess.run([*base, "--steps", "128", *common], capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    result = read_json(tmp_path / "runs" / ENV / "PPO" / "seed_0" / "result.json")
    assert result["trainer"] == "fast" and result["timesteps"] == 128
    bad = tmp_path / "bad.toml"
    bad.write_text("[algos.PPO]\nsde_sample_freq = 4\n")
    refused = subprocess.run(
        [*base, "--steps", "128", *common[:0], "--config", str(bad), "--out", str(tmp_path / "x")], capture_output=True, text=True, timeout=600
    )
    assert refused.returncode == 2
    lines = refused.stderr.strip().splitlines()
    assert len(lines) == 1 and "'sde_sample_freq' is not supported by the fast trainer" in lines[0], refused.stderr
    assert not (tmp_path / "x").exists()


def test_the_grid_estimate_times_the_fast_trainer(monkeypatch: pytest.MonkeyPatch) -> None:
    import bluesky_gym.training.fast as fast
    from bluesky_gym.training.sweep import estimate

    made: list[str] = []
    real = fast.trainer_class
    monkeypatch.setattr(fast, "trainer_class", lambda algo: made.append(algo) or real(algo))
    est = estimate(TINY, [ENV], ["PPO", "SAC"], ENV, probe_steps=64, env_probe_steps=64, verbose=0, n_envs=2)
    assert made == ["PPO", "SAC"]  # the configuration's trainer is the one timed
    assert {row["algo"] for row in est["per_run"]} == {"PPO", "SAC"} and all(row["steps_per_s_cpu"] > 0 for row in est["per_run"])


def test_env_device_cuda_is_refused_in_one_line_without_a_gpu(tmp_path: Path) -> None:
    """No GPU and no CUDA simulator (as in the native suite): one line naming what is missing, nothing written."""
    from bluesky_gym.core import cuda_target

    if cuda_target.SIMULATOR or cuda_target.device_present():
        pytest.skip("a CUDA device (or numba-cuda's simulator) is there: tests/device trains on it")
    command = [sys.executable, "-m", "bluesky_gym", "train", "--env", "SectorCREnv-v1", "--trainer", "fast", "--env-device", "cuda",
               "--steps", "8", "--quiet", "--no-tensorboard", "--out", str(tmp_path / "runs")]  # fmt: skip
    refused = subprocess.run(command, capture_output=True, text=True, timeout=600)
    assert refused.returncode == 2
    lines = refused.stderr.strip().splitlines()
    assert len(lines) == 1 and "--env-device cuda" in lines[0], refused.stderr
    assert "CUDA GPU" in lines[0] or "pip install" in lines[0], refused.stderr
    assert not (tmp_path / "runs").exists()
