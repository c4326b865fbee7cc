"""Recorded ADS-B data in, :class:`~bluesky_gym.realtraffic.flights.RecordedFlights` out, cleaned with the ``traffic`` library.

Two sources: the sample collections that the ``traffic`` package ships (no network access), and
users' own tables (CSV or Parquet) with the columns time, callsign, lat, lon, altitude,
groundspeed, track, vertical_rate and, optionally, typecode and icao24. Both go through the same
cleaning, done by the library's own tools:

1. ``Traffic.clean_invalid()`` (faulty callsigns and repeated positions, where the data has them);
2. ``Traffic.assign_id()``: one identifier per flight, separating flights that reuse a callsign;
3. per flight: ground segments dropped (``query("not onground")`` where the data has the flag,
   and samples below :data:`MIN_ALTITUDE_FT`), ``filter()`` (the default spike filter), and
   ``filter(FilterConsistency())`` where the altitude still jumps (a glitch the default filter left),
   ``split(GAP)`` at gaps in reception, ``resample()`` to one sample every
   :data:`~bluesky_gym.realtraffic.flights.SAMPLE_PERIOD` seconds;
4. route points: ``simplify()`` (Douglas-Peucker on the 3-D track, tolerance
   :data:`SIMPLIFY_TOLERANCE_M`).

Steps 3 and 4 are computed by :mod:`bluesky_gym.realtraffic.cleaning`: the library's methods on
the arrays of each flight, with the same results, several times faster than through the
library's per-flight objects; a flight that module does not take is cleaned by the library's
methods themselves (``reference=True`` cleans every flight so, for comparison). A
:class:`Progress` says what is being done: the steps, the time the cleaning is expected to take,
then the flights cleaned, the rate and the time left.

Units are converted to SI here, at the edge (ft, kt, ft/min in; m, m/s out).
"""

from __future__ import annotations

import sys
import time
import warnings
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any, TextIO

import numpy as np

from bluesky_gym.core.extras import missing_extra
from bluesky_gym.core.units import FPM, FT, KTS
from bluesky_gym.realtraffic import cleaning
from bluesky_gym.realtraffic.flights import SAMPLE_PERIOD, UNKNOWN_TYPE, RecordedFlights

#: The extra that installs the ``traffic`` library.
EXTRA = "realtraffic"
#: Sample collections of the ``traffic`` package used as episode data (airliner traffic).
SAMPLE_COLLECTIONS = ("switzerland", "quickstart")
#: Columns of a user table, and the ``traffic`` column each becomes.
TABLE_COLUMNS = {
    "time": "timestamp",
    "callsign": "callsign",
    "lat": "latitude",
    "lon": "longitude",
    "altitude": "altitude",
    "groundspeed": "groundspeed",
    "track": "track",
    "vertical_rate": "vertical_rate",
}
OPTIONAL_COLUMNS = {"typecode": "typecode", "icao24": "icao24"}
#: Alternative spellings accepted for the table columns.
COLUMN_ALIASES = {"timestamp": "time", "latitude": "lat", "longitude": "lon"}

MIN_ALTITUDE_FT = 1000.0  # ft: samples below are treated as ground / airport surface segments
GAP = "2 min"  # a flight is split where no position was received for longer
GAP_S = 120  # s, the same
MIN_DURATION_S = 300.0  # s: shorter flight segments are dropped
SIMPLIFY_TOLERANCE_M = 1000.0  # m: Douglas-Peucker tolerance of the route points
SIMPLIFY_Z_FACTOR = 3.048  # traffic's default weight of altitude [ft] against distance [m]
MAX_GROUNDSPEED_KT = 700.0  # kt: a segment faster than this is a decoding error
MAX_PLAUSIBLE_VS_FPM = 8000.0  # ft/min: a flight whose filtered altitude changes faster has a glitch left
#: Expected time of the flight loop: seconds per flight and per airborne position, from both sample
#: collections on a 2-core machine (switzerland 3-8 s, quickstart 12 s, depending on the load).
#: Long flights the consistency filter takes cost more (a month of calibration flights, all of them
#: circling, about 8 times more); the progress lines report the rate actually reached.
SECONDS_PER_FLIGHT = 0.001
SECONDS_PER_POSITION = 0.00005


