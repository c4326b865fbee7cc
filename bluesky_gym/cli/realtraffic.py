"""``bluesky-gym realtraffic``: prepare recorded traffic, measure the replay's fidelity, collection statistics.

Examples::

    bluesky-gym realtraffic prepare --sample switzerland            # clean a traffic sample into the cache
    bluesky-gym realtraffic prepare --table flights.csv --out my.npz  # a user's ADS-B table
    bluesky-gym realtraffic fidelity --windows 64                    # deviation from the recordings after 5, 10, 20 min
    bluesky-gym realtraffic stats --episodes 50                      # flights, aircraft-hours, conflicts, policy KPIs
    bluesky-gym realtraffic report results/realtraffic               # the tables of README.md and docs/realtraffic.md
    bluesky-gym realtraffic scn --seed 0 --out episode.scn           # an episode's window, flown with nobody acting, as a BlueSky scenario

``prepare`` cleans with the ``traffic`` library (the ``realtraffic`` extra), saying what it does
(the steps, the expected time, then the flights cleaned, the rate and the time left), and writes a ``.npz``
file that the environments read with numpy alone (``gym.make("RealTrafficCREnv-v0",
collections=("my.npz",), ...)``). ``fidelity`` replays 20-minute windows with nobody acting and
prints, per collection, the median and 95th percentile of the lateral and vertical deviation from
the recorded tracks 5, 10 and 20 minutes after each aircraft appeared, as a Markdown table.
``stats`` prints per collection: flights, aircraft-hours, losses of separation per flight-hour
when nobody acts, and the KPIs of the ``random`` and ``classical`` policies (and of ``--model``)
on its test windows. With ``--json FILE`` both save their figures with the command line that
made them, the package version and their inputs; ``report DIR`` writes the tables of the pages
(``README.md`` and ``docs/realtraffic.md`` by default) between their ``<!-- realtraffic:NAME -->``
markers from the JSON files of ``DIR`` (see :mod:`bluesky_gym.realtraffic.report`); with
``--check`` it only says whether the pages are up to date.
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
    fid.add_argument("--type", metavar="ICAO", help="fly every aircraft as this type instead of its recorded one (a comparison), e.g. A320")
    fid.add_argument("--cache-dir", metavar="DIR", help="cache directory")
    fid.add_argument("--json", type=Path, metavar="FILE", help="also write the figures as JSON (for 'realtraffic report')")
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
    st.add_argument(
        "--model",
        nargs="+",
        metavar="PATH",
        help="also evaluate trained models (run directories or .zip), e.g. the demo's PPO; several of one algorithm (seeds) make one row, their mean",
    )
    st.add_argument("--cache-dir", metavar="DIR", help="cache directory")
    st.add_argument("--json", type=Path, metavar="FILE", help="also write the figures as JSON (for 'realtraffic report')")
    st.set_defaults(func=run_stats)
    rep = sub.add_parser("report", help="write the fidelity and statistics tables of the pages from saved JSON files")
    rep.add_argument("directory", type=Path, metavar="DIR", help="directory of the JSON files of 'fidelity --json' and 'stats --json'")
    rep.add_argument(
        "pages",
        nargs="*",
        type=Path,
        metavar="PAGE",
        help="Markdown pages with <!-- realtraffic:NAME --> blocks (default: README.md docs/realtraffic.md)",
    )
    rep.add_argument("--check", dest="check_only", action="store_true", help="change nothing; exit with 1 if a page differs from what the files give")
    rep.set_defaults(func=run_report)


def _spread(items: list[Any], n: int) -> list[Any]:
    """``n`` items evenly spread over ``items`` (all if fewer)."""
    if len(items) <= n:
        return items
    step = len(items) / n
    return [items[int(i * step)] for i in range(n)]


def _collections(args: argparse.Namespace) -> list[str]:
    from bluesky_gym.realtraffic.sources import SAMPLE_COLLECTIONS

    return list(args.collections or SAMPLE_COLLECTIONS)


def _replay(name: str, n_windows: int, cache: str | None, actype: str | None = None) -> tuple[Any, Any, dict[str, Any]]:
    """Replay ``n_windows`` windows of a collection: its flights, the :class:`Fidelity` and the collection's entry of the JSON."""
    import dataclasses

    from bluesky_gym.core.aircraft import resolve_type
    from bluesky_gym.environments.real_traffic.task import RealTrafficConfig
    from bluesky_gym.realtraffic.cache import load_collection
    from bluesky_gym.realtraffic.fidelity import fidelity, large_vertical_deviations
    from bluesky_gym.realtraffic.scenario import MAX_ROUTE_POINTS, simulator_type, windows

    cfg = RealTrafficConfig()
    flights = load_collection(name, cache)
    with_type = int(sum(1 for t in flights.typecode if str(t).strip()))
    if actype is not None:
        flights = dataclasses.replace(flights, typecode=np.array([actype] * flights.n_flights))
    found = windows(flights, FIDELITY_WINDOW_S, FIDELITY_STRIDE_S, cfg.radius_nm, cfg.min_traffic, cfg.max_traffic)
    if not found:
        raise ValueError(f"{name}: no {FIDELITY_WINDOW_S / 60:.0f}-minute window with traffic")
    chosen = _spread(found, n_windows)
    result = fidelity(flights, chosen, cfg.max_traffic + 1, MAX_ROUTE_POINTS)
    flown: dict[str, int] = {}
    for w in chosen:
        for f in w.flights:
            t = resolve_type(simulator_type(str(flights.typecode[f])))
            flown[t] = flown.get(t, 0) + 1
    entry = {
        "name": flights.name,
        "windows": result.windows,
        "flights": flights.n_flights,
        "flights_with_type": with_type,
        "flown_types": flown,
        "rows": result.summary(),
        "large_vertical": large_vertical_deviations(flights, result),
    }
    return flights, result, entry


