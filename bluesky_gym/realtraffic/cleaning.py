"""The per-flight cleaning of :mod:`bluesky_gym.realtraffic.sources`, computed on numpy arrays.

The ``traffic`` library cleans a collection flight by flight, each step building pandas frames
and ``Flight`` objects: cleaning a sample collection took minutes, mostly in that per-flight
Python (pandas' pure-Python fallback for the string columns of a resampling, a PROJ database
search per flight for the projection of the Douglas-Peucker simplification), and, for the few
flights the consistency filter takes, in NetworkX building and searching a graph of up to
hundreds of thousands of edges in Python.

This module computes the same steps, with the same formulas and the same numpy, scipy, PROJ and
library functions in the same order, on the arrays of one flight: the library's default filter
(``FilterAboveSigmaMedian``, then a backward and a forward fill), its ``split``, its
``resample`` (first value of each bin, linear interpolation, the track unwrapped) and its
``simplify``; the consistency filter runs the library's own ``FilterConsistency`` with the
longest path of its exact solver computed by :func:`longest_consistent_path`, NetworkX's
Bellman-Ford (SPFA) step for step, compiled. The results are the library's bit for bit (the tests
compare them on excerpts of both sample collections). A flight that does not fit what this
module expects (timestamps not strictly increasing, several callsigns, a column without data) is
left to the library's own methods (:func:`bluesky_gym.realtraffic.sources.clean` does that).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from bluesky_gym.core.jit import jit
from bluesky_gym.core.units import FPM, FT, KTS

Array = NDArray[np.float64]
IntArray = NDArray[np.int64]

#: The numeric columns carried through the cleaning (the ``traffic`` names).
NUMERIC = ("latitude", "longitude", "altitude", "groundspeed", "track", "vertical_rate")
#: Columns that must be present (``vertical_rate`` may be missing: it then reads 0).
REQUIRED = NUMERIC[:5]
#: The per-flight text columns (one value per flight, or none).
TEXT = ("callsign", "icao24", "flight_id", "typecode")
NS = 1_000_000_000  # nanoseconds per second


class NotForArrays(Exception):
    """A flight (or collection) this module does not clean; the library's methods do."""


@dataclass
class Columns:
    """The columns of a collection as numpy arrays, and what the library's filters need to know of their types.

    Attributes:
        ts: (rows,) timestamps [ns since 1970, UTC].
        values: Numeric columns as float64 (NaN where missing), by ``traffic`` name.
        numpy_numeric: Names of the numeric columns of a numpy dtype (the default filter's
            features; the library ignores pyarrow-backed columns there).
        arrow: Names of the numeric columns backed by pyarrow (their mean is pyarrow's).
        codes: Text columns factorised: (rows,) codes, -1 where missing.
        uniques: The values of the codes.
        timestamp: The original timestamp column (the consistency filter reads it as the library would).
    """

    ts: IntArray
    values: dict[str, Array]
    numpy_numeric: frozenset[str]
    arrow: frozenset[str]
    codes: dict[str, IntArray]
    uniques: dict[str, Any]
    timestamp: Any

    @classmethod
    def of(cls, data: Any) -> Columns:
        """The columns of a pandas frame of recorded positions (``traffic`` column names).

        Raises:
            NotForArrays: The frame does not fit (a column missing, timestamps not in UTC, NaN
                values in a pyarrow column, where the library tells NaN from missing).
        """
        import pandas as pd

        missing = [c for c in (*REQUIRED, "timestamp", "flight_id") if c not in data.columns]
        if missing:
            raise NotForArrays(f"columns {missing} missing")
        stamp = data["timestamp"]
        if str(getattr(stamp.dt, "tz", None)) != "UTC":
            raise NotForArrays("timestamps not in UTC")
        ts = np.ascontiguousarray(stamp.astype("datetime64[ns, UTC]").astype("int64").to_numpy(dtype=np.int64))
        values: dict[str, Array] = {}
        numpy_numeric, arrow = set(), set()
        for name in NUMERIC:
            if name not in data.columns:
                continue
            column = data[name]
            values[name] = np.ascontiguousarray(column.astype(float).to_numpy(dtype=np.float64))
            if column.dtype in [np.float32, np.float64, np.int32, np.int64]:  # the default filter's own test
                numpy_numeric.add(name)
            if isinstance(column.dtype, pd.ArrowDtype):
                arrow.add(name)
                if int(np.isnan(values[name]).sum()) != int(column.isna().sum()):
                    raise NotForArrays(f"NaN values in the pyarrow column {name!r}")
        codes: dict[str, IntArray] = {}
        uniques: dict[str, Any] = {}
        for name in TEXT:
            if name in data.columns:
                c, u = pd.factorize(data[name], use_na_sentinel=True)
                codes[name], uniques[name] = np.asarray(c, dtype=np.int64), u
        return cls(ts, values, frozenset(numpy_numeric), frozenset(arrow), codes, uniques, stamp)


