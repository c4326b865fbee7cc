"""From recorded flights and a time window to a scenario on the core, and its replay.

A :class:`Window` is one scenario: a start time, a duration, an ownship (a flight recorded over
the whole window) and the recorded traffic around it. :func:`windows` lists every such window of a
collection; :func:`split_windows` divides them into a training and a test part that share no
recorded time. :class:`WindowPlayer` plays windows on any :class:`~bluesky_gym.core.physics.Physics`:

* every aircraft is created at its recorded state at the window start, or at its first recorded
  sample if it appears later (at the first decision step from then on), and deleted after its
  last recorded sample;
* its route is the flight's route points (Douglas-Peucker simplification of the 3-D track, see
  :mod:`bluesky_gym.realtraffic.sources`) ahead of it, flown with LNAV;
* its vertical and speed profile is the recorded one: before every decision step each
  aircraft gets as targets the recorded altitude :data:`ALT_LOOKAHEAD` ahead, with the vertical
  speed that reaches it in time (at most its type's maximum), and the recorded speed :data:`SPEED_LOOKAHEAD` ahead (as CAS,
  ground speed taken as TAS).

With no other command every aircraft so follows its recorded path; how closely is what
:mod:`bluesky_gym.realtraffic.fidelity` measures. Aircraft are created through
:func:`create_recorded`, the one place that passes the recorded type code to the simulator.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from bluesky_gym.core.aircraft import FALLBACK_TYPE, ROTORCRAFT_TYPES, aircraft_performance
from bluesky_gym.core.atmosphere import tas2cas
from bluesky_gym.core.physics import Physics
from bluesky_gym.core.units import FT, NM
from bluesky_gym.realtraffic.flights import RecordedFlights

Array = NDArray[np.float64]
IntArray = NDArray[np.int64]

ALT_LOOKAHEAD = 60.0  # s: the altitude target is the recorded altitude this far ahead
SPEED_LOOKAHEAD = 20.0  # s: the speed target is the recorded speed this far ahead
PROFILE_STEP = 10.0  # s: the commanded vertical speed is the recorded one over this time ahead
ALT_CORRECTION_TIME = 30.0  # s: an altitude error is corrected over this time
MIN_VS = 0.5  # m/s: smallest vertical speed commanded for a climb or descent
MIN_CAS = 30.0  # m/s: floor of the commanded CAS (a speed below 2 would be read as a Mach number)
EARTH_RADIUS = 6371000.0  # m, for the flat neighbourhood test of the window catalogue
MAX_ROUTE_POINTS = 32  # route points given to an aircraft (those ahead of it, in order)
SEPARATION_NM = 5.0  # NM, horizontal separation minimum
SEPARATION_VERTICAL = 1000.0 * FT  # m, vertical separation minimum


@dataclass(frozen=True)
class Window:
    """One scenario of a collection.

    Attributes:
        start: Window start [s since the collection's epoch].
        duration: Window length [s].
        ownship: Flight index of the ownship (recorded over the whole window).
        traffic: Flight indices of the other aircraft, closest first.
    """

    start: float
    duration: float
    ownship: int
    traffic: tuple[int, ...]

    @property
    def flights(self) -> tuple[int, ...]:
        """Ownship first, then the traffic: the aircraft slots of the scenario."""
        return (self.ownship, *self.traffic)


def windows(
    flights: RecordedFlights,
    duration: float,
    stride: float,
    radius_nm: float,
    min_traffic: int,
    max_traffic: int,
) -> list[Window]:
    """Every scenario window of a collection.

    Window starts are multiples of ``stride``; an ownship is a flight recorded over the whole
    window; its traffic are the flights recorded at some time of the window within ``radius_nm`` of
    the ownship at the same time (at the sample times), the ``max_traffic`` closest. Windows with
    fewer than ``min_traffic`` aircraft around are skipped.
    """
    t_start, t_end = flights.t0, flights.t_end
    first = np.ceil(t_start.min() / stride) * stride
    starts = np.arange(first, t_end.max() - duration + 1e-9, stride)
    n_steps = int(round(duration / flights.period)) + 1
    offsets = np.arange(n_steps) * flights.period
    out: list[Window] = []
    radius_m = radius_nm * NM
    for s in starts:
        own = np.flatnonzero((t_start <= s) & (t_end >= s + duration))
        others = np.flatnonzero((t_start <= s + duration) & (t_end >= s))
        if own.size == 0 or others.size < 2:
            continue
        times = s + offsets  # (k,)
        tt = np.broadcast_to(times, (others.size, n_steps))
        ff = np.broadcast_to(others[:, None], tt.shape)
        st = flights.at(ff, tt)
        present = (tt >= t_start[ff]) & (tt <= t_end[ff])
        lat, lon = np.radians(st["lat"]), np.radians(st["lon"])
        for o in own:
            row = int(np.searchsorted(others, o))
            dlat = lat - lat[row]
            dlon = (lon - lon[row] + np.pi) % (2 * np.pi) - np.pi
            d = EARTH_RADIUS * np.hypot(dlat, dlon * np.cos(lat[row]))
            d = np.where(present, d, np.inf).min(axis=1)
            d[row] = np.inf
            near = np.flatnonzero(d <= radius_m)
            if near.size < min_traffic:
                continue
            near = near[np.argsort(d[near], kind="stable")][:max_traffic]
            out.append(Window(float(s), float(duration), int(o), tuple(int(others[k]) for k in near)))
    return out


def split_windows(all_windows: list[Window], test_fraction: float, t_min: float, t_max: float) -> tuple[list[Window], list[Window]]:
    """Split windows by time: training windows end before the split time, test windows start at or after it.

    The split time is ``t_min + (1 - test_fraction) (t_max - t_min)``; windows across it are
    dropped, so the two parts share no recorded second.
    """
    t_split = t_min + (1.0 - test_fraction) * (t_max - t_min)
    train = [w for w in all_windows if w.start + w.duration <= t_split]
    test = [w for w in all_windows if w.start >= t_split]
    return train, test


def create_recorded(
    sim: Physics, env: IntArray, slot: IntArray, lat: Array, lon: Array, hdg: Array, alt: Array, cas: Array, typecode: NDArray[np.str_]
) -> None:
    """Create recorded aircraft: the one place that hands their recorded type to the simulator.

    ``typecode`` is the recorded ICAO type code. A type BlueSky flies with OpenAP flies with its
    own data (synonyms included); a missing code, a type BlueSky does not know and a rotorcraft
    fly with BlueSky's fallback for an unknown type, the B744. (The core flies rotorcraft with
    BlueSky's rotor model since RealTrafficCREnv-v0 was defined; its recorded flights keep the
    fallback, so that its episodes stay as they were.)
    """
    actype = [simulator_type(str(t)) for t in np.atleast_1d(typecode)]
    sim.create(env, slot, lat=lat, lon=lon, hdg=hdg, alt=alt, spd=cas, actype=actype)


def simulator_type(typecode: str) -> str:
    """The type name :func:`create_recorded` gives the simulator for a recorded ``typecode`` (upper case).

    ``resolve_type`` of it is the type whose performance the aircraft flies with.
    """
    code = typecode.strip().upper()
    return FALLBACK_TYPE if (not code or code in ROTORCRAFT_TYPES) else code


class WindowPlayer:
    """Plays recorded windows on a batched physics, one window per airspace.

    Args:
        sim: The physics (its ``max_aircraft`` bounds the aircraft of a window, its
            ``max_waypoints`` the route points given to each).
        flights: The recorded flights the windows refer to.
        guided_ownship: Whether slot 0 also gets the recorded vertical and speed profile (False
            when an agent flies it).
        guided_traffic: Whether the other slots get it (False when every aircraft is an agent).
    """

    def __init__(self, sim: Physics, flights: RecordedFlights, guided_ownship: bool = True, guided_traffic: bool = True) -> None:
        self.sim = sim
        self.flights = flights
        self.guided_ownship = guided_ownship
        self.guided_traffic = guided_traffic
        shape = (sim.n_envs, sim.max_aircraft)
        self.flight = np.full(shape, -1, np.int64)  # recorded flight of each slot (-1: none)
        self.t_appear = np.full(shape, np.inf)  # s since epoch: first sample used
        self.t_leave = np.full(shape, -np.inf)  # s since epoch: last recorded sample
        self.created = np.zeros(shape, bool)
        self.t_created = np.full(shape, np.nan)  # s since epoch: when the aircraft was created
        self.done = np.zeros(shape, bool)  # created and deleted again
        self.start = np.zeros(sim.n_envs)  # s since epoch: window start
        self.elapsed = np.zeros(sim.n_envs)  # s since the window start
        self._cas = flights.cas()

    def now(self, envs: IntArray | None = None) -> Array:
        """Recorded-time clock of airspaces ``envs`` [s since epoch]."""
        idx = slice(None) if envs is None else envs
        return self.start[idx] + self.elapsed[idx]

    def load(self, envs: IntArray, chosen: list[Window]) -> None:
        """Put ``chosen[i]`` into airspace ``envs[i]`` (empty airspaces) and create the aircraft present at its start."""
        envs = np.asarray(envs, dtype=np.int64)
        for e, w in zip(envs, chosen):
            if len(w.flights) > self.sim.max_aircraft:
                raise ValueError(f"window has {len(w.flights)} aircraft, the physics {self.sim.max_aircraft} slots")
            fl = np.asarray(w.flights, dtype=np.int64)
            self.flight[e] = -1
            self.flight[e, : len(fl)] = fl
            self.t_appear[e] = np.inf
            self.t_leave[e] = -np.inf
            self.t_appear[e, : len(fl)] = np.maximum(self.flights.t0[fl], w.start)
            self.t_leave[e, : len(fl)] = np.minimum(self.flights.t_end[fl], w.start + w.duration)
            self.start[e] = w.start
        self.elapsed[envs] = 0.0
        self.created[envs] = False
        self.t_created[envs] = np.nan
        self.done[envs] = False
        self.update(envs)

    def advance_clock(self, seconds: float) -> None:
        """Count ``seconds`` of simulated time in every airspace (after the physics ran them)."""
        self.elapsed += seconds

    def update(self, envs: IntArray | None = None) -> None:
        """Create the aircraft due, delete those past their recording, and give every traffic aircraft its targets."""
        sim = self.sim
        envs = np.arange(sim.n_envs) if envs is None else np.asarray(envs, dtype=np.int64)
        now = self.now()[:, None]
        rows = np.zeros(sim.n_envs, bool)
        rows[envs] = True
        ended = rows[:, None] & self.created & ~self.done & (now > self.t_leave + 1e-6)
        if ended.any():
            e, s = np.nonzero(ended)
            sim.delete(e, s)
            self.done[e, s] = True
        due = rows[:, None] & (self.flight >= 0) & ~self.created & (now >= self.t_appear - 1e-6) & (now <= self.t_leave + 1e-6)
        if due.any():
            e, s = np.nonzero(due)
            self._create(e, s, now[e, 0])
        guided = rows[:, None] & self.created & ~self.done
        if not self.guided_ownship:
            guided[:, 0] = False
        if not self.guided_traffic:
            guided[:, 1:] = False
        if guided.any():
            e, s = np.nonzero(guided)
            self.guide(e, s, now[e, 0])

    def _create(self, e: IntArray, s: IntArray, t: Array) -> None:
        fl = self.flight[e, s]
        st = self.flights.at(fl, t)
        cas = tas2cas(st["gs"], st["alt"])
        create_recorded(self.sim, e, s, st["lat"], st["lon"], st["trk"], st["alt"], cas, self.flights.typecode[fl])
        self.created[e, s] = True
        self.t_created[e, s] = t
        cap = self.sim.max_waypoints
        for ei, si, fi, ti in zip(e, s, fl, t):
            k = (ti - self.flights.t0[fi]) / self.flights.period
            pts = self.flights.route_points(int(fi))
            ahead = pts[pts > k + 1e-9][:cap]
            if ahead.size == 0:
                continue
            idx = self.flights.offset[fi] + ahead
            for la, lo in zip(self.flights.lat[idx], self.flights.lon[idx]):
                self.sim.add_waypoint(int(ei), int(si), float(la), float(lo))

    def targets(self, e: IntArray, s: IntArray, t: Array) -> tuple[Array, Array]:
        """Recorded altitude target [m] (ALT_LOOKAHEAD ahead) and CAS target [m/s] (SPEED_LOOKAHEAD ahead) of slots ``(e, s)`` at ``t``."""
        fl = self.flight[e, s]
        alt = self.flights.at(fl, t + ALT_LOOKAHEAD)["alt"]
        sp = self.flights.at(fl, t + SPEED_LOOKAHEAD)
        return alt, tas2cas(sp["gs"], sp["alt"])

    def guide(self, e: IntArray, s: IntArray, t: Array, alt_offset: Array | float = 0.0, cas_offset: Array | float = 0.0) -> None:
        """Command the recorded altitude and speed profile (plus offsets [m], [m/s]) to slots ``(e, s)``.

        The altitude target is the recorded altitude :data:`ALT_LOOKAHEAD` ahead; the vertical speed
        is the recorded one over the next :data:`PROFILE_STEP` plus a correction of the current
        altitude error over :data:`ALT_CORRECTION_TIME`, at most the aircraft type's ``vsmax``: a
        larger request makes BlueSky's performance limit trade climb for acceleration
        (``(1 - ax/axmax) vsmax``, docs/dynamics.md §1.5), so an aircraft accelerating at its limit
        would stop climbing.
        """
        alt_target, cas_target = self.targets(e, s, t)
        alt_target = alt_target + alt_offset
        sim = self.sim
        fl = self.flight[e, s]
        alt_now = self.flights.at(fl, t)["alt"] + alt_offset
        rate = (self.flights.at(fl, t + PROFILE_STEP)["alt"] + alt_offset - alt_now) / PROFILE_STEP
        vs = rate + (alt_now - sim.alt[e, s]) / ALT_CORRECTION_TIME
        dz = alt_target - sim.alt[e, s]
        level = np.abs(rate) < MIN_VS  # the recording is level now: hold its current altitude
        hold = ~level & (vs * dz <= 0.0)  # ahead of the recorded profile: wait for it
        move = ~level & ~hold
        if level.any():
            sim.cmd_altitude(e[level], s[level], alt_now[level])
        if hold.any():
            sim.cmd_altitude(e[hold], s[hold], sim.alt[e[hold], s[hold]])
        if move.any():
            em, sm = e[move], s[move]
            vsmax = np.array([aircraft_performance(name).vsmax for name in sim.aircraft_type(em, sm)])
            sim.cmd_altitude(em, sm, alt_target[move], np.sign(dz[move]) * np.clip(np.abs(vs[move]), MIN_VS, vsmax))
        sim.cmd_speed(e, s, np.maximum(cas_target + cas_offset, MIN_CAS))
