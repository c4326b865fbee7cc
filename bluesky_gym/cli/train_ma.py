"""``bluesky-gym train-ma``: one PPO policy shared by every aircraft of a multi-agent environment.

Examples::

    bluesky-gym train-ma --env sector_cr_v0 --steps 1e6 --seed 0
    bluesky-gym train-ma --env merge_v0 --steps 400000 --num-envs 16 --eval-episodes 32 --save merge

The environments are the multi-agent forms (``horizontal_cr_v0``, ``sector_cr_v0``, ``merge_v0``;
their single-agent or centralised ids are accepted too). Every agent slot of ``--num-envs``
parallel multi-agent episodes is one row of an SB3 VecEnv; ``--steps`` counts row-steps (empty
slots included). After training, the policy, a random policy, MVP and the classical
conflict-resolution rule are evaluated on ``--eval-episodes`` held-out scenarios and their KPIs
printed. Needs the ``train`` and ``multiagent`` extras.
"""

from __future__ import annotations

import argparse
import sys
from typing import Any

from bluesky_gym.cli.arguments import non_negative_int, positive_float, positive_int
from bluesky_gym.core.extras import MissingDependencyError


def multiagent_name(text: str) -> str:
    """Parse a multi-agent environment: its name, single-agent id or centralised id."""
    from bluesky_gym.envs.registry import ENVIRONMENTS, multiagent_entries

    for e in ENVIRONMENTS:
        m = e.multiagent
        if m is not None and text in (m.name, m.centralised_id, e.id):
            return m.name
    raise argparse.ArgumentTypeError(f"must be one of {', '.join(m.name for m in multiagent_entries())}, got {text!r}")


def add_parser(subparsers: Any) -> None:
    """Register the ``train-ma`` subcommand."""
    from bluesky_gym.multiagent.train import DEFAULTS

    p = subparsers.add_parser("train-ma", help="train a policy shared by every aircraft of a multi-agent environment", description=__doc__)
    p.add_argument("--env", type=multiagent_name, default="sector_cr_v0", metavar="NAME", help="multi-agent environment (default: sector_cr_v0)")
    p.add_argument("--steps", type=positive_int, default=DEFAULTS["timesteps"], metavar="N", help="PPO row-steps (default: 1e6)")
    p.add_argument("--num-envs", type=positive_int, default=DEFAULTS["episodes"], metavar="K", help="parallel episodes (default: 16)")
    p.add_argument("--eval-episodes", type=positive_int, default=DEFAULTS["eval_episodes"], metavar="N", help="held-out episodes (default: 32)")
    p.add_argument("--seed", type=non_negative_int, default=0, help="run seed (default: 0)")
    p.add_argument("--n-steps", type=positive_int, default=DEFAULTS["n_steps"], metavar="N", help="PPO rollout length per row (default: 32)")
    p.add_argument(
        "--batch-size", type=positive_int, default=DEFAULTS["batch_size"], metavar="N", help="minibatch of live transitions (default: 1024)"
    )
    p.add_argument("--n-epochs", type=positive_int, default=DEFAULTS["n_epochs"], metavar="N", help="PPO epochs per rollout (default: 5)")
    p.add_argument("--learning-rate", type=positive_float, default=DEFAULTS["learning_rate"], metavar="LR", help="(default: 1e-3)")
    p.add_argument("--gamma", type=positive_float, default=DEFAULTS["gamma"], help="discount factor (default: 0.95)")
    p.add_argument("--log-std-init", type=float, default=DEFAULTS["log_std_init"], metavar="X", help="initial log std of the actions (default: -1)")
    p.add_argument("--threads", type=positive_int, default=1, metavar="N", help="PyTorch threads (default: 1)")
    p.add_argument("--save", metavar="PATH", help="save the model to PATH.zip and the observation statistics to PATH.pkl")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run the ``train-ma`` subcommand."""
    try:
        from bluesky_gym.core.extras import require_sb3

        require_sb3()
        from bluesky_gym.multiagent.train import train_and_compare

        train_and_compare(
            args.env,
            args.steps,
            eval_episodes=args.eval_episodes,
            threads=args.threads,
            save=args.save,
            episodes=args.num_envs,
            n_steps=args.n_steps,
            batch_size=args.batch_size,
            n_epochs=args.n_epochs,
            learning_rate=args.learning_rate,
            gamma=args.gamma,
            log_std_init=args.log_std_init,
            seed=args.seed,
        )
    except (MissingDependencyError, ValueError) as exc:
        print(f"bluesky-gym train-ma: error: {exc}", file=sys.stderr)
        return 2
    return 0
