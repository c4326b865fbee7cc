"""``bluesky-gym train`` and ``bluesky-gym demo``: train agents on the native batched envs.

Examples::

    bluesky-gym train --env DescentEnv-v0 --algo PPO --steps 200000 --num-envs 16 --seed 0
    bluesky-gym train --env SectorCREnv-v0 --algo SAC --steps 2e6 --config configs/paper.toml
    bluesky-gym train --env SectorCREnv-v0 --algo PPO --steps 2e6 --config configs/paper-fast.toml
    bluesky-gym demo            # the main job: minutes of PPO, evaluation, plots, GIF

``train`` uses the paper's hyperparameters (``configs/paper.toml``) unless a ``--config`` file
overrides them; command-line options override both. ``--trainer sb3`` (the default) trains with
Stable-Baselines3's own loops; ``--trainer fast`` trains the same SB3 networks with the same
update rules on batched rollouts, many times faster (``docs/training-fast.md``); both write the
same run directory and SB3 model files. A hyperparameter the fast trainer does not implement is
an error. The run directory
``<out>/<ID>/<ALGO>/seed_<S>`` records the exact configuration, package versions and seeds, the
episode log (return and KPIs per episode), checkpoints, the final model and its evaluation on
held-out scenarios, and SB3's TensorBoard log (``tensorboard/``). Rerunning the same command
resumes an interrupted run from its last checkpoint, or does nothing if the run is finished. PPO
trains whole rollouts of ``n_steps x num_envs`` steps: a ``--steps`` that is not a multiple is
rounded up, with a warning. The id, scenario options and hyperparameter names are checked before
the run directory is created. A damaged run directory (a checkpoint file missing or cut off, an
episode log shorter than its checkpoint, a JSON file that does not parse) is named and left alone
until rerun with ``--resume-from-last-intact`` (continue from the last intact checkpoint) or
``--restart``. The multi-agent environments are trained with ``bluesky-gym train-ma``.

``demo`` trains PPO on 16 batched environments (``configs/demo.toml``, the fast trainer), evaluates
the policy against the ``random`` and ``classical`` reference policies (and ``mvp`` for the
environments with traffic) on held-out scenarios, and writes the learning curves, the aggregate
plot and (when rendering is available) a GIF of the trained policy.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from bluesky_gym.cli.arguments import add_env_option, deprecated_alias, non_negative_int, positive_int, warn
from bluesky_gym.core.extras import MissingDependencyError
from bluesky_gym.training import ALGORITHMS, TRAINERS


def algorithm(text: str) -> str:
    """Parse an algorithm name (case-insensitive)."""
    name = text.upper()
    if name not in ALGORITHMS:
        raise argparse.ArgumentTypeError(f"must be one of {', '.join(ALGORITHMS)}, got {text}")
    return name


def add_run_options(p: argparse.ArgumentParser) -> None:
    """Add the options shared by ``train`` and ``sweep`` (they override the config file)."""
    p.add_argument("--steps", type=positive_int, metavar="N", help="environment steps per run (default: config, 2e6)")
    p.add_argument("--num-envs", type=positive_int, metavar="K", help="episodes simulated together per run (default: config, 1)")
    deprecated_alias(p, "--n-envs", "--num-envs", "num_envs", type=positive_int, metavar="K")
    p.add_argument("--config", type=Path, metavar="FILE", help="TOML or JSON config over the paper's defaults (see configs/paper.toml)")
    p.add_argument("--checkpoint-freq", type=positive_int, metavar="N", help="steps between checkpoints (default: config, 50000)")
    p.add_argument("--eval-episodes", type=non_negative_int, metavar="N", help="held-out episodes evaluated at the end (default: 50)")
    p.add_argument("--device", help="torch device of the learner: cpu, cuda, cuda:1, mps (default: config, cpu)")
    p.add_argument(
        "--trainer",
        choices=TRAINERS,
        help="sb3: Stable-Baselines3's own loops; fast: SB3's networks and updates on batched rollouts (docs/training-fast.md) "
        "(default: config, sb3)",
    )
    p.add_argument(
        "--env-device",
        choices=("cpu", "cuda"),
        help="where the fast trainer's environments run: cuda steps them on the GPU and trains from its tensors without host copies "
        "(needs the gpu and train extras and a CUDA GPU; default: config, cpu)",
    )
    p.add_argument(
        "--compile",
        choices=("auto", "on", "off"),
        help="compile the fast trainer's PPO update with torch.compile (auto: for small minibatches in long runs; default: config, auto)",
    )


def check_env_device(env_device: str) -> None:
    """Raise (one line) where the environments cannot run on ``env_device``: ``cuda`` without the extras or a GPU.

    Raises:
        MissingDependencyError: numba-cuda (the ``gpu`` extra) or PyTorch is missing.
        ValueError: Neither a CUDA GPU nor numba-cuda's simulator is there.
    """
    if env_device == "cpu":
        return
    from bluesky_gym.envs.device import TensorIO

    try:
        TensorIO()
    except RuntimeError as exc:
        raise ValueError(f"--env-device {env_device}: {exc}") from None


def check_device(device: str) -> None:
    """Raise ``ValueError`` if the torch device is malformed or not present on this machine (CUDA, MPS)."""
    from bluesky_gym.core.extras import require_sb3

    require_sb3()
    import torch

    try:
        dev = torch.device(device)
    except RuntimeError as exc:
        raise ValueError(f"--device {device!r} is not a torch device (e.g. cpu, cuda, cuda:0, mps): {exc}") from None
    if dev.type == "cuda":
        if not torch.cuda.is_available():
            raise ValueError(
                f"--device {device}: PyTorch finds no CUDA device on this machine (torch.cuda.is_available() is False); use --device cpu"
            )
        if dev.index is not None and dev.index >= torch.cuda.device_count():
            raise ValueError(f"--device {device}: this machine has {torch.cuda.device_count()} CUDA device(s)")
    elif dev.type == "mps" and not torch.backends.mps.is_available():
        raise ValueError(f"--device {device}: PyTorch finds no MPS device on this machine; use --device cpu")


def ppo_rounding(algo: str, hyperparams: dict[str, Any], num_envs: int, steps: int) -> str | None:
    """The warning for a PPO step budget that is not a whole number of rollouts (None otherwise).

    PPO collects rollouts of ``n_steps`` steps in each of ``num_envs`` environments and trains
    until the rollout in which the budget is reached ends.
    """
    if algo.upper() != "PPO":
        return None
    rollout = int(hyperparams.get("n_steps", 2048)) * num_envs
    if steps % rollout == 0:
        return None
    done = -(-steps // rollout) * rollout
    return (
        f"PPO trains whole rollouts of n_steps x num_envs = {hyperparams.get('n_steps', 2048)} x {num_envs} = {rollout} steps: "
        f"--steps {steps} becomes {done} (set n_steps in [algos.PPO] of a --config file for shorter rollouts)"
    )


def add_damage_options(p: argparse.ArgumentParser) -> None:
    """Add the choice for a damaged run directory (``train`` and ``sweep``): ``args.on_damage``."""
    damaged = p.add_mutually_exclusive_group()
    damaged.add_argument(
        "--resume-from-last-intact",
        dest="on_damage",
        action="store_const",
        const="resume",
        default="error",
        help="if a run directory is damaged, resume from its last intact checkpoint",
    )
    damaged.add_argument(
        "--restart", dest="on_damage", action="store_const", const="restart", help="if a run directory is damaged, start the run over"
    )


def load_config(path: Path | None) -> dict[str, Any]:
    """Return the paper's defaults merged with a config file."""
    from bluesky_gym.training.hyperparams import PAPER, load_config_file, merge

    return merge(PAPER, load_config_file(path)) if path is not None else merge(PAPER, {})


