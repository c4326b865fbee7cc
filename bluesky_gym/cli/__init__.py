"""The ``bluesky-gym`` command line (also ``python -m bluesky_gym``).

Each subcommand lives in its own module of this package and exposes ``add_parser(subparsers)``,
which registers the subcommand and sets ``func`` (taking the parsed arguments, returning an exit
code) as its default.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

# Modules that define subcommands, in the order they appear in --help.
SUBCOMMAND_MODULES = ("catalog", "train", "evaluate", "plot", "results", "sweep", "render", "bench", "replay", "runs")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every available subcommand."""
    parser = argparse.ArgumentParser(prog="bluesky-gym", description="Air traffic reinforcement-learning environments and benchmark.")
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
    args = build_parser().parse_args(argv)
    return int(args.func(args) or 0)


if __name__ == "__main__":
    sys.exit(main())