class Progress:
    """Says what a cleaning is doing: each step as it starts, the expected time, then the flights cleaned.

    Args:
        name: The collection (or file) named in every line.
        out: Where the lines go (default: standard output), flushed at once.
        every_s: Seconds between two progress lines of the flight loop.
        clock: Seconds, monotonic (a test passes its own).
    """

    def __init__(self, name: str, out: TextIO | None = None, every_s: float = 5.0, clock: Callable[[], float] = time.monotonic) -> None:
        self.name = name
        self.out = out
        self.every_s = every_s
        self.clock = clock
        self.total = 0
        self.started = self.last = clock()

    def say(self, text: str) -> None:
        """Print one line about the collection."""
        print(f"bluesky-gym: {self.name}: {text}", file=self.out or sys.stdout, flush=True)

    def step(self, text: str) -> None:
        """A step that may take a few seconds starts."""
        self.say(f"{text}...")

    def start(self, flights: int, positions: int) -> None:
        """The flight loop starts: say how long it is expected to take."""
        self.total = flights
        self.started = self.last = self.clock()
        expected = SECONDS_PER_FLIGHT * flights + SECONDS_PER_POSITION * positions
        self.say(f"cleaning {flights} flights ({positions:,} positions), expected to take about {_duration(expected)}")

    def advance(self, done: int) -> None:
        """``done`` flights of the total are cleaned; a line every ``every_s`` seconds: count, share, rate, time left."""
        now = self.clock()
        if now - self.last < self.every_s or done >= self.total:
            return
        self.last = now
        elapsed = max(now - self.started, 1e-9)
        rate = done / elapsed
        left = (self.total - done) / rate if rate > 0 else float("inf")
        self.say(f"{done}/{self.total} flights cleaned ({100.0 * done / self.total:.0f}%), {rate:.1f} flights/s, about {_duration(left)} left")

    def finish(self, kept: int) -> None:
        """The flight loop is done."""
        elapsed = self.clock() - self.started
        self.say(f"{self.total} flights cleaned in {_duration(elapsed)}: {kept} flight segments kept")


class Quiet(Progress):
    """A :class:`Progress` that says nothing."""

    def say(self, text: str) -> None:
        """Say nothing."""


def _duration(seconds: float) -> str:
    """``seconds`` in words: "40 s", "3.5 min", "1.2 h"."""
    if seconds != seconds or seconds == float("inf"):
        return "an unknown time"
    if seconds < 90:
        return f"{max(seconds, 1.0):.0f} s"
    if seconds < 5400:
        return f"{seconds / 60:.1f} min"
    return f"{seconds / 3600:.1f} h"


def require_traffic() -> Any:
    """Import the ``traffic`` library, or raise :class:`~bluesky_gym.core.extras.MissingDependencyError` naming the extra."""
    try:
        import traffic.core
    except ImportError as exc:
        raise missing_extra(f"recorded traffic needs the 'traffic' library ({exc})", EXTRA) from exc
    return traffic.core


def load_sample(name: str, consistency: bool = True, progress: Progress | None = None) -> RecordedFlights:
    """A sample collection shipped by the ``traffic`` package, cleaned (no network access).

    Args:
        name: One of :data:`SAMPLE_COLLECTIONS` (or another ``traffic.data.samples`` collection).
        consistency: Also apply the library's consistency filter to flights with an altitude glitch left (see :func:`clean`).
        progress: Says what is being done (default: nothing).
    """
    progress = progress or Quiet(name)
    progress.step("reading the traffic sample collection")
    require_traffic()
    import traffic.data.samples as samples

    try:
        raw = getattr(samples, name)
    except (AttributeError, RuntimeError) as exc:
        raise ValueError(f"unknown traffic sample collection {name!r}; the environments use {', '.join(SAMPLE_COLLECTIONS)}") from exc
    return clean(raw, name, consistency, progress=progress)


