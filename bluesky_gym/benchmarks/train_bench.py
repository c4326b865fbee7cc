"""Training throughput: end-to-end environment steps per second of each trainer, side by side.

For each setting (an algorithm, a number of environments and hyperparameters) the benchmark
measures, in one process and one after the other:

* the environment alone: the native vector environment with random actions (the ceiling);
* ``sb3``: Stable-Baselines3's ``learn`` on :class:`~bluesky_gym.training.sb3_vec_env.SB3VecEnv`;
* ``fast``: the fast trainer (:mod:`bluesky_gym.training.fast`), eager, and (``fast+compile``)
  with its PPO update compiled by ``torch.compile``.

A trainer's figure is environment steps of training (collection and updates) per second of wall
time, after a warm-up that is not timed (it also absorbs compilation); each cell is the median of
``repeat`` measurements, and the ratios are taken against the environment alone and SB3 measured
in the same run.
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from bluesky_gym.benchmarks.timing import env_step_rate
from bluesky_gym.envs.seeds import train_env_seeds
from bluesky_gym.training import make_vector_env
from bluesky_gym.training.hyperparams import PAPER, merge
from bluesky_gym.training.runner import make_run_spec, new_model, set_torch_threads

DEFAULT_ENV = "SectorCREnv-v0"
SEED = 0
#: The trainers measured: SB3, the fast trainer eager, the fast trainer with its update compiled.
TRAINERS = ("sb3", "fast", "fast+compile")


@dataclass(frozen=True)
class Setting:
    """One training configuration of the benchmark.

    Attributes:
        name: Short name (``--setting``).
        title: What it is, for the table.
        algo: Algorithm.
        n_envs: Batched environments.
        hyperparams: Overrides of the paper's hyperparameters of ``algo``.
        warmup: Training steps before the timed part (not timed).
        measured: Training steps timed.

    """

    name: str
    title: str
    algo: str
    n_envs: int
    hyperparams: dict[str, Any] = field(default_factory=dict)
    warmup: int = 0
    measured: int = 0


SETTINGS: dict[str, Setting] = {
    s.name: s
    for s in (
        Setting(
            "ppo-1024",
            "PPO, 1024 envs x 16 steps, batch 4096, 10 epochs",
            "PPO",
            1024,
            {"n_steps": 16, "batch_size": 4096, "n_epochs": 10},
            warmup=16_384,
            measured=5 * 16_384,
        ),
        Setting(
            "ppo-paper",
            "PPO, 16 envs x 128 steps, batch 64, 10 epochs (the paper's 2048 steps per rollout)",
            "PPO",
            16,
            {"n_steps": 128, "batch_size": 64, "n_epochs": 10},
            warmup=2_048,
            measured=8 * 2_048,
        ),
        Setting("sac-paper", "SAC, 1 env, the paper's settings (batch 256, one gradient step per step)", "SAC", 1, {}, warmup=300, measured=1_200),
    )
}


def _spec(env_id: str, setting: Setting, trainer: str, device: str) -> Any:
    config = merge(PAPER, {"algos": {setting.algo: setting.hyperparams}})
    return make_run_spec(config, env_id, setting.algo, SEED, n_envs=setting.n_envs, total_timesteps=1, device=device, trainer=trainer)


def sb3_rate(env_id: str, setting: Setting, device: str = "cpu") -> float:
    """Environment steps per second of SB3's ``learn`` with ``setting``, after its warm-up."""
    from bluesky_gym.training.sb3_vec_env import SB3VecEnv

    spec = _spec(env_id, setting, "sb3", device)
    venv = SB3VecEnv(env_id, num_envs=setting.n_envs)
    try:
        model = new_model(spec, venv)
        model.learn(setting.warmup)
        start = model.num_timesteps
        t0 = time.perf_counter()
        model.learn(setting.measured, reset_num_timesteps=False)
        return float((model.num_timesteps - start) / (time.perf_counter() - t0))
    finally:
        venv.close()


