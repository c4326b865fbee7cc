"""Recorded flights as plain arrays: the form the scenarios, the environments and the cache use.

A :class:`RecordedFlights` holds many cleaned trajectories sampled at a fixed period (SI units,
seconds since the collection's epoch), and for each flight the indices of its route points (the
samples kept by a Douglas-Peucker simplification of the 3-D track). It needs numpy only: the
``traffic`` library is used once, to clean and resample the data (:mod:`bluesky_gym.realtraffic.sources`),
and the result is saved as one ``.npz`` file.
"""

from __future__ import annotations

import math
import os
import tempfile
import zipfile
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from bluesky_gym.core.atmosphere import tas2cas
from bluesky_gym.core.jit import grid_range, jit, jit_inline
from bluesky_gym.core.scalar import clip, mod

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

        The kernel :func:`recorded_states` (its scalar :func:`sample_weight`, :func:`lerp` and
        :func:`track_at`, which the tasks' kernels call too).

        Args:
            flight: Flight indices, any shape.
            t: Times [s since epoch], same shape.

        Returns:
            ``lat``, ``lon``, ``alt``, ``gs``, ``trk``, ``vs`` arrays of that shape (the track is
            interpolated along the shorter arc).
        """
        ff, tt = np.broadcast_arrays(np.asarray(flight, dtype=np.int64), np.asarray(t, dtype=np.float64))
        shape = ff.shape
        out = {name: np.empty(shape) for name in _STATE}
        recorded_states(
            *self.kernel_arrays(), np.ascontiguousarray(ff).reshape(-1), np.ascontiguousarray(tt).reshape(-1), *(out[k].reshape(-1) for k in _STATE)
        )
        return out if shape else {k: v[()] for k, v in out.items()}

    def kernel_arrays(self) -> tuple[Array, IntArray, float, Array, Array, Array, Array, Array, Array]:
        """The recordings as kernels read them: ``t0``, ``offset``, ``period``, the samples' ``lat``, ``lon``, ``alt``, ``gs``, ``trk``, ``vs``."""
        return (self.t0, self.offset, float(self.period), self.lat, self.lon, self.alt, self.gs, self.trk, self.vs)

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


#: The interpolated fields of :meth:`RecordedFlights.at`, in :func:`recorded_states`' order.
_STATE = ("lat", "lon", "alt", "gs", "trk", "vs")


# --- the interpolation, one scalar form for the CPU and the device ---------------------------------
@jit_inline
def sample_weight(t0, offset, period, f, t):
    """Sample ``i0`` (in the concatenated arrays) and weight ``w`` of flight ``f`` at time ``t`` [s]: the state is ``(1 - w) a[i0] + w a[i0 + 1]``.

    The time is clamped to the flight's span (``np.clip``'s semantics, NaN kept); the last
    segment is used at and after the last sample.
    """
    last = offset[f + 1] - offset[f] - 1
    x = clip((t - t0[f]) / period, 0.0, float(last))
    k0 = int(math.floor(x))
    cap = last - 1 if last - 1 > 0 else 0
    if k0 > cap:
        k0 = cap
    return offset[f] + k0, x - k0


@jit_inline
def lerp(a, i0, w):
    """``a`` between samples ``i0`` and ``i0 + 1`` at weight ``w`` (:func:`sample_weight`)."""
    return (1.0 - w) * a[i0] + w * a[i0 + 1]


@jit_inline
def track_at(trk, i0, w):
    """The track [deg, 0..360) between samples ``i0`` and ``i0 + 1`` at weight ``w``, along the shorter arc."""
    d = mod(trk[i0 + 1] - trk[i0] + 180.0, 360.0) - 180.0
    return mod(trk[i0] + w * d, 360.0)


@jit
def recorded_states(t0, offset, period, lat, lon, alt, gs, trk, vs, flight, t, lat_out, lon_out, alt_out, gs_out, trk_out, vs_out):
    """:meth:`RecordedFlights.at` of points ``(flight[i], t[i])`` (the recordings as :meth:`RecordedFlights.kernel_arrays` gives them)."""
    for i in grid_range(flight.shape[0]):
        i0, w = sample_weight(t0, offset, period, flight[i], t[i])
        lat_out[i] = lerp(lat, i0, w)
        lon_out[i] = lerp(lon, i0, w)
        alt_out[i] = lerp(alt, i0, w)
        gs_out[i] = lerp(gs, i0, w)
        vs_out[i] = lerp(vs, i0, w)
        trk_out[i] = track_at(trk, i0, w)


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