def load_table(path: str | Path, name: str | None = None, consistency: bool = True, progress: Progress | None = None) -> RecordedFlights:
    """A user's ADS-B table (``.csv`` or ``.parquet``), cleaned.

    Columns: time (ISO 8601 or POSIX seconds, UTC), callsign, lat, lon [deg], altitude [ft],
    groundspeed [kt], track [deg], vertical_rate [ft/min]; optional typecode (ICAO type code) and
    icao24. ``timestamp``, ``latitude`` and ``longitude`` are accepted for time, lat and lon.

    Raises:
        ValueError: naming the file (and line, for a bad value) when the table is not usable.
    """
    core = require_traffic()
    import pandas as pd

    path = Path(path)
    if not path.exists():
        raise ValueError(f"{path}: no such file")
    progress = progress or Quiet(str(path))
    progress.step("reading the table")
    suffix = path.suffix.lower()
    if suffix == ".csv":
        df = pd.read_csv(path, dtype={"callsign": str, "icao24": str, "typecode": str})
        first_line = 2  # line 1 is the header
    elif suffix in (".parquet", ".pq"):
        df = pd.read_parquet(path)
        first_line = 1
    else:
        raise ValueError(f"{path}: unsupported table format {suffix!r}; use .csv or .parquet")
    df = df.rename(columns={k: v for k, v in COLUMN_ALIASES.items() if k in df.columns and v not in df.columns})
    missing = [c for c in TABLE_COLUMNS if c not in df.columns]
    if missing:
        raise ValueError(f"{path}: missing column(s) {missing}; a table needs {list(TABLE_COLUMNS)} (optional: {list(OPTIONAL_COLUMNS)})")
    if len(df) == 0:
        raise ValueError(f"{path}: the table has no rows")
    for col in ("lat", "lon", "altitude", "groundspeed", "track", "vertical_rate"):
        values = pd.to_numeric(df[col], errors="coerce")
        bad = np.flatnonzero(values.isna().to_numpy() & df[col].notna().to_numpy())
        if bad.size:
            raise ValueError(f"{path}:{first_line + int(bad[0])}: column {col!r} is not a number: {df[col].iloc[int(bad[0])]!r}")
        df[col] = values
    time = df["time"]
    if pd.api.types.is_numeric_dtype(time):
        stamps = pd.to_datetime(time, unit="s", utc=True, errors="coerce")
    else:
        stamps = pd.to_datetime(time, utc=True, errors="coerce", format="ISO8601")
    bad = np.flatnonzero(stamps.isna().to_numpy())
    if bad.size:
        raise ValueError(f"{path}:{first_line + int(bad[0])}: column 'time' is not a time: {time.iloc[int(bad[0])]!r}")
    df["time"] = stamps
    for col, lo, hi in (("lat", -90.0, 90.0), ("lon", -180.0, 180.0)):
        bad = np.flatnonzero(((df[col] < lo) | (df[col] > hi)).to_numpy())
        if bad.size:
            raise ValueError(f"{path}:{first_line + int(bad[0])}: {col} {df[col].iloc[int(bad[0])]} outside [{lo}, {hi}]")
    df = df.rename(columns={**TABLE_COLUMNS, **OPTIONAL_COLUMNS})
    df["callsign"] = df["callsign"].astype(str).str.strip()
    if "icao24" not in df.columns:
        df["icao24"] = df["callsign"]
    return clean(core.Traffic(df), name or path.stem, consistency, progress=progress)


def clean(raw: Any, name: str, consistency: bool = True, progress: Progress | None = None, reference: bool = False) -> RecordedFlights:
    """Clean a ``traffic.Traffic`` (or ``Flight``) with the library's tools and convert it (see the module docstring).

    Args:
        raw: The recorded trajectories.
        name: Collection name.
        consistency: Flights whose altitude still changes faster than :data:`MAX_PLAUSIBLE_VS_FPM`
            after the default filter are filtered again with the library's ``FilterConsistency``
            (which keeps the longest mutually consistent sequence of samples; about a tenth of
            the flights of the samples).
        progress: Says what is being done (default: nothing).
        reference: Clean every flight through the library's own per-flight methods (slow; what
            :mod:`bluesky_gym.realtraffic.cleaning` is compared with).
    """
    core = require_traffic()
    progress = progress or Quiet(name)
    traffic = raw if isinstance(raw, core.Traffic) else core.Traffic(raw.data)
    progress.step("identifying the flights (clean_invalid, assign_id)")
    traffic = traffic.clean_invalid()
    if "flight_id" not in traffic.data.columns:
        traffic = traffic.assign_id().eval()
    if traffic is None or len(traffic.data) == 0:
        raise ValueError(f"{name}: no flights left after cleaning")
    epoch = traffic.data["timestamp"].min().floor("h")
    data = _airborne(traffic.data)
    columns: cleaning.Columns | None = None
    if not reference:
        try:
            columns = cleaning.Columns.of(data)
        except cleaning.NotForArrays:
            columns = None
    groups = cleaning.flight_rows(columns) if columns is not None else [np.asarray(r) for _, r in sorted(data.groupby("flight_id").indices.items())]
    kernels = cleaning.default_kernels(columns) if columns is not None else {}
    flights: list[dict[str, Any]] = []
    progress.start(len(groups), len(data))
    with warnings.catch_warnings():
        # Two known, harmless notices of the library: its consistency filter falls back from the
        # optional graph-tool to NetworkX (slower, same result), and Douglas-Peucker divides by the
        # zero length of a stretch that returns to its start (it then splits that stretch instead).
        warnings.filterwarnings("ignore", message="graph-tool library not installed", category=UserWarning)
        warnings.filterwarnings("ignore", message="invalid value encountered in divide", category=RuntimeWarning, module="traffic")
        for done, rows in enumerate(groups, 1):
            try:
                if columns is None:
                    raise cleaning.NotForArrays("the library's methods")
                flights += _clean_arrays(columns, rows, kernels, int(epoch.value), consistency)
            except cleaning.NotForArrays:
                flight = core.Flight(data.iloc[rows])
                flights += [_arrays(segment, epoch) for segment in _clean_flight(flight, consistency)]
            progress.advance(done)
    progress.finish(len(flights))
    if not flights:
        raise ValueError(f"{name}: no flight of at least {MIN_DURATION_S:.0f} s above {MIN_ALTITUDE_FT:.0f} ft left after cleaning")
    flights.sort(key=lambda f: (f["t0"], f["flight_id"]))
    return _concatenate(flights, name, epoch.isoformat())


