"""Throughput of the simulation core: aircraft-sub-steps per second.

One aircraft-sub-step is one aircraft advanced by one simulation time step. The native core is
measured for every batch size (airspaces) and aircraft count asked for, with each available step
kernel; the real BlueSky is measured for one airspace (it has one simulator per process) with
the same aircraft counts, in another interpreter when needed.

The work is the same on both sides: A320s spread over about 200 km around 52°N 4°E at mixed
altitudes (1000-11000 m), CAS 120-140 m/s, level, with every third aircraft turning (it gets a
heading target 120° away, alternately left and right, before every timed block, so turns go
on throughout the measurement), DT 1 s, no wind, no conflict detection.

The mixed-fleet lines fly the same traffic with each aircraft of a type drawn from
:data:`MIXED_FLEET` (ten types from business jets to the B744), at the largest batch size.
"""

from __future__ import annotations

import inspect
import statistics
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from bluesky_gym.benchmarks.external import run_worker
from bluesky_gym.benchmarks.timing import combine, measure
from bluesky_gym.core import Simulator, jit

BATCH_SIZES: tuple[int, ...] = (1, 256, 4096)
AIRCRAFT_COUNTS: tuple[int, ...] = (1, 6, 20)
DT = 1.0  # s
TURN_ANGLE = 120.0  # deg, heading change commanded to the turning aircraft
TURN_EVERY = 3  # every third aircraft (slots 0, 3, 6, ...) turns
DEFAULT_SECONDS = 0.8  # time budget per cell [s]: the default run takes well under a minute
#: The issue's target: aircraft-sub-steps per second at 4096 airspaces x 20 aircraft, one core.
TARGET_RATE = 1.0e7
TARGET_CELL = (4096, 20)
TARGET_BLUESKY_RATIO = 400.0
#: Types of the mixed-fleet lines: narrow-body, wide-body, regional and business jets.
MIXED_FLEET: tuple[str, ...] = ("A320", "B738", "A321", "B744", "B772", "A332", "E190", "CRJ9", "C550", "GLF6")
MIXED_FLEET_SEED = 1

Array = NDArray[np.float64]


@dataclass(frozen=True)
class CoreScenario:
    """Initial aircraft states, each array shaped (airspaces, aircraft).

    Attributes:
        lat: Latitude [deg].
        lon: Longitude [deg].
        hdg: Heading [deg].
        alt: Altitude [m].
        cas: Calibrated airspeed [m/s].
        turn: Heading change of the turn commands [deg]; 0 for aircraft that fly straight.

    """

    lat: Array
    lon: Array
    hdg: Array
    alt: Array
    cas: Array
    turn: Array