def _words(action: str, given: dict[str, Any]) -> list[str]:
    """The command line of ``realtraffic ACTION`` (program name left out) with the options in ``given`` (None: absent), paths cleaned."""
    from bluesky_gym.realtraffic.report import clean_path

    words = ["realtraffic", action]
    for flag, value in given.items():
        if value is None or value is False:
            continue
        words.append(flag)
        if value is True:
            continue
        values = value if isinstance(value, list) else [value]
        words.extend(clean_path(v) if isinstance(v, Path) or _is_path(v) else str(v) for v in values)
    return words


def _is_path(value: Any) -> bool:
    text = str(value)
    return "/" in text or text.endswith((".npz", ".zip"))


def _write_json(path: Path, doc: dict[str, Any]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(doc, indent=2) + "\n", encoding="utf-8")


def run_prepare(args: argparse.Namespace) -> int:
    """Run ``realtraffic prepare``."""
    from bluesky_gym.realtraffic.cache import collection_path
    from bluesky_gym.realtraffic.sources import Progress, load_sample, load_table

    try:
        if args.sample:
            out = args.out or collection_path(args.sample, args.cache_dir)
            flights = load_sample(args.sample, consistency=not args.no_consistency, progress=Progress(args.sample))
        else:
            if args.out is None:
                raise ValueError("--table needs --out FILE.npz")
            out = args.out
            flights = load_table(args.table, consistency=not args.no_consistency, progress=Progress(str(args.table)))
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
    import bluesky_gym
    from bluesky_gym.core.aircraft import supported_types
    from bluesky_gym.realtraffic.fidelity import format_markdown
    from bluesky_gym.realtraffic.report import clean_path, command_line, fidelity_document

    results, entries = [], []
    actype = args.type.strip().upper() if args.type else None
    try:
        if actype is not None and actype not in supported_types():
            raise ValueError(f"--type {args.type}: not a type BlueSky flies with OpenAP data (e.g. A320, B738, B744)")
        names = _collections(args)
        for name in names:
            _, result, entry = _replay(name, args.windows, args.cache_dir, actype)
            results.append(result)
            entries.append(entry)
    except (MissingDependencyError, ValueError) as exc:
        print(f"bluesky-gym realtraffic: error: {exc}", file=sys.stderr)
        return 2
    print(format_markdown(results))
    windows = ", ".join(f"{r.collection}: {r.windows} windows" for r in results)
    flown = f"every aircraft flown as the {actype}" if actype else "every aircraft with its recorded type (BlueSky's B744 where missing or unknown)"
    print(f"\n{windows} of 20 minutes, nobody acting, {flown}")
    if args.json:
        shown = [clean_path(n) if _is_path(n) else n for n in names]
        words = _words("fidelity", {"--collections": names, "--windows": args.windows, "--type": actype, "--json": args.json})
        inputs = {"collections": shown, "windows": args.windows, "window_minutes": FIDELITY_WINDOW_S / 60.0, "type": actype}
        _write_json(args.json, fidelity_document(command_line(words), bluesky_gym.__version__, inputs, entries))
    return 0


