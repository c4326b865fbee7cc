"""``bluesky-gym train`` and ``bluesky-gym demo``: train SB3 agents on the native batched envs.

Examples::

    bluesky-gym train DescentEnv-v0 --algo PPO --steps 200000 --n-envs 16 --seed 0
    bluesky-gym train SectorCREnv-v0 --algo SAC --steps 2e6 --config configs/paper.toml --out runs
    bluesky-gym demo                      # the main job: a few minutes of PPO, evaluation, plots, GIF

``train`` uses the paper's hyperparameters (``configs/paper.toml``) unless a ``--config`` file
overrides them; command-line options override both. The run directory
``<out>/<ID>/<ALGO>/seed_<S>`` records the exact configuration, package versions and seeds, the
episode log (return and KPIs per episode), checkpoints, the final model and its evaluation on
held-out scenarios, and SB3's TensorBoard log (``tensorboard/``). Rerunning the same command
resumes an interrupted run from its last checkpoint, or does nothing if the run is finished.
The id, scenario options and hyperparameter names are checked before the run directory is
created. A damaged run directory (a checkpoint file missing or cut off, an episode log shorter
than its checkpoint, a JSON file that does not parse) is named and left alone until rerun with
``--resume-from-last-intact`` (continue from the last intact checkpoint) or ``--restart``.

``demo`` trains PPO on 16 batched environments (``configs/demo.toml``), evaluates the policy
against the ``random`` and ``classical`` reference policies on held-out scenarios, and writes the
learning curves, the aggregate plot and (when rendering is available) a GIF of the trained
policy.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from bluesky_gym.cli.arguments import non_negative_int, positive_int
from bluesky_gym.core.extras import MissingDependencyError
from bluesky_gym.training import ALGORITHMS


def algorithm(text: str) -> str:
    """Parse an algorithm name (case-insensitive)."""
    name = text.upper()
    if name not in ALGORITHMS:
        raise argparse.ArgumentTypeError(f"must be one of {', '.join(ALGORITHMS)}, got {text}")
    return name


def add_run_options(p: argparse.ArgumentParser) -> None:
    """Add the options shared by ``train`` and ``sweep`` (they override the config file)."""
    p.add_argument("--steps", type=positive_int, metavar="N", help="environment steps per run (default: config, 2e6)")
    p.add_argument("--n-envs", type=positive_int, metavar="K", help="batched environments per run (default: config, 1)")
    p.add_argument("--config", type=Path, metavar="FILE", help="TOML or JSON config over the paper's defaults (see configs/paper.toml)")
    p.add_argument("--checkpoint-freq", type=positive_int, metavar="N", help="steps between checkpoints (default: config, 50000)")
    p.add_argument("--eval-episodes", type=non_negative_int, metavar="N", help="held-out episodes evaluated at the end (default: 50)")
    p.add_argument("--device", help="torch device (default: config, cpu)")


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
        "n_envs": args.n_envs,
        "checkpoint_freq": args.checkpoint_freq,
        "eval_episodes": args.eval_episodes,
        "device": args.device,
    }


def add_parser(subparsers: Any) -> None:
    """Register the ``train`` and ``demo`` subcommands."""
    p = subparsers.add_parser(
        "train", help="train an SB3 agent on one environment", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument("env_id", metavar="ID", help="environment id, e.g. DescentEnv-v0")
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
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    d.add_argument("--env", default="DescentEnv-v0", metavar="ID", help="environment id (default: DescentEnv-v0)")
    d.add_argument("--steps", type=positive_int, metavar="N", help="PPO steps (default: configs/demo.toml, 250000)")
    d.add_argument("--n-envs", type=positive_int, metavar="K", help="batched environments (default: 16)")
    d.add_argument("--seed", type=non_negative_int, default=0, help="run seed (default: 0)")
    d.add_argument("--episodes", type=positive_int, default=100, metavar="N", help="held-out evaluation episodes (default: 100)")
    d.add_argument("--out", type=Path, default=Path("runs/demo"), metavar="DIR", help="output directory (default: runs/demo)")
    d.add_argument("--no-gif", action="store_true", help="do not render a GIF")
    d.add_argument("--no-progress", action="store_true", help="no progress bar")
    d.set_defaults(func=run_demo)


def run_train(args: argparse.Namespace) -> int:
    """Run the ``train`` subcommand."""
    from bluesky_gym.training.runner import RunConfigMismatch, RunDamaged, RunLocked, make_run_spec, run_dir_for, run_training

    try:
        config = load_config(args.config)
        spec = make_run_spec(config, args.env_id, args.algo, args.seed, **run_overrides(args))
        run_dir = run_dir_for(args.out, args.env_id, args.algo, args.seed)
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

    try:
        demo(
            args.env,
            out=args.out,
            steps=args.steps,
            n_envs=args.n_envs,
            seed=args.seed,
            episodes=args.episodes,
            gif=not args.no_gif,
            progress_bar=not args.no_progress,
        )
    except (MissingDependencyError, ValueError) as exc:
        print(f"bluesky-gym demo: error: {exc}", file=sys.stderr)
        return 2
    return 0
