"""``bluesky-gym replay``: play BlueSky scenario files (``.scn``) on the core and write the trajectories.

Examples::

    bluesky-gym replay --list                                           # the shipped geometries
    bluesky-gym replay super8 --duration 900 --out super8.csv           # a shipped geometry, or a path
    bluesky-gym replay super8 wall6 --copies 100 --duration 600         # 200 airspaces in one batch
    bluesky-gym replay super8 --duration 600 --out bs.csv --backend bluesky

Every scenario (each file, each copy) flies in its own airspace of one batch. The CSV has one row
per aircraft per step with the columns, units (SI) and timing of the BlueSky reference recordings:
row ``t=0`` is the state after the commands at time 0 (creation and the rest), and a command at
time ``t`` acts in the step that starts at the first multiple of ``dt`` at or after ``t``. The last
columns are the performance outputs ``thrust`` [N], ``drag`` [N] and ``fuelflow`` [kg/s]. With
several scenarios a first column ``scenario`` names the file (``name#k`` for copy ``k``).
A file name that does not exist is looked up among the shipped geometries.

Without ``--duration`` a replay runs to the last command's time plus 60 s, rounded up to a whole
step. More than ``--max-steps`` steps (default 1,000,000) are refused, and so is a file without
commands (empty, or only comments); a file that creates no aircraft, and every aircraft type
BlueSky does not know (it flies as the B744, as in BlueSky), get a warning. The summary counts
the time numba spends compiling its kernels or loading them from its cache apart from the
simulation.
"""

from __future__ import annotations

import argparse
import csv
import math
import sys
import time
import warnings
from pathlib import Path
from typing import Any

from bluesky_gym.cli.arguments import positive_float, positive_int, warn

#: BlueSky 1.1.1's cost of one simulated second [s] with a few aircraft (about 1 ms per step of 1 s;
#: ``--backend bluesky`` measures it on this machine); used only for the speed-up estimate of the summary.
BLUESKY_SECONDS_PER_SIM_SECOND = 1.0e-3
#: Seconds between progress lines.
PROGRESS_INTERVAL = 2.0
#: Simulated time after the last command when no ``--duration`` is given [s].
DEFAULT_TAIL = 60.0
#: Default of ``--max-steps``: a replay of more steps is refused (a ``DT 1e-9`` would take days).
MAX_STEPS = 1_000_000
#: The command's name in its messages.
PROG = "bluesky-gym replay"


def add_parser(subparsers: Any) -> None:
    """Register the ``replay`` subcommand."""
    p = subparsers.add_parser(
        "replay",
        help="play BlueSky .scn scenario files and write the trajectories as CSV",
        description=__doc__,
    )
    p.add_argument("files", nargs="*", metavar="FILE.scn", help="scenario files (or names of shipped geometries)")
    p.add_argument("--dt", type=positive_float, help="time step [s] (default: the files' DT, else 1)")
    p.add_argument(
        "--duration",
        type=positive_float,
        help="simulated time [s], a whole number of steps (default: the last command's time + 60, rounded up to a whole step)",
    )
    p.add_argument("--out", type=Path, metavar="TRAJ.csv", help="trajectory CSV (default: none, only the summary)")
    p.add_argument("--copies", type=positive_int, default=1, metavar="N", help="airspaces per file (default: 1)")
    p.add_argument(
        "--max-steps", type=positive_int, default=MAX_STEPS, metavar="N", help=f"refuse to play more steps than this (default: {MAX_STEPS:,})"
    )
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
        print(f"{PROG}: error: give at least one FILE.scn (or --list)", file=sys.stderr)
        return 2
    try:
        return _replay(args)
    except (ScenarioError, FileNotFoundError) as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 2
    except ImportError as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 2


def _time_step_origin(files: list[Any], given: float | None) -> str:
    """Where the replay's time step comes from, in the words of the command line or the file."""
    from bluesky_gym.scenarios.parser import TimeStep

    if given is not None:
        return f"--dt {given:g}"
    for s in files:
        for c in s.commands:
            if isinstance(c, TimeStep):
                return f"DT in {c.source}"
    return "the default time step"


def _step_count(files: list[Any], args: argparse.Namespace, dt: float) -> int:
    """The number of steps to play: ``--duration`` (a whole number of steps), else the last command's time + 60 s rounded up.

    Raises:
        ScenarioError: ``--duration`` is not a whole number of steps, or the steps exceed ``--max-steps``.
    """
    from bluesky_gym.scenarios import ScenarioError

    origin = _time_step_origin(files, args.dt)
    if args.duration is not None:
        n_steps = int(round(args.duration / dt))
        if abs(n_steps * dt - args.duration) > 1e-9 * max(1.0, args.duration):
            raise ScenarioError(f"--duration {args.duration:g} s is not a whole number of steps of {dt:g} s ({origin})")
        what = f"--duration {args.duration:g} s"
    else:
        end = max(s.end_time for s in files)
        exact = (end + DEFAULT_TAIL) / dt
        n_steps = int(round(exact))
        if abs(n_steps - exact) > 1e-9 * max(1.0, exact):
            n_steps = math.ceil(exact)  # rounded up to a whole step
        what = f"the default duration ({end:g} s, the last command's time, + {DEFAULT_TAIL:g} s)"
    if n_steps > args.max_steps:
        raise ScenarioError(
            f"{what} in steps of {dt:g} s ({origin}) is {n_steps:,} steps, more than --max-steps {args.max_steps:,}; "
            "give a larger time step, a shorter --duration or a larger --max-steps"
        )
    return n_steps


