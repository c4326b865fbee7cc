"""``bluesky-gym realtraffic``: prepare recorded traffic, measure the replay's fidelity, collection statistics.

Examples::

    bluesky-gym realtraffic prepare --sample switzerland            # clean a traffic sample into the cache
    bluesky-gym realtraffic prepare --table flights.csv --out my.npz  # a user's ADS-B table
    bluesky-gym realtraffic fidelity --windows 64                    # deviation from the recordings after 5, 10, 20 min
    bluesky-gym realtraffic stats --episodes 50                      # flights, aircraft-hours, conflicts, policy KPIs
    bluesky-gym realtraffic scn --seed 0 --out episode.scn           # an episode's window, flown with nobody acting, as a BlueSky scenario

``prepare`` cleans with the ``traffic`` library (the ``realtraffic`` extra) and writes a ``.npz``
file that the environments read with numpy alone (``gym.make("RealTrafficCREnv-v0",
collections=("my.npz",), ...)``). ``fidelity`` replays 20-minute windows with nobody acting and
prints, per collection, the median and 95th percentile of the lateral and vertical deviation from
the recorded tracks 5, 10 and 20 minutes after each aircraft appeared, as a Markdown table.
``stats`` prints per collection: flights, aircraft-hours, losses of separation per flight-hour
when nobody acts, and the KPIs of the ``random`` and ``classical`` policies (and of ``--model``)
on its test windows.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from bluesky_gym.cli.train import positive_int
from bluesky_gym.core.extras import MissingDependencyError

HEADER = (
    "| collection | flights | aircraft-hours | LoS per flight-hour (nobody acts) | policy | return | LoS / episode | min sep [NM] | route dev [NM] |"
)
FIDELITY_WINDOW_S = 1200.0  # s: long enough for the 20-minute horizon
FIDELITY_STRIDE_S = 300.0  # s between candidate window starts


def add_parser(subparsers: Any) -> None:
    """Register the ``realtraffic`` subcommand."""
    p = subparsers.add_parser(
        "realtraffic",
        help="recorded traffic: prepare data, fidelity of the replay, statistics",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    sub = p.add_subparsers(dest="action", metavar="ACTION")
    sub.required = True
    prep = sub.add_parser("prepare", help="clean a traffic sample (into the cache) or an ADS-B table (into --out)")
    src = prep.add_mutually_exclusive_group(required=True)
    src.add_argument("--sample", metavar="NAME", help="a sample collection of the traffic package (switzerland, quickstart)")
    src.add_argument("--table", type=Path, metavar="FILE", help="a CSV or Parquet ADS-B table")
    prep.add_argument("--out", type=Path, metavar="FILE.npz", help="output file (default for --sample: the cache directory)")
    prep.add_argument("--cache-dir", metavar="DIR", help="cache directory (default: $BLUESKY_GYM_CACHE, else ~/.cache/bluesky-gym)")
    prep.add_argument(
        "--no-consistency",
        action="store_true",
        help="skip traffic's FilterConsistency on flights with an altitude glitch left by the default filter (faster, less clean)",
    )
    prep.set_defaults(func=run_prepare)
    fid = sub.add_parser("fidelity", help="deviation of the replay from the recorded tracks after 5, 10 and 20 minutes")
    fid.add_argument("--collections", nargs="+", default=None, metavar="NAME", help="collections (default: switzerland quickstart)")
    fid.add_argument("--windows", type=positive_int, default=64, metavar="N", help="windows per collection, spread over its time (default: 64)")
    fid.add_argument("--cache-dir", metavar="DIR", help="cache directory")
    fid.add_argument("--json", type=Path, metavar="FILE", help="also write the figures as JSON")
    fid.set_defaults(func=run_fidelity)
    scn = sub.add_parser("scn", help="write the window of an episode of RealTrafficCREnv-v0, flown with nobody acting, as a BlueSky .scn file")
    scn.add_argument("--seed", type=int, default=0, help="episode seed (evaluation-range seeds, 2**31 and above, draw from the test split)")
    scn.add_argument("--collections", nargs="+", default=None, metavar="NAME", help="collections (default: switzerland quickstart)")
    scn.add_argument("--cache-dir", metavar="DIR", help="cache directory")
    scn.add_argument("--out", type=Path, required=True, metavar="FILE.scn", help="output file")
    scn.set_defaults(func=run_scn)
    st = sub.add_parser("stats", help="per collection: flights, aircraft-hours, conflicts per flight-hour, random/classical KPIs")
    st.add_argument("--collections", nargs="+", default=None, metavar="NAME", help="collections (default: switzerland quickstart)")
    st.add_argument("--windows", type=positive_int, default=64, metavar="N", help="windows replayed for the conflict rate (default: 64)")
    st.add_argument("--episodes", type=positive_int, default=50, metavar="N", help="test episodes per policy (default: 50)")
    st.add_argument("--model", metavar="PATH", help="also evaluate a trained model (run directory or .zip), e.g. the demo's PPO")
    st.add_argument("--cache-dir", metavar="DIR", help="cache directory")
    st.add_argument("--json", type=Path, metavar="FILE", help="also write the figures as JSON")
    st.set_defaults(func=run_stats)


def _spread(items: list[Any], n: int) -> list[Any]:
    """``n`` items evenly spread over ``items`` (all if fewer)."""
    if len(items) <= n:
        return items
    step = len(items) / n
    return [items[int(i * step)] for i in range(n)]


def _collections(args: argparse.Namespace) -> list[str]:
    from bluesky_gym.realtraffic.sources import SAMPLE_COLLECTIONS

    return list(args.collections or SAMPLE_COLLECTIONS)


def _replay(name: str, n_windows: int, cache: str | None) -> Any:
    from bluesky_gym.realtraffic.cache import load_collection
    from bluesky_gym.realtraffic.fidelity import fidelity
    from bluesky_gym.realtraffic.scenario import MAX_ROUTE_POINTS, windows
    from bluesky_gym.tasks.real_traffic import RealTrafficConfig

    cfg = RealTrafficConfig()
    flights = load_collection(name, cache)
    found = windows(flights, FIDELITY_WINDOW_S, FIDELITY_STRIDE_S, cfg.radius_nm, cfg.min_traffic, cfg.max_traffic)
    if not found:
        raise ValueError(f"{name}: no {FIDELITY_WINDOW_S / 60:.0f}-minute window with traffic")
    return flights, fidelity(flights, _spread(found, n_windows), cfg.max_traffic + 1, MAX_ROUTE_POINTS)


def run_prepare(args: argparse.Namespace) -> int:
    """Run ``realtraffic prepare``."""
    from bluesky_gym.realtraffic.cache import collection_path
    from bluesky_gym.realtraffic.sources import load_sample, load_table

    try:
        if args.sample:
            flights = load_sample(args.sample, consistency=not args.no_consistency)
            out = args.out or collection_path(args.sample, args.cache_dir)
        else:
            if args.out is None:
                raise ValueError("--table needs --out FILE.npz")
            flights = load_table(args.table, consistency=not args.no_consistency)
            out = args.out
        flights.save(out)
    except (MissingDependencyError, ValueError) as exc:
        print(f"bluesky-gym realtraffic: error: {exc}", file=sys.stderr)
        return 2
    print(f"{out}: {flights.n_flights} flights, {flights.flight_hours():.1f} aircraft-hours")
    return 0


def run_scn(args: argparse.Namespace) -> int:
    """Run ``realtraffic scn``."""
    import gymnasium as gym

    import bluesky_gym
    from bluesky_gym.realtraffic.cache import load_collection, window_of_part
    from bluesky_gym.realtraffic.fidelity import write_window_scenario

    bluesky_gym.register_envs()
    try:
        names = _collections(args)
        env = gym.make("RealTrafficCREnv-v0", collections=tuple(names), cache_dir=args.cache_dir)
        env.reset(seed=args.seed)
        task = env.unwrapped.task  # type: ignore[attr-defined]
        k, window = window_of_part([load_collection(n, args.cache_dir) for n in names], task.window(0))
        flights = load_collection(names[k], args.cache_dir)
        path = write_window_scenario(flights, window, args.out, task.max_waypoints())
    except (MissingDependencyError, ValueError) as exc:
        print(f"bluesky-gym realtraffic: error: {exc}", file=sys.stderr)
        return 2
    print(f"{path}: {flights.name}, {len(window.flights)} aircraft, {window.duration:.0f} s flown with nobody acting")
    return 0


def run_fidelity(args: argparse.Namespace) -> int:
    """Run ``realtraffic fidelity``."""
    from bluesky_gym.realtraffic.fidelity import format_markdown

    results = []
    try:
        for name in _collections(args):
            results.append(_replay(name, args.windows, args.cache_dir)[1])
    except (MissingDependencyError, ValueError) as exc:
        print(f"bluesky-gym realtraffic: error: {exc}", file=sys.stderr)
        return 2
    print(format_markdown(results))
    windows = ", ".join(f"{r.collection}: {r.windows} windows" for r in results)
    print(f"\n{windows} of 20 minutes, nobody acting, every aircraft with its recorded type (BlueSky's B744 where missing or unknown)")
    if args.json:
        args.json.write_text(json.dumps({r.collection: r.summary() for r in results}, indent=2))
    return 0


def run_stats(args: argparse.Namespace) -> int:
    """Run ``realtraffic stats``."""
    import gymnasium as gym

    import bluesky_gym
    from bluesky_gym.training.evaluation import evaluate, load_policy
    from bluesky_gym.training.policies import reference_policy

    bluesky_gym.register_envs()

    rows = []
    policies = ["random", "classical"] + ([args.model] if args.model else [])
    try:
        for name in _collections(args):
            space = gym.make("RealTrafficCREnv-v0", collections=(name,), cache_dir=args.cache_dir).action_space
            # fresh per collection: the random policy's generator restarts
            low, high = np.asarray(getattr(space, "low")), np.asarray(getattr(space, "high"))  # noqa: B009 - a Box
            made = {p: reference_policy(p, "RealTrafficCREnv-v0", low, high) for p in policies[:2]}
            if args.model:
                made[args.model] = load_policy(args.model)
            flights, replay = _replay(name, args.windows, args.cache_dir)
            row: dict[str, Any] = {
                "collection": name,
                "flights": flights.n_flights,
                "aircraft_hours": round(flights.flight_hours(), 1),
                "conflicts_per_flight_hour": round(replay.conflicts_per_flight_hour, 3),
            }
            options = {"collections": (name,), "split": "test", "cache_dir": args.cache_dir}
            for policy in policies:
                res = evaluate("RealTrafficCREnv-v0", made[policy], args.episodes, env_options=options)
                s = res.summary
                route = [float(e.get("kpi_mean_route_deviation_nm", "nan")) for e in res.episodes]
                row[policy] = {
                    "return": s["return"]["mean"],
                    "los_per_episode": s["los"]["mean"],
                    "min_separation_nm": s["min_sep_nm"]["mean"],
                    "route_deviation_nm": float(np.nanmean(route)) if route else float("nan"),
                }
            rows.append(row)
    except (MissingDependencyError, ValueError, FileNotFoundError) as exc:
        print(f"bluesky-gym realtraffic: error: {exc}", file=sys.stderr)
        return 2
    print(HEADER)
    print("|---|---:|---:|---:|---|---:|---:|---:|---:|")
    for r in rows:
        for policy in policies:
            k = r[policy]
            print(
                f"| {r['collection']} | {r['flights']} | {r['aircraft_hours']} | {r['conflicts_per_flight_hour']} | {policy} | "
                f"{k['return']:.2f} | {k['los_per_episode']:.2f} | {k['min_separation_nm']:.2f} | {k['route_deviation_nm']:.2f} |"
            )
    if args.json:
        args.json.write_text(json.dumps(rows, indent=2))
    return 0
