"""Train a policy shared by all agents with PPO and compare its KPIs with random and classical policies.

The command line is ``bluesky-gym train-ma`` (:mod:`bluesky_gym.cli.train_ma`, which calls
:func:`train_and_compare`)::

    bluesky-gym train-ma --env sector_cr_v0 --steps 1e6 --seed 0

``python -m bluesky_gym.multiagent.train`` is deprecated: it hands its arguments to
``bluesky-gym train-ma`` (the old ``--timesteps`` and ``--episodes`` renamed to ``--steps`` and
``--num-envs``), which parses, checks and runs them; this module keeps no parser of its own.

The policy is trained on :class:`~bluesky_gym.multiagent.sb3.SharedPolicyVecEnv`: every agent
slot of ``episodes`` parallel multi-agent episodes is one row, ``timesteps`` counts row-steps
(dummy rows of empty slots included). Observations are normalised with running statistics of the
live rows (:class:`~bluesky_gym.multiagent.sb3.LiveRowsVecNormalize`) and PPO's minibatches are
drawn from live transitions only (:class:`~bluesky_gym.multiagent.sb3.LiveRowsRolloutBuffer`).

The trained policy is then evaluated deterministically on ``eval_episodes`` held-out scenarios
(evaluation seeds, never used in training), together with the random policy, the classical
geometric rule (:class:`~bluesky_gym.multiagent.policies.GeometricCRPolicy`) and MVP conflict
resolution (:class:`~bluesky_gym.multiagent.policies.MVPPolicy`), on the same scenarios, and a
KPI table is printed: losses of separation per episode and per agent, LoS pair-steps, minimum
separation, mean |drift|, fraction of agents that completed (exit / arrival) and return per agent
(mean +- 95% half-width over the episodes).

Needs Stable-Baselines3 and PyTorch: ``pip install -e ".[train]"``.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

# The command line reads DEFAULTS to build its parser: the evaluation and the policies are
# imported where they are used, so that building the parser stays cheap.
DEFAULTS: dict[str, Any] = {
    "timesteps": 1_000_000,
    "episodes": 16,
    "n_steps": 32,
    "batch_size": 1024,
    "n_epochs": 5,
    "learning_rate": 1e-3,
    "gamma": 0.95,
    "log_std_init": -1.0,
    "eval_episodes": 32,
}


def train(
    env: str,
    timesteps: int,
    *,
    episodes: int = DEFAULTS["episodes"],
    n_steps: int = DEFAULTS["n_steps"],
    batch_size: int = DEFAULTS["batch_size"],
    n_epochs: int = DEFAULTS["n_epochs"],
    learning_rate: float = DEFAULTS["learning_rate"],
    gamma: float = DEFAULTS["gamma"],
    log_std_init: float = DEFAULTS["log_std_init"],
    seed: int = 0,
    verbose: int = 0,
) -> tuple[Any, Any]:
    """Train a shared PPO policy on a multi-agent environment.

    Args:
        env: Multi-agent environment name.
        timesteps: PPO row-steps.
        episodes: Parallel multi-agent episodes (rows = episodes x agent slots).
        n_steps: Rollout length per row.
        batch_size: Minibatch size, in live transitions.
        n_epochs: Epochs per rollout.
        learning_rate: Learning rate.
        gamma: Discount factor.
        log_std_init: Initial log standard deviation of the Gaussian actions.
        seed: Run seed.
        verbose: SB3 verbosity.

    Returns:
        The trained PPO model and its observation normaliser (frozen:
        ``training = False``); pass both to :class:`~bluesky_gym.multiagent.policies.SB3Policy`.
    """
    from stable_baselines3 import PPO

    from bluesky_gym.multiagent.sb3 import LiveRowsRolloutBuffer, LiveRowsVecNormalize, SharedPolicyVecEnv, track_live_rows

    rows = SharedPolicyVecEnv(env, n_episodes=episodes)
    venv = LiveRowsVecNormalize(rows)
    with warnings.catch_warnings():
        # SB3 checks the batch size against the whole rollout; minibatches here split its live part.
        warnings.filterwarnings("ignore", message="You have specified a mini-batch size")
        model = PPO(
            "MultiInputPolicy",
            venv,
            n_steps=n_steps,
            batch_size=batch_size,
            n_epochs=n_epochs,
            learning_rate=learning_rate,
            gamma=gamma,
            seed=seed,
            verbose=verbose,
            device="cpu",
            rollout_buffer_class=LiveRowsRolloutBuffer,
            policy_kwargs={"log_std_init": log_std_init},
        )
    track_live_rows(model, rows)
    model.learn(total_timesteps=timesteps)
    venv.training = False
    return model, venv


def train_and_compare(
    env: str,
    timesteps: int,
    *,
    eval_episodes: int = DEFAULTS["eval_episodes"],
    threads: int = 1,
    save: str | None = None,
    **hyperparams: Any,
) -> None:
    """Train a shared policy (:func:`train`), evaluate it with the references and print the KPI table.

    Args:
        env: Multi-agent environment name.
        timesteps: PPO row-steps.
        eval_episodes: Held-out evaluation episodes.
        threads: PyTorch threads.
        save: Save the model to ``save.zip`` and the observation statistics to ``save.pkl``.
        **hyperparams: Keyword arguments of :func:`train` (``episodes``, ``n_steps``, ``seed``, ...).

    """
    import torch

    from bluesky_gym.multiagent.evaluation import evaluate, kpi_table
    from bluesky_gym.multiagent.policies import GeometricCRPolicy, MVPPolicy, RandomPolicy, SB3Policy

    torch.set_num_threads(threads)
    t0 = time.time()
    model, normalizer = train(env, timesteps, **hyperparams)
    rows = normalizer.venv
    print(f"trained {env}: {timesteps} row-steps ({rows.num_envs} rows), {rows.episodes_done} training episodes, {time.time() - t0:.0f} s")
    if save:
        model.save(f"{save}.zip")
        normalizer.save(f"{save}.pkl")
        print(f"saved {save}.zip and {save}.pkl")
    t1 = time.time()
    policies = (
        RandomPolicy(seed=hyperparams.get("seed", 0)),
        GeometricCRPolicy(),
        MVPPolicy(),
        SB3Policy(model, normalizer=normalizer, name="shared PPO"),
    )
    results = {p.name: evaluate(env, p, eval_episodes) for p in policies}
    print(f"evaluation on {eval_episodes} held-out episodes ({time.time() - t1:.0f} s):")
    print(kpi_table(results))


#: Options of the deprecated entry point that ``bluesky-gym train-ma`` spells differently.
RENAMED_OPTIONS = {"--timesteps": "--steps", "--episodes": "--num-envs"}


def train_ma_arguments(argv: Sequence[str]) -> list[str]:
    """The ``bluesky-gym train-ma`` arguments of the deprecated entry point's ``argv`` (renamed options translated)."""
    out = []
    for arg in argv:
        name, sep, value = arg.partition("=")
        out.append(RENAMED_OPTIONS[name] + sep + value if name in RENAMED_OPTIONS else arg)
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """Deprecated: run ``bluesky-gym train-ma`` with these arguments and return its exit code.

    The command runs in a new interpreter (``python -m bluesky_gym train-ma``): the command line
    sits above this package, which does not import it.
    """
    args = train_ma_arguments(sys.argv[1:] if argv is None else argv)
    print(f"python -m bluesky_gym.multiagent.train: warning: deprecated; use `bluesky-gym train-ma {' '.join(args)}`", file=sys.stderr, flush=True)
    sys.stdout.flush()
    package_root = str(Path(__file__).resolve().parents[2])  # this copy of the package, in the new interpreter too
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in (package_root, os.environ.get("PYTHONPATH", "")) if p))
    return subprocess.call([sys.executable, "-m", "bluesky_gym", "train-ma", *args], env=env)


if __name__ == "__main__":
    sys.exit(main())