def run_overrides(args: argparse.Namespace) -> dict[str, Any]:
    """Return the ``run`` values given on the command line."""
    return {
        "total_timesteps": args.steps,
        "n_envs": args.num_envs,
        "checkpoint_freq": args.checkpoint_freq,
        "eval_episodes": args.eval_episodes,
        "device": args.device,
        "trainer": args.trainer,
        "compile": {"on": True, "off": False}.get(args.compile, args.compile),
        "env_device": args.env_device,
    }


def add_parser(subparsers: Any) -> None:
    """Register the ``train`` and ``demo`` subcommands."""
    p = subparsers.add_parser("train", help="train an agent on one environment (Stable-Baselines3 or the fast trainer)", description=__doc__)
    add_env_option(p)
    p.add_argument("--algo", type=algorithm, default="PPO", help=f"one of {', '.join(ALGORITHMS)} (default: PPO)")
    p.add_argument("--seed", type=non_negative_int, default=0, help="run seed, below 2**31 (default: 0)")
    p.add_argument("--out", type=Path, default=Path("runs"), metavar="DIR", help="output directory (default: runs)")
    add_run_options(p)
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--quiet", action="store_true", help="no messages")
    p.add_argument("--no-tensorboard", action="store_true", help="no TensorBoard log (default: <run dir>/tensorboard)")
    add_damage_options(p)
    p.set_defaults(func=run_train)

    d = subparsers.add_parser(
        "demo",
        help="the main job: train PPO for a few minutes, compare with the reference policies, plot",
        description=__doc__,
    )
    d.add_argument("--env", default="DescentEnv-v0", metavar="ID", help="environment id (default: DescentEnv-v0)")
    d.add_argument("--steps", type=positive_int, metavar="N", help="PPO steps (default: configs/demo.toml, 250000)")
    d.add_argument("--num-envs", type=positive_int, metavar="K", help="episodes simulated together (default: 16)")
    deprecated_alias(d, "--n-envs", "--num-envs", "num_envs", type=positive_int, metavar="K")
    d.add_argument("--seed", type=non_negative_int, default=0, help="run seed (default: 0)")
    d.add_argument("--episodes", type=positive_int, default=100, metavar="N", help="held-out evaluation episodes (default: 100)")
    d.add_argument("--out", type=Path, default=Path("runs/demo"), metavar="DIR", help="output directory (default: runs/demo)")
    d.add_argument("--no-gif", action="store_true", help="do not render a GIF")
    d.add_argument("--no-progress", action="store_true", help="no progress bar")
    d.add_argument("--trainer", choices=TRAINERS, help="fast (default) or sb3 (Stable-Baselines3's own loops)")
    d.set_defaults(func=run_demo)