def _airborne(data: Any) -> Any:
    """The positions :func:`_clean_flight`'s queries keep, for every flight at once (they are row by row)."""
    if "onground" in data.columns:
        data = data.query("not onground")
    return data.query(f"altitude >= {MIN_ALTITUDE_FT} and groundspeed > 0 and groundspeed < {MAX_GROUNDSPEED_KT}")


def _clean_arrays(
    columns: cleaning.Columns, rows: Any, kernels: dict[str, tuple[int, ...]], epoch_ns: int, consistency: bool
) -> list[dict[str, Any]]:
    """:func:`_clean_flight` and :func:`_arrays` of one flight, on its arrays (:mod:`bluesky_gym.realtraffic.cleaning`).

    Raises:
        cleaning.NotForArrays: The flight is one for the library's methods (nothing is returned for it then).
    """
    if len(rows) < 3:
        return []
    ts = columns.ts[rows]
    if np.any(np.diff(ts) <= 0):
        raise cleaning.NotForArrays("timestamps not strictly increasing")
    values = cleaning.sigma_median_filter({k: v[rows] for k, v in columns.values.items()}, kernels)
    if consistency and cleaning.altitude_glitch(ts, values["altitude"], MAX_PLAUSIBLE_VS_FPM):
        values = cleaning.consistency_filter(columns, rows, values)
    out = []
    for lo, hi in cleaning.split(ts, GAP_S * cleaning.NS):
        if (ts[hi - 1] - ts[lo]) / cleaning.NS < MIN_DURATION_S:
            continue
        times, resampled = cleaning.resample(ts[lo:hi], {k: v[lo:hi] for k, v in values.items()}, int(SAMPLE_PERIOD))
        if any(np.isnan(resampled[c]).any() for c in cleaning.REQUIRED):
            raise cleaning.NotForArrays("a resampled column with gaps")
        if (times[-1] - times[0]) / cleaning.NS < MIN_DURATION_S:
            continue
        wp = cleaning.route_points(resampled, columns.arrow, SIMPLIFY_TOLERANCE_M, SIMPLIFY_Z_FACTOR)
        text = cleaning.text_of(columns, rows[lo:hi])
        flight = cleaning.si_arrays(times, resampled, wp, epoch_ns)
        flight["callsign"] = str(text["callsign"] or "")
        flight["icao24"] = str(text["icao24"] or "")
        flight["typecode"] = str(text["typecode"]).strip().upper() if text["typecode"] is not None else UNKNOWN_TYPE
        flight["flight_id"] = str(text["flight_id"] or text["callsign"])
        out.append(flight)
    return out


def _clean_flight(flight: Any, consistency: bool = True) -> Iterable[Any]:
    """The airborne, filtered, resampled segments of one flight, with their route points."""
    if "onground" in flight.data.columns:
        flight = flight.query("not onground")
    if flight is None:
        return
    flight = flight.query(f"altitude >= {MIN_ALTITUDE_FT} and groundspeed > 0 and groundspeed < {MAX_GROUNDSPEED_KT}")
    if flight is None or len(flight.data) < 3:
        return
    flight = flight.filter()
    if consistency and _altitude_glitch(flight):
        from traffic.algorithms.filters.consistency import FilterConsistency

        flight = flight.filter(FilterConsistency())
    for segment in flight.split(GAP):
        if segment.duration.total_seconds() < MIN_DURATION_S:
            continue
        resampled = segment.resample(f"{int(SAMPLE_PERIOD)}s")
        data = resampled.data
        keep = data[["latitude", "longitude", "altitude", "groundspeed", "track"]].notna().all(axis=1)
        if not keep.all():
            # keep the longest run of complete samples (interpolation leaves NaN only at the ends)
            runs = np.split(np.arange(len(data)), np.flatnonzero(np.diff(keep.to_numpy().astype(int)) != 0) + 1)
            best = max((r for r in runs if keep.iloc[r[0]]), key=len, default=None)
            if best is None or len(best) < 2:
                continue
            resampled = resampled.__class__(data.iloc[best])
        if resampled.duration.total_seconds() < MIN_DURATION_S:
            continue
        simplified = resampled.simplify(SIMPLIFY_TOLERANCE_M, altitude="altitude", z_factor=SIMPLIFY_Z_FACTOR)
        yield resampled, simplified


