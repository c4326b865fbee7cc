"""Where the cleaned collections live, and how a collection is found, built once, and combined.

A collection is named either by a ``traffic`` sample (``"switzerland"``, ``"quickstart"``), which
is cleaned on first use (tens of seconds, with progress; needs the ``realtraffic`` extra) and saved in the cache
directory, or by the path of a ``.npz`` file written by ``bluesky-gym realtraffic prepare``
(:meth:`~bluesky_gym.realtraffic.flights.RecordedFlights.save`), which needs numpy only.

The cache directory is, in this order: the ``cache_dir`` argument (the environments' option of the
same name), the ``BLUESKY_GYM_CACHE`` environment variable, ``$XDG_CACHE_HOME/bluesky-gym``, and
``~/.cache/bluesky-gym`` (in the user's home directory).
"""

from __future__ import annotations

import os
from functools import lru_cache
from pathlib import Path

import numpy as np

from bluesky_gym.realtraffic.flights import FORMAT_VERSION, RecordedFlights
from bluesky_gym.realtraffic.scenario import Window

CACHE_ENV = "BLUESKY_GYM_CACHE"
GAP_BETWEEN_COLLECTIONS = 86400.0  # s: time put between combined collections (no window spans two)


def cache_dir(explicit: str | os.PathLike[str] | None = None) -> Path:
    """The directory of the cleaned collections (see the module docstring for the order)."""
    if explicit:
        return Path(explicit).expanduser()
    env = os.environ.get(CACHE_ENV)
    if env:
        return Path(env).expanduser()
    xdg = os.environ.get("XDG_CACHE_HOME")
    base = Path(xdg).expanduser() if xdg else Path.home() / ".cache"
    return base / "bluesky-gym"


def is_file_name(name: str) -> bool:
    """Whether a collection name is a path to a ``.npz`` file rather than a sample name."""
    return name.endswith(".npz") or os.sep in name or "/" in name


def collection_path(name: str, directory: str | os.PathLike[str] | None = None) -> Path:
    """The file of collection ``name`` (a sample name, cached, or a ``.npz`` path)."""
    if is_file_name(name):
        return Path(name).expanduser()
    return cache_dir(directory) / "realtraffic" / f"{name}-v{FORMAT_VERSION}.npz"


def load_collection(name: str, directory: str | os.PathLike[str] | None = None, verbose: bool = True) -> RecordedFlights:
    """Collection ``name``: read from its file, or (a sample not cached yet) cleaned from the ``traffic`` samples and cached.

    A sample's cache file that cannot be read (damaged) is cleaned again into the same place, and
    said so; a ``.npz`` file of the user's is never rewritten: its error names it.
    """
    path = collection_path(name, directory)
    damaged: ValueError | None = None
    if path.exists():
        try:
            return _load(str(path.resolve()), path.stat().st_mtime_ns)
        except ValueError as exc:
            if is_file_name(name):
                raise
            damaged = exc
    else:
        unprepared([name], directory)  # a missing .npz file is refused there
    from bluesky_gym.core.extras import MissingDependencyError
    from bluesky_gym.realtraffic.sources import Progress, Quiet, load_sample

    if damaged is not None:
        print(f"bluesky-gym: {damaged}; cleaning the traffic sample collection {name!r} again into it", flush=True)
    elif verbose:
        print(f"bluesky-gym: cleaning the traffic sample collection {name!r} once into {path}", flush=True)
    try:
        flights = load_sample(name, progress=Progress(name) if verbose or damaged is not None else Quiet(name))
    except MissingDependencyError as exc:
        if damaged is None:
            raise
        raise MissingDependencyError(f"{damaged}; delete it, or clean {name!r} again with the 'traffic' library: {exc}") from exc
    flights.save(path)
    return flights


def unprepared(names: tuple[str, ...] | list[str], directory: str | os.PathLike[str] | None = None) -> list[str]:
    """The sample collections of ``names`` not cleaned into the cache directory yet.

    Raises:
        ValueError: A ``.npz`` collection that does not exist (it cannot be prepared here).
    """
    out = []
    for name in names:
        path = collection_path(name, directory)
        if path.exists():
            continue
        if is_file_name(name):
            raise ValueError(f"{path}: no such recorded-flights file (write one with `bluesky-gym realtraffic prepare`)")
        out.append(name)
    return out


