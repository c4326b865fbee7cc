"""The scale benchmark: N aircraft flown for a simulated time, with and without conflict detection and resolution.

``bluesky-gym bench scale`` flies the same seeded random traffic (:func:`scale_scenario`) on the
native core and, up to :data:`BLUESKY_MAX_AIRCRAFT` aircraft by default, on the real BlueSky 1.1.1
in its own interpreter, side by side: once without conflict detection, once with BlueSky's
compiled state-based detection and MVP resolution (``ASAS CSTATEBASED``, ``RESO MVP``), DT 1 s.
Each figure is the wall-clock time of the flight alone (creating the traffic and compiling the
kernels are not timed), on one core.

The traffic has the same density whatever N: A320s at random positions spread evenly over an area of
:data:`AREA_PER_AIRCRAFT` per aircraft (a band of latitude around the equator, as square as it
can be within :data:`MAX_LATITUDE`), random headings, cruising level at random altitudes between
:data:`ALT_RANGE` and random CAS in :data:`CAS_RANGE`.
"""

from __future__ import annotations

import json
import math
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from bluesky_gym.benchmarks.external import run_worker
from bluesky_gym.core import Simulator
from bluesky_gym.core.resolution import AsasConfig
from bluesky_gym.core.units import R_EARTH

#: Aircraft counts of the default run.
AIRCRAFT_COUNTS: tuple[int, ...] = (1000, 10000)
DEFAULT_SIM_TIME = 600.0  # s of simulated flight
DT = 1.0  # s, the simulation step (BlueSky's ASAS interval: detection and resolution every step)
#: Largest aircraft count flown on BlueSky by default (its conflict detection is O(n^2)).
BLUESKY_MAX_AIRCRAFT = 1000
AREA_PER_AIRCRAFT = 2500.0e6  # m^2: one aircraft per 50 km x 50 km
MAX_LATITUDE = 60.0  # deg, the traffic's band of latitude reaches at most this far from the equator
ALT_RANGE = (8000.0, 11500.0)  # m
CAS_RANGE = (120.0, 150.0)  # m/s
SEED = 0
#: The issue's targets: the core at least this many times BlueSky at 1000 aircraft with CD&R, and
#: 100,000 aircraft for one simulated hour with CD&R in under this many seconds.
TARGET_VS_BLUESKY = 100.0
TARGET_100K_HOUR_S = 600.0

Array = NDArray[np.float64]
Say = Callable[[str], None] | None


@dataclass(frozen=True)
class ScaleScenario:
    """The initial traffic, one entry per aircraft: latitude, longitude, heading [deg], altitude [m], CAS [m/s]."""

    lat: Array
    lon: Array
    hdg: Array
    alt: Array
    cas: Array

    def rows(self) -> list[list[float]]:
        """The aircraft as ``[lat, lon, hdg, alt, cas]`` lists (what the BlueSky worker creates)."""
        rows: list[list[float]] = np.stack((self.lat, self.lon, self.hdg, self.alt, self.cas), axis=1).tolist()
        return rows


def scale_scenario(n_aircraft: int, seed: int = SEED) -> ScaleScenario:
    """The benchmark traffic of ``n_aircraft`` aircraft (see the module docstring).

    Positions are uniform on the sphere within a band ``|lat| <= L`` and ``|lon| <= W/2``, where
    ``L`` makes the area as square as it can (at most :data:`MAX_LATITUDE`) and ``W`` gives the
    area ``n_aircraft * AREA_PER_AIRCRAFT``.

    Raises:
        ValueError: ``n_aircraft`` below 1, or so many that the band would pass once round the earth.
    """
    if n_aircraft < 1:
        raise ValueError(f"n_aircraft must be >= 1, got {n_aircraft}")
    area = n_aircraft * AREA_PER_AIRCRAFT
    half_lat = min(0.5 * math.sqrt(area) / R_EARTH, math.radians(MAX_LATITUDE))
    width = area / (R_EARTH * R_EARTH * 2.0 * math.sin(half_lat))  # rad of longitude
    if width >= 2.0 * math.pi:
        raise ValueError(f"{n_aircraft} aircraft do not fit the benchmark's density below {MAX_LATITUDE} deg of latitude")
    rng = np.random.default_rng(seed)
    n = n_aircraft
    s = math.sin(half_lat)
    return ScaleScenario(
        lat=np.degrees(np.arcsin(rng.uniform(-s, s, n))),
        lon=np.degrees(rng.uniform(-0.5 * width, 0.5 * width, n)),
        hdg=rng.uniform(0.0, 360.0, n),
        alt=rng.uniform(*ALT_RANGE, n),
        cas=rng.uniform(*CAS_RANGE, n),
    )