def _altitude_glitch(flight: Any) -> bool:
    """Whether the altitude changes faster than :data:`MAX_PLAUSIBLE_VS_FPM` between two samples."""
    data = flight.data
    dt = data["timestamp"].diff().dt.total_seconds().to_numpy()[1:]
    dz = np.abs(np.diff(data["altitude"].to_numpy(dtype=float)))
    ok = dt > 0
    return bool(np.any(dz[ok] / dt[ok] * 60.0 > MAX_PLAUSIBLE_VS_FPM))


def _arrays(pair: tuple[Any, Any], epoch: Any) -> dict[str, Any]:
    """One resampled flight and its simplification as SI arrays."""
    flight, simplified = pair
    data = flight.data.reset_index(drop=True)
    times = data["timestamp"]
    t = (times - epoch).dt.total_seconds().to_numpy()
    keep_times = set(simplified.data["timestamp"])
    wp = np.flatnonzero(times.isin(keep_times).to_numpy())
    wp = np.union1d(wp, [0, len(data) - 1]).astype(np.int64)
    vs = data["vertical_rate"].to_numpy(dtype=float) if "vertical_rate" in data.columns else np.full(len(data), np.nan)
    vs = np.nan_to_num(vs, nan=0.0)
    typecode = (
        str(data["typecode"].dropna().iloc[0]).strip().upper() if "typecode" in data.columns and data["typecode"].notna().any() else UNKNOWN_TYPE
    )
    return {
        "t0": float(t[0]),
        "lat": data["latitude"].to_numpy(dtype=float),
        "lon": data["longitude"].to_numpy(dtype=float),
        "alt": data["altitude"].to_numpy(dtype=float) * FT,
        "gs": data["groundspeed"].to_numpy(dtype=float) * KTS,
        "trk": data["track"].to_numpy(dtype=float) % 360.0,
        "vs": vs * FPM,
        "wp": wp,
        "callsign": str(flight.callsign or ""),
        "icao24": str(flight.icao24 or ""),
        "typecode": typecode,
        "flight_id": str(flight.flight_id or flight.callsign),
    }


def _concatenate(flights: list[dict[str, Any]], name: str, epoch: str) -> RecordedFlights:
    counts = [len(f["lat"]) for f in flights]
    ids = [f["flight_id"] for f in flights]
    seen: dict[str, int] = {}
    for i, fid in enumerate(ids):  # split segments of one flight get distinct ids
        n = seen.get(fid, 0)
        seen[fid] = n + 1
        if n:
            ids[i] = f"{fid}.{n}"
    return RecordedFlights(
        name=name,
        epoch=epoch,
        period=SAMPLE_PERIOD,
        t0=np.array([f["t0"] for f in flights]),
        offset=np.concatenate([[0], np.cumsum(counts)]).astype(np.int64),
        lat=np.concatenate([f["lat"] for f in flights]),
        lon=np.concatenate([f["lon"] for f in flights]),
        alt=np.concatenate([f["alt"] for f in flights]),
        gs=np.concatenate([f["gs"] for f in flights]),
        trk=np.concatenate([f["trk"] for f in flights]),
        vs=np.concatenate([f["vs"] for f in flights]),
        wp_offset=np.concatenate([[0], np.cumsum([len(f["wp"]) for f in flights])]).astype(np.int64),
        wp_index=np.concatenate([f["wp"] for f in flights]).astype(np.int64),
        callsign=np.array([f["callsign"] for f in flights], dtype=np.str_),
        icao24=np.array([f["icao24"] for f in flights], dtype=np.str_),
        typecode=np.array([f["typecode"] for f in flights], dtype=np.str_),
        flight_id=np.array(ids, dtype=np.str_),
    )