def run_train(args: argparse.Namespace) -> int:
    """Run the ``train`` subcommand."""
    from bluesky_gym.training.runner import RunConfigMismatch, RunDamaged, RunLocked, make_run_spec, run_dir_for, run_training

    run_dir = run_dir_for(args.out, args.env, args.algo, args.seed)
    try:
        config = load_config(args.config)
        spec = make_run_spec(config, args.env, args.algo, args.seed, **run_overrides(args))
        check_device(spec.device)
        check_env_device(spec.env_device)
        if not args.quiet and args.steps is not None:
            note = ppo_rounding(spec.algo, spec.hyperparams, spec.n_envs, spec.total_timesteps)
            if note:
                warn("bluesky-gym train", note)
        result = run_training(
            spec,
            run_dir,
            progress_bar=not (args.no_progress or args.quiet),
            verbose=0 if args.quiet else 1,
            on_damage=args.on_damage,
            tensorboard=not args.no_tensorboard,
        )
    except (MissingDependencyError, RunConfigMismatch, RunLocked, RunDamaged, ValueError, FileNotFoundError) as exc:
        print(f"bluesky-gym train: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"\ninterrupted; rerun the same command to resume from the last checkpoint in {run_dir}", file=sys.stderr)
        return 130
    if not args.quiet:
        if result.get("skipped"):
            print(f"{run_dir} is already finished ({result['timesteps']} steps); nothing to do")
        print(f"run directory: {run_dir}")
        if result.get("eval"):
            from bluesky_gym.training.evaluation import format_table, load_result

            print(format_table([load_result(run_dir, "eval")]))
    return 0


def run_demo(args: argparse.Namespace) -> int:
    """Run the ``demo`` subcommand."""
    from bluesky_gym.training.demo import run_demo as demo
    from bluesky_gym.training.hyperparams import DEMO, PAPER, merge, resolve

    run, hp, _ = resolve(merge(PAPER, DEMO), args.env, "PPO")
    note = ppo_rounding("PPO", hp, args.num_envs or int(run["n_envs"]), args.steps) if args.steps is not None else None
    if note:
        warn("bluesky-gym demo", note)
    try:
        demo(
            args.env,
            out=args.out,
            steps=args.steps,
            n_envs=args.num_envs,
            seed=args.seed,
            episodes=args.episodes,
            gif=not args.no_gif,
            progress_bar=not args.no_progress,
            trainer=args.trainer,
        )
    except (MissingDependencyError, ValueError) as exc:
        print(f"bluesky-gym demo: error: {exc}", file=sys.stderr)
        return 2
    return 0