def flight_rows(columns: Columns) -> list[IntArray]:
    """The rows of every flight (by ``flight_id``, in the library's iteration order: sorted ids), each in table order."""
    codes = columns.codes["flight_id"]
    order = np.argsort(np.asarray(columns.uniques["flight_id"]).astype(str), kind="stable")
    rank = np.empty(len(order), np.int64)
    rank[order] = np.arange(len(order))
    keep = codes >= 0
    rows = np.flatnonzero(keep)
    key = rank[codes[keep]]
    sort = np.argsort(key, kind="stable")
    ordered = rows[sort]
    bounds = np.flatnonzero(np.diff(key[sort])) + 1
    return np.split(ordered, bounds) if len(ordered) else []


# --- the default filter ---------------------------------------------------------------------------
def default_kernels(columns: Columns) -> dict[str, tuple[int, ...]]:
    """Kernel sizes of ``FilterAboveSigmaMedian()`` per carried column: its defaults, 17 for other numpy-typed numeric columns."""
    from traffic.algorithms.filters import FilterAboveSigmaMedian

    kernels: dict[str, tuple[int, ...]] = {name: (17,) for name in columns.values if name in columns.numpy_numeric}
    for name, sizes in FilterAboveSigmaMedian.default.items():
        if name in columns.values:
            kernels[name] = (sizes,) if isinstance(sizes, int) else tuple(sizes)
    return kernels


def sigma_median_filter(values: dict[str, Array], kernels: dict[str, tuple[int, ...]]) -> dict[str, Array]:
    """The library's default filter on one flight: samples far from the running median removed, then filled.

    A sample is removed where its squared deviation from the running median exceeds the running
    median of the squared deviations.

    ``FilterAboveSigmaMedian.cascaded_filters`` and ``apply``, then ``bfill().ffill()``.
    """
    from scipy import signal

    out = {}
    for name, y in values.items():
        y = y.copy()
        for size in kernels.get(name, ()):
            if size > len(y):
                continue
            y_m = signal.medfilt(y, size)
            sq_eps = (y - y_m) ** 2
            sigma = np.sqrt(signal.medfilt(sq_eps, size))
            y[sq_eps > sigma] = np.nan
        out[name] = fill_both_ways(y)
    return out


def fill_both_ways(y: Array) -> Array:
    """``bfill().ffill()``: every missing value takes the next present one, those after the last the last one."""
    missing = np.isnan(y)
    if not missing.any() or missing.all():
        return y
    n = len(y)
    nxt = np.where(missing, n, np.arange(n))
    nxt = np.minimum.accumulate(nxt[::-1])[::-1]
    out = y.copy()
    fill = missing & (nxt < n)
    out[fill] = y[nxt[fill]]
    last = int(np.flatnonzero(~missing)[-1])
    out[last + 1 :] = y[last]
    return out


def altitude_glitch(ts: IntArray, altitude: Array, max_vs_fpm: float) -> bool:
    """Whether the altitude changes faster than ``max_vs_fpm`` between two samples (the timestamps' ``diff().dt.total_seconds()``)."""
    dt = np.diff(ts) / NS
    dz = np.abs(np.diff(altitude))
    ok = dt > 0
    return bool(np.any(dz[ok] / dt[ok] * 60.0 > max_vs_fpm))


