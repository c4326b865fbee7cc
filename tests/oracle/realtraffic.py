"""Readable numpy form of the recorded flights' interpolation (oracle of :meth:`bluesky_gym.realtraffic.flights.RecordedFlights.at`)."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


def recorded_at(flights: Any, flight: Any, t: Any) -> dict[str, Array]:
    """Linearly interpolated state of flights ``flight`` at times ``t`` (clamped to each flight's span; the track along the shorter arc)."""
    flight = np.asarray(flight, dtype=np.int64)
    t = np.asarray(t, dtype=np.float64)
    last = flights.n_samples[flight] - 1
    x = np.clip((t - flights.t0[flight]) / flights.period, 0.0, last)
    k0 = np.minimum(np.floor(x).astype(np.int64), np.maximum(last - 1, 0))
    w = x - k0
    i0 = flights.offset[flight] + k0
    i1 = i0 + 1
    out = {name: (1.0 - w) * getattr(flights, name)[i0] + w * getattr(flights, name)[i1] for name in ("lat", "lon", "alt", "gs", "vs")}
    d = (flights.trk[i1] - flights.trk[i0] + 180.0) % 360.0 - 180.0
    out["trk"] = (flights.trk[i0] + w * d) % 360.0
    return out
