"""How closely the simulated aircraft follow their recorded paths when nobody acts.

:func:`fidelity` replays windows with :class:`~bluesky_gym.realtraffic.scenario.WindowPlayer` on
the native core and compares, for every aircraft, the simulated position with the recorded one
at the same time, 5, 10 and 20 minutes after the aircraft was created: the lateral deviation
(great-circle distance) and the vertical deviation (|altitude difference|). It reports the median
and the 95th percentile over all aircraft still recorded at that age.

:func:`fly` is that replay (nobody acting, every aircraft guided along its recording), and
:func:`window_scenario` writes a window as the replay flies it as a BlueSky ``.scn`` file, with the
package's one scenario writer (:class:`~bluesky_gym.scenarios.export.ScenarioRecorder`): every
command the replay gives is a line of the file, so the scenario player (``bluesky-gym replay``)
flies the file exactly as the replay flew the window, and BlueSky plays it too.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from datetime import datetime, timedelta
from pathlib import Path
from typing import cast

import numpy as np
from numpy.typing import NDArray

from bluesky_gym.core.aircraft import aircraft_performance
from bluesky_gym.core.geo import qdrdist
from bluesky_gym.core.physics import Physics
from bluesky_gym.core.simulator import Simulator
from bluesky_gym.core.units import FT, NM
from bluesky_gym.realtraffic.flights import RecordedFlights
from bluesky_gym.realtraffic.scenario import MAX_ROUTE_POINTS, SEPARATION_NM, SEPARATION_VERTICAL, Window, WindowPlayer, simulator_type
from bluesky_gym.scenarios.export import ScenarioRecorder

HORIZONS_S = (300.0, 600.0, 1200.0)  # s after creation: 5, 10, 20 minutes
DT = 1.0  # s, simulation time step
DECISION_STEP = 10.0  # s between the player's updates
BATCH = 64  # windows simulated together
LARGE_VERTICAL = 1000.0 * FT  # m: a vertical deviation above this is classified by its cause


@dataclass
class Fidelity:
    """Lateral and vertical deviations from the recorded tracks, per horizon.

    Attributes:
        collection: Collection name.
        windows: Windows replayed.
        lateral_m: Horizon [s] -> lateral deviations [m] of every aircraft recorded at that age.
        vertical_m: Horizon [s] -> vertical deviations [m].
        flight: Horizon [s] -> the recorded flight (index into the collection) of each deviation.
        time: Horizon [s] -> the time of each deviation [s since the collection's epoch].
        conflicts: Losses of separation (pair events) counted in the replay.
        aircraft_hours: Simulated aircraft-hours of the replay.
    """

    collection: str
    windows: int
    lateral_m: dict[float, NDArray[np.float64]] = field(default_factory=dict)
    vertical_m: dict[float, NDArray[np.float64]] = field(default_factory=dict)
    flight: dict[float, NDArray[np.int64]] = field(default_factory=dict)
    time: dict[float, NDArray[np.float64]] = field(default_factory=dict)
    conflicts: int = 0
    aircraft_hours: float = 0.0

    @property
    def conflicts_per_flight_hour(self) -> float:
        """Losses of separation (5 NM / 1000 ft pair events) per simulated aircraft-hour, with nobody acting."""
        return self.conflicts / self.aircraft_hours if self.aircraft_hours > 0 else float("nan")

    def summary(self) -> list[dict[str, float]]:
        """One row per horizon: aircraft, median and 95th percentile lateral [NM] and vertical [ft] deviation."""
        rows = []
        for h in sorted(self.lateral_m):
            lat = self.lateral_m[h] / NM
            ver = self.vertical_m[h] / FT
            n = len(lat)
            rows.append(
                {
                    "minutes": h / 60.0,
                    "aircraft": float(n),
                    "lateral_median_nm": float(np.median(lat)) if n else float("nan"),
                    "lateral_p95_nm": float(np.percentile(lat, 95)) if n else float("nan"),
                    "vertical_median_ft": float(np.median(ver)) if n else float("nan"),
                    "vertical_p95_ft": float(np.percentile(ver, 95)) if n else float("nan"),
                }
            )
        return rows


def fidelity(
    flights: RecordedFlights, chosen: list[Window], max_aircraft: int, max_waypoints: int, horizons: tuple[float, ...] = HORIZONS_S
) -> Fidelity:
    """Replay ``chosen`` windows with nobody acting and measure the deviation from the recordings.

    Args:
        flights: The recorded flights.
        chosen: Windows to replay (each at least as long as the largest horizon to measure it).
        max_aircraft: Aircraft slots per airspace (at least the largest window's aircraft).
        max_waypoints: Route points given to each aircraft.
        horizons: Ages at which to compare [s], multiples of the decision step.
    """
    result = Fidelity(flights.name, len(chosen), {h: np.zeros(0) for h in horizons}, {h: np.zeros(0) for h in horizons})
    lateral: dict[float, list[NDArray[np.float64]]] = {h: [] for h in horizons}
    vertical: dict[float, list[NDArray[np.float64]]] = {h: [] for h in horizons}
    flight: dict[float, list[NDArray[np.int64]]] = {h: [] for h in horizons}
    times: dict[float, list[NDArray[np.float64]]] = {h: [] for h in horizons}
    for b in range(0, len(chosen), BATCH):
        batch = chosen[b : b + BATCH]
        sim = Simulator(len(batch), max_aircraft, dt=DT, max_waypoints=max_waypoints)
        player = WindowPlayer(sim, flights, guided_ownship=True)
        player.load(np.arange(len(batch)), batch)
        in_los = np.zeros((len(batch), max_aircraft, max_aircraft), bool)
        for _ in fly(sim, player, max(w.duration for w in batch)):
            now = player.now()[:, None]
            age = now - player.t_created
            live = sim.active & player.created & ~player.done & (now <= player.t_leave + 1e-6)
            result.aircraft_hours += float(live.sum()) * DECISION_STEP / 3600.0
            los = pair_los(sim.lat, sim.lon, sim.alt, live)
            result.conflicts += int((los & ~in_los).sum()) // 2
            in_los = los
            for h in horizons:
                hit = live & (np.abs(age - h) < 1e-6)
                if not hit.any():
                    continue
                e, s = np.nonzero(hit)
                rec = flights.at(player.flight[e, s], now[e, 0])
                _, dist_nm = qdrdist(sim.lat[e, s], sim.lon[e, s], rec["lat"], rec["lon"])
                lateral[h].append(np.asarray(dist_nm) * NM)
                vertical[h].append(np.abs(sim.alt[e, s] - rec["alt"]))
                flight[h].append(player.flight[e, s])
                times[h].append(now[e, 0])
    for h in horizons:
        result.lateral_m[h] = np.concatenate(lateral[h]) if lateral[h] else np.zeros(0)
        result.vertical_m[h] = np.concatenate(vertical[h]) if vertical[h] else np.zeros(0)
        result.flight[h] = np.concatenate(flight[h]) if flight[h] else np.zeros(0, np.int64)
        result.time[h] = np.concatenate(times[h]) if times[h] else np.zeros(0)
    return result


def fly(sim: Physics, player: WindowPlayer, duration: float) -> Iterator[None]:
    """Fly the windows loaded into ``player`` for ``duration`` [s] with nobody acting.

    Runs :data:`DECISION_STEP` at a time (in steps of the physics' ``dt``) and yields after each,
    with the player's clock advanced; when resumed, the player creates, deletes and guides its
    aircraft for the next decision step (not after the last one).
    """
    sub = int(round(DECISION_STEP / sim.dt))
    n_steps = int(round(duration / DECISION_STEP))
    for k in range(n_steps):
        sim.run(sub)
        player.advance_clock(DECISION_STEP)
        yield
        if k < n_steps - 1:
            player.update()


def window_title(flights: RecordedFlights, window: Window) -> str:
    """One line naming the collection, the window (UTC when the epoch is a date), its aircraft and the ownship."""
    try:
        start: str = (datetime.fromisoformat(flights.epoch) + timedelta(seconds=window.start)).isoformat(timespec="seconds")
    except ValueError:
        start = f"t = {window.start:g} s after {flights.epoch}"
    own = str(flights.callsign[window.ownship]) or str(flights.flight_id[window.ownship])
    return (
        f"{flights.name}: {window.duration:g} s from {start}, {len(window.flights)} recorded aircraft (ownship {own}), "
        "each guided along its recording, nobody acting"
    )


def window_scenario(flights: RecordedFlights, window: Window, max_waypoints: int = MAX_ROUTE_POINTS, title: str | None = None) -> str:
    """``window`` flown with nobody acting (as :func:`fidelity` flies it), as ``.scn`` text.

    The window is flown on the native core with the :class:`WindowPlayer` under a
    :class:`~bluesky_gym.scenarios.export.ScenarioRecorder`, and the recorder's text is returned:
    every aircraft is created (``CRE``, with its recorded type or BlueSky's fallback B744) when it
    appears and given its route points (``ADDWPT``, which engages LNAV), then its altitude and
    speed targets every decision step (``ALT``, ``SPD``), and deleted (``DEL``) after its
    recording ends or at the end of the window. Aircraft are named by their recorded callsigns
    (made unique). Times are relative to the window start.

    Args:
        flights: The recorded flights.
        window: The window to write.
        max_waypoints: Route points given to each aircraft (as in the environments).
        title: The file's title line (default: :func:`window_title`).
    """
    sim = Simulator(1, len(window.flights), dt=DT, max_waypoints=max_waypoints)
    rec = ScenarioRecorder(sim)
    rec.reset_envs()
    rec.set_callsigns(0, [str(flights.callsign[f]) for f in window.flights])
    physics = cast(Physics, rec)  # a Physics by delegation
    player = WindowPlayer(physics, flights, guided_ownship=True)
    player.load(np.array([0]), [window])
    for _ in fly(physics, player, window.duration):
        pass
    alive = np.flatnonzero(sim.active[0])
    if alive.size:
        rec.delete(0, alive)
    return rec.scenario_text(0, title=window_title(flights, window) if title is None else title)


def write_window_scenario(flights: RecordedFlights, window: Window, path: str | Path, max_waypoints: int = MAX_ROUTE_POINTS) -> Path:
    """Write :func:`window_scenario` to ``path`` (parent directories are made); returns the path."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text(window_scenario(flights, window, max_waypoints))
    return p


def large_vertical_deviations(flights: RecordedFlights, result: Fidelity, threshold: float = LARGE_VERTICAL) -> list[dict[str, float]]:
    """Vertical deviations above ``threshold`` [m] per horizon, by what the recording asked of the aircraft's type.

    Each such deviation is put in the first class that applies to the recording between the
    aircraft's creation and the comparison: ``above_ceiling`` (recorded above the ceiling ``hmax``
    of the type the aircraft flies with), ``steeper_than_vsmax`` (recorded climbing or descending
    faster than the type's ``vsmax``), ``other``.

    Returns:
        One row per horizon: ``minutes``, ``aircraft`` (compared), ``large`` and the three classes.
    """
    rows = []
    for h in sorted(result.vertical_m):
        counts = {"above_ceiling": 0, "steeper_than_vsmax": 0, "other": 0}
        for f, t in zip(result.flight[h][result.vertical_m[h] > threshold], result.time[h][result.vertical_m[h] > threshold]):
            perf = aircraft_performance(simulator_type(str(flights.typecode[f])))
            sl = flights.samples(int(f))
            k0 = max(int(np.floor((t - h - flights.t0[f]) / flights.period)), 0)
            k1 = int(np.ceil((t - flights.t0[f]) / flights.period)) + 1
            alt, vs = flights.alt[sl][k0:k1], flights.vs[sl][k0:k1]
            if alt.size and alt.max() > perf.hmax:
                counts["above_ceiling"] += 1
            elif vs.size and np.abs(vs).max() > perf.vsmax:
                counts["steeper_than_vsmax"] += 1
            else:
                counts["other"] += 1
        rows.append({"minutes": h / 60.0, "aircraft": len(result.vertical_m[h]), "large": sum(counts.values()), **counts})
    return rows


def pair_los(lat: NDArray[np.float64], lon: NDArray[np.float64], alt: NDArray[np.float64], live: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """(n, m, m) whether two live aircraft of an airspace are within 5 NM and 1000 ft (flat-earth distance)."""
    coslat = np.cos(np.radians(lat))
    dy = (lat[:, :, None] - lat[:, None, :]) * 60.0
    dx = ((lon[:, :, None] - lon[:, None, :] + 180.0) % 360.0 - 180.0) * 60.0 * coslat[:, :, None]
    both = live[:, :, None] & live[:, None, :]
    m = lat.shape[1]
    return (
        both & ~np.eye(m, dtype=bool)[None] & (np.hypot(dx, dy) < SEPARATION_NM) & (np.abs(alt[:, :, None] - alt[:, None, :]) < SEPARATION_VERTICAL)
    )


#: Columns of the fidelity table (one row per collection and horizon).
TABLE_HEADER = "| collection | after | aircraft | lateral median [NM] | lateral p95 [NM] | vertical median [ft] | vertical p95 [ft] |"


def summary_table(summaries: list[tuple[str, list[dict[str, float]]]]) -> str:
    """A Markdown table of (collection, :meth:`Fidelity.summary` rows) pairs."""
    lines = [TABLE_HEADER, "|---|---:|---:|---:|---:|---:|---:|"]
    for collection, rows in summaries:
        for row in rows:
            lines.append(
                f"| {collection} | {row['minutes']:.0f} min | {row['aircraft']:.0f} | {row['lateral_median_nm']:.2f} | "
                f"{row['lateral_p95_nm']:.2f} | {row['vertical_median_ft']:.0f} | {row['vertical_p95_ft']:.0f} |"
            )
    return "\n".join(lines)


def format_markdown(results: list[Fidelity]) -> str:
    """A Markdown table of the fidelity of each collection."""
    return summary_table([(r.collection, r.summary()) for r in results])
