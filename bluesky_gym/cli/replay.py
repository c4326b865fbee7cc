"""``bluesky-gym replay``: play BlueSky scenario files (``.scn``) on the core and write the trajectories.

Examples::

    bluesky-gym replay --list                                           # the shipped geometries
    bluesky-gym replay super8 --duration 900 --out super8.csv           # a shipped geometry, or a path
    bluesky-gym replay super8 wall6 --copies 100 --duration 600         # 200 airspaces in one batch
    bluesky-gym replay super8 --duration 600 --out bs.csv --backend bluesky

Every scenario (each file, each copy) flies in its own airspace of one batch. The CSV has one row
per aircraft per step with the columns, units (SI) and timing of the BlueSky reference recordings:
row ``t=0`` is the state after the commands at time 0 (creation and the rest), and a command at
time ``t`` acts in the step that starts at the first multiple of ``dt`` at or after ``t``. With
several scenarios a first column ``scenario`` names the file (``name#k`` for copy ``k``).
A file name that does not exist is looked up among the shipped geometries.
"""

from __future__ import annotations

import argparse
import csv
import sys
import time
from pathlib import Path
from typing import Any

from bluesky_gym.cli.arguments import positive_float, positive_int

#: BlueSky 1.1.1's cost of one simulated second [s] with a few aircraft (about 1 ms per step of 1 s;
#: ``--backend bluesky`` measures it on this machine); used only for the speed-up estimate of the summary.
BLUESKY_SECONDS_PER_SIM_SECOND = 1.0e-3
#: Seconds between progress lines.
PROGRESS_INTERVAL = 2.0


def add_parser(subparsers: Any) -> None:
    """Register the ``replay`` subcommand."""
    p = subparsers.add_parser(
        "replay",
        help="play BlueSky .scn scenario files and write the trajectories as CSV",
        description=__doc__,
    )
    p.add_argument("files", nargs="*", metavar="FILE.scn", help="scenario files (or names of shipped geometries)")
    p.add_argument("--dt", type=positive_float, help="time step [s] (default: the files' DT, else 1)")
    p.add_argument("--duration", type=positive_float, help="simulated time [s] (default: the last command's time + 60)")
    p.add_argument("--out", type=Path, metavar="TRAJ.csv", help="trajectory CSV (default: none, only the summary)")
    p.add_argument("--copies", type=positive_int, default=1, metavar="N", help="airspaces per file (default: 1)")
    p.add_argument("--backend", choices=("native", "bluesky"), default="native", help="physics backend (default: native)")
    p.add_argument("--list", action="store_true", help="list the shipped scenario geometries and exit")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.set_defaults(func=run)


def _resolve(name: str) -> Path:
    from bluesky_gym.scenarios.geometries import shipped_scenario

    path = Path(name)
    return path if path.exists() else shipped_scenario(name)


def run(args: argparse.Namespace) -> int:
    """Run the ``replay`` subcommand."""
    from bluesky_gym.scenarios import ScenarioError
    from bluesky_gym.scenarios.geometries import shipped_scenarios

    if args.list:
        for path in shipped_scenarios():
            print(path.name)
        return 0
    if not args.files:
        print("bluesky-gym replay: error: give at least one FILE.scn (or --list)", file=sys.stderr)
        return 2
    try:
        return _replay(args)
    except (ScenarioError, FileNotFoundError) as exc:
        print(f"bluesky-gym replay: error: {exc}", file=sys.stderr)
        return 2
    except ImportError as exc:
        print(f"bluesky-gym replay: error: {exc}", file=sys.stderr)
        return 2