# --- the consistency filter -----------------------------------------------------------------------
def consistency_filter(columns: Columns, rows: IntArray, values: dict[str, Array]) -> dict[str, Array]:
    """The library's ``filter(FilterConsistency())`` on one flight (its exact solver's longest path compiled)."""
    import pandas as pd

    frame = pd.DataFrame({"timestamp": columns.timestamp.iloc[rows].reset_index(drop=True), **values})
    filtered = _consistency_class()().apply(frame.copy()).bfill().ffill()
    return {name: filtered[name].to_numpy(dtype=np.float64) for name in values}


_CLASS: type | None = None


def _consistency_class() -> type:
    """``FilterConsistency`` with the exact solver of :func:`exact_solver` (made once, the library imported on demand)."""
    global _CLASS
    if _CLASS is None:
        from traffic.algorithms.filters.consistency import FilterConsistency

        class Consistency(FilterConsistency):
            """The library's filter; its ``solve`` (traffic 2.13) calls :func:`consistency_solver`."""

            def solve(self, compute_dd: Any, data: Any, exact_when_kept_below: float, backup: bool = False) -> Any:
                n = data.shape[0]
                inhorizon = self.backup_horizon if backup else self.horizon
                horizon = n if inhorizon is None else min(inhorizon, n)
                dt = self.compute_dt(data, horizon)
                dd = compute_dd(data, dt, horizon)
                mask = consistency_solver(dd, exact_when_kept_below, self.backup_exact)
                if backup or not 1 - np.mean(mask) < exact_when_kept_below:
                    return mask
                return self.solve(compute_dd, data, exact_when_kept_below, True)

        _CLASS = Consistency
    return _CLASS


def consistency_solver(dd: NDArray[np.bool_], exact_when_kept_below: float, exact_backup: bool) -> NDArray[np.bool_]:
    """The library's ``consistency_solver`` with :func:`exact_solver`."""
    from traffic.algorithms.filters.consistency import approx_solver

    if exact_backup and exact_when_kept_below == 1:
        return exact_solver(dd)
    mask = approx_solver(dd)
    if exact_backup and 1 - np.mean(mask) < exact_when_kept_below:
        return exact_solver(dd)
    return mask