def fast_rate(env_id: str, setting: Setting, device: str = "cpu", compile: bool = False) -> float:
    """Environment steps per second of the fast trainer with ``setting``, after its warm-up."""
    from bluesky_gym.training.fast import trainer_class
    from bluesky_gym.training.sb3_vec_env import SB3VecEnv

    spec = _spec(env_id, setting, "fast", device)
    venv = SB3VecEnv(env_id, num_envs=setting.n_envs)
    try:
        model = new_model(spec, venv)
        trainer = trainer_class(setting.algo)(model, venv.venv, seed=SEED, compile=compile)
        trainer.start(train_env_seeds(SEED, setting.n_envs))
        trainer.learn(setting.warmup)
        start = trainer.num_timesteps
        t0 = time.perf_counter()
        trainer.learn(start + setting.measured)
        return float((trainer.num_timesteps - start) / (time.perf_counter() - t0))
    finally:
        venv.close()


def env_rate(env_id: str, n_envs: int, seconds: float = 2.0) -> float:
    """Environment steps per second of the native vector environment alone, with random actions."""
    venv = make_vector_env(env_id, n_envs)
    try:
        return float(env_step_rate(venv, seconds, seed=SEED, num_envs=n_envs)["rate"])
    finally:
        venv.close()


def run(
    env_id: str = DEFAULT_ENV,
    settings: Sequence[str] = tuple(SETTINGS),
    trainers: Sequence[str] = TRAINERS,
    repeat: int = 1,
    device: str = "cpu",
    threads: int = 1,
    progress: Any = None,
) -> dict[str, Any]:
    """Measure every (setting, trainer) cell; return the rates and the ratios.

    Args:
        env_id: Environment id.
        settings: Names of :data:`SETTINGS`.
        trainers: ``sb3``, ``fast`` and/or ``fast+compile``.
        repeat: Measurements per cell (the median is reported).
        device: Torch device of the learners.
        threads: Torch threads (0: PyTorch's default).
        progress: Called with a line per finished measurement (or None).

    """
    set_torch_threads(threads)
    rows = []
    for name in settings:
        setting = SETTINGS[name]
        mine = [t for t in trainers if t != "fast+compile" or setting.algo == "PPO"]  # the fast trainer compiles PPO's update only
        cells: dict[str, list[float]] = {"env": [], **{t: [] for t in mine}}
        for _ in range(repeat):  # interleaved, so that a change of machine load touches every cell alike
            cells["env"].append(env_rate(env_id, setting.n_envs))
            for trainer in mine:
                if trainer == "sb3":
                    rate = sb3_rate(env_id, setting, device)
                else:
                    rate = fast_rate(env_id, setting, device, compile=trainer == "fast+compile")
                cells[trainer].append(rate)
                if progress is not None:
                    progress(f"{name}: {trainer} {rate:,.0f} env-steps/s")
        medians = {k: statistics.median(v) for k, v in cells.items()}
        row: dict[str, Any] = {"setting": name, "title": setting.title, "algo": setting.algo, "n_envs": setting.n_envs}
        row.update(rates=medians, raw=cells)
        row["vs_env"] = {k: v / medians["env"] for k, v in medians.items() if k != "env"}
        if "sb3" in medians:
            row["vs_sb3"] = {k: v / medians["sb3"] for k, v in medians.items() if k not in ("env", "sb3")}
        rows.append(row)
    return {"env_id": env_id, "device": device, "threads": threads, "repeat": repeat, "rows": rows}


def format_table(result: dict[str, Any]) -> str:
    """The results as a Markdown table: one line per (setting, trainer)."""
    lines = [
        f"{result['env_id']}, learner on {result['device']}, {result['threads']} torch thread(s), median of {result['repeat']}",
        "",
        "| setting | trainer | env-steps/s | x env alone | x SB3 |",
        "|---|---|---:|---:|---:|",
    ]
    for row in result["rows"]:
        for trainer, rate in row["rates"].items():
            vs_env = "" if trainer == "env" else f"{row['vs_env'][trainer]:.2f}"
            vs_sb3 = f"{row['vs_sb3'][trainer]:.2f}" if trainer in row.get("vs_sb3", {}) else ""
            label = "environment alone" if trainer == "env" else trainer
            lines.append(f"| {row['title']} | {label} | {rate:,.0f} | {vs_env} | {vs_sb3} |")
    return "\n".join(lines)
