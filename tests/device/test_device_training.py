"""The fast trainer on environments made with ``device="cuda"``: trained from their tensors, without host copies.

Under numba-cuda's simulator the environments' tensors are CPU tensors and their episodes the CPU
environment's bit for bit, so a run with ``env_device="cuda"`` must be the run with
``env_device="cpu"``, number for number: the same episode log and the same trained weights.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from bluesky_gym.core import cuda_target

from .conftest import needs_device

pytest.importorskip("stable_baselines3", reason="needs Stable-Baselines3 (the 'train' extra)")
torch = pytest.importorskip("torch")
pytestmark = needs_device

from bluesky_gym.training.hyperparams import PAPER, merge  # noqa: E402
from bluesky_gym.training.runner import make_run_spec, run_training  # noqa: E402

ENV = "SectorCREnv-v1"
TINY = merge(
    PAPER,
    {
        "run": {"trainer": "fast"},
        "algos": {"PPO": {"n_steps": 8, "batch_size": 24, "n_epochs": 2}, "SAC": {"buffer_size": 400, "learning_starts": 6, "batch_size": 8}},
        "env_options": {ENV: {"max_episode_steps": 5}},
    },
)


@pytest.mark.parametrize("algo", ["PPO", "SAC"])
def test_a_run_on_device_environments_is_the_run_on_cpu_environments(algo: str, tmp_path: Path) -> None:
    weights, logs = {}, {}
    for env_device in ("cpu", "cuda"):
        spec = make_run_spec(TINY, ENV, algo, 1, n_envs=3, total_timesteps=24, eval_episodes=0, env_device=env_device)
        assert spec.env_device == env_device and "env_device" not in spec.identity()
        d = tmp_path / env_device
        run_training(spec, d, verbose=0, tensorboard=False)
        from stable_baselines3 import PPO, SAC

        model = (PPO if algo == "PPO" else SAC).load(d / "model.zip", device="cpu")
        weights[env_device] = {k: v.clone() for k, v in model.policy.state_dict().items()}
        rows = [line.split(",") for line in (d / "episodes.csv").read_text().splitlines()]
        wall = rows[0].index("wall_time_s")  # the one column that differs between two runs
        logs[env_device] = [r[:wall] + r[wall + 1 :] for r in rows]
    assert len(logs["cpu"]) > 3, "episodes must end (time limit 5) and be logged"
    if cuda_target.SIMULATOR:
        assert logs["cuda"] == logs["cpu"]
        for k, v in weights["cpu"].items():
            assert torch.equal(weights["cuda"][k], v), k
    else:  # on a GPU the episodes agree within the physics' rounding: the logs have the same columns and rows
        assert logs["cuda"][0] == logs["cpu"][0] and len(logs["cuda"]) == len(logs["cpu"])


def test_env_device_is_refused_with_the_sb3_trainer() -> None:
    with pytest.raises(ValueError, match="needs the fast trainer"):
        make_run_spec(merge(PAPER, {}), ENV, "PPO", 0, env_device="cuda")
    with pytest.raises(ValueError, match="env_device must be one of cpu, cuda, got 'gpu'"):
        make_run_spec(TINY, ENV, "PPO", 0, env_device="gpu")


def test_train_command_takes_env_device(tmp_path: Path) -> None:
    config = tmp_path / "tiny.toml"
    config.write_text(f'[algos.PPO]\nn_steps = 4\nbatch_size = 12\nn_epochs = 1\n[env_options."{ENV}"]\nmax_episode_steps = 3\n')
    command = [sys.executable, "-m", "bluesky_gym", "train", "--env", ENV, "--trainer", "fast", "--num-envs", "3", "--steps", "12"]
    command += ["--env-device", "cuda", "--config", str(config), "--eval-episodes", "0", "--quiet", "--no-tensorboard", "--out", str(tmp_path)]
    done = subprocess.run(command, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    assert (tmp_path / ENV / "PPO" / "seed_0" / "model.zip").exists()
