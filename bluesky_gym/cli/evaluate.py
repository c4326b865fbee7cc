r"""``bluesky-gym eval``: deterministic evaluation on held-out scenarios, as a KPI table.

Examples::

    bluesky-gym eval --env DescentEnv-v0 --model runs/DescentEnv-v0/PPO/seed_0 --episodes 100
    bluesky-gym eval --env MergeEnv-v0 --model random --model classical \
        --model runs/MergeEnv-v0/SAC/seed_0/model.zip
    bluesky-gym eval --env SectorCREnv-v0 --model classical --episodes 200 --out results/sector
    bluesky-gym eval --env HorizontalCREnv-v0 --model random --model classical --model mvp

``--model`` is a trained model (a run directory or a ``.zip``; its algorithm is read from the run's
config or the file; ``--algo``, if given, must agree), ``random`` (uniform actions),
``classical`` (the hand-written reference controller of the environment) or ``mvp`` (BlueSky's
MVP conflict resolution, for the environments with traffic; docs/baselines.md); repeat it to
compare policies. A model trained on another environment (its run's ``config.json`` says which)
or whose observation space differs from the environment's is refused, and so is a model file that
is cut off or damaged (it fails its zip checksums, or the size and SHA-256 its run recorded).

Episode ``j`` is the scenario of ``reset(seed=2**31 + j)``: the evaluation seeds start at 2**31,
while every training scenario seed is below 2**31, so evaluation scenarios are never trained on,
and every policy is scored on the same scenarios. The table gives the mean and a 95% confidence
half-width of return, success rate, losses of separation per episode, minimum separation, mean
absolute drift, time to goal (successful episodes) and episode length. When both ``random`` and
``classical`` are evaluated, a normalised score (0 = random, 1 = classical) is added. Results are
saved as ``eval_<policy>.json`` and ``eval_<policy>_episodes.csv`` in ``--out`` (default:
``runs/eval/<ID>``, next to the training runs).
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path
from typing import Any

from bluesky_gym.cli.arguments import add_env_option, deprecated_alias, non_negative_int, positive_int
from bluesky_gym.cli.train import algorithm
from bluesky_gym.core.extras import MissingDependencyError
from bluesky_gym.tasks import REFERENCE_POLICIES, RESOLUTION_REFERENCES


def add_parser(subparsers: Any) -> None:
    """Register the ``eval`` subcommand."""
    p = subparsers.add_parser(
        "eval",
        help="evaluate policies on held-out scenarios (KPI table)",
        description=__doc__,
    )
    add_env_option(p)
    p.add_argument(
        "--model",
        action="append",
        required=True,
        metavar="PATH",
        help="run directory, model .zip, 'random', 'classical', 'mvp', 'eby', 'swarm' or 'ssd' (repeatable)",
    )
    p.add_argument("--algo", type=algorithm, help="algorithm of the model files (default: from the run or the file)")
    p.add_argument("--episodes", type=positive_int, default=100, metavar="N", help="held-out episodes (default: 100)")
    p.add_argument("--seed-offset", type=non_negative_int, default=0, metavar="J", help="first evaluation scenario index (default: 0)")
    p.add_argument("--num-envs", type=positive_int, default=64, metavar="K", help="episodes simulated together (default: 64)")
    deprecated_alias(p, "--batch", "--num-envs", "num_envs", type=positive_int, metavar="K")
    p.add_argument("--out", type=Path, metavar="DIR", help="directory for the result files (default: runs/eval/<ID>)")
    p.set_defaults(func=run)


def _stem(spec: str) -> str:
    if spec in REFERENCE_POLICIES or spec in RESOLUTION_REFERENCES:
        return f"eval_{spec}"
    p = Path(spec)
    parts = [x for x in (p.parent.parent.name, p.parent.name, p.stem) if x] if p.suffix == ".zip" else [p.parent.name, p.name]
    return "eval_" + re.sub(r"[^A-Za-z0-9_.-]+", "_", "_".join(parts))


def run(args: argparse.Namespace) -> int:
    """Run the ``eval`` subcommand."""
    from bluesky_gym.training.evaluation import evaluate, format_table, make_policy, save_result

    out = args.out or Path("runs") / "eval" / args.env  # below runs/, with the training runs (git-ignored)
    results = []
    try:
        for spec in args.model:
            policy = make_policy(spec, args.env, args.algo)
            res = evaluate(args.env, policy, args.episodes, seed_offset=args.seed_offset, batch=args.num_envs)
            json_path, _ = save_result(res, out, stem=_stem(spec))
            print(f"{res.policy}: {len(res.episodes)} episodes in {res.wall_time_s:.1f} s -> {json_path}", file=sys.stderr)
            results.append(res)
    except (MissingDependencyError, ValueError, FileNotFoundError) as exc:
        print(f"bluesky-gym eval: error: {exc}", file=sys.stderr)
        return 2
    names = {r.policy: r.mean_return for r in results}
    refs = {k: names[k] for k in ("random", "classical")} if {"random", "classical"} <= set(names) else None
    print(format_table(results, refs))
    return 0
