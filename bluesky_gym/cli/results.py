"""``bluesky-gym results``: the results page (Markdown and figures) from sweep directories.

Examples::

    bluesky-gym results results/v0-ppo results/v1-ppo --out docs/results.md

For every environment in the sweeps: a KPI table of the reference policies (``random``,
``classical``, ``mvp`` where it applies) and of every trained algorithm, with 95% confidence
intervals over seeds and held-out episodes; its learning curves and KPI curves; and per
environment version an aggregate of the normalised held-out scores (IQM, mean, median,
optimality gap, probability of improvement; ``rliable``). Figures go to a directory named after
the page (``docs/results/`` for ``docs/results.md``). The page names the command that made it;
rerunning the command on the same directories reproduces it.

The reference policies are evaluated on the same held-out scenarios as the runs (as many
episodes as the runs' evaluations, or ``--reference-episodes N``) where a sweep does not hold
their per-episode records yet, and kept in its ``references/episodes/`` for the next time.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from bluesky_gym.cli.arguments import non_negative_int
from bluesky_gym.core.extras import MissingDependencyError


def add_parser(subparsers: Any) -> None:
    """Register the ``results`` subcommand."""
    p = subparsers.add_parser(
        "results",
        help="write the results page (KPI tables, curves, aggregate) from sweeps",
        description=__doc__,
    )
    p.add_argument("sweeps", nargs="+", type=Path, metavar="SWEEP_DIR", help="sweep (or run) directories")
    p.add_argument("--out", type=Path, default=Path("docs/results.md"), metavar="FILE", help="the page to write (default: docs/results.md)")
    p.add_argument(
        "--reference-episodes",
        type=non_negative_int,
        metavar="N",
        help="held-out episodes of the reference policies a sweep lacks (default: as many as the runs' evaluations)",
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run the ``results`` subcommand."""
    from bluesky_gym.training.results import build_results, complete_references

    command = ["bluesky-gym", "results", *map(str, args.sweeps), "--out", str(args.out)]
    try:
        for line in complete_references(args.sweeps, args.reference_episodes):
            print(line, file=sys.stderr)
        page = build_results(args.sweeps, args.out, command)
    except (MissingDependencyError, FileNotFoundError, ValueError) as exc:
        print(f"bluesky-gym results: error: {exc}", file=sys.stderr)
        return 2
    print(f"wrote {page} and its figures in {page.parent / page.stem}")
    return 0
