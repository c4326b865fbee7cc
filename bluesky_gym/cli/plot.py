"""``bluesky-gym plot``: learning curves and the cross-environment aggregate of training runs.

Examples::

    bluesky-gym plot runs                                   # every run below runs/
    bluesky-gym plot runs/DescentEnv-v0/PPO runs/DescentEnv-v0/SAC --out figures

Each RUN_DIR is a run directory or any directory above runs (a sweep). Written to ``--out``:

* ``learning_curves.png``: episode return against environment steps per environment, one line
  per algorithm and configuration (mean over seeds, 95% bootstrap band over seeds), like the
  paper's figure, with the reference policies' held-out returns as horizontal lines;
* ``kpis_<ID>.png``: return and the KPIs that matter for the environment against steps;
* ``aggregate.png`` and ``aggregate.json``: interquartile mean (IQM) of normalised scores
  ``(score - random) / (classical - random)`` per algorithm across environments and seeds, with
  95% stratified bootstrap confidence intervals: of the final held-out return, and of the
  training return over the fraction of training done.

The reference scores come from a ``references/`` directory of a sweep or demo above the runs;
otherwise they are computed (``--reference-episodes`` held-out episodes of ``random`` and
``classical``) and cached in ``<out>/references``. Runs that have not logged an episode yet are
skipped with a message; unfinished runs (a sweep still running) are plotted up to their last
logged episode and counted in the legend.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from bluesky_gym.cli.arguments import non_negative_int
from bluesky_gym.core.extras import MissingDependencyError


def add_parser(subparsers: Any) -> None:
    """Register the ``plot`` subcommand."""
    p = subparsers.add_parser(
        "plot",
        help="learning curves and aggregate scores of runs (PNG)",
        description=__doc__,
    )
    p.add_argument("run_dirs", nargs="+", type=Path, metavar="RUN_DIR", help="run or sweep directories")
    p.add_argument("--out", type=Path, default=Path("plots"), metavar="DIR", help="output directory (default: plots)")
    p.add_argument(
        "--reference-episodes",
        type=non_negative_int,
        metavar="N",
        help="held-out episodes for missing reference scores (default: the runs' eval episodes; 0: no aggregate)",
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run the ``plot`` subcommand."""
    from bluesky_gym.training.evaluation import reference_returns, reference_scores
    from bluesky_gym.training.plotting import aggregate, find_references, find_runs, load_run, plot_aggregate, plot_learning_curves

    try:
        dirs = find_runs(args.run_dirs)
        if not dirs:
            raise FileNotFoundError(f"no run directories (with config.json) below {', '.join(map(str, args.run_dirs))}")
        runs = [load_run(d) for d in dirs]
        waiting = [r for r in runs if not r.timesteps.size]
        runs = [r for r in runs if r.timesteps.size]
        if not runs:
            raise ValueError(f"none of the {len(waiting)} runs below {', '.join(map(str, args.run_dirs))} has logged an episode yet; nothing to plot")
        for r in waiting:
            print(f"skipping {r.path}: no episode logged yet (a run that is starting, or that failed before training)", file=sys.stderr)
        unfinished = [r for r in runs if not r.finished]
        if unfinished:
            print(f"{len(unfinished)} of {len(runs)} runs are unfinished: plotted up to their last logged episode", file=sys.stderr)
        env_ids = sorted({r.env_id for r in runs})
        refs = find_references(dirs, env_ids)
        episodes = args.reference_episodes
        if episodes is None:
            episodes = max(int(r.config.get("eval_episodes", 0)) for r in runs) or 50
        if episodes > 0:
            for env_id in env_ids:
                if env_id not in refs:
                    print(f"computing reference scores of {env_id} on {episodes} held-out episodes", file=sys.stderr)
                    refs[env_id] = reference_returns(reference_scores(env_id, episodes, args.out / "references"))
        written = plot_learning_curves(runs, args.out, references=refs)
        if episodes > 0:
            written += plot_aggregate(aggregate(runs, refs), args.out)
    except (MissingDependencyError, FileNotFoundError, ValueError, KeyError) as exc:
        print(f"bluesky-gym plot: error: {exc}", file=sys.stderr)
        return 2
    print(f"{len(runs)} runs ({', '.join(env_ids)})")
    for p in written:
        print(f"wrote {p}")
    return 0
