"""``bluesky-gym runs``: list training runs and their status.

Examples::

    bluesky-gym runs                 # every run below ./runs
    bluesky-gym runs runs/sweep --json
    bluesky-gym runs results/ppo-2e6 --summarise   # finished runs reduced to what results need

``--summarise`` reduces every finished run below DIR to its summary, the files a results page
reads (configuration, process record, held-out evaluation, result and the learning curve binned
into ``curve.csv``): checkpoints, the TensorBoard log, the episode log and (without
``--keep-model``) the final model are removed, and ``result.json`` records what was removed. Runs
that are not finished, or are damaged, are left alone and named.

For every run directory below DIR: environment, algorithm, seed, steps done out of the total,
status (running, finished, damaged, failed, interrupted, new) and the latest score (the
held-out return of a finished run, else the mean return of the last 20 training episodes).
Damage and errors are named below the table; ``bluesky-gym train`` with the run's options
resumes an interrupted run, and offers ``--resume-from-last-intact`` or ``--restart`` for a
damaged one.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any


def add_parser(subparsers: Any) -> None:
    """Register the ``runs`` subcommand."""
    p = subparsers.add_parser(
        "runs",
        help="list training runs with their status and latest score",
        description=__doc__,
    )
    p.add_argument("dirs", nargs="*", type=Path, default=[Path("runs")], metavar="DIR", help="run or sweep directories (default: runs)")
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    p.add_argument("--summarise", action="store_true", help="reduce every finished run to its summary (for committing results)")
    p.add_argument("--keep-model", action="store_true", help="with --summarise: keep the final model.zip")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run the ``runs`` subcommand."""
    from bluesky_gym.training.status import describe_run, find_run_dirs, format_runs

    try:
        dirs = find_run_dirs(args.dirs)
    except FileNotFoundError as exc:
        print(f"bluesky-gym runs: error: {exc}", file=sys.stderr)
        return 2
    if args.summarise:
        return _summarise(dirs, args.keep_model)
    rows = [describe_run(d) for d in dirs]
    if args.json:
        print(json.dumps(rows, indent=2))
    elif not rows:
        print(f"no runs below {', '.join(map(str, args.dirs))}")
    else:
        print(format_runs(rows, args.dirs[0] if len(args.dirs) == 1 else None))
    return 0


def _summarise(dirs: list[Path], keep_model: bool) -> int:
    """Summarise the finished runs of ``dirs``; exit 1 if one was damaged."""
    from bluesky_gym.training.runner import run_status
    from bluesky_gym.training.summary import summarise_run

    failed = False
    for d in dirs:
        if run_status(d) != "finished":
            print(f"{d}: not finished, left as it is")
            continue
        try:
            record = summarise_run(d, keep_model=keep_model)
        except ValueError as exc:
            print(f"bluesky-gym runs: {exc}", file=sys.stderr)
            failed = True
            continue
        print(f"{d}: summarised (removed: {', '.join(record['removed']) or 'nothing'})")
    return 1 if failed else 0
