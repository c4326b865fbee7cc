"""Synthetic recorded flights with known routes (no ADS-B data needed)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from bluesky_gym.core.geo import kwikpos
from bluesky_gym.core.units import NM
from bluesky_gym.realtraffic.flights import SAMPLE_PERIOD, RecordedFlights


def fly(lat0: float, lon0: float, legs: list[tuple[float, float]], gs: float, alt: list[float] | float) -> dict[str, np.ndarray]:
    """Samples every SAMPLE_PERIOD of a flight along ``legs`` (course [deg], length [NM]) at ground speed ``gs`` [m/s].

    ``alt`` is constant or one altitude [m] per leg end (linear along each leg). Returns the
    arrays and the route point sample numbers (start, each leg end).
    """
    lat, lon, trk, z = [lat0], [lon0], [legs[0][0]], []
    alts = [alt] * (len(legs) + 1) if np.isscalar(alt) else list(alt)
    step_nm = gs * SAMPLE_PERIOD / NM
    wp = [0]
    z.append(alts[0])
    for k, (course, length) in enumerate(legs):
        n = int(round(length / step_nm))
        for j in range(1, n + 1):
            la, lo = kwikpos(lat[-1], lon[-1], course, step_nm)
            lat.append(float(la))
            lon.append(float(lo))
            trk.append(course)
            z.append(alts[k] + (alts[k + 1] - alts[k]) * j / n)
        wp.append(len(lat) - 1)
    n = len(lat)
    vs = np.gradient(np.array(z)) / SAMPLE_PERIOD
    return {
        "lat": np.array(lat),
        "lon": np.array(lon),
        "alt": np.array(z),
        "gs": np.full(n, gs),
        "trk": np.array(trk) % 360.0,
        "vs": vs,
        "wp": np.array(sorted(set(wp)), dtype=np.int64),
    }


def collection(flights: list[tuple[float, dict[str, np.ndarray]]], name: str = "synthetic") -> RecordedFlights:
    """A collection of (start time [s], samples) flights."""
    counts = [len(f["lat"]) for _, f in flights]
    return RecordedFlights(
        name=name,
        epoch="2024-01-01T00:00:00+00:00",
        period=SAMPLE_PERIOD,
        t0=np.array([t for t, _ in flights], dtype=float),
        offset=np.concatenate([[0], np.cumsum(counts)]).astype(np.int64),
        lat=np.concatenate([f["lat"] for _, f in flights]),
        lon=np.concatenate([f["lon"] for _, f in flights]),
        alt=np.concatenate([f["alt"] for _, f in flights]),
        gs=np.concatenate([f["gs"] for _, f in flights]),
        trk=np.concatenate([f["trk"] for _, f in flights]),
        vs=np.concatenate([f["vs"] for _, f in flights]),
        wp_offset=np.concatenate([[0], np.cumsum([len(f["wp"]) for _, f in flights])]).astype(np.int64),
        wp_index=np.concatenate([f["wp"] for _, f in flights]).astype(np.int64),
        callsign=np.array([f"SYN{i:03d}" for i in range(len(flights))]),
        icao24=np.array([f"{i:06x}" for i in range(len(flights))]),
        typecode=np.array(["A320"] * len(flights)),
        flight_id=np.array([f"SYN{i:03d}_000" for i in range(len(flights))]),
    )


def traffic_collection(n_flights: int = 16, spacing_s: float = 600.0, seed: int = 0) -> RecordedFlights:
    """Flights crossing a common area, one every ``spacing_s``, each about 40 minutes long, on dog-leg routes."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n_flights):
        course = float(rng.uniform(0, 360))
        lat0, lon0 = kwikpos(47.0, 8.0, (course + 180.0) % 360.0, 150.0)
        legs = [(course, 150.0), ((course + rng.uniform(-40, 40)) % 360.0, 160.0)]
        f = fly(float(lat0), float(lon0), legs, gs=230.0, alt=[10000.0, 10000.0, 9000.0])
        out.append((i * spacing_s, f))
    return collection(out)


def joining_collection(n_traffic: int = 45, spacing_s: float = 150.0) -> RecordedFlights:
    """A flight shuttling 10 NM east and west of 47N 8E for two hours, and short flights crossing that point, one starting every ``spacing_s``.

    Each crossing flight is recorded for about 6 minutes, so every 10-minute window of the
    shuttling flight has aircraft appearing and leaving mid-window.
    """
    out = [(0.0, fly(47.0, 8.0 - 5.0 / 60.0 / np.cos(np.radians(47.0)), [(90.0, 10.0), (270.0, 10.0)] * 20, gs=100.0, alt=10000.0))]
    for i in range(n_traffic):
        course = (i * 47.0) % 360.0
        lat0, lon0 = kwikpos(47.0, 8.0, (course + 180.0) % 360.0, 15.0)
        out.append((60.0 + i * spacing_s, fly(float(lat0), float(lon0), [(course, 30.0)], gs=150.0, alt=10000.0 + 600.0 * (i % 3))))
    return collection(out)


def save(flights: RecordedFlights, directory: Path, name: str = "synthetic.npz") -> str:
    """Save to ``directory/name`` and return the path as a string (a collection option value)."""
    return str(flights.save(directory / name))