def core_flight(scenario: ScaleScenario, sim_time: float, cdr: bool, pair_search: str = "auto") -> dict[str, Any]:
    """Fly the traffic on the native core for ``sim_time`` simulated seconds.

    Returns:
        ``wall_s`` (the flight alone), ``steps``, ``pair_search`` (what the simulator chose) and
        ``conflicts`` (the pairs being resolved at the end; 0 without CD&R).

    Raises:
        RuntimeError: An aircraft left the valid state.
    """
    n = scenario.lat.size
    sim = Simulator(1, n, dt=DT, pair_search=pair_search)
    sim.create(0, np.arange(n), scenario.lat, scenario.lon, scenario.hdg, scenario.alt, scenario.cas)
    if cdr:
        sim.set_conflict_resolution(0, AsasConfig(detector="CSTATEBASED", resolution=True))
    steps = round(sim_time / DT)
    start = time.perf_counter()
    sim.run(steps)
    wall = time.perf_counter() - start
    if not np.all(sim.active) or not np.all(np.isfinite(sim.lat)):
        raise RuntimeError("the benchmark traffic left the valid state (inactive slot or non-finite position)")
    pairs = int(sim._reso_keys.size + np.count_nonzero(sim._reso_pairs)) if cdr else 0
    return {"wall_s": wall, "steps": steps, "pair_search": sim.pair_search, "conflicts": pairs}


def warm_up() -> None:
    """Compile (or load) every kernel the flights use, so that no flight times the compilation."""
    sc = scale_scenario(8)
    for pair_search in ("all-pairs", "grid"):
        for cdr in (False, True):
            core_flight(sc, 3.0, cdr, pair_search)


def bluesky_flights(python: str, scenario: ScaleScenario, sim_time: float, timeout: float) -> dict[str, Any]:
    """Fly the traffic on the real BlueSky in ``python``, without and with CD&R.

    Returns:
        The worker's result (``versions``, ``results``: ``{"cdr": bool, "wall_s": ...}`` per flight),
        or ``{"error": ...}``.
    """
    with tempfile.TemporaryDirectory(prefix="bluesky-gym-scale-") as tmp:
        path = Path(tmp) / "aircraft.json"
        path.write_text(json.dumps(scenario.rows()), encoding="utf-8")
        config = {"aircraft_file": str(path), "sim_time": sim_time, "dt": DT, "cdr": [False, True]}
        return run_worker(python, "bluesky-scale", config, timeout)