def core_scenario(n_envs: int, n_aircraft: int, seed: int = 0) -> CoreScenario:
    """Build the benchmark traffic: mixed altitudes and speeds, every third aircraft turning.

    Args:
        n_envs: Number of airspaces.
        n_aircraft: Aircraft per airspace.
        seed: Seed of the generator.

    """
    rng = np.random.default_rng(seed)
    shape = (n_envs, n_aircraft)
    slot = np.arange(n_aircraft)
    turning = slot % TURN_EVERY == 0
    direction = np.where((slot // TURN_EVERY) % 2 == 0, 1.0, -1.0)
    turn = np.broadcast_to(np.where(turning, direction * TURN_ANGLE, 0.0), shape).copy()
    return CoreScenario(
        lat=52.0 + rng.uniform(-1.0, 1.0, shape),
        lon=4.0 + rng.uniform(-1.5, 1.5, shape),
        hdg=rng.uniform(0.0, 360.0, shape),
        alt=rng.uniform(1000.0, 11000.0, shape),
        cas=rng.uniform(120.0, 140.0, shape),
        turn=turn,
    )


def simulator_accepts_kernel() -> bool:
    """Tell whether :class:`~bluesky_gym.core.Simulator` takes a ``kernel`` argument."""
    return "kernel" in inspect.signature(Simulator).parameters


def make_simulator(n_envs: int, n_aircraft: int, kernel: str | None = None) -> Simulator:
    """Create a simulator of the benchmark size; ``kernel`` None means the simulator's default."""
    if kernel is not None and simulator_accepts_kernel():
        choice: dict[str, Any] = {"kernel": kernel}  # a Simulator with a choice of step kernels
        return Simulator(n_envs, n_aircraft, dt=DT, **choice)
    sim = Simulator(n_envs, n_aircraft, dt=DT)
    if kernel is not None and kernel != kernel_of(sim):
        raise ValueError(f"this Simulator has only the {kernel_of(sim)!r} kernel, cannot use {kernel!r}")
    return sim


def kernel_of(sim: Any) -> str:
    """Return the step kernel a simulator uses.

    A simulator with a choice names it (``sim.kernel``); one without runs its single step
    implementation, compiled with numba (``"compiled"``) or as plain Python without it (``"python"``).
    """
    kernel = getattr(sim, "kernel", None)
    if kernel is not None:
        return str(kernel)
    return "compiled" if jit.AVAILABLE else "python"


def available_kernels() -> list[str]:
    """List the kernels to benchmark: ``"numpy"`` where the simulator offers it, and the simulator's default."""
    default = kernel_of(Simulator(1, 1, dt=DT))
    kernels = ["numpy"] if simulator_accepts_kernel() else [default]
    if default not in kernels:
        kernels.append(default)
    return kernels


def populate(sim: Simulator, scenario: CoreScenario, fleet: Sequence[str] | None = None) -> tuple[NDArray[np.int64], NDArray[np.int64], Array]:
    """Create the scenario's aircraft in every airspace and command the first turns.

    Args:
        sim: The simulator.
        scenario: The traffic.
        fleet: Aircraft types to draw each aircraft's type from (None: every aircraft an A320).

    Returns:
        ``(env, slot, turn)`` of the turning aircraft, for :func:`recommand_turns`.

    """
    n_envs, n_aircraft = scenario.lat.shape
    env_grid, slot_grid = np.meshgrid(np.arange(n_envs), np.arange(n_aircraft), indexing="ij")
    env, slot = env_grid.ravel(), slot_grid.ravel()
    types: dict[str, Any] = {}
    if fleet is not None:
        types["actype"] = [fleet[i] for i in np.random.default_rng(MIXED_FLEET_SEED).integers(0, len(fleet), env.size)]
    sim.create(env, slot, scenario.lat.ravel(), scenario.lon.ravel(), scenario.hdg.ravel(), scenario.alt.ravel(), scenario.cas.ravel(), **types)
    turning = scenario.turn.ravel() != 0.0
    turns = (env[turning], slot[turning], scenario.turn.ravel()[turning])
    recommand_turns(sim, *turns)
    return turns


def recommand_turns(sim: Simulator, env: NDArray[np.int64], slot: NDArray[np.int64], turn: Array) -> None:
    """Give the turning aircraft a heading target ``turn`` degrees from their heading."""
    if env.size:
        sim.cmd_heading(env, slot, (sim.hdg[env, slot] + turn) % 360.0)


def native_core_rate(n_envs: int, n_aircraft: int, seconds: float, kernel: str | None = None, fleet: Sequence[str] | None = None) -> dict[str, Any]:
    """Measure aircraft-sub-steps per second of the native core for one batch size.

    Args:
        n_envs: Airspaces stepped together.
        n_aircraft: Aircraft per airspace.
        seconds: Time budget of the timed blocks [s].
        kernel: Step kernel (None: the simulator's default).
        fleet: Aircraft types of a mixed fleet (None: A320 only).

    Returns:
        The :func:`~bluesky_gym.benchmarks.timing.measure` result plus ``kernel``, ``envs``,
        ``aircraft`` and ``fleet`` (``"A320"`` or ``"mixed (N types)"``).

    """
    sim = make_simulator(n_envs, n_aircraft, kernel)
    turns = populate(sim, core_scenario(n_envs, n_aircraft), fleet)
    result: dict[str, Any] = measure(sim.step, float(n_envs * n_aircraft), seconds, between=lambda: recommand_turns(sim, *turns))
    if not np.all(sim.active) or not np.all(np.isfinite(sim.lat)):
        raise RuntimeError("the benchmark traffic left the valid state (inactive slot or non-finite position)")
    result.update(kernel=kernel_of(sim), envs=n_envs, aircraft=n_aircraft, fleet="A320" if fleet is None else f"mixed ({len(fleet)} types)")
    return result


def bluesky_core_rates(python: str, aircraft_counts: Sequence[int], seconds: float) -> dict[str, Any]:
    """Measure aircraft-sub-steps per second of the real BlueSky (one airspace) in ``python``.

    Returns:
        The worker's result (``versions`` and ``results``, one per aircraft count), or
        ``{"error": ...}``.

    """
    sets = []
    for n in aircraft_counts:
        sc = core_scenario(1, n)
        fields = (sc.lat[0], sc.lon[0], sc.hdg[0], sc.alt[0], sc.cas[0], sc.turn[0])
        sets.append([[float(v[i]) for v in fields] for i in range(n)])
    config = {"sets": sets, "seconds": seconds, "dt": DT}
    timeout = 90.0 + 5.0 * seconds * len(sets)
    result = run_worker(python, "bluesky-core", config, timeout)
    result["python"] = python
    return result


def run_core(
    batch_sizes: Sequence[int] = BATCH_SIZES,
    aircraft_counts: Sequence[int] = AIRCRAFT_COUNTS,
    kernels: Sequence[str] | None = None,
    seconds: float = DEFAULT_SECONDS,
    bluesky_python: str | None = None,
    progress: Any = None,
    repeats: int = 1,
) -> dict[str, Any]:
    """Run the whole core benchmark.

    With ``repeats`` > 1 the whole set of measurements (native cells, then BlueSky) is run that
    many times; each figure is the median over the runs and each ratio the median of the ratios
    measured within the same run.

    Args:
        batch_sizes: Numbers of airspaces of the native core.
        aircraft_counts: Aircraft per airspace.
        kernels: Step kernels of the native core (default: :func:`available_kernels`).
        seconds: Time budget per measurement [s].
        bluesky_python: Interpreter with the real BlueSky, or None to skip it.
        progress: Optional callable taking a one-line status message.
        repeats: Number of runs.

    Returns:
        ``{"native": [...], "mixed": [...], "bluesky": {...} | None, "target": {...}, "settings": {...}}``
        (``mixed``: the mixed-fleet cells, at the largest batch size).

    """
    kernels = list(kernels) if kernels else available_kernels()
    say = progress or (lambda _msg: None)
    runs: list[tuple[list[dict[str, Any]], dict[str, Any] | None]] = []
    mixed_runs: list[list[dict[str, Any]]] = []
    for rep in range(repeats):
        tag = f"run {rep + 1}/{repeats}: " if repeats > 1 else ""
        native = []
        mixed = []
        for kernel in kernels:
            for n_envs in batch_sizes:
                for n_ac in aircraft_counts:
                    say(f"core: {tag}{kernel} kernel, {n_envs} x {n_ac} aircraft")
                    native.append(native_core_rate(n_envs, n_ac, seconds, kernel))
            for n_ac in aircraft_counts:  # the same traffic as a mixed fleet, at the largest batch
                say(f"core: {tag}{kernel} kernel, {max(batch_sizes)} x {n_ac} aircraft, mixed fleet")
                mixed.append(native_core_rate(max(batch_sizes), n_ac, seconds, kernel, MIXED_FLEET))
        mixed_runs.append(mixed)
        bluesky = None
        if bluesky_python:
            say(f"core: {tag}BlueSky with {', '.join(map(str, aircraft_counts))} aircraft")
            bluesky = bluesky_core_rates(bluesky_python, aircraft_counts, seconds)
        bs_rate = {r["aircraft"]: r["rate"] for r in (bluesky or {}).get("results", [])}
        for row in native + mixed:
            base = bs_rate.get(row["aircraft"])
            row["vs_bluesky"] = row["rate"] / base if base else None
        runs.append((native, bluesky))

    native = []
    for i in range(len(runs[0][0])):
        cells = [run[0][i] for run in runs]
        row = combine(cells)
        ratios = [c["vs_bluesky"] for c in cells if c["vs_bluesky"] is not None]
        row["vs_bluesky"] = statistics.median(ratios) if ratios else None
        row["vs_bluesky_runs"] = ratios
        native.append(row)
    mixed = [combine([run[i] for run in mixed_runs]) for i in range(len(mixed_runs[0]))]
    bluesky = _combine_bluesky([run[1] for run in runs]) if bluesky_python else None
    return {
        "native": native,
        "mixed": mixed,
        "bluesky": bluesky,
        "target": {"envs": TARGET_CELL[0], "aircraft": TARGET_CELL[1], "rate": TARGET_RATE, "vs_bluesky": TARGET_BLUESKY_RATIO},
        "settings": {"dt": DT, "seconds": seconds, "repeats": repeats, "turn_angle": TURN_ANGLE, "turn_every": TURN_EVERY},
    }


def _combine_bluesky(runs: list[dict[str, Any] | None]) -> dict[str, Any] | None:
    """Median over runs of the BlueSky worker results (a failed run is skipped)."""
    good = [r for r in runs if r is not None and "error" not in r]
    if not good:
        return runs[0]
    out = dict(good[0])
    out["results"] = [combine([r["results"][i] for r in good]) for i in range(len(good[0]["results"]))]
    out["failed_runs"] = len(runs) - len(good)
    return out