def exact_solver(dd: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """The library's ``exact_solver``: the points off the longest consistent path are removed.

    With graph-tool installed the library uses it (another path among equally long ones), so this
    does too; otherwise the path is NetworkX's, computed by :func:`longest_consistent_path`.
    """
    try:
        import graph_tool.all  # noqa: F401
    except ImportError:
        path = longest_consistent_path(np.ascontiguousarray(dd, dtype=np.bool_))
        res = np.full(dd.shape[1], True)
        res[path] = False
        return res
    from traffic.algorithms.filters.consistency import exact_solver as library_solver

    out: NDArray[np.bool_] = library_solver(dd)
    return out


def longest_consistent_path(dd: NDArray[np.bool_]) -> IntArray:
    """The points of the path ``traffic.algorithms.filters.consistency.get_nxlongest`` finds, without its first and last node.

    The library builds a NetworkX graph: point ``i`` to point ``i + h`` where ``dd[h, i]``
    (``h > 0``, in that order), a source before every point and a sink after, every edge of
    weight -1, and asks for the shortest path from the source to the sink with Bellman-Ford, whose
    first predecessors make the path. :func:`_spfa` runs NetworkX's algorithm (SPFA, ``networkx
    3``) on the same graph with its successors in the same order, so it finds the same path among
    equally long ones.
    """
    horizon, n = dd.shape
    if n == 0:
        return np.zeros(0, np.int64)
    beyond = np.nonzero(dd[1:])
    if beyond[0].size and int(np.max(beyond[0] + 1 + beyond[1])) >= n:
        raise NotForArrays("an edge past the last point")
    path = _spfa(dd)
    if path[0] < 0:
        raise NotForArrays("a predecessor list longer than the in-degree")
    return path


@jit
def _spfa(dd: NDArray[np.bool_]) -> IntArray:
    horizon, n = dd.shape
    source, sink = n + 1, n  # NetworkX's nodes -1 and n
    total = n + 2
    # predecessor lists: at most the in-degree of each node
    indeg = np.zeros(total, np.int64)
    for h in range(1, horizon):
        for i in range(n - h):
            if dd[h, i]:
                indeg[i + h] += 1
    for i in range(n):
        indeg[i] += 1  # from the source
    indeg[sink] = n + 1  # from every point and the source
    start = np.zeros(total + 1, np.int64)
    for v in range(total):
        start[v + 1] = start[v] + indeg[v]
    pred = np.empty(start[total], np.int64)
    plen = np.zeros(total, np.int64)
    inf = np.iinfo(np.int64).max
    dist = np.full(total, inf, np.int64)
    dist[source] = 0
    queue = np.empty(total, np.int64)
    in_q = np.zeros(total, np.bool_)
    succ = np.empty(max(horizon, n) + 2, np.int64)
    head, size = 0, 1
    queue[0] = source
    in_q[source] = True
    while size > 0:
        u = queue[head]
        head = (head + 1) % total
        size -= 1
        in_q[u] = False
        waiting = False
        for k in range(plen[u]):
            if in_q[pred[start[u] + k]]:
                waiting = True
                break
        if waiting:
            continue
        if u == sink:
            continue  # no successors
        # successors in NetworkX's order: the source's every point then the sink; a point's
        # consistent points i + h by increasing h, then the sink
        count = 0
        if u == source:
            for v in range(n + 1):
                succ[count] = v
                count += 1
        else:
            for h in range(1, horizon):
                if u + h >= n:
                    break
                if dd[h, u]:
                    succ[count] = u + h
                    count += 1
            succ[count] = sink
            count += 1
        du = dist[u]
        for k in range(count):
            v = succ[k]
            dv = du - 1
            if dv < dist[v]:
                if not in_q[v]:
                    queue[(head + size) % total] = v
                    size += 1
                    in_q[v] = True
                dist[v] = dv
                pred[start[v]] = u
                plen[v] = 1
            elif dist[v] != inf and dv == dist[v]:
                if plen[v] >= indeg[v]:
                    return np.full(1, -1, np.int64)
                pred[start[v] + plen[v]] = u
                plen[v] += 1
    # the first predecessors from the sink back to the source
    steps = 0
    node = sink
    while node != source:
        node = pred[start[node]]
        steps += 1
    out = np.empty(steps - 1, np.int64)
    node = pred[start[sink]]
    k = steps - 2
    while node != source:
        out[k] = node
        k -= 1
        node = pred[start[node]]
    return out


# --- split, resample, simplify --------------------------------------------------------------------
def split(ts: IntArray, gap_ns: int, lo: int = 0, hi: int | None = None) -> Iterator[tuple[int, int]]:
    """The library's ``split(gap)``: row ranges cut at the largest gap (recursively) while it is longer than ``gap_ns``; single rows dropped."""
    hi = len(ts) if hi is None else hi
    if hi - lo < 2:
        return
    d = np.diff(ts[lo:hi])
    k = int(np.argmax(d))
    if d[k] > gap_ns:
        yield from split(ts, gap_ns, lo, lo + k + 1)
        yield from split(ts, gap_ns, lo + k + 1, hi)
    else:
        yield lo, hi


def resample(ts: IntArray, values: dict[str, Array], period_s: int) -> tuple[IntArray, dict[str, Array]]:
    """The library's ``resample(f"{period_s}s")``: the first value of every bin, the empty bins interpolated linearly, the track unwrapped.

    Returns:
        The bin times [ns] and the resampled columns (``track`` from the unwrapped track, modulo 360).
    """
    step = period_s * NS
    bins = ts // step
    first_bin = int(bins[0])
    n = int(bins[-1]) - first_bin + 1
    index = bins - first_bin
    columns = dict(values)
    if "track" in columns:
        track = columns["track"]
        present = ~np.isnan(track)
        unwrapped = np.full(len(track), np.nan)
        unwrapped[present] = np.degrees(np.unwrap(np.radians(track[present])))
        columns["track_unwrapped"] = unwrapped
    out: dict[str, Array] = {}
    positions = np.arange(n)
    for name, y in columns.items():
        present = ~np.isnan(y)
        binned = np.full(n, np.nan)
        used, first = np.unique(index[present], return_index=True)
        binned[used] = y[present][first]
        out[name] = _interpolate(binned, positions)
    if "track" in out:
        out["track"] = out.pop("track_unwrapped") % 360
    times = (first_bin + positions) * step
    return times.astype(np.int64), out


def _interpolate(y: Array, positions: IntArray) -> Array:
    """The ``interpolate()`` of pandas (linear, forward): inner and trailing gaps filled by ``np.interp``, leading ones kept."""
    invalid = np.isnan(y)
    valid = ~invalid
    if not valid.any() or valid.all():
        return y
    y = y.copy()
    y[invalid] = np.interp(positions[invalid], positions[valid], y[valid])
    y[: int(np.argmax(valid))] = np.nan
    return y


def route_points(values: dict[str, Array], arrow: frozenset[str], tolerance_m: float, z_factor: float) -> IntArray:
    """The library's ``simplify(tolerance, altitude="altitude", z_factor)``: samples kept by its Douglas-Peucker on the 3-D track.

    The track is projected as the library does (a Lambert conformal conic projection centred on
    it, through PROJ), without its search of the PROJ database for every flight.
    """
    import pandas as pd
    import pyproj
    from traffic.algorithms.douglas_peucker import douglas_peucker

    lat, lon = values["latitude"], values["longitude"]

    def series(name: str) -> Any:
        return pd.Series(values[name], dtype="double[pyarrow]" if name in arrow else np.float64)

    s_lat, s_lon = series("latitude"), series("longitude")
    params = {"lat_1": s_lat.min(), "lat_2": s_lat.max(), "lat_0": s_lat.mean(), "lon_0": s_lon.mean()}
    lcc = " ".join(f"+{key}={value}" for key, value in params.items())
    pipeline = f"+proj=pipeline +step +proj=unitconvert +xy_in=deg +xy_out=rad +step +proj=lcc +ellps=WGS84 {lcc}"
    transformer = pyproj.Transformer.from_pipeline(pipeline)
    x, y = transformer.transform(lon, lat)
    mask = douglas_peucker(tolerance=tolerance_m, x=x, y=y, z=values["altitude"], z_factor=z_factor)
    return np.union1d(np.flatnonzero(mask), [0, len(lat) - 1]).astype(np.int64)


def si_arrays(times: IntArray, values: dict[str, Array], wp: IntArray, epoch_ns: int) -> dict[str, Any]:
    """The arrays of a cleaned flight in SI units (as :func:`bluesky_gym.realtraffic.sources._arrays` converts the library's)."""
    n = len(times)
    vs = values["vertical_rate"] if "vertical_rate" in values else np.full(n, np.nan)
    return {
        "t0": float(((times - epoch_ns) / NS)[0]),
        "lat": values["latitude"],
        "lon": values["longitude"],
        "alt": values["altitude"] * FT,
        "gs": values["groundspeed"] * KTS,
        "trk": values["track"] % 360.0,
        "vs": np.nan_to_num(vs, nan=0.0) * FPM,
        "wp": wp,
    }


def text_of(columns: Columns, rows: IntArray) -> dict[str, str | None]:
    """The one value of each text column over ``rows`` (None where it has none).

    Raises:
        NotForArrays: A column has several values there (the library would give a set).
    """
    out: dict[str, str | None] = {}
    for name in TEXT:
        if name not in columns.codes:
            out[name] = None
            continue
        codes = np.unique(columns.codes[name][rows])
        codes = codes[codes >= 0]
        if len(codes) > 1:
            raise NotForArrays(f"several values of {name}")
        out[name] = columns.uniques[name][int(codes[0])] if len(codes) else None
    return out