class _CompileClock:
    """Seconds spent compiling numba kernels or loading them from numba's cache, measured as numba reports them.

    numba announces every compilation and cache load with a ``numba:compiler_lock`` event (its
    public event API); the replay counts that time apart from the simulation. Zero without numba.
    """

    def __init__(self) -> None:
        self._event: Any = None
        self._listener: Any = None
        try:
            from numba.core import event
        except ImportError:  # pragma: no cover - numba is a dependency
            return
        self._event = event
        self._listener = event.TimingListener()
        event.register("numba:compiler_lock", self._listener)

    @property
    def seconds(self) -> float:
        """Compilation and cache-loading time so far [s] (until :meth:`close`)."""
        return float(self._listener.duration) if self._listener is not None and self._listener.done else 0.0

    def close(self) -> None:
        """Stop measuring; :attr:`seconds` keeps its value."""
        if self._event is not None:
            self._event.unregister("numba:compiler_lock", self._listener)
            self._event = None


def _replay(args: argparse.Namespace) -> int:
    from bluesky_gym.scenarios import ScenarioError, read_scenario
    from bluesky_gym.scenarios.player import (
        ScenarioPlayer,
        UnknownAircraftTypeWarning,
        common_dt,
        slots_needed,
        unknown_type_message,
        unknown_types,
        waypoints_needed,
    )

    files = [read_scenario(_resolve(f)) for f in args.files]
    for s in files:
        if not s.commands:
            raise ScenarioError(f"{s.name}: no commands (the file is empty or holds only comments and blank lines); nothing to replay")
        if not s.callsigns:
            warn(PROG, f"{s.name}: creates no aircraft; its trajectories are empty")
    scenarios = [s for s in files for _ in range(args.copies)]
    names = [name if args.copies == 1 else f"{name}#{k}" for name in args.files for k in range(args.copies)]
    dt = common_dt(files, args.dt)
    n_steps = _step_count(files, args, dt)
    for actype, source in unknown_types(files).items():
        warn(PROG, unknown_type_message(actype, source))
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
    clock = _CompileClock()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UnknownAircraftTypeWarning)  # warned above, once per type
            if args.backend == "native":
                from bluesky_gym.core import Simulator

                sim = Simulator(len(scenarios), max_aircraft, dt=dt, max_waypoints=max_waypoints)
                player = ScenarioPlayer(scenarios, sim)
                sim_wall += _play(player, n_steps, dt, writer, names, len(scenarios) > 1, log, start, clock)
            else:
                from bluesky_gym.backends.bluesky_sim import BlueSkyPhysics

                bsim = BlueSkyPhysics(max_aircraft, dt=dt, max_waypoints=max_waypoints)
                try:
                    for k, s in enumerate(scenarios):
                        bsim.reset_envs()
                        player = ScenarioPlayer([s], bsim)
                        sim_wall += _play(player, n_steps, dt, writer, [names[k]], len(scenarios) > 1, log, start, clock)
                finally:
                    bsim.close()
    finally:
        clock.close()
        if out_file is not None:
            out_file.close()
    wall = time.perf_counter() - start
    aircraft = sum(len(s.callsigns) for s in scenarios)
    simulated = n_steps * dt * len(scenarios)
    compiling = f"{clock.seconds:.2f} s compiling or loading the numba kernels, " if clock.seconds > 0.0 else ""
    log(
        f"replayed {len(scenarios)} scenario(s), {aircraft} aircraft, {n_steps} steps of {dt:g} s on the {args.backend} backend "
        f"in {wall:.2f} s wall ({compiling}{sim_wall:.2f} s simulating)"
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


def _play(player: Any, n_steps: int, dt: float, writer: Any, names: list[str], prefix: bool, log: Any, start: float, clock: _CompileClock) -> float:
    """Run one player for ``n_steps`` steps, writing rows when ``writer`` is given; returns the time spent simulating [s].

    The time numba spends compiling or loading kernels during the steps (``clock``) is not simulating.

    Raises:
        ScenarioError: An aircraft's state is not finite at the end.
    """
    spent = 0.0
    last = time.perf_counter()

    def write(k: int) -> None:
        rows = player.snapshot(_time_value(k, dt))
        if prefix:
            envs = player.scenario_of_rows()
            rows = [[names[e], *r] for e, r in zip(envs, rows)]
        writer.writerows(rows)

    if writer is None:
        t, compiled = time.perf_counter(), clock.seconds
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
        spent = time.perf_counter() - t - (clock.seconds - compiled)
        player.check_finite(_time_value(n_steps, dt))
        return spent
    write(0)
    for k in range(1, n_steps + 1):
        t, compiled = time.perf_counter(), clock.seconds
        player.step()
        spent += time.perf_counter() - t - (clock.seconds - compiled)
        write(k)
        now = time.perf_counter()
        if now - last > PROGRESS_INTERVAL:
            log(f"  t = {k * dt:g} / {n_steps * dt:g} s ({100 * k / n_steps:.0f}%), {now - start:.1f} s wall")
            last = now
    player.check_finite(_time_value(n_steps, dt))
    return spent
