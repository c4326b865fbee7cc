"""The ``bluesky-gym`` command line (also ``python -m bluesky_gym``).

Each subcommand lives in its own module of this package and exposes ``add_parser(subparsers)``,
which registers the subcommand and sets ``func`` (taking the parsed arguments, returning an exit
code) as its default. The conventions every subcommand follows (``--env``, ``--num-envs``,
``--episodes``, no abbreviations, deprecated aliases) are in :mod:`bluesky_gym.cli.arguments`.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from collections.abc import Sequence

# Modules that define subcommands, in the order they appear in --help.
SUBCOMMAND_MODULES = ("catalog", "train", "train_ma", "evaluate", "plot", "results", "runs", "sweep", "render", "bench", "replay", "realtraffic")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every available subcommand."""
    import bluesky_gym
    from bluesky_gym.cli.arguments import Parser
    from bluesky_gym.core.extras import DISTRIBUTION

    parser = Parser(prog="bluesky-gym", description="Air traffic reinforcement-learning environments and benchmark.")
    parser.add_argument("--version", action="version", version=f"%(prog)s {bluesky_gym.__version__} ({DISTRIBUTION})")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name in SUBCOMMAND_MODULES:
        try:
            module = importlib.import_module(f"bluesky_gym.cli.{name}")
        except ModuleNotFoundError as exc:
            if exc.name == f"bluesky_gym.cli.{name}":
                continue
            raise
        module.add_parser(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit code."""
    from bluesky_gym.cli.arguments import chosen_env

    args, extras = build_parser().parse_known_args(argv)
    if extras:
        args.cli_parser.unrecognized(extras)
    if hasattr(args, "env_required"):
        chosen_env(args.cli_parser, args)
    check = getattr(args, "check", None)
    if check is not None:
        check(args.cli_parser, args)
    try:
        return int(args.func(args) or 0)
    except BrokenPipeError:  # output piped into a reader that stopped (``| head``)
        sys.stdout = open(os.devnull, "w")  # noqa: SIM115 - replaces the closed stdout until exit
        return 0


if __name__ == "__main__":
    sys.exit(main())
