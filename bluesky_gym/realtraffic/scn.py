"""A scenario of recorded traffic as a BlueSky ``.scn`` file (BlueSky plays it too).

Each aircraft of the window is created (``CRE``) at its recorded state when it appears, gets its
route points ahead of it with their recorded altitudes and speeds as constraints (``ADDWPT``),
LNAV and VNAV on, and is deleted (``DEL``) when its recording ends. Times are relative to the
window start; units are BlueSky's (ft, kt). An aircraft whose type is not recorded is written as
:data:`FALLBACK_TYPE`, the type the core flies.

This is a minimal writer for recorded windows; scenarios of any kind have their own reader and
writer in the package's scenario tools.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from bluesky_gym.core.atmosphere import tas2cas
from bluesky_gym.core.units import FT, KTS
from bluesky_gym.realtraffic.flights import RecordedFlights
from bluesky_gym.realtraffic.scenario import MAX_ROUTE_POINTS, Window
from bluesky_gym.scenarios.export import scn_time

FALLBACK_TYPE = "A320"


def scn_lines(flights: RecordedFlights, window: Window) -> list[str]:
    """The ``.scn`` lines of ``window``, in time order."""
    events: list[tuple[float, int, str]] = []
    for k, f in enumerate(window.flights):
        acid = str(flights.callsign[f]) or f"AC{k:03d}"
        acid = f"{acid}_{k}" if acid in {flights.callsign[g] for g in window.flights[:k]} else acid
        actype = str(flights.typecode[f]) or FALLBACK_TYPE
        t_in = max(float(flights.t0[f]), window.start)
        t_out = min(float(flights.t_end[f]), window.start + window.duration)
        st = flights.at(np.array([f]), np.array([t_in]))
        cas = float(tas2cas(st["gs"], st["alt"])[0])
        rel = t_in - window.start
        events.append(
            (
                rel,
                0,
                f"CRE {acid},{actype},{st['lat'][0]:.6f},{st['lon'][0]:.6f},{st['trk'][0]:.1f},{st['alt'][0] / FT:.0f},{cas / KTS:.0f}",
            )
        )
        k_in = (t_in - flights.t0[f]) / flights.period
        pts = flights.route_points(int(f))
        ahead = pts[pts > k_in + 1e-9][:MAX_ROUTE_POINTS]
        idx = flights.offset[f] + ahead
        wp_cas = tas2cas(flights.gs[idx], flights.alt[idx])
        for la, lo, z, v in zip(flights.lat[idx], flights.lon[idx], flights.alt[idx], wp_cas):
            events.append((rel, 1, f"ADDWPT {acid} {la:.6f} {lo:.6f} {z / FT:.0f} {v / KTS:.0f}"))
        if len(ahead):
            events.append((rel, 2, f"LNAV {acid} ON"))
            events.append((rel, 2, f"VNAV {acid} ON"))
        if t_out < window.start + window.duration:
            events.append((t_out - window.start + flights.period, 3, f"DEL {acid}"))
    events.sort(key=lambda e: (e[0], e[1]))
    return [f"{scn_time(t)}>{cmd}" for t, _, cmd in events]


def write_scn(flights: RecordedFlights, window: Window, path: str | Path) -> Path:
    """Write ``window`` as a ``.scn`` file."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    header = f"# {flights.name}: {len(window.flights)} recorded aircraft, {window.duration:.0f} s from t = {window.start:.0f} s after {flights.epoch}"
    path.write_text("\n".join([header, *scn_lines(flights, window)]) + "\n")
    return path