def default_data_ready() -> bool:
    """Whether the collections of the real-traffic environment's default configuration are in the cache directory."""
    from bluesky_gym.realtraffic.sources import SAMPLE_COLLECTIONS

    return not unprepared(SAMPLE_COLLECTIONS)


def default_data_note() -> str | None:
    """What to know about the data of the real-traffic environment's default configuration: None when they are prepared."""
    from bluesky_gym.realtraffic.sources import EXTRA, SAMPLE_COLLECTIONS

    missing = unprepared(SAMPLE_COLLECTIONS)
    if not missing:
        return None
    commands = "; ".join(f"bluesky-gym realtraffic prepare --sample {name}" for name in missing)
    return (
        f"not prepared in {cache_dir()}: the first reset cleans the traffic sample collection(s) {', '.join(missing)} "
        f"(the '{EXTRA}' extra; tens of seconds, with progress), or prepare them beforehand: {commands}"
    )


@lru_cache(maxsize=8)
def _load(path: str, mtime_ns: int) -> RecordedFlights:
    del mtime_ns  # part of the cache key: a rewritten file is read again
    return RecordedFlights.load(path)


def combine(parts: list[RecordedFlights], name: str) -> tuple[RecordedFlights, list[float]]:
    """One collection of several, each shifted in time after the previous one.

    Returns:
        The combined flights and each part's time shift [s] (its t = 0 in the combined clock).
    """
    shifts = time_shifts(parts)
    counts = [int(p.offset[-1]) for p in parts]
    wps = [int(p.wp_offset[-1]) for p in parts]
    sample_base = np.concatenate([[0], np.cumsum(counts)])
    wp_base = np.concatenate([[0], np.cumsum(wps)])
    return (
        RecordedFlights(
            name=name,
            epoch=parts[0].epoch,
            period=parts[0].period,
            t0=np.concatenate([p.t0 + s for p, s in zip(parts, shifts)]),
            offset=np.concatenate([[0]] + [p.offset[1:] + b for p, b in zip(parts, sample_base)]).astype(np.int64),
            lat=np.concatenate([p.lat for p in parts]),
            lon=np.concatenate([p.lon for p in parts]),
            alt=np.concatenate([p.alt for p in parts]),
            gs=np.concatenate([p.gs for p in parts]),
            trk=np.concatenate([p.trk for p in parts]),
            vs=np.concatenate([p.vs for p in parts]),
            wp_offset=np.concatenate([[0]] + [p.wp_offset[1:] + b for p, b in zip(parts, wp_base)]).astype(np.int64),
            wp_index=np.concatenate([p.wp_index for p in parts]).astype(np.int64),
            callsign=np.concatenate([p.callsign for p in parts]),
            icao24=np.concatenate([p.icao24 for p in parts]),
            typecode=np.concatenate([p.typecode for p in parts]),
            flight_id=np.concatenate([p.flight_id for p in parts]),
        ),
        shifts,
    )


def time_shifts(parts: list[RecordedFlights]) -> list[float]:
    """Each part's time shift in :func:`combine` [s]: its t = 0 in the combined clock."""
    shifts: list[float] = []
    t = 0.0
    for p in parts:
        shifts.append(t - float(p.t0.min()))
        t += float(p.t_end.max() - p.t0.min()) + GAP_BETWEEN_COLLECTIONS
    return shifts


def window_of_part(parts: list[RecordedFlights], window: Window) -> tuple[int, Window]:
    """The part a window of the :func:`combine`-d ``parts`` comes from, and the window in that part's own flights and clock.

    Raises:
        ValueError: The window's flights are not all in one part.
    """
    base = 0
    for k, (part, shift) in enumerate(zip(parts, time_shifts(parts))):
        if base <= window.ownship < base + part.n_flights:
            if not all(base <= f < base + part.n_flights for f in window.flights):
                raise ValueError(f"the window's flights {window.flights} span several collections")
            return k, Window(window.start - shift, window.duration, window.ownship - base, tuple(f - base for f in window.traffic))
        base += part.n_flights
    raise ValueError(f"the window's ownship {window.ownship} is not a flight of the collections ({base} flights)")
