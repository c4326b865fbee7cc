r"""``bluesky-gym sweep``: the benchmark grid (environments x algorithms x seeds), resumable.

Examples::

    bluesky-gym sweep --env DescentEnv-v0,MergeEnv-v0 --algos PPO SAC --seeds 0 1 2 \
        --steps 100000 --local
    bluesky-gym sweep --env all --algos all --seeds 0 1 2 --steps 2e6      # Ray on this machine
    bluesky-gym sweep --env all --algos all --seeds 0 1 2 --address ray://head:10001 \
        --out sweeps/paper
    bluesky-gym sweep --env all --algos all --steps 2e6 --estimate  # how long would it take?

Every run goes to ``<out>/<ID>/<ALGO>/seed_<S>`` (the same layout as ``train``) with the paper's
hyperparameters unless ``--config`` overrides them. Rerunning the same command skips finished
runs and resumes interrupted ones from their last checkpoint (model, optimiser, replay buffer
and timesteps), so a killed sweep loses at most the steps since each run's last checkpoint.
Result files are replaced atomically: a killed sweep never leaves a half-written result.

By default the runs are Ray tasks (``pip install -e ".[distributed]"``): on a local Ray
instance, or on the cluster at ``--address`` (then ``--out`` must be a directory every node
sees). ``--local`` runs them one after the other in this process, without Ray.

At the end, the reference policies are evaluated on the same held-out scenarios (cached in
``<out>/references``), and ``<out>/sweep.json`` lists every run with its held-out return and
normalised score; ``bluesky-gym plot <out>`` draws the figures. ``--references eby swarm ssd`` also
evaluates those reference policies (MVP's mapping flying BlueSky's Eby, Swarm or SSD resolution)
on the environments with traffic.

``--estimate`` trains nothing: it times every environment (random actions) and every algorithm
(a short training on ``--probe-env``), and extrapolates the grid's CPU time and wall-clock time
(written to ``<out>/estimate.json``).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from bluesky_gym.cli.arguments import add_env_option, deprecated_alias, non_negative_int, positive_int, warn
from bluesky_gym.cli.train import add_damage_options, add_run_options, check_device, load_config, ppo_rounding, run_overrides
from bluesky_gym.core.extras import MissingDependencyError
from bluesky_gym.tasks import RESOLUTION_REFERENCES
from bluesky_gym.training import ALGORITHMS


def add_parser(subparsers: Any) -> None:
    """Register the ``sweep`` subcommand."""
    p = subparsers.add_parser(
        "sweep",
        help="train the grid of environments x algorithms x seeds (Ray or --local)",
        description=__doc__,
    )
    add_env_option(p, several=True)
    deprecated_alias(p, "--envs", "--env", "env", extend=True, nargs="+", metavar="ID")
    p.add_argument("--algos", nargs="+", default=["all"], metavar="ALGO", help=f"algorithms ({', '.join(ALGORITHMS)}) or 'all' (default)")
    p.add_argument("--seeds", nargs="+", type=non_negative_int, default=[0], metavar="S", help="run seeds (default: 0)")
    p.add_argument("--out", type=Path, default=Path("runs/sweep"), metavar="DIR", help="sweep directory (default: runs/sweep)")
    add_run_options(p)
    add_damage_options(p)
    where = p.add_mutually_exclusive_group()
    where.add_argument("--local", action="store_true", help="run sequentially in this process, without Ray")
    where.add_argument("--address", metavar="ADDR", help="Ray cluster to join (default: start Ray locally)")
    p.add_argument("--cpus-per-run", type=float, default=1.0, metavar="C", help="CPUs Ray reserves per run (default: 1)")
    p.add_argument("--quiet", action="store_true", help="fewer messages")
    p.add_argument(
        "--references",
        nargs="+",
        default=[],
        choices=tuple(RESOLUTION_REFERENCES),
        metavar="NAME",
        help=f"also evaluate these reference policies where an environment has traffic ({', '.join(RESOLUTION_REFERENCES)})",
    )
    est = p.add_argument_group("estimating the time of a grid (nothing is trained)")
    est.add_argument("--estimate", action="store_true", help="measure steps/s per algorithm and environment and extrapolate the grid's time")
    est.add_argument("--probe-env", metavar="ID", help="environment the algorithms are timed on (default: the first of --env)")
    est.add_argument("--probe-steps", type=positive_int, default=2048, metavar="N", help="timed training steps per algorithm (default: 2048)")
    p.set_defaults(func=run)


def _expand(values: list[str], universe: list[str] | tuple[str, ...], what: str) -> list[str]:
    if [v.lower() for v in values] == ["all"]:
        return list(universe)
    lookup = {u.upper(): u for u in universe}
    out = []
    for v in values:
        if v.upper() not in lookup:
            raise ValueError(f"unknown {what} {v!r}; choose from {', '.join(universe)} or 'all'")
        out.append(lookup[v.upper()])
    return list(dict.fromkeys(out))


def _estimate(args: argparse.Namespace, config: dict[str, Any], envs: list[str], algos: list[str], verbose: int) -> int:
    import os

    from bluesky_gym.training.io import atomic_write_json
    from bluesky_gym.training.sweep import estimate, format_estimate

    probe = args.probe_env or envs[0]
    est = estimate(config, envs, algos, probe, args.probe_steps, verbose=verbose, **run_overrides(args))
    workers = 1.0 if args.local else max(1.0, (os.cpu_count() or 1) / args.cpus_per_run)
    print(format_estimate(est, len(args.seeds), workers))
    atomic_write_json(args.out / "estimate.json", {**est, "seeds": len(args.seeds), "parallel_runs": workers})
    return 0


def run(args: argparse.Namespace) -> int:
    """Run the ``sweep`` subcommand."""
    import bluesky_gym
    from bluesky_gym.training.sweep import format_summary, plan, run_local, run_ray, write_summary

    verbose = 0 if args.quiet else 1
    try:
        envs = _expand(args.env, bluesky_gym.available_envs(), "environment")
        algos = _expand(args.algos, ALGORITHMS, "algorithm")
        config = load_config(args.config)
        if args.estimate:
            return _estimate(args, config, envs, algos, verbose)
        cells = plan(config, envs, algos, args.seeds, args.out, **run_overrides(args))
        check_device(cells[0].spec.device)
        if verbose and args.steps is not None:
            for note in dict.fromkeys(ppo_rounding(c.spec.algo, c.spec.hyperparams, c.spec.n_envs, c.spec.total_timesteps) for c in cells):
                if note:
                    warn("bluesky-gym sweep", note)
        if verbose:
            print(f"sweep of {len(cells)} runs ({len(envs)} environments x {len(algos)} algorithms x {len(args.seeds)} seeds) -> {args.out}")
        if args.local:
            results = run_local(cells, verbose, args.on_damage)
        else:
            results = run_ray(cells, args.address, args.cpus_per_run, verbose, args.on_damage)
        episodes = max(c.spec.eval_episodes for c in cells)
        summary = write_summary(args.out, cells, results, reference_episodes=episodes, extra_references=args.references)
    except (MissingDependencyError, ValueError, FileNotFoundError) as exc:
        print(f"bluesky-gym sweep: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"\ninterrupted; rerun the same command to resume (finished runs are skipped) in {args.out}", file=sys.stderr)
        return 130
    print(format_summary(summary))
    failed = [r for r in summary["runs"] if r["status"] != "finished"]
    for r in failed:
        print(f"FAILED {r['run_dir']}: {r['error']}", file=sys.stderr)
    return 1 if failed else 0
