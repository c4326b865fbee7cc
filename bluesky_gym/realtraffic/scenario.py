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
from bluesky_gym.core.atmosphere import isa_layered, tas2cas, tas2cas_at
from bluesky_gym.core.commands import select_altitude, select_speed
from bluesky_gym.core.jit import grid_range, jit, jit_inline
from bluesky_gym.core.physics import Physics
from bluesky_gym.core.scalar import clip, maximum, sign
from bluesky_gym.core.units import FT, NM
from bluesky_gym.realtraffic.flights import RecordedFlights, lerp, sample_weight

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


# --- the recorded profile as commands: one scalar form for the CPU and the device ------------------
@jit_inline
def profile_targets(t0, offset, period, rec_alt, rec_gs, f, t):
    """Recorded altitude target [m] (:data:`ALT_LOOKAHEAD` ahead) and CAS target [m/s] (:data:`SPEED_LOOKAHEAD` ahead) of flight ``f`` at ``t``.

    The CAS is the recorded ground speed taken as TAS at the recorded altitude (layered ISA, as
    :func:`~bluesky_gym.core.atmosphere.tas2cas`). The recordings are those of
    :meth:`~bluesky_gym.realtraffic.flights.RecordedFlights.kernel_arrays`.
    """
    i0, w = sample_weight(t0, offset, period, f, t + ALT_LOOKAHEAD)
    alt = lerp(rec_alt, i0, w)
    i0, w = sample_weight(t0, offset, period, f, t + SPEED_LOOKAHEAD)
    p, rho, _ = isa_layered(lerp(rec_alt, i0, w))
    return alt, tas2cas_at(lerp(rec_gs, i0, w), p, rho)


@jit_inline
def profile_commands(t0, offset, period, rec_alt, rec_gs, f, t, alt, vsmax, alt_offset, cas_offset):
    """The commands that make an aircraft at altitude ``alt`` [m] fly flight ``f``'s recorded profile at ``t`` (plus offsets [m], [m/s]).

    See :meth:`WindowPlayer.guide`. Returns the ALT command's altitude [m] and vertical speed
    [m/s] (0: none given, BlueSky's default rate) and the SPD command's CAS [m/s]; ``vsmax`` is the
    aircraft type's largest vertical speed [m/s].
    """
    alt_target, cas_target = profile_targets(t0, offset, period, rec_alt, rec_gs, f, t)
    alt_target = alt_target + alt_offset
    i0, w = sample_weight(t0, offset, period, f, t)
    alt_now = lerp(rec_alt, i0, w) + alt_offset
    i0, w = sample_weight(t0, offset, period, f, t + PROFILE_STEP)
    rate = (lerp(rec_alt, i0, w) + alt_offset - alt_now) / PROFILE_STEP
    vs = rate + (alt_now - alt) / ALT_CORRECTION_TIME
    dz = alt_target - alt
    spd = maximum(cas_target + cas_offset, MIN_CAS)
    if abs(rate) < MIN_VS:  # the recording is level now: hold its current altitude
        return alt_now, 0.0, spd
    if vs * dz <= 0.0:  # ahead of the recorded profile: wait for it
        return alt, 0.0, spd
    return alt_target, sign(dz) * clip(abs(vs), MIN_VS, vsmax), spd


@jit
def profile_command_rows(t0, offset, period, rec_alt, rec_gs, flight, envs, slots, t, alt, vsmax, alt_offset, cas_offset, alt_out, vs_out, spd_out):
    """:func:`profile_commands` of aircraft ``(envs[r], slots[r])`` at ``t[r]``, offsets ``alt_offset[r]``, ``cas_offset[r]``.

    The host's form: the physics' commands are then given with them (:meth:`WindowPlayer.guide`).
    """
    for r in grid_range(envs.shape[0]):
        e = envs[r]
        s = slots[r]
        alt_out[r], vs_out[r], spd_out[r] = profile_commands(
            t0, offset, period, rec_alt, rec_gs, flight[e, s], t[r], alt[e, s], vsmax[e, s], alt_offset[r], cas_offset[r]
        )