def _replay(args: argparse.Namespace) -> int:
    from bluesky_gym.scenarios import ScenarioError, read_scenario
    from bluesky_gym.scenarios.player import ScenarioPlayer, common_dt, slots_needed, waypoints_needed

    files = [read_scenario(_resolve(f)) for f in args.files]
    scenarios = [s for s in files for _ in range(args.copies)]
    names = [name if args.copies == 1 else f"{name}#{k}" for name in args.files for k in range(args.copies)]
    dt = common_dt(files, args.dt)
    duration = args.duration if args.duration is not None else max(s.end_time for s in files) + 60.0
    n_steps = int(round(duration / dt))
    if abs(n_steps * dt - duration) > 1e-9 * max(1.0, duration):
        raise ScenarioError(f"--duration {duration:g} s is not a whole number of steps of {dt:g} s")
    max_aircraft = max(1, *(slots_needed(s) for s in files))
    max_waypoints = max(4, *(waypoints_needed(s) for s in files))
    log = (lambda s: None) if args.quiet else (lambda s: print(s, file=sys.stderr))

    writer = None
    out_file = None
    if args.out is not None:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        out_file = open(args.out, "w", newline="")  # noqa: SIM115 - closed below
        writer = csv.writer(out_file)
        columns = ["t", "acid", *_columns()[2:]]
        writer.writerow((["scenario"] if len(scenarios) > 1 else []) + columns)
    start = time.perf_counter()
    sim_wall = 0.0
    try:
        if args.backend == "native":
            from bluesky_gym.core import Simulator

            warm = Simulator(1, 1, dt=dt)  # compile (or load) the kernels before the clock starts
            warm.create(0, 0)
            warm.run(2)
            sim = Simulator(len(scenarios), max_aircraft, dt=dt, max_waypoints=max_waypoints)
            player = ScenarioPlayer(scenarios, sim)
            sim_wall += _play(player, n_steps, dt, writer, names, len(scenarios) > 1, log, start)
        else:
            from bluesky_gym.backends.bluesky_sim import BlueSkyPhysics

            bsim = BlueSkyPhysics(max_aircraft, dt=dt, max_waypoints=max_waypoints)
            try:
                for k, s in enumerate(scenarios):
                    bsim.reset_envs()
                    player = ScenarioPlayer([s], bsim)
                    sim_wall += _play(player, n_steps, dt, writer, [names[k]], len(scenarios) > 1, log, start)
            finally:
                bsim.close()
    finally:
        if out_file is not None:
            out_file.close()
    wall = time.perf_counter() - start
    aircraft = sum(len(s.callsigns) for s in scenarios)
    simulated = n_steps * dt * len(scenarios)
    log(
        f"replayed {len(scenarios)} scenario(s), {aircraft} aircraft, {n_steps} steps of {dt:g} s on the {args.backend} backend "
        f"in {wall:.2f} s wall ({sim_wall:.2f} s simulating)"
    )
    rate = simulated / max(sim_wall, 1e-9)
    line = f"{rate:,.0f} simulated seconds per wall second (all airspaces)"
    if args.backend == "native":
        line += f"; about {rate * BLUESKY_SECONDS_PER_SIM_SECOND:,.1f}x BlueSky's ~1 ms per simulated second (measure it with --backend bluesky)"
    log(line)
    if args.out is not None:
        log(f"wrote {args.out}")
    return 0


def _columns() -> tuple[str, ...]:
    from bluesky_gym.scenarios.player import TRAJECTORY_COLUMNS

    return TRAJECTORY_COLUMNS


def _time_value(k: int, dt: float) -> float | int:
    t = k * dt
    return int(t) if float(t).is_integer() else t


def _play(player: Any, n_steps: int, dt: float, writer: Any, names: list[str], prefix: bool, log: Any, start: float) -> float:
    """Run one player for ``n_steps`` steps, writing rows when ``writer`` is given; returns the time spent simulating [s]."""
    spent = 0.0
    last = time.perf_counter()

    def write(k: int) -> None:
        rows = player.snapshot(_time_value(k, dt))
        if prefix:
            envs = player.scenario_of_rows()
            rows = [[names[e], *r] for e, r in zip(envs, rows)]
        writer.writerows(rows)

    if writer is None:
        t = time.perf_counter()
        chunk = max(1, n_steps // 20)
        done = 0
        while done < n_steps:
            k = min(chunk, n_steps - done)
            player.advance(k)
            done += k
            now = time.perf_counter()
            if now - last > PROGRESS_INTERVAL:
                log(f"  t = {done * dt:g} / {n_steps * dt:g} s ({100 * done / n_steps:.0f}%), {now - start:.1f} s wall")
                last = now
        return time.perf_counter() - t
    write(0)
    for k in range(1, n_steps + 1):
        t = time.perf_counter()
        player.step()
        spent += time.perf_counter() - t
        write(k)
        now = time.perf_counter()
        if now - last > PROGRESS_INTERVAL:
            log(f"  t = {k * dt:g} / {n_steps * dt:g} s ({100 * k / n_steps:.0f}%), {now - start:.1f} s wall")
            last = now
    return spent