def run_scale(
    aircraft_counts: Sequence[int] = AIRCRAFT_COUNTS,
    sim_time: float = DEFAULT_SIM_TIME,
    bluesky_python: str | None = None,
    bluesky_max_aircraft: int = BLUESKY_MAX_AIRCRAFT,
    progress: Say = None,
) -> dict[str, Any]:
    """Run the scale benchmark.

    Args:
        aircraft_counts: Numbers of aircraft (one airspace each).
        sim_time: Simulated time of each flight [s].
        bluesky_python: Interpreter with BlueSky 1.1.1, or None to fly the core alone.
        bluesky_max_aircraft: Largest count flown on BlueSky.
        progress: Optional callable taking a one-line status message.

    Returns:
        ``{"rows": [...], "settings": {...}}``; each row has ``aircraft``, ``cdr``,
        ``sim_time_s``, ``core_wall_s``, ``bluesky_wall_s`` (None where BlueSky was not flown or
        failed), and ``pair_search``, ``conflicts`` and ``bluesky_error`` (None or the failure).
    """
    say = progress or (lambda _msg: None)
    say("scale: compiling the kernels")
    warm_up()
    rows: list[dict[str, Any]] = []
    for n in aircraft_counts:
        scenario = scale_scenario(n)
        bluesky: dict[bool, float] = {}
        error = None
        if bluesky_python and n <= bluesky_max_aircraft:
            say(f"scale: BlueSky, {n} aircraft, {sim_time:g} s without and with CD&R")
            result = bluesky_flights(bluesky_python, scenario, sim_time, timeout=120.0 + 0.05 * n * sim_time)
            if "error" in result:
                error = str(result["error"])
            else:
                bluesky = {bool(r["cdr"]): float(r["wall_s"]) for r in result["results"]}
        for cdr in (False, True):
            say(f"scale: core, {n} aircraft, {sim_time:g} s {'with' if cdr else 'without'} CD&R")
            core = core_flight(scenario, sim_time, cdr)
            rows.append(
                {
                    "aircraft": n,
                    "cdr": cdr,
                    "sim_time_s": sim_time,
                    "core_wall_s": core["wall_s"],
                    "bluesky_wall_s": bluesky.get(cdr),
                    "pair_search": core["pair_search"],
                    "conflicts": core["conflicts"],
                    "bluesky_error": error,
                }
            )
    settings = {
        "dt": DT,
        "seed": SEED,
        "area_per_aircraft_km2": AREA_PER_AIRCRAFT / 1e6,
        "alt_range_m": list(ALT_RANGE),
        "cas_range_ms": list(CAS_RANGE),
        "detection": "CSTATEBASED",
        "resolution": "MVP",
        "bluesky_max_aircraft": bluesky_max_aircraft,
    }
    return {"rows": rows, "settings": settings}


def format_scale(result: dict[str, Any]) -> str:
    """The scale benchmark as a text table."""
    lines = [
        f"{'aircraft':>9} {'CD&R':>5} {'sim time':>9} {'core wall':>10} {'BlueSky wall':>13} {'core/BlueSky':>13} {'pairs':>6}",
    ]
    for r in result["rows"]:
        bs = r["bluesky_wall_s"]
        ratio = f"{bs / r['core_wall_s']:.0f}x" if bs is not None and r["core_wall_s"] > 0 else "-"
        lines.append(
            f"{r['aircraft']:>9} {'on' if r['cdr'] else 'off':>5} {r['sim_time_s']:>8g}s {r['core_wall_s']:>9.2f}s "
            f"{'-' if bs is None else f'{bs:.2f}s':>13} {ratio:>13} {r['conflicts']:>6}"
        )
    errors = sorted({r["bluesky_error"] for r in result["rows"] if r["bluesky_error"]})
    lines.extend(f"BlueSky failed: {e}" for e in errors)
    lines.append(
        f"targets: core >= {TARGET_VS_BLUESKY:.0f}x BlueSky at 1000 aircraft with CD&R; "
        f"100,000 aircraft, 1 h with CD&R < {TARGET_100K_HOUR_S / 60:.0f} min (one core; 'pairs': pairs being resolved at the end)"
    )
    return "\n".join(lines)


def _seconds(x: float) -> str:
    if x < 1.0:
        return f"{x:.2f} s"
    if x < 100.0:
        return f"{x:.1f} s"
    return f"{x:.0f} s ({x / 60.0:.1f} min)"


def format_scale_markdown(results: Sequence[dict[str, Any]]) -> str:
    """The rows of one or more scale benchmark results as one Markdown table (docs/backends.md)."""
    lines = ["| aircraft | CD&R | simulated time | core wall | BlueSky wall | core / BlueSky |", "|---:|:---:|---:|---:|---:|---:|"]
    for result in results:
        for r in result["rows"]:
            t = float(r["sim_time_s"])
            sim = f"{t / 3600.0:g} h" if t % 3600.0 == 0.0 else f"{t:g} s"
            bs = r["bluesky_wall_s"]
            ratio = f"{bs / r['core_wall_s']:.0f}x" if bs is not None else ""
            cells = [f"{r['aircraft']:,}", "on" if r["cdr"] else "off", sim, _seconds(r["core_wall_s"]), "-" if bs is None else _seconds(bs), ratio]
            lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)