@jit
def guide_airspaces(t0, offset, period, rec_alt, rec_gs, flight, guided, start, elapsed, alt, vsmax, selalt, swvnav, selvs, selspd, swvnavspd):
    """:meth:`WindowPlayer.update`'s guidance on the device: :func:`profile_commands` of every ``guided`` aircraft, written into the autopilot state.

    Airspace ``e``'s recorded-time clock is ``start[e] + elapsed[e]``; the commands are the core's
    (:func:`~bluesky_gym.core.commands.select_altitude`, :func:`~bluesky_gym.core.commands.select_speed`).
    """
    for e in grid_range(guided.shape[0]):
        now = start[e] + elapsed[e]
        for s in range(guided.shape[1]):
            if guided[e, s]:
                target, vs, spd = profile_commands(t0, offset, period, rec_alt, rec_gs, flight[e, s], now, alt[e, s], vsmax[e, s], 0.0, 0.0)
                select_altitude(e, s, target, vs, alt, selalt, swvnav, selvs)
                select_speed(e, s, spd, selspd, swvnavspd)


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
        self.guided = np.zeros(shape, bool)  # flying now and given the recorded profile (guided_ownship / guided_traffic)
        self.vsmax = np.zeros(shape)  # m/s: the largest vertical speed of each aircraft's type (set at its creation)
        self.start = np.zeros(sim.n_envs)  # s since epoch: window start
        self.elapsed = np.zeros(sim.n_envs)  # s since the window start

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
        self.guided[envs] = False
        self.update(envs)

    def advance_clock(self, seconds: float) -> None:
        """Count ``seconds`` of simulated time in every airspace (after the physics ran them)."""
        self.elapsed += seconds

    def update(self, envs: IntArray | None = None) -> None:
        """Create the aircraft due, delete those past their recording, and give every guided aircraft its targets."""
        envs = np.arange(self.sim.n_envs) if envs is None else np.asarray(envs, dtype=np.int64)
        self.schedule(envs)
        rows = np.zeros(self.sim.n_envs, bool)
        rows[envs] = True
        guided = rows[:, None] & self.guided
        if guided.any():
            e, s = np.nonzero(guided)
            self.guide(e, s, self.now()[e])

    def due(self, envs: IntArray | None = None) -> tuple[tuple[IntArray, IntArray], tuple[IntArray, IntArray]]:
        """The aircraft of airspaces ``envs`` (all when None) past their recording, and those due to appear: ``((env, slot), (env, slot))``.

        Known on the host from the recorded times and the clock alone (no aircraft state is read);
        in the order of the airspaces, then of their slots.
        """
        if envs is None:
            rows: IntArray | slice = slice(None)
            index = np.arange(self.sim.n_envs)
        else:
            index = np.unique(np.asarray(envs, dtype=np.int64))
            rows = index
        now = self.now(index)[:, None]
        created, t_leave = self.created[rows], self.t_leave[rows]
        ended = created & ~self.done[rows] & (now > t_leave + 1e-6)
        due = (self.flight[rows] >= 0) & ~created & (now >= self.t_appear[rows] - 1e-6) & (now <= t_leave + 1e-6)
        ended_r, ended_s = np.nonzero(ended)
        due_r, due_s = np.nonzero(due)
        return (index[ended_r], ended_s), (index[due_r], due_s)

    def next_event(self, envs: IntArray | None = None) -> Array:
        """The earliest recorded time [s since epoch] at which an aircraft of each airspace ``envs`` (all when None) may leave or appear.

        Inf where none will. Before it (by more than the schedule's 1e-6 s tolerance) :meth:`due`
        finds nothing in that airspace, so a step need not look at its slots.
        """
        rows = slice(None) if envs is None else np.asarray(envs, dtype=np.int64)
        created = self.created[rows]
        leave = np.where(created & ~self.done[rows], self.t_leave[rows], np.inf)
        appear = np.where((self.flight[rows] >= 0) & ~created, self.t_appear[rows], np.inf)
        out: Array = np.minimum(leave, appear).min(axis=1)
        return out

    def schedule(self, envs: IntArray | None = None) -> None:
        """Delete the aircraft of airspaces ``envs`` (all when None) past their recording, then create those due (:meth:`due`)."""
        (ended_e, ended_s), (due_e, due_s) = self.due(envs)
        if ended_e.size:
            self.sim.delete(ended_e, ended_s)
            self.done[ended_e, ended_s] = True
            self.guided[ended_e, ended_s] = False
        if due_e.size:
            self._create(due_e, due_s, self.now()[due_e])

    def _create(self, e: IntArray, s: IntArray, t: Array) -> None:
        fl = self.flight[e, s]
        st = self.flights.at(fl, t)
        cas = tas2cas(st["gs"], st["alt"])
        codes = self.flights.typecode[fl]
        create_recorded(self.sim, e, s, st["lat"], st["lon"], st["trk"], st["alt"], cas, codes)
        self.created[e, s] = True
        self.t_created[e, s] = t
        self.vsmax[e, s] = [aircraft_performance(simulator_type(str(c))).vsmax for c in codes]
        self.guided[e, s] = np.where(s == 0, self.guided_ownship, self.guided_traffic)
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

    def guide(self, e: IntArray, s: IntArray, t: Array, alt_offset: Array | float = 0.0, cas_offset: Array | float = 0.0) -> None:
        """Command the recorded altitude and speed profile (plus offsets [m], [m/s]) to slots ``(e, s)``.

        The altitude target is the recorded altitude :data:`ALT_LOOKAHEAD` ahead; the vertical speed
        is the recorded one over the next :data:`PROFILE_STEP` plus a correction of the current
        altitude error over :data:`ALT_CORRECTION_TIME`, at most the aircraft type's ``vsmax``: a
        larger request makes BlueSky's performance limit trade climb for acceleration
        (``(1 - ax/axmax) vsmax``, docs/dynamics.md §1.5), so an aircraft accelerating at its limit
        would stop climbing. Where the recording is level, the recorded altitude is held; where the
        aircraft is ahead of the recorded profile, its own altitude. The kernel
        :func:`profile_command_rows` (:func:`profile_commands`, which the device's
        :func:`guide_airspaces` gives as well), then the physics' ALT and SPD commands.
        """
        e = np.asarray(e, dtype=np.int64)
        s = np.asarray(s, dtype=np.int64)
        rows = e.shape[0]
        t = np.ascontiguousarray(np.broadcast_to(np.asarray(t, dtype=np.float64), (rows,)))
        alt_off, cas_off = (np.ascontiguousarray(np.broadcast_to(np.asarray(x, dtype=np.float64), (rows,))) for x in (alt_offset, cas_offset))
        alt, vs, spd = np.empty(rows), np.empty(rows), np.empty(rows)
        f = self.flights
        profile_command_rows(
            f.t0, f.offset, float(f.period), f.alt, f.gs, self.flight, e, s, t, self.sim.alt, self.vsmax, alt_off, cas_off, alt, vs, spd
        )
        self.sim.cmd_altitude(e, s, alt, vs)
        self.sim.cmd_speed(e, s, spd)