def run_stats(args: argparse.Namespace) -> int:
    """Run ``realtraffic stats``."""
    import gymnasium as gym

    import bluesky_gym
    from bluesky_gym.envs.registry import entry
    from bluesky_gym.realtraffic.report import clean_path, command_line, stats_document, stats_lines
    from bluesky_gym.training.evaluation import evaluate, load_policy
    from bluesky_gym.training.policies import Policy, reference_policy

    bluesky_gym.register_envs()

    rows = []
    models: list[str] = list(args.model or [])
    try:
        names = _collections(args)
        for name in names:
            space = gym.make("RealTrafficCREnv-v0", collections=(name,), cache_dir=args.cache_dir).action_space
            # fresh per collection: the random policy's generator restarts
            low, high = np.asarray(getattr(space, "low")), np.asarray(getattr(space, "high"))  # noqa: B009 - a Box
            # rows: random, classical, then one per algorithm of the models (its seeds averaged)
            acting: dict[str, list[Policy]] = {
                p: [reference_policy(p, "RealTrafficCREnv-v0", low, high)] for p in entry("RealTrafficCREnv-v0").reference_policies
            }
            trained: dict[str, list[Policy]] = {}
            for path in models:
                loaded = load_policy(path)
                trained.setdefault(type(loaded.model).__name__, []).append(loaded)
            acting.update({algo if len(ms) == 1 else f"{algo} ({len(ms)} seeds)": ms for algo, ms in trained.items()})
            flights, replay, _ = _replay(name, args.windows, args.cache_dir)
            row: dict[str, Any] = {
                "collection": flights.name,
                "flights": flights.n_flights,
                "aircraft_hours": round(flights.flight_hours(), 1),
                "conflicts_per_flight_hour": round(replay.conflicts_per_flight_hour, 3),
                "policies": {},
            }
            options = {"collections": (name,), "split": "test", "cache_dir": args.cache_dir}
            for label, members in acting.items():
                kpis = []
                for member in members:
                    res = evaluate("RealTrafficCREnv-v0", member, args.episodes, env_options=options)
                    s = res.summary
                    route = [float(e.get("kpi_mean_route_deviation_nm", "nan")) for e in res.episodes]
                    kpis.append(
                        {
                            "return": s["return"]["mean"],
                            "los_per_episode": s["los"]["mean"],
                            "min_separation_nm": s["min_sep_nm"]["mean"],
                            "route_deviation_nm": float(np.nanmean(route)) if route else float("nan"),
                        }
                    )
                row["policies"][label] = {key: float(np.mean([k[key] for k in kpis])) for key in kpis[0]}
            rows.append(row)
    except (MissingDependencyError, ValueError, FileNotFoundError) as exc:
        print(f"bluesky-gym realtraffic: error: {exc}", file=sys.stderr)
        return 2
    print("\n".join(stats_lines(rows)))
    if args.json:
        model = [clean_path(m) for m in models] if models else None
        given = {"--collections": names, "--windows": args.windows, "--episodes": args.episodes, "--model": models or None, "--json": args.json}
        inputs = {
            "collections": [clean_path(n) if _is_path(n) else n for n in names],
            "windows": args.windows,
            "episodes": args.episodes,
            "model": model,
        }
        _write_json(args.json, stats_document(command_line(_words("stats", given)), bluesky_gym.__version__, inputs, rows))
    return 0


def run_report(args: argparse.Namespace) -> int:
    """Run ``realtraffic report``."""
    from bluesky_gym.realtraffic.report import ReportError, blocks_in, fill, render_blocks

    pages = args.pages or [Path("README.md"), Path("docs/realtraffic.md")]
    stale = []
    try:
        blocks = render_blocks(args.directory)
        for page in pages:
            if not page.is_file():
                raise ReportError(f"{page}: no such page")
            text = page.read_text(encoding="utf-8")
            names = blocks_in(text)
            if not names:
                raise ReportError(f"{page}: no <!-- realtraffic:NAME --> block to fill")
            new = fill(text, blocks, str(page))
            if new == text:
                print(f"{page}: up to date ({', '.join(names)})")
                continue
            stale.append(page)
            if args.check_only:
                print(f"{page}: differs from what {args.directory} gives ({', '.join(names)})")
            else:
                page.write_text(new, encoding="utf-8")
                print(f"{page}: wrote {', '.join(names)}")
    except ReportError as exc:
        print(f"bluesky-gym realtraffic: error: {exc}", file=sys.stderr)
        return 2
    return 1 if (args.check_only and stale) else 0
