"""Recorded flights as plain arrays: the form the scenarios, the environments and the cache use.

A :class:`RecordedFlights` holds many cleaned trajectories sampled at a fixed period (SI units,
seconds since the collection's epoch), and for each flight the indices of its route points (the
samples kept by a Douglas-Peucker simplification of the 3-D track). It needs numpy only: the
``traffic`` library is used once, to clean and resample the data (:mod:`bluesky_gym.realtraffic.sources`),
and the result is saved as one ``.npz`` file.
"""

from __future__ import annotations

import os
import tempfile
import zipfile
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from bluesky_gym.core.atmosphere import tas2cas

Array = NDArray[np.float64]
IntArray = NDArray[np.int64]

#: Version of the cache file layout (a change makes old cache files be rebuilt).
FORMAT_VERSION = 1
#: Sample period of the cleaned trajectories [s].
SAMPLE_PERIOD = 10.0
#: Type code written when the data has none (the simulator then uses its fallback type).
UNKNOWN_TYPE = ""


@dataclass(frozen=True)
class RecordedFlights:
    """Cleaned recorded trajectories, resampled every ``period`` seconds, concatenated.

    Flight ``f`` has samples ``offset[f]:offset[f + 1]`` at times ``t0[f] + k * period`` and route
    points ``wp_index[wp_offset[f]:wp_offset[f + 1]]`` (sample numbers within the flight, increasing,
    first and last sample included).

    Attributes:
        name: Collection name.
        epoch: ISO 8601 UTC time of t = 0.
        period: Sample period [s].
        t0: (F,) time of each flight's first sample [s since epoch].
        offset: (F + 1,) sample offsets.
        lat: Latitude [deg] of every sample.
        lon: Longitude [deg].
        alt: Altitude [m] (barometric).
        gs: Ground speed [m/s].
        trk: Track [deg].
        vs: Vertical rate [m/s].
        wp_offset: (F + 1,) route point offsets.
        wp_index: Route point sample numbers, within their flight.
        callsign: (F,) callsigns.
        icao24: (F,) transponder addresses.
        typecode: (F,) ICAO aircraft type codes ("" where the data has none).
        flight_id: (F,) unique flight identifiers (callsign and a counter).
    """

    name: str
    epoch: str
    period: float
    t0: Array
    offset: IntArray
    lat: Array
    lon: Array
    alt: Array
    gs: Array
    trk: Array
    vs: Array
    wp_offset: IntArray
    wp_index: IntArray
    callsign: NDArray[np.str_]
    icao24: NDArray[np.str_]
    typecode: NDArray[np.str_]
    flight_id: NDArray[np.str_]

    def __post_init__(self) -> None:
        n = len(self.t0)
        if len(self.offset) != n + 1 or len(self.wp_offset) != n + 1:
            raise ValueError(f"recorded flights {self.name!r}: offsets do not match the {n} flights")
        for name in ("callsign", "icao24", "typecode", "flight_id"):
            if len(getattr(self, name)) != n:
                raise ValueError(f"recorded flights {self.name!r}: {name} has {len(getattr(self, name))} entries for {n} flights")
        m = int(self.offset[-1])
        for name in ("lat", "lon", "alt", "gs", "trk", "vs"):
            if len(getattr(self, name)) != m:
                raise ValueError(f"recorded flights {self.name!r}: {name} has {len(getattr(self, name))} samples, expected {m}")
        if np.any(np.diff(self.offset) < 2):
            raise ValueError(f"recorded flights {self.name!r}: every flight needs at least two samples")

    # --- sizes and times -------------------------------------------------------------------------
    @property
    def n_flights(self) -> int:
        """Number of flights."""
        return len(self.t0)

    @property
    def n_samples(self) -> IntArray:
        """(F,) samples per flight."""
        return np.diff(self.offset)

    @property
    def t_end(self) -> Array:
        """(F,) time of each flight's last sample [s since epoch]."""
        return self.t0 + (self.n_samples - 1) * self.period

    def flight_hours(self) -> float:
        """Recorded aircraft-hours (sum of the flights' durations) [h]."""
        return float(np.sum(self.t_end - self.t0) / 3600.0)

    def cas(self) -> Array:
        """CAS [m/s] of every sample, from the ground speed taken as TAS (no wind) at the recorded altitude."""
        return tas2cas(self.gs, self.alt)

    # --- sampling --------------------------------------------------------------------------------
    def at(self, flight: IntArray, t: Array) -> dict[str, Array]:
        """Linearly interpolated state of flights ``flight`` at times ``t`` (clamped to each flight's span).

        Args:
            flight: Flight indices, any shape.
            t: Times [s since epoch], same shape.

        Returns:
            ``lat``, ``lon``, ``alt``, ``gs``, ``trk``, ``vs`` arrays of that shape (the track is
            interpolated along the shorter arc).
        """
        flight = np.asarray(flight, dtype=np.int64)
        t = np.asarray(t, dtype=np.float64)
        last = self.n_samples[flight] - 1
        x = np.clip((t - self.t0[flight]) / self.period, 0.0, last)
        k0 = np.minimum(np.floor(x).astype(np.int64), np.maximum(last - 1, 0))
        w = x - k0
        i0 = self.offset[flight] + k0
        i1 = i0 + 1
        out = {name: (1.0 - w) * getattr(self, name)[i0] + w * getattr(self, name)[i1] for name in ("lat", "lon", "alt", "gs", "vs")}
        d = (self.trk[i1] - self.trk[i0] + 180.0) % 360.0 - 180.0
        out["trk"] = (self.trk[i0] + w * d) % 360.0
        return out

    def samples(self, f: int) -> slice:
        """Sample range of flight ``f`` in the concatenated arrays."""
        return slice(int(self.offset[f]), int(self.offset[f + 1]))

    def route_points(self, f: int) -> IntArray:
        """Sample numbers (within flight ``f``) of its route points."""
        return self.wp_index[int(self.wp_offset[f]) : int(self.wp_offset[f + 1])]

    def subset(self, flights: IntArray, name: str | None = None) -> RecordedFlights:
        """A collection of the flights ``flights`` only (same epoch)."""
        flights = np.asarray(flights, dtype=np.int64)
        parts = [np.arange(self.offset[f], self.offset[f + 1]) for f in flights]
        wps = [self.route_points(int(f)) for f in flights]
        idx = np.concatenate(parts) if parts else np.zeros(0, np.int64)
        return RecordedFlights(
            name=self.name if name is None else name,
            epoch=self.epoch,
            period=self.period,
            t0=self.t0[flights],
            offset=np.concatenate([[0], np.cumsum([len(p) for p in parts], dtype=np.int64)]).astype(np.int64),
            lat=self.lat[idx],
            lon=self.lon[idx],
            alt=self.alt[idx],
            gs=self.gs[idx],
            trk=self.trk[idx],
            vs=self.vs[idx],
            wp_offset=np.concatenate([[0], np.cumsum([len(w) for w in wps], dtype=np.int64)]).astype(np.int64),
            wp_index=np.concatenate(wps).astype(np.int64) if wps else np.zeros(0, np.int64),
            callsign=self.callsign[flights],
            icao24=self.icao24[flights],
            typecode=self.typecode[flights],
            flight_id=self.flight_id[flights],
        )

    # --- files -----------------------------------------------------------------------------------
    def save(self, path: str | Path) -> Path:
        """Write the collection to ``path`` (``.npz``), atomically."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        arrays = {name: getattr(self, name) for name in _ARRAYS}
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=path.name, suffix=".tmp")
        os.close(fd)
        try:
            with open(tmp, "wb") as fh:
                np.savez_compressed(
                    fh,
                    format_version=np.int64(FORMAT_VERSION),
                    name=np.str_(self.name),
                    epoch=np.str_(self.epoch),
                    period=np.float64(self.period),
                    **arrays,
                )
            os.replace(tmp, path)
        finally:
            if os.path.exists(tmp):
                os.unlink(tmp)
        return path

    @classmethod
    def load(cls, path: str | Path) -> RecordedFlights:
        """Read a collection written by :meth:`save`.

        Raises:
            ValueError: naming the file, if it is not one: :class:`DamagedFile` if it cannot be
                read (cut short, emptied, overwritten, an array that does not decompress).
        """
        path = Path(path)
        try:
            with np.load(path, allow_pickle=False) as data:
                version = int(data["format_version"])
                if version != FORMAT_VERSION:
                    raise _WrongVersion(f"{path}: recorded-flights format {version}, expected {FORMAT_VERSION}")
                return cls(
                    name=str(data["name"]),
                    epoch=str(data["epoch"]),
                    period=float(data["period"]),
                    **{name: data[name] for name in _ARRAYS},
                )
        except _WrongVersion:
            raise
        except KeyError as exc:
            raise ValueError(f"{path}: not a recorded-flights file (no array {exc})") from exc
        except (EOFError, zipfile.BadZipFile, zlib.error) as exc:
            raise DamagedFile(f"{path}: not a recorded-flights file (damaged: {_damage(exc)})") from exc
        except ValueError as exc:
            if "pickle" in str(exc):  # numpy's word for bytes that are neither .npy nor .npz
                raise DamagedFile(f"{path}: not a recorded-flights file (damaged: not an .npz archive)") from exc
            raise ValueError(f"{path}: not a recorded-flights file ({exc})") from exc
        except OSError as exc:
            raise ValueError(f"{path}: cannot read the recorded-flights file ({exc.strerror or exc})") from exc


class DamagedFile(ValueError):
    """A file of recorded flights that cannot be read: cut short, emptied, overwritten or changed."""


def _damage(exc: BaseException) -> str:
    """What is wrong with a file that numpy could not read, in words."""
    if isinstance(exc, EOFError):
        return "empty"
    if isinstance(exc, zipfile.BadZipFile):
        return f"cut short or not an .npz archive: {exc}"
    return f"an array does not decompress: {exc}"


class _WrongVersion(ValueError):
    """A recorded-flights file of another format version."""


_ARRAYS = ("t0", "offset", "lat", "lon", "alt", "gs", "trk", "vs", "wp_offset", "wp_index", "callsign", "icao24", "typecode", "flight_id")
