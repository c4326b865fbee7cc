"""The batched BlueSky-equivalent traffic simulator.

One :class:`Simulator` holds ``n_envs`` independent airspaces with room for ``max_aircraft``
aircraft each. Every state array is shaped ``(n_envs, max_aircraft)`` and an ``active`` mask says
which slots hold an aircraft. Creating and deleting aircraft writes into preallocated slots, and
one :meth:`Simulator.step` advances every airspace by ``dt`` seconds with the compiled step
kernel (:mod:`bluesky_gym.core.step`), in BlueSky 1.1.1's update order [docs/dynamics.md §2].

The kernel skips inactive slots; their values are meaningless and readers must use the
``active`` mask. :class:`Simulator` implements :class:`~bluesky_gym.core.physics.Physics`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from bluesky_gym.core import geo as _geo
from bluesky_gym.core import performance as pf
from bluesky_gym.core.aircraft import DEFAULT_TYPE, aircraft_performance
from bluesky_gym.core.atmosphere import vcasormach
from bluesky_gym.core.commands import altitude_commands
from bluesky_gym.core.conflicts import create_conflicts, detect_loop, resolve_pair_search
from bluesky_gym.core.lnav import BANK_LNAV, lnav_kernel, turn_distances
from bluesky_gym.core.resolution import (
    AsasConfig,
    ConflictResolver,
    ended_loop,
    mvp_loop,
    release_loop,
    renew_loop,
    resolution_targets,
    resume_loop,
    targets_loop,
)
from bluesky_gym.core.resolvers import resolver_class
from bluesky_gym.core.state import (
    FIELD_INDEX,
    FLOAT_FIELDS,
    NON_FLOAT_STATE,
    STATE_FIELDS,
    AircraftState,
    aircraft_index,
    checked_index,
    clear_flagged,
    gather_columns,
    gather_rows,
    scatter_columns,
    scatter_rows,
)
from bluesky_gym.core.step import MEMO_COLUMNS, post_kernel, pre_kernel, run_kernel, step_kernel
from bluesky_gym.core.units import ASAS_INTERVAL, BANK_DEFAULT, G0, NM, NO_VALUE, PERFORMANCE_INTERVAL, WIND_MIN_ALT
from bluesky_gym.core.wind import WindField

Array = NDArray[np.float64]
IntArray = NDArray[np.int64]


def _route_position(lat: ArrayLike, lon: ArrayLike) -> tuple[Array, Array]:
    """A waypoint position as BlueSky's route stores it: (lat + 90) % 180 - 90, (lon + 180) % 360 - 180.

    The round trip can move a coordinate by one ulp, which LNAV then sees.
    """
    lat = np.asarray(lat, dtype=np.float64)
    lon = np.asarray(lon, dtype=np.float64)
    return (lat + 90.0) % 180.0 - 90.0, (lon + 180.0) % 360.0 - 180.0


class _Field:
    """A state array stored as one row of a contiguous block.

    Reading gives a writable (n_envs, max_aircraft) view; assigning copies into the block, so the
    arrays never move and the compiled kernel can work on the block in place.
    """

    def __init__(self, block: str, index: int) -> None:
        self.block = block
        self.index = index

    def __get__(self, obj: Simulator | None, owner: type) -> Array:
        if obj is None:
            return self  # type: ignore[return-value]
        return getattr(obj, self.block)[self.index]  # type: ignore[no-any-return]

    def __set__(self, obj: Simulator, value: ArrayLike) -> None:
        getattr(obj, self.block)[self.index][...] = value


class Simulator(AircraftState):
    """Many independent BlueSky airspaces stepped together.

    Args:
        n_envs: Number of independent airspaces (environments).
        max_aircraft: Aircraft slots per airspace.
        dt: Simulation time step [s].
        max_waypoints: Route capacity per aircraft.
        perf: Performance data of the default aircraft type (None: BlueSky's OpenAP A320, read
            when first needed, so that building a simulator does not import OpenAP). An
            aircraft created without ``actype`` is of this type.
        geo: ``"compiled"`` (BlueSky's compiled geo functions, as a plain BlueSky run uses them)
            or ``"python"`` (BlueSky's Python geo module, which the reference gym environments end up
            with). Only LNAV uses them; they differ in the last bits.
        pair_search: Which aircraft pairs conflict resolution evaluates: ``"all-pairs"`` (every
            pair, in (n_envs, max_aircraft, max_aircraft) arrays), ``"grid"`` (the pairs a grid of
            latitude bands finds, as lists: time and memory about linear in the aircraft at a
            given density; :func:`~bluesky_gym.core.conflicts.detect_grid`) or ``"auto"`` (the
            grid from :data:`~bluesky_gym.core.conflicts.GRID_MIN_AIRCRAFT` slots per airspace).
            Both give the same flight to the bit.
    """

    def __init__(
        self,
        n_envs: int,
        max_aircraft: int,
        dt: float = 1.0,
        max_waypoints: int = 4,
        perf: pf.AircraftPerformance | None = None,
        geo: str = "compiled",
        pair_search: str = "auto",
    ) -> None:
        self.pair_search = resolve_pair_search(pair_search, int(max_aircraft))
        if geo not in ("compiled", "python"):
            raise ValueError(f"geo must be 'compiled' or 'python', got {geo!r}")
        self.geo = geo
        self._qdrdist = _geo.qdrdist if geo == "compiled" else _geo.qdrdist_python
        if n_envs < 1 or max_aircraft < 1:
            raise ValueError(f"n_envs and max_aircraft must be >= 1, got {n_envs} and {max_aircraft}")
        if not dt > 0:
            raise ValueError(f"dt must be > 0 s, got {dt}")
        self.n_envs = int(n_envs)
        self.max_aircraft = int(max_aircraft)
        self.max_waypoints = int(max_waypoints)
        self.dt = float(dt)
        # Aircraft types: name -> row of the performance table the kernels read per aircraft.
        # Row 0 is the default type; rows are added as new types are created, never removed.
        # The default type's data (OpenAP, about a second to import) is read at first use.
        default = DEFAULT_TYPE if perf is None else perf.name
        self._type_names: list[str] = [default.upper()]
        self._type_rows: dict[str, int] = {default.upper(): 0}
        self._performance: tuple[list[pf.AircraftPerformance], Array] | None = None
        if perf is not None:
            self._performance = ([perf], np.array([pf.table_row(perf)], dtype=np.float64))
        self.simt = 0.0
        self._since_perf = PERFORMANCE_INTERVAL  # the first step always runs the performance update
        shape = (self.n_envs, self.max_aircraft)
        self._defaults: dict[str, tuple[type, float]] = {}
        # All float64 state lives in one block (fields, n_envs, max_aircraft) that never moves.
        n_slots = self.n_envs * self.max_aircraft
        # Rows are padded so that they do not start at the same offset modulo 4 KiB, which would
        # make the compiled kernel's per-field streams collide in the CPU caches.
        pad = next(p for p in (24, 40, 56) if ((n_slots + p) * 8) % 4096 not in (0, 64, 4032))
        self._float_raw = np.empty((len(FLOAT_FIELDS), n_slots + pad))
        self._float_flat = self._float_raw[:, :n_slots]  # (fields, aircraft) view, padded rows
        self._float_block = self._float_flat.reshape(len(FLOAT_FIELDS), *shape)  # a view as well
        for name, dtype, value in STATE_FIELDS:
            if dtype is np.float64:
                self._float_block[FIELD_INDEX[name]] = value
            else:
                setattr(self, name, np.full(shape, value, dtype=dtype))
            self._defaults[name] = (dtype, value)
        self.route_lat = np.zeros((*shape, self.max_waypoints))  # deg
        self.route_lon = np.zeros((*shape, self.max_waypoints))  # deg
        self.type_index = np.zeros(shape, dtype=np.int64)  # row of the performance table (see aircraft_type)
        self._type_flat = self.type_index.reshape(-1)  # a view
        self.wind = WindField(self.n_envs)
        self._empty = np.zeros(0)
        self._phase_flat = self.phase.reshape(-1)  # a view
        self._active_flat = self.active.reshape(-1)  # a view
        # Memo table of the step kernel: (n_envs * max_aircraft, columns), NaN = nothing cached.
        self._memo = np.full((self.n_envs * self.max_aircraft, MEMO_COLUMNS), np.nan)
        self._empty_bool = np.zeros(0, dtype=np.bool_)
        self._empty_int = np.zeros(0, dtype=np.int64)
        # Conflict resolution (BlueSky's ASAS with RESO MVP): the configuration of each airspace that
        # has one, and the resolution state of every airspace (pairs being resolved, held values).
        self._asas: dict[int, AsasConfig] = {}
        # The pairs being resolved: (n_envs, m, m) for all-pairs; for the grid, sorted keys (env * m + own) * m + intruder.
        m_pairs = self.max_aircraft if self.pair_search == "all-pairs" else 0
        self._reso_pairs = np.zeros((self.n_envs, m_pairs, m_pairs), dtype=np.bool_)
        self._reso_keys = np.zeros(0, np.int64)
        self._reso_held = np.full((4, self.n_envs, self.max_aircraft), np.nan)
        self._reso_following = np.zeros((self.n_envs, self.max_aircraft), dtype=np.bool_)  # who follows (methods that make everyone follow)
        # One resolver per ASAS configuration, kept from step to step for its work arrays (the grid's;
        # a cache: the resolution state above is handed to it at each step).
        self._resolvers: dict[AsasConfig, ConflictResolver] = {}
        self._vs_limits_cache: tuple[int, Array, Array] = (0, np.zeros(0), np.zeros(0))

    def _types_loaded(self) -> tuple[list[pf.AircraftPerformance], Array]:
        if self._performance is None:
            perf = aircraft_performance(self._type_names[0])
            self._performance = ([perf], np.array([pf.table_row(perf)], dtype=np.float64))
        return self._performance

    @property
    def perf(self) -> pf.AircraftPerformance:
        """Performance data of the default aircraft type (row 0 of the type table)."""
        return self._types_loaded()[0][0]

    @property
    def _type_perf(self) -> list[pf.AircraftPerformance]:
        """Performance data of each type in use, by row."""
        return self._types_loaded()[0]

    @property
    def _table(self) -> Array:
        """The performance table the kernels read: one row of coefficients per type in use."""
        return self._types_loaded()[1]

    @_table.setter
    def _table(self, table: Array) -> None:
        self._performance = (self._types_loaded()[0], table)

    # ------------------------------------------------------------------------------------------
    # Airspace management
    # ------------------------------------------------------------------------------------------
    def reset_envs(self, envs: ArrayLike | None = None) -> None:
        """Remove all aircraft and wind from the given airspaces (all when ``envs`` is None)."""
        idx = slice(None) if envs is None else np.asarray(envs, dtype=np.int64)
        for name, (_dtype, value) in self._defaults.items():
            getattr(self, name)[idx] = value
        self.route_lat[idx] = 0.0
        self.route_lon[idx] = 0.0
        self.type_index[idx] = 0
        self.wind.clear(None if envs is None else idx)
        for e in range(self.n_envs) if envs is None else np.atleast_1d(np.asarray(envs, dtype=np.int64)).tolist():
            self._asas.pop(int(e), None)
        self._forget_resolutions(idx)

    def _forget_resolutions(self, idx: slice | IntArray) -> None:
        """Drop the resolutions in progress of airspaces ``idx``."""
        self._reso_pairs[idx] = False
        self._reso_held[:, idx] = np.nan
        self._reso_following[idx] = False
        if self._reso_keys.size:
            forget = np.zeros(self.n_envs, np.bool_)
            forget[idx] = True
            self._reso_keys = self._reso_keys[~forget[self._reso_keys // (self.max_aircraft * self.max_aircraft)]]

    def create(
        self,
        env: ArrayLike,
        slot: ArrayLike,
        lat: ArrayLike = 52.0,
        lon: ArrayLike = 4.0,
        hdg: ArrayLike = 0.0,
        alt: ArrayLike = 0.0,
        spd: ArrayLike = 0.0,
        actype: str | Sequence[str] | NDArray[np.str_] | None = None,
    ) -> None:
        """Create aircraft, as BlueSky's ``traf.cre`` [docs/dynamics.md §2.4].

        Every aircraft gets the performance data of its own type (BlueSky 1.1.1 gives all aircraft
        of one ``traf.cre`` call the data of the last one's type; the BlueSky backend therefore
        creates a mixed batch in runs of equal type) [docs/dynamics.md §1.2].

        Args:
            env: Airspace index of each new aircraft.
            slot: Slot index of each new aircraft (must be free).
            lat: Latitude [deg].
            lon: Longitude [deg]; wrapped once to [-180, 180].
            hdg: Heading [deg], stored as given.
            alt: Altitude [m].
            spd: CAS [m/s], or Mach when 0.1 < spd < 2.
            actype: Aircraft type, one name for all or one per aircraft, any case (None: the
                default type, the A320). Unknown types fly as the B744, as in BlueSky;
                rotorcraft fly BlueSky's rotor model [docs/dynamics.md §1.2b].
        """
        env, slot = self._index(env, slot)
        if np.any(self.active[env, slot]):
            raise ValueError("create: an aircraft already exists in one of the requested slots")
        n = env.shape[0]
        rows = self._type_rows_of(actype, n)
        lat_a, lon_a, hdg_a, alt_a, spd_a = (np.broadcast_to(np.asarray(x, dtype=np.float64), (n,)).copy() for x in (lat, lon, hdg, alt, spd))
        lon_a[lon_a > 180.0] -= 360.0
        lon_a[lon_a < -180.0] += 360.0
        for name, (_dtype, value) in self._defaults.items():
            getattr(self, name)[env, slot] = value
        self.route_lat[env, slot] = 0.0
        self.route_lon[env, slot] = 0.0
        self._memo.reshape(self.n_envs, self.max_aircraft, -1)[env, slot] = np.nan  # the slot's cached values were another aircraft's
        self.type_index[env, slot] = rows
        # BlueSky's performance defaults of a new aircraft: phase NA, whose envelope (through the
        # always-true en-route clause) is the en-route one, and WRAP's take-off acceleration (a
        # rotorcraft: its own envelope and BlueSky's default of 2 m/s^2).
        initial = np.array([(p.vmin_enroute, p.vmax_enroute, p.axmax_initial) for p in self._type_perf])[rows]
        self.vmin[env, slot] = initial[:, 0]
        self.vmax[env, slot] = initial[:, 1]
        self.axmax[env, slot] = initial[:, 2]
        self.active[env, slot] = True
        self._reso_following[env, slot] = False  # a new aircraft does not follow a resolution (BlueSky: cr.active starts False)
        self.lat[env, slot] = lat_a
        self.lon[env, slot] = lon_a
        self.alt[env, slot] = alt_a
        self.hdg[env, slot] = hdg_a
        self.trk[env, slot] = hdg_a
        tas, cas, mach = vcasormach(spd_a, alt_a)
        self.tas[env, slot] = tas
        self.cas[env, slot] = cas
        self.mach[env, slot] = mach
        self.gs[env, slot] = tas
        hdgrad = np.radians(hdg_a)
        gsnorth = tas * np.cos(hdgrad)
        gseast = tas * np.sin(hdgrad)
        windy = self.wind.has_wind[env]
        if np.any(windy):
            e, s = env[windy], slot[windy]
            applywind = alt_a[windy] > WIND_MIN_ALT
            wn, we = self.wind.at(e, lat_a[windy], lon_a[windy])
            self.windnorth[e, s] = wn
            self.windeast[e, s] = we
            gsn = gsnorth[windy] + wn * applywind
            gse = gseast[windy] + we * applywind
            gsnorth[windy] = gsn
            gseast[windy] = gse
            self.trk[e, s] = np.logical_not(applywind) * hdg_a[windy] + applywind * np.degrees(np.arctan2(gse, gsn))
            self.gs[e, s] = np.sqrt(gsn**2 + gse**2)
        self.gsnorth[env, slot] = gsnorth
        self.gseast[env, slot] = gseast
        self.selspd[env, slot] = cas
        self.selalt[env, slot] = alt_a
        self.ap_tas[env, slot] = tas
        self.ap_alt[env, slot] = alt_a
        self.ap_trk[env, slot] = self.trk[env, slot]

    def _type_rows_of(self, actype: str | Sequence[str] | NDArray[np.str_] | None, n: int) -> IntArray:
        """Rows of the performance table for ``n`` new aircraft of type(s) ``actype`` (new types are added)."""
        if actype is None:
            return np.zeros(n, dtype=np.int64)
        names = [actype] * n if isinstance(actype, str) else [str(a) if isinstance(a, np.str_) else a for a in actype]
        if len(names) != n:
            raise ValueError(f"actype: expected one type or {n} types (one per aircraft), got {len(names)}")
        rows = np.empty(n, dtype=np.int64)
        for k, name in enumerate(names):
            if not isinstance(name, str):
                raise TypeError(f"actype must be a type name (str), got {type(name).__name__} {name!r}")
            key = name.upper()
            row = self._type_rows.get(key)
            if row is None:
                perf = aircraft_performance(key)
                row = len(self._type_names)
                self._type_names.append(key)
                self._type_rows[key] = row
                self._type_perf.append(perf)
                self._table = np.vstack([self._table, np.array([pf.table_row(perf)])])
            rows[k] = row
        return rows

    @property
    def aircraft_types(self) -> tuple[str, ...]:
        """The type names in use, upper case; ``type_index`` holds each aircraft's position in it."""
        return tuple(self._type_names)

    def aircraft_type(self, env: ArrayLike, slot: ArrayLike) -> list[str]:
        """Type names of aircraft, as they were given at creation (upper case; an unknown type keeps its name).

        Args:
            env: Airspace indices.
            slot: Aircraft slots (holding aircraft).
        """
        env, slot = self._index(env, slot)
        return [self._type_names[r] for r in self.type_index[env, slot]]

    def aircraft_performance(self, env: int, slot: int) -> pf.AircraftPerformance:
        """The performance data aircraft ``slot`` of airspace ``env`` flies with (a B744's for an unknown type)."""
        env_a, slot_a = self._index(env, slot)
        return self._type_perf[int(self.type_index[env_a[0], slot_a[0]])]

    def delete(self, env: ArrayLike, slot: ArrayLike) -> None:
        """Delete aircraft (free their slots)."""
        env, slot = self._index(env, slot)
        self.active[env, slot] = False

    # ------------------------------------------------------------------------------------------
    # Commands [docs/dynamics.md §2.5]; each acts as if stacked before the next step.
    # ------------------------------------------------------------------------------------------
    def cmd_heading(self, env: ArrayLike, slot: ArrayLike, hdg: ArrayLike) -> None:
        """``HDG acid hdg`` [deg]: select a track (wind-corrected above 50 ft); LNAV off."""
        env, slot = self._index(env, slot)
        hdg = np.asarray(hdg, dtype=np.float64)
        trk = hdg.copy() if hdg.shape == env.shape else np.broadcast_to(hdg, env.shape).copy()
        windy = self.wind.has_wind[env] if self.wind.any else None
        if windy is not None and windy.any():
            e, s = env[windy], slot[windy]
            above = self.alt[e, s] > WIND_MIN_ALT
            e, s, h = e[above], s[above], trk[windy][above]
            tasnorth = self.tas[e, s] * np.cos(np.radians(h))
            taseast = self.tas[e, s] * np.sin(np.radians(h))
            vn, ve = self.wind.at(e, self.lat[e, s], self.lon[e, s])
            sel = np.flatnonzero(windy)[above]
            trk[sel] = np.degrees(np.arctan2(taseast + ve, tasnorth + vn)) % 360.0
        self.ap_trk[env, slot] = trk
        self.swlnav[env, slot] = False

    def cmd_speed(self, env: ArrayLike, slot: ArrayLike, casmach: ArrayLike) -> None:
        """``SPD acid`` with the speed already in SI: CAS [m/s] or Mach; VNAV speed off."""
        env, slot = self._index(env, slot)
        self.selspd[env, slot] = casmach
        self.swvnavspd[env, slot] = False

    def cmd_altitude(self, env: ArrayLike, slot: ArrayLike, alt: ArrayLike, vs: ArrayLike | None = None) -> None:
        """``ALT acid alt [vs]`` in SI (BlueSky's ``ap.selaltcmd``): the kernel :func:`~bluesky_gym.core.commands.altitude_commands`.

        A vertical speed of 0 is none given (as in BlueSky). Each aircraft at most once per call.
        """
        env, slot = self._index(env, slot)
        target = np.ascontiguousarray(np.broadcast_to(np.asarray(alt, dtype=np.float64), env.shape))
        vs_arr = np.zeros(env.shape) if vs is None else np.ascontiguousarray(np.broadcast_to(np.asarray(vs, dtype=np.float64), env.shape))
        altitude_commands(env, slot, target, vs_arr, self.alt, self.selalt, self.swvnav, self.selvs)

    def cmd_vertical_speed(self, env: ArrayLike, slot: ArrayLike, vs: ArrayLike) -> None:
        """``VS acid vs`` in m/s: a rate only; nothing moves without a different ``selalt``."""
        env, slot = self._index(env, slot)
        self.selvs[env, slot] = vs
        self.swvnav[env, slot] = False

    def set_autopilot(
        self,
        env: ArrayLike,
        slot: ArrayLike,
        *,
        selalt: ArrayLike | None = None,
        selvs: ArrayLike | None = None,
        swvnav: ArrayLike | None = None,
        ap_trk: ArrayLike | None = None,
    ) -> None:
        """Write autopilot values directly, as the reference gym code writes BlueSky's arrays.

        Unlike the commands, nothing else changes (no LNAV or VNAV switching, no vertical-speed
        logic). Each argument left None stays unchanged; values broadcast over ``(env, slot)``.

        Args:
            env: Airspace indices.
            slot: Aircraft slots.
            selalt: Selected altitude [m].
            selvs: Selected vertical speed [m/s].
            swvnav: VNAV switch.
            ap_trk: Autopilot track [deg].
        """
        env, slot = self._index(env, slot)
        if selalt is not None:
            self.selalt[env, slot] = selalt
        if selvs is not None:
            self.selvs[env, slot] = selvs
        if swvnav is not None:
            self.swvnav[env, slot] = swvnav
        if ap_trk is not None:
            self.ap_trk[env, slot] = ap_trk

    def set_state(self, env: ArrayLike, slot: ArrayLike, *, alt: ArrayLike | None = None, hdg: ArrayLike | None = None) -> None:
        """Write aircraft state directly (the reference gym code's ``traf.alt[i] = ...``, ``traf.hdg[i] = ...``).

        Args:
            env: Airspace indices.
            slot: Aircraft slots.
            alt: Altitude [m], or None to leave it.
            hdg: Heading [deg], or None to leave it.
        """
        env, slot = self._index(env, slot)
        if alt is not None:
            self.alt[env, slot] = alt
        if hdg is not None:
            self.hdg[env, slot] = hdg

    def add_waypoint(self, env: ArrayLike, slot: ArrayLike, lat: ArrayLike, lon: ArrayLike) -> None:
        """``ADDWPT acid lat lon``: append a fly-by waypoint (before the destination).

        The aircraft then goes direct to its active waypoint with LNAV on [docs/dynamics.md §2.6].
        """
        env, slot = self._index(env, slot)
        self._check_route_room(env, slot)
        nwp = self.nwp[env, slot]
        idx = np.where(self.route_has_dest[env, slot], nwp - 1, nwp)
        # Insert at idx: move a destination (if any) one place up.
        has_dest = self.route_has_dest[env, slot]
        if np.any(has_dest):
            e, s, i = env[has_dest], slot[has_dest], idx[has_dest]
            self.route_lat[e, s, i + 1] = self.route_lat[e, s, i]
            self.route_lon[e, s, i + 1] = self.route_lon[e, s, i]
            # BlueSky keeps the active index, so an active destination becomes the new waypoint.
        self.route_lat[env, slot, idx], self.route_lon[env, slot, idx] = _route_position(lat, lon)
        self._after_route_insert(env, slot, grew=np.ones(env.shape, bool))

    def set_destination(self, env: ArrayLike, slot: ArrayLike, lat: ArrayLike, lon: ArrayLike) -> None:
        """``DEST acid lat lon``: set (or overwrite) the route's destination [docs/dynamics.md §2.7].

        VNAV is left out of this core (see README), so a destination that is the route's only
        waypoint is flown with LNAV only.
        """
        env, slot = self._index(env, slot)
        has_dest = self.route_has_dest[env, slot]
        self._check_route_room(env[~has_dest], slot[~has_dest])
        idx = np.where(has_dest, self.nwp[env, slot] - 1, self.nwp[env, slot])
        self.route_lat[env, slot, idx], self.route_lon[env, slot, idx] = _route_position(lat, lon)
        self.route_has_dest[env, slot] = True
        self._after_route_insert(env, slot, grew=~has_dest)

    def cmd_direct(self, env: ArrayLike, slot: ArrayLike, waypoint: ArrayLike) -> None:
        """``DIRECT acid wpname``: make route waypoint ``waypoint`` (0-based) active and fly to it; LNAV on.

        As BlueSky's ``route.direct``, the next-leg bearing and the last-waypoint flag stay as they were.
        """
        env, slot = self._index(env, slot)
        wp = np.broadcast_to(np.asarray(waypoint, dtype=np.int64), env.shape)
        if np.any((wp < 0) | (wp >= self.nwp[env, slot])):
            raise ValueError("DIRECT: waypoint index outside the aircraft's route")
        self.iactwp[env, slot] = wp
        self._direct(env, slot)

    def cmd_lnav(self, env: ArrayLike, slot: ArrayLike, on: ArrayLike) -> None:
        """``LNAV acid ON/OFF``; ON (when off) goes direct to the best active waypoint (BlueSky's ``route.findact``)."""
        env, slot = self._index(env, slot)
        on_a = np.broadcast_to(np.asarray(on, dtype=bool), env.shape)
        if np.any(on_a & (self.nwp[env, slot] <= 0)):
            raise ValueError("LNAV ON: the aircraft has no waypoints or destination")
        self.swlnav[env[~on_a], slot[~on_a]] = False
        switch = on_a & ~self.swlnav[env, slot]
        e, s = env[switch], slot[switch]
        for k in range(e.size):
            self.iactwp[e[k], s[k]] = self._find_active(int(e[k]), int(s[k]))
        self._direct(e, s)

    def _find_active(self, env: int, slot: int) -> int:
        """The waypoint LNAV activates when switched on (BlueSky ``route.findact``).

        It is the nearest waypoint not behind the active one, or the one after it when the turn to
        it takes longer than flying to it.
        """
        nwp = int(self.nwp[env, slot])
        if nwp == 1:
            return 0
        dy = self.route_lat[env, slot, :nwp] - self.lat[env, slot]
        dx = (self.route_lon[env, slot, :nwp] - self.lon[env, slot]) * np.cos(np.deg2rad(self.lat[env, slot]))
        dist2 = dx * dx + dy * dy
        near = max(int(self.iactwp[env, slot]), int(np.argmin(dist2)))
        if near + 1 < nwp:
            qdr = math.degrees(math.atan2(dx[near], dy[near]))
            delhdg = abs((self.trk[env, slot] - qdr + 180.0) % 360.0 - 180.0)
            tas = max(0.01, float(self.tas[env, slot]))
            time_turn = tas * math.radians(delhdg) / (G0 * math.tan(BANK_DEFAULT))
            time_straight = math.sqrt(dist2[near]) * 60.0 * NM / tas
            if time_turn > time_straight:
                near += 1
        return near

    def _check_route_room(self, env: IntArray, slot: IntArray) -> None:
        if np.any(self.nwp[env, slot] >= self.max_waypoints):
            raise ValueError(f"route full: at most {self.max_waypoints} waypoints per aircraft (max_waypoints)")

    def _after_route_insert(self, env: IntArray, slot: IntArray, grew: NDArray[np.bool_]) -> None:
        self.nwp[env[grew], slot[grew]] += 1
        # BlueSky: next_qdr is computed from the (old) active waypoint before it is set.
        self.next_qdr[env, slot] = self._next_leg_qdr(env, slot, self.iactwp[env, slot])
        self.swlastwp[env, slot] = self.iactwp[env, slot] == self.nwp[env, slot] - 1
        self.iactwp[env, slot] = np.maximum(self.iactwp[env, slot], 0)
        self._direct(env, slot)

    def _next_leg_qdr(self, env: IntArray, slot: IntArray, iact: IntArray) -> Array:
        """Bearing of the leg after waypoint ``iact`` (``route.getnextqdr``), -999 if none."""
        nxt = (iact > -1) & (iact < self.nwp[env, slot] - 1)
        i0 = np.clip(iact, 0, self.max_waypoints - 1)
        i1 = np.clip(iact + 1, 0, self.max_waypoints - 1)
        qdr, _ = self._qdrdist(
            self.route_lat[env, slot, i0], self.route_lon[env, slot, i0], self.route_lat[env, slot, i1], self.route_lon[env, slot, i1]
        )
        return np.where(nxt, qdr, NO_VALUE)

    def _direct(self, env: IntArray, slot: IntArray) -> None:
        """``DIRECT`` to the active waypoint: activate it from the current position; LNAV on."""
        i = self.iactwp[env, slot]
        wlat = self.route_lat[env, slot, i]
        wlon = self.route_lon[env, slot, i]
        self.actwp_lat[env, slot] = wlat
        self.actwp_lon[env, slot] = wlon
        qdr, _ = self._qdrdist(self.lat[env, slot], self.lon[env, slot], wlat, wlon)
        self.curlegdir[env, slot] = qdr
        self.turndist[env, slot] = turn_distances(self.tas[env, slot], qdr, self.next_qdr[env, slot])
        self.turnphi[env, slot] = BANK_LNAV
        self.swlnav[env, slot] = True

    def creconfs(
        self,
        env: ArrayLike,
        target: ArrayLike,
        slot: ArrayLike,
        dpsi: ArrayLike,
        dcpa: ArrayLike,
        tlosh: ArrayLike,
        dh: ArrayLike | None = None,
        tlosv: ArrayLike | None = None,
        spd: ArrayLike | None = None,
        actype: str | Sequence[str] | NDArray[np.str_] | None = None,
    ) -> None:
        """Create intruders in conflict with targets (BlueSky ``traf.creconfs``).

        See :func:`bluesky_gym.core.conflicts.create_conflicts` for the arguments; ``actype`` is
        the intruders' type (one name or one per intruder; None: the default type).
        """
        create_conflicts(self, env, target, slot, dpsi, dcpa, tlosh, dh, tlosv, spd, actype=actype)

    # ------------------------------------------------------------------------------------------
    # Stepping [docs/dynamics.md §2.1-2.2]
    # ------------------------------------------------------------------------------------------
    def set_conflict_resolution(self, env: ArrayLike, config: AsasConfig) -> None:
        """Switch BlueSky's ASAS for airspaces ``env``: conflict detection and resolution flown by the aircraft.

        With detection on and ``RESO MVP`` (or another method of
        :data:`~bluesky_gym.core.resolvers.RESOLVERS`, :attr:`AsasConfig.method`;
        :attr:`AsasConfig.resolving`), every step detects the conflicts of the start-of-step state
        after the autopilot, runs the method (:class:`~bluesky_gym.core.resolution.MVPResolver`,
        ...) and flies its track, speed, altitude and
        vertical speed wherever BlueSky's ASAS would, as BlueSky 1.1.1's ``APorASAS`` does; an
        aircraft whose resolution ends goes DIRECT to its best active waypoint. A new
        configuration keeps the resolutions in progress. Without ``resolving`` the airspace flies
        its autopilot (detection alone changes nothing).

        Raises:
            ValueError: ``dt`` is below BlueSky's ASAS interval (1 s; the ASAS would then run every
                few steps, which is not modelled), an unknown method, or a method that does not
                support this simulator's ``pair_search``.
        """
        envs = checked_index(env, self.n_envs, "environment index")
        method = resolver_class(config.method)
        if config.resolving and self.pair_search not in method.pair_searches:
            allowed = " or ".join(repr(p) for p in method.pair_searches)
            raise ValueError(f"RESO {config.method} needs pair_search {allowed}, this simulator has {self.pair_search!r}")
        if config.resolving and self.dt < ASAS_INTERVAL - 1e-9:
            raise ValueError(f"conflict resolution needs dt >= {ASAS_INTERVAL} s (BlueSky's asas_dt), got {self.dt} s")
        for e in np.atleast_1d(envs).tolist():
            self._asas[int(e)] = config
        if not config.resolving:
            self._forget_resolutions(envs)

    def conflict_resolution(self, env: int) -> AsasConfig:
        """The ASAS configuration of airspace ``env`` (BlueSky's defaults unless set)."""
        return self._asas.get(int(env), AsasConfig())

    def step(self) -> None:
        """Advance every airspace by ``dt`` seconds."""
        do_perf = self._performance_due()
        self.simt += self.dt
        if any(c.resolving for c in self._asas.values()):
            self._step_resolving(do_perf)
            return
        self._advance(do_perf)

    def _advance(self, do_perf: bool) -> None:
        """One step of every aircraft without conflict resolution: LNAV, then the step kernel."""
        if self.swlnav.any():
            lnav_kernel(self._float_flat, *self._lnav_args())
        wn, we, haswind, any_wind = self._wind_args()
        step_kernel(
            self._float_flat,
            self._phase_flat,
            wn,
            we,
            haswind,
            any_wind,
            do_perf,
            self.dt,
            self._table,
            self._type_args(),
            self._memo,
            self._active_flat,
        )

    def _step_resolving(self, do_perf: bool) -> None:
        """:meth:`step` with conflict resolution: autopilot, then ASAS, then the kinematics (BlueSky's ``traf.update``)."""
        if self.swlnav.any():
            lnav_kernel(self._float_flat, *self._lnav_args())
        type_args = self._type_args()
        pre_kernel(self._float_flat, self._phase_flat, do_perf, self._table, type_args, self._memo, self._active_flat)
        shape = (self.n_envs, self.max_aircraft)
        follow = np.zeros(shape, dtype=np.bool_)
        targets = np.zeros((4, *shape))  # track, ground speed, altitude, vertical speed
        vsmin, vsmax = self._vs_limits()
        groups: dict[AsasConfig, list[int]] = {}
        for e, config in self._asas.items():
            if config.resolving:
                groups.setdefault(config, []).append(e)
        for config, members in groups.items():  # airspaces with the same settings resolve in one batch
            envs = np.array(sorted(members), dtype=np.int64)
            every = envs.size == self.n_envs
            sel: slice | IntArray = slice(None) if every else envs  # views where the group is every airspace
            view: Simulator | _AirspaceView = self if every else _AirspaceView(self, envs)
            resolver = self._resolvers.get(config)
            if resolver is None:
                resolver = self._resolvers[config] = resolver_class(config.method)(
                    config.settings,
                    rpz=config.rpz,
                    hpz=config.hpz,
                    lookahead=config.lookahead,
                    detector=str(config.detector),
                    python_geo=self.geo == "python",
                    pair_search=self.pair_search,
                )
            resolver.vsmin, resolver.vsmax = vsmin[view.type_index], vsmax[view.type_index]
            resolver.pairs, resolver.held = self._reso_pairs[sel], self._reso_held[:, sel]
            resolver.following = self._reso_following[sel]
            if self.pair_search == "grid":
                resolver.pair_keys = self._group_keys(envs)
            group_follow, group_ended = resolver.advance(view)
            self._reso_pairs[sel], self._reso_held[:, sel] = resolver.pairs, resolver.held
            self._reso_following[sel] = resolver.following if resolver.follow_all else False
            if self.pair_search == "grid":
                self._store_group_keys(envs, resolver.pair_keys)
            follow[sel] = group_follow
            targets[:, sel] = resolution_targets(resolver.held)
            # BlueSky's waypoint recovery: an aircraft whose resolution ended goes DIRECT to its best waypoint.
            if group_ended.any():
                for k, s in zip(*np.nonzero(group_ended & (self.nwp[sel] > 0))):
                    e = int(envs[k])
                    self.iactwp[e, s] = self._find_active(e, int(s))
                    self._direct(np.array([e]), np.array([s]))
        wn, we, haswind, any_wind = self._wind_args()
        post_kernel(
            self._float_flat,
            self._phase_flat,
            wn,
            we,
            haswind,
            any_wind,
            self.dt,
            self._table,
            type_args,
            self._memo,
            self._active_flat,
            follow.reshape(-1),
            *(np.ascontiguousarray(t).reshape(-1) for t in targets),
        )

    def _vs_limits(self) -> tuple[Array, Array]:
        """The vertical-speed limits of each type in use, by row (vsmin, vsmax) [m/s]; types are only ever added."""
        n, vsmin, vsmax = self._vs_limits_cache
        perf = self._type_perf
        if n != len(perf):
            vsmin, vsmax = np.array([p.vsmin for p in perf]), np.array([p.vsmax for p in perf])
            self._vs_limits_cache = (len(perf), vsmin, vsmax)
        return vsmin, vsmax

    def _group_keys(self, envs: IntArray) -> NDArray[np.int64]:
        """The pair keys of airspaces ``envs`` (sorted), renumbered as a resolver of those airspaces sees them."""
        mm = self.max_aircraft * self.max_aircraft
        if envs.size == self.n_envs:
            return self._reso_keys
        env: IntArray = self._reso_keys // mm
        pos = np.minimum(np.searchsorted(envs, env), envs.size - 1)
        mine = envs[pos] == env
        keys: IntArray = self._reso_keys[mine] - (env[mine] - pos[mine]) * mm
        return keys

    def _store_group_keys(self, envs: IntArray, keys: NDArray[np.int64]) -> None:
        """Put back the pair keys of airspaces ``envs`` from a resolver of those airspaces."""
        mm = self.max_aircraft * self.max_aircraft
        if envs.size == self.n_envs:
            self._reso_keys = keys
            return
        mine = np.zeros(self.n_envs, np.bool_)
        mine[envs] = True
        local = keys // mm
        self._reso_keys = np.sort(np.concatenate((self._reso_keys[~mine[self._reso_keys // mm]], keys + (envs[local] - local) * mm)))

    def run(self, n_steps: int, trace: bool = False, stop: Callable[[Array], ArrayLike] | None = None) -> Array | None:
        """Advance every airspace by ``n_steps`` steps (same result as calling :meth:`step` n times).

        While any wind is uniform, the aircraft do not influence each other between steps (LNAV
        included), so each one is advanced through all ``n_steps`` at once while it sits in the
        CPU cache.

        Args:
            n_steps: Number of steps.
            trace: Also return every aircraft's position after each step.
            stop: Optional ``stop(track) -> ended_at``: given the positions
                ``(k, 2, n_envs, max_aircraft)`` of the first ``k <= n_steps`` steps, an int array
                ``(n_envs,)`` with the number of steps after which each airspace's episode ended
                (``1..k``), or 0 where it did not end within the track. An airspace that ended after
                ``j < n_steps`` steps is left in its state after ``j`` steps; when every airspace
                ended, the shared clock stops at the largest ``j``. Implies ``trace``. (Here ``stop``
                is called once, with the whole track, and the ended airspaces are rewound.)

        Returns:
            With ``trace`` or ``stop``, an array (n_steps, 2, n_envs, max_aircraft) of latitudes
            and longitudes [deg] (empty slots, and airspaces after their end, hold meaningless
            values); otherwise None.
        """
        if n_steps < 0:
            raise ValueError(f"n_steps must be >= 0, got {n_steps}")
        if stop is not None and any(c.resolving for c in self._asas.values()):
            raise ValueError("run(stop=...) cannot rewind airspaces with conflict resolution; step them instead")
        if stop is None:
            return self._run(n_steps, trace)
        start = self._snapshot()
        track = self._run(n_steps, True)
        assert track is not None
        ended = np.asarray(stop(track), dtype=np.int64).reshape(-1)
        if ended.shape != (self.n_envs,) or np.any((ended < 0) | (ended > n_steps)):
            raise ValueError(f"stop must return (n_envs,) = ({self.n_envs},) step counts in [0, {n_steps}]")
        early = np.flatnonzero((ended > 0) & (ended < n_steps))
        if early.size:
            end = self._snapshot()
            self._restore(start)
            stopped = []
            done = 0
            for j in np.unique(ended[early]):  # rewind and run again to each end, keeping those airspaces
                self._run(int(j) - done, False)
                done = int(j)
                group = early[ended[early] == j]
                stopped.append((group, self._snapshot(group)))
            if not np.all(ended > 0) or ended.max() == n_steps:
                self._restore(end)  # some airspace ran to the end: so do the clocks
            for group, state in stopped:
                self._restore(state, group)
        return track

    def _run(self, n_steps: int, trace: bool) -> Array | None:
        """:meth:`run` without ``stop``."""
        track = np.empty((n_steps, 2, self.n_envs, self.max_aircraft)) if trace else None
        independent = n_steps > 1 and not (self.wind.count > 1).any() and not any(c.resolving for c in self._asas.values())
        if not independent:
            for k in range(n_steps):
                self.step()
                if track is not None:
                    track[k, 0], track[k, 1] = self.lat, self.lon
            return track
        if self.dt >= PERFORMANCE_INTERVAL - 1e-9:  # due at every step (what the timer gives)
            self._since_perf = 0.0
            perf_due = np.ones(n_steps, bool)
        else:
            perf_due = np.array([self._performance_due() for _ in range(n_steps)])
        self.simt += n_steps * self.dt
        self._advance_many(perf_due, track)
        return track

    def _advance_many(self, perf_due: NDArray[np.bool_], track: Array | None) -> None:
        """``len(perf_due)`` steps of independent aircraft, each aircraft through all of them (see :meth:`run`); positions into ``track``."""
        wn, we, haswind, any_wind = self._wind_args()  # uniform: the same wind wherever the aircraft goes
        run_kernel(
            self._float_flat,
            self._phase_flat,
            wn,
            we,
            haswind,
            any_wind,
            perf_due,
            self.dt,
            self._table,
            self._type_args(),
            self._memo,
            self._active_flat,
            self._lnav_args() if self.swlnav.any() else None,
            None if track is None else track.reshape(perf_due.shape[0], 2, -1),
        )

    def _type_args(self) -> IntArray:
        """Each aircraft's row of the performance table as the kernels take it (empty: all row 0)."""
        return self._type_flat if len(self._type_names) > 1 else self._empty_int

    def _wind_args(self) -> tuple[Array, Array, NDArray[np.bool_], bool]:
        """Wind at every aircraft as the kernels take it: (north, east, has wind, any wind)."""
        if not self.wind.any:
            return self._empty, self._empty, self._empty_bool, False
        wn, we = (np.ascontiguousarray(w).reshape(-1) for w in self.wind.at_all(self.lat, self.lon))
        return wn, we, np.repeat(self.wind.has_wind, self.max_aircraft), True

    def _snapshot(self, envs: ArrayLike | None = None) -> dict[str, Any]:
        """A copy of the aircraft and route state of airspaces ``envs`` (all when None), and the clocks.

        The wind definition is not part of it (it does not change while stepping).
        """
        idx = slice(None) if envs is None else checked_index(envs, self.n_envs, "environment index")
        snap: dict[str, Any] = {"_float_block": self._float_block[:, idx].copy(), "simt": self.simt, "_since_perf": self._since_perf}
        for name in NON_FLOAT_STATE:
            snap[name] = getattr(self, name)[idx].copy()
        return snap

    def _restore(self, snap: dict[str, Any], envs: ArrayLike | None = None) -> None:
        """Put airspaces back to a :meth:`_snapshot` of the same airspaces.

        Args:
            snap: The snapshot.
            envs: The airspaces it was taken of; None means all of them, clocks included (a
                partial restore leaves the shared clocks as they are).
        """
        if envs is None:
            self._float_block[...] = snap["_float_block"]
            self.simt, self._since_perf = snap["simt"], snap["_since_perf"]
            for name in NON_FLOAT_STATE:
                getattr(self, name)[...] = snap[name]
            return
        idx = checked_index(envs, self.n_envs, "environment index")
        self._float_block[:, idx] = snap["_float_block"]
        for name in NON_FLOAT_STATE:
            getattr(self, name)[idx] = snap[name]

    def _lnav_args(self) -> tuple[Any, ...]:
        """The LNAV arrays as the compiled kernels take them (flattened views)."""
        m = self.n_envs * self.max_aircraft
        return (
            self.swlnav.reshape(-1),
            self.swvnav.reshape(-1),
            self.swvnavspd.reshape(-1),
            self.swlastwp.reshape(-1),
            self.active.reshape(-1),
            self.iactwp.reshape(-1),
            self.nwp.reshape(-1),
            self.route_lat.reshape(m, -1),
            self.route_lon.reshape(m, -1),
            self.geo == "python",
        )

    def _performance_due(self) -> bool:
        """BlueSky's 1 s performance timer: every step for dt >= 1 s."""
        self._since_perf += self.dt
        if self._since_perf >= PERFORMANCE_INTERVAL - 1e-9:
            self._since_perf = 0.0
            return True
        return False

    # ------------------------------------------------------------------------------------------
    def _index(self, env: ArrayLike, slot: ArrayLike) -> tuple[IntArray, IntArray]:
        """Validated, broadcast 1-D (env, slot) index arrays."""
        return aircraft_index(env, slot, self.n_envs, self.max_aircraft)

    def state_fields(self) -> Sequence[str]:
        """Names of the per-aircraft state arrays."""
        return [name for name, _, _ in STATE_FIELDS]


class _AirspaceView:
    """The state arrays the resolution methods read of some airspaces of a :class:`Simulator`, shaped (len(envs), max_aircraft).

    Copies, or views of the simulator's arrays where ``envs`` are all its airspaces (``envs`` is sorted); read only.
    """

    def __init__(self, sim: Simulator, envs: IntArray) -> None:
        k: slice | IntArray = slice(None) if envs.size == sim.n_envs else envs
        self.active = sim.active[k]
        self.type_index = sim.type_index[k]
        self.lat, self.lon, self.alt, self.tas = sim.lat[k], sim.lon[k], sim.alt[k], sim.tas[k]
        self.gs, self.trk, self.vs, self.gseast, self.gsnorth = sim.gs[k], sim.trk[k], sim.vs[k], sim.gseast[k], sim.gsnorth[k]
        self.selalt, self.ap_vs, self.vmin, self.vmax = sim.selalt[k], sim.ap_vs[k], sim.vmin[k], sim.vmax[k]
        self.cas, self.ap_trk, self.selspd, self.selvs = sim.cas[k], sim.ap_trk[k], sim.selspd[k], sim.selvs[k]  # read by Swarm
        self.hdg = sim.hdg[k]  # read by SSD
        self._sim, self._envs = sim, envs

    def aircraft_type(self, env: ArrayLike, slot: ArrayLike) -> list[str]:
        """Type names of aircraft; ``env`` counts the airspaces of this view."""
        return self._sim.aircraft_type(self._envs[np.asarray(env, dtype=np.int64)], slot)


for _name, _i in FIELD_INDEX.items():
    setattr(Simulator, _name, _Field("_float_block", _i))
del _name, _i


#: The attributes holding the aircraft and route state that the kernels read and write.
_KERNEL_STATE = frozenset({*(name for name, _, _ in STATE_FIELDS), "route_lat", "route_lon", "type_index"}) | {
    "_float_raw",
    "_float_flat",
    "_float_block",
    "_phase_flat",
    "_active_flat",
    "_type_flat",
    "_memo",
    "_reso_pairs",
    "_reso_held",
}


#: The autopilot switches :meth:`DeviceSimulator.device_arrays` gives (bool, per aircraft).
DEVICE_SWITCHES = ("swlnav", "swvnav", "swvnavspd", "swlastwp")


class DeviceSimulator(Simulator):
    """A :class:`Simulator` whose aircraft state lives on a CUDA GPU while it is stepped.

    The state moves to the device at the first step after a change on the host, and stays there
    while the simulator steps: each :meth:`step` is one launch of the LNAV kernel (when any
    aircraft flies LNAV) and one of the step kernel over every aircraft of every airspace, and
    :meth:`run` one launch of the run kernel (every aircraft through all its steps), whatever the
    number of airspaces. With conflict resolution a step is nine launches: LNAV, autopilot,
    detection, MVP, the ASAS bookkeeping, ``resumenav``, ended resolutions, targets, kinematics.
    These are the CPU core's own kernels (:mod:`bluesky_gym.core.step`, :mod:`bluesky_gym.core.lnav`,
    :mod:`bluesky_gym.core.conflicts`, :mod:`bluesky_gym.core.resolution`), compiled for CUDA by
    :mod:`bluesky_gym.core.cuda_target`. :meth:`device_arrays` gives device views of the state
    for other kernels (the tasks'), without bringing it back.
    Reading or writing any state array (or any command, which does) first copies the state back
    to the host; the next step copies it to the device again. Everything else is the
    :class:`Simulator`'s, so this class implements :class:`~bluesky_gym.core.physics.Physics`.

    On the device: no wind, or a wind that is uniform within each airspace (one point or none);
    conflict resolution when every airspace has the same CSTATEBASED configuration with MVP.
    Wind fields of several points, STATEBASED and mixed ASAS configurations raise
    :class:`NotImplementedError` at the step (use :class:`Simulator`). Airspaces hold at most
    :data:`bluesky_gym.core.cuda_target.SCRATCH_CAPACITY` + 1 aircraft.

    Results agree with :class:`Simulator` to within the rounding of the GPU's arithmetic (fused
    multiply-adds, libdevice's functions; docs/backends.md), and are bit-identical under
    numba-cuda's simulator (``NUMBA_ENABLE_CUDASIM=1``), which runs the same kernels as Python.

    The arguments are :class:`Simulator`'s. Needs the ``gpu`` extra and a CUDA GPU (or the simulator).
    """

    def __init__(
        self,
        n_envs: int,
        max_aircraft: int,
        dt: float = 1.0,
        max_waypoints: int = 4,
        perf: pf.AircraftPerformance | None = None,
        geo: str = "compiled",
    ) -> None:
        from bluesky_gym.core import cuda_target

        cuda_target.require()
        if max_aircraft - 1 > cuda_target.SCRATCH_CAPACITY:
            raise ValueError(f"DeviceSimulator: at most {cuda_target.SCRATCH_CAPACITY + 1} aircraft per airspace, got {max_aircraft}")
        object.__setattr__(self, "_device", None)
        super().__init__(n_envs, max_aircraft, dt=dt, max_waypoints=max_waypoints, perf=perf, geo=geo)
        self._cuda = cuda_target
        self._wind_key: tuple[bytes, ...] | None = None
        self._wind_device: tuple[Any, Any, Any, bool] | None = None

    def __getattribute__(self, name: str) -> Any:
        if name in _KERNEL_STATE and object.__getattribute__(self, "_device") is not None:
            object.__getattribute__(self, "_to_host")()
        return object.__getattribute__(self, name)

    @property
    def on_device(self) -> bool:
        """Whether the current state is on the device (the host arrays are stale until the next access)."""
        return object.__getattribute__(self, "_device") is not None

    def device_arrays(self, *names: str) -> tuple[Any, ...]:
        """Device views (n_envs, max_aircraft) of state arrays, for kernels launched on the device; the state stays there.

        ``names`` are float state fields (``lat``, ``tas``, ...), ``active`` or an autopilot switch
        (:data:`DEVICE_SWITCHES`). The views are current until the next command or host read
        (which bring the state back to the host). Kernels may write the float fields and the
        switches (as commands do); the next step flies with what they wrote.

        Raises:
            KeyError: A name that is none of these.
        """
        d = self._to_device()
        out = []
        for name in names:
            if name == "active" or name in DEVICE_SWITCHES:
                out.append(d[name].reshape(self.n_envs, self.max_aircraft))
            elif name in FIELD_INDEX:
                out.append(d["F"][FIELD_INDEX[name]].reshape(self.n_envs, self.max_aircraft))
            else:
                raise KeyError(f"device_arrays: {name!r} is not a float state field, 'active' or one of {DEVICE_SWITCHES}")
        return tuple(out)

    def device_state(self) -> Any:
        """The device's float state block (fields, n_envs, max_aircraft): every float field of every aircraft (:data:`FLOAT_FIELDS`' order).

        For kernels that keep and give back the state of whole airspaces (a task's device step
        that stops some airspaces within a decision step); current, and writable, as
        :meth:`device_arrays`' views.
        """
        return self._to_device()["F"].reshape(len(FLOAT_FIELDS), self.n_envs, self.max_aircraft)

    def reset_on_host(self, envs: NDArray[np.int64], reset: Callable[[], None]) -> None:
        """Run ``reset`` (new scenarios of airspaces ``envs``) on the host, moving only those airspaces' aircraft.

        While the state is on the device, ``reset`` must clear airspaces ``envs`` first
        (:meth:`reset_envs`) and then read and write those airspaces only: the host arrays of
        the others are stale meanwhile. Afterwards the aircraft of ``envs`` go to the device state
        (one upload and one launch per state array), and the rest of the state never leaves
        the device. Where conflict resolution runs (its bookkeeping spans airspaces), or where
        the state is on the host already, the whole state is on the host for ``reset``, as
        with any command.
        """
        envs = np.asarray(envs, dtype=np.int64)
        m = self.max_aircraft
        self._on_host((envs[:, None] * m + np.arange(m)).reshape(-1), reset, gather=False)

    def edit_on_host(self, env: ArrayLike, slot: ArrayLike, edit: Callable[[], None]) -> None:
        """Run ``edit`` (a change of aircraft ``(env, slot)``) on the host, moving only those aircraft.

        While the state is on the device, those aircraft come to the host (one launch and one
        copy per state array), ``edit`` runs, and they go back (one upload and one launch per
        state array): the rest of the state never leaves the device. ``edit`` must read and
        write those aircraft only; the host arrays of the others are stale meanwhile.
        :meth:`create`, :meth:`delete` and :meth:`add_waypoint` use it, so that a task's traffic
        can enter and leave mid-episode without the whole state crossing. Where conflict
        resolution runs, or where the state is on the host already, ``edit`` simply runs on the
        host, as any command does.
        """
        env_a, slot_a = self._index(env, slot)
        self._on_host(np.unique(env_a * self.max_aircraft + slot_a), edit, gather=True)

    def create(
        self,
        env: ArrayLike,
        slot: ArrayLike,
        lat: ArrayLike = 52.0,
        lon: ArrayLike = 4.0,
        hdg: ArrayLike = 0.0,
        alt: ArrayLike = 0.0,
        spd: ArrayLike = 0.0,
        actype: str | Sequence[str] | NDArray[np.str_] | None = None,
    ) -> None:
        """:meth:`Simulator.create`; on the device, only the new aircraft's rows cross (:meth:`edit_on_host`)."""
        self.edit_on_host(env, slot, lambda: Simulator.create(self, env, slot, lat, lon, hdg, alt, spd, actype))

    def delete(self, env: ArrayLike, slot: ArrayLike) -> None:
        """:meth:`Simulator.delete`; on the device, only those aircraft's rows cross (:meth:`edit_on_host`)."""
        self.edit_on_host(env, slot, lambda: Simulator.delete(self, env, slot))

    def delete_flagged(self, flags: Any) -> None:
        """Delete the aircraft flagged in ``flags``, a device array (n_envs, max_aircraft) of booleans, on the device (one launch).

        For a task's device step that finds the aircraft to remove with a kernel (traffic that
        left an airspace): as :meth:`delete` of those aircraft, without the flags or the state
        crossing to the host.
        """
        if tuple(flags.shape) != (self.n_envs, self.max_aircraft):
            raise ValueError(f"delete_flagged: flags must have shape {(self.n_envs, self.max_aircraft)}, got {tuple(flags.shape)}")
        d = self._to_device()
        n = self.n_envs * self.max_aircraft
        self._cuda.launch(clear_flagged, n, flags.reshape(n), d["active"])

    def add_waypoint(self, env: ArrayLike, slot: ArrayLike, lat: ArrayLike, lon: ArrayLike) -> None:
        """:meth:`Simulator.add_waypoint`; on the device, only those aircraft's rows cross (:meth:`edit_on_host`)."""
        self.edit_on_host(env, slot, lambda: Simulator.add_waypoint(self, env, slot, lat, lon))

    def _on_host(self, rows: NDArray[np.int64], change: Callable[[], None], gather: bool) -> None:
        """Run ``change`` on the host with aircraft ``rows`` (flat indices) moved: brought back first where ``gather``, sent back after."""
        d = object.__getattribute__(self, "_device")
        if d is None or any(c.resolving for c in self._asas.values()):
            change()
            return
        cuda = self._cuda
        up, launch = cuda.to_device, cuda.launch
        object.__setattr__(self, "_device", None)  # host reads no longer bring the state back
        flat = self.n_envs * self.max_aircraft
        rows_d = up(rows)
        host_columns = {"F": self._float_flat, "phase": self._phase_flat.reshape(1, flat), "active": self._active_flat.reshape(1, flat)}
        host_columns.update({name: getattr(self, name).reshape(1, flat) for name in (*DEVICE_SWITCHES, "iactwp", "nwp")})
        host_rows = {"memo": self._memo, "route_lat": self.route_lat.reshape(flat, -1), "route_lon": self.route_lon.reshape(flat, -1)}

        def device_columns(name: str) -> Any:
            return d[name] if name == "F" else d[name].reshape(1, flat)

        if gather:
            for name, host in host_columns.items():
                out = cuda.device_empty((host.shape[0], rows.size), host.dtype)
                launch(gather_columns, rows.size, rows_d, device_columns(name), out)
                host[:, rows] = out.copy_to_host()
            for name, host in host_rows.items():
                out = cuda.device_empty((rows.size, host.shape[1]), host.dtype)
                launch(gather_rows, rows.size, rows_d, d[name], out)
                host[rows] = out.copy_to_host()
        try:
            change()
        except BaseException:
            object.__setattr__(self, "_device", d)  # the device state is whole; the host rows are not
            raise
        for name, host in host_columns.items():
            launch(scatter_columns, rows.size, rows_d, up(np.ascontiguousarray(host[:, rows])), device_columns(name))
        for name, host in host_rows.items():
            launch(scatter_rows, rows.size, rows_d, up(np.ascontiguousarray(host[rows])), d[name])
        types = self._type_args()
        if types.size != d["types"].size:  # a second aircraft type appeared: every row (the device never changes types)
            d["types"] = up(types)
        elif types.size:
            launch(scatter_columns, rows.size, rows_d, up(np.ascontiguousarray(types[rows]).reshape(1, -1)), d["types"].reshape(1, flat))
        if d["table"].shape != self._table.shape:
            d["table"] = up(self._table)
        d["any_lnav"] = d["any_lnav"] or bool(self.swlnav.reshape(-1)[rows].any())
        object.__setattr__(self, "_device", d)
        if any(c.resolving for c in self._asas.values()):  # resolution switched on by the change: its arrays start on the host
            self._to_host()

    def _to_host(self) -> None:
        """Copy the state back from the device (the host arrays become current)."""
        d = object.__getattribute__(self, "_device")
        object.__setattr__(self, "_device", None)
        np.copyto(self._float_flat, d["F"].copy_to_host())
        self._phase_flat[...] = d["phase"].copy_to_host()
        self._active_flat[...] = d["active"].copy_to_host()  # (delete_flagged deletes on the device)
        self._memo[...] = d["memo"].copy_to_host()
        for name in ("swlnav", "swvnav", "swvnavspd", "swlastwp", "iactwp"):
            getattr(self, name).reshape(-1)[...] = d[name].copy_to_host()
        self._reso_pairs[...] = d["pairs"].copy_to_host()
        self._reso_held[...] = d["held"].copy_to_host()

    def _to_device(self) -> dict[str, Any]:
        """The device copy of the state, made from the host arrays where the host holds the state."""
        d = object.__getattribute__(self, "_device")
        if d is not None:
            return d  # type: ignore[no-any-return]
        up = self._cuda.to_device
        m = self.n_envs * self.max_aircraft
        d = {
            "F": up(self._float_flat),
            "phase": up(self._phase_flat),
            "memo": up(self._memo),
            "active": up(self._active_flat),
            "types": up(self._type_args()),
            "table": up(self._table),
            **{name: up(getattr(self, name).reshape(-1)) for name in ("swlnav", "swvnav", "swvnavspd", "swlastwp", "iactwp", "nwp")},
            "route_lat": up(self.route_lat.reshape(m, -1)),
            "route_lon": up(self.route_lon.reshape(m, -1)),
            # LNAV only ever switches itself off on the device: no aircraft flies it later if none does now.
            "any_lnav": bool(self.swlnav.any()),
            # ASAS bookkeeping (BlueSky's resolution pairs and held resolutions), and the per-step work arrays.
            "pairs": up(self._reso_pairs),
            "held": up(self._reso_held),
        }
        if any(c.resolving for c in self._asas.values()):
            d.update(self._resolution_arrays())
        object.__setattr__(self, "_device", d)
        return d

    def _device_wind(self) -> tuple[Any, Any, Any, bool]:
        """The wind at every aircraft as the kernels take it, on the device (uniform within each airspace)."""
        w = self.wind
        if not w.any:
            key: tuple[bytes, ...] = ()
        else:
            if (w.count > 1).any():
                raise NotImplementedError("DeviceSimulator: wind fields of several points per airspace run on the CPU Simulator only")
            key = (w.count.tobytes(), w.vnorth[:, :1].tobytes(), w.veast[:, :1].tobytes())
        if self._wind_device is None or key != self._wind_key:
            up = self._cuda.to_device
            if not w.any:
                self._wind_device = (up(np.zeros(0)), up(np.zeros(0)), up(np.zeros(0, dtype=np.bool_)), False)
            else:
                zeros = np.zeros((self.n_envs, self.max_aircraft))  # uniform: the wind does not depend on the position
                wn, we = (np.ascontiguousarray(x).reshape(-1) for x in w.at_all(zeros, zeros))
                self._wind_device = (up(wn), up(we), up(np.repeat(w.has_wind, self.max_aircraft)), True)
            self._wind_key = key
        return self._wind_device

    def _lnav_device_args(self, d: dict[str, Any]) -> tuple[Any, ...]:
        keys = ("swlnav", "swvnav", "swvnavspd", "swlastwp", "active", "iactwp", "nwp", "route_lat", "route_lon")
        return (*(d[k] for k in keys), self.geo == "python")

    def _advance(self, do_perf: bool) -> None:
        wn, we, haswind, any_wind = self._device_wind()
        d = self._to_device()
        n = self.n_envs * self.max_aircraft
        if d["any_lnav"]:
            self._cuda.launch(lnav_kernel, n, d["F"], *self._lnav_device_args(d))
        args = (d["phase"], wn, we, haswind, any_wind, do_perf, self.dt, d["table"], d["types"], d["memo"], d["active"])
        self._cuda.launch(step_kernel, n, d["F"], *args)

    def _advance_many(self, perf_due: NDArray[np.bool_], track: Array | None) -> None:
        wn, we, haswind, any_wind = self._device_wind()
        d = self._to_device()
        n = self.n_envs * self.max_aircraft
        lnav = self._lnav_device_args(d) if d["any_lnav"] else None
        trace = None if track is None else self._cuda.to_device(np.empty((perf_due.shape[0], 2, n)))
        args = (d["phase"], wn, we, haswind, any_wind, self._cuda.to_device(perf_due), self.dt, d["table"], d["types"], d["memo"], d["active"])
        self._cuda.launch(run_kernel, n, d["F"], *args, lnav, trace)
        if track is not None and trace is not None:
            track[...] = trace.copy_to_host().reshape(track.shape)

    def set_conflict_resolution(self, env: ArrayLike, config: AsasConfig) -> None:
        """:meth:`Simulator.set_conflict_resolution`; with the state brought back to the host first."""
        if self.on_device:
            self._to_host()
        super().set_conflict_resolution(env, config)

    def _resolution_arrays(self) -> dict[str, Any]:
        """Device arrays of the conflict detection and resolution: pair pictures, MVP's outputs, targets."""
        up = self._cuda.to_device
        shape = (self.n_envs, self.max_aircraft)
        pairs = (*shape, self.max_aircraft)
        vsmin, vsmax = (limit[self.type_index] for limit in self._vs_limits())
        return {
            "conflict": up(np.zeros(pairs, np.bool_)),
            "los": up(np.zeros(pairs, np.bool_)),
            **{k: up(np.zeros(pairs)) for k in ("qdr", "dist", "tcpa", "dcpa", "tlos")},
            # MVP writes active aircraft only (the others stay NaN, as mvp() gives them; activity does not change on the device).
            **{k: up(np.full(shape, np.nan)) for k in ("res_trk", "res_gs", "res_vs", "res_alt", "tsolv")},
            "dv": up(np.full((*shape, 3), np.nan)),
            "keep": up(np.zeros(pairs, np.bool_)),
            "follow": up(np.zeros(shape, np.bool_)),
            "ended": up(np.zeros(shape, np.bool_)),
            "any_ended": up(np.zeros(1, np.bool_)),
            "targets": up(np.zeros((4, *shape))),
            "vsmin": up(np.ascontiguousarray(vsmin, dtype=np.float64)),
            "vsmax": up(np.ascontiguousarray(vsmax, dtype=np.float64)),
        }

    def _device_asas(self) -> AsasConfig:
        """The one ASAS configuration of every airspace, which the device runs (see the class docstring)."""
        configs = {self._asas.get(e, AsasConfig()) for e in range(self.n_envs)}
        config = next(iter(configs))
        if len(configs) > 1 or not config.resolving or config.detector != "CSTATEBASED" or config.method != "MVP":
            raise NotImplementedError(
                "DeviceSimulator: conflict resolution runs on the device when every airspace has the same CSTATEBASED configuration with RESO MVP"
            )
        return config

    def _step_resolving(self, do_perf: bool) -> None:
        """:meth:`Simulator._step_resolving` on the device: a fixed number of launches over every airspace.

        LNAV (when any aircraft flies it), the autopilot and performance, conflict detection,
        MVP, the ASAS bookkeeping, ``resumenav``, the aircraft whose resolution ended, the targets
        and the kinematics: the CPU core's kernels, one launch each. One flag comes back to the host;
        only where a resolution ended does the host send those aircraft DIRECT to their best
        waypoint (BlueSky's recovery), with the state copied back for it.
        """
        config = self._device_asas()
        wind = self._device_wind()
        d = self._to_device()
        launch = self._cuda.launch
        n_envs, m = self.n_envs, self.max_aircraft
        n = n_envs * m
        if d["any_lnav"]:
            launch(lnav_kernel, n, d["F"], *self._lnav_device_args(d))
        launch(pre_kernel, n, d["F"], d["phase"], do_perf, d["table"], d["types"], d["memo"], d["active"])

        def field(name: str) -> Any:
            return d["F"][FIELD_INDEX[name]].reshape(n_envs, m)

        active = d["active"].reshape(n_envs, m)
        lat, lon, alt, gs, trk, vs = (field(k) for k in ("lat", "lon", "alt", "gs", "trk", "vs"))
        gseast, gsnorth = field("gseast"), field("gsnorth")
        rpz, hpz, look, s = float(config.rpz), float(config.hpz), float(config.lookahead), config.settings
        c = (d["conflict"], d["los"], d["qdr"], d["dist"], d["tcpa"], d["dcpa"], d["tlos"])
        launch(detect_loop, n_envs, lat, lon, alt, gs, trk, vs, active, rpz, hpz, look, *c)
        res = (d["res_trk"], d["res_gs"], d["res_vs"], d["res_alt"])
        launch(
            mvp_loop, n_envs, d["conflict"], d["qdr"], d["dist"], d["tcpa"], d["tlos"], active, alt, gseast, gsnorth, vs, trk, gs,
            field("selalt"), field("ap_vs"), field("vmin"), field("vmax"), d["vsmin"], d["vsmax"],
            rpz * s.resofach, hpz * s.resofacv, look, s.mode, 1.0 if s.swresohoriz else 0.0, *res, d["dv"], d["tsolv"],
        )  # fmt: skip
        candidates = d["pairs"]  # becomes the candidates in place; the pairs kept go to the other buffer
        launch(renew_loop, n_envs, d["conflict"], *res, candidates, d["held"])
        launch(resume_loop, n_envs, candidates, lat, lon, gseast, gsnorth, trk, active, rpz, rpz * s.resofach, d["keep"], d["follow"])
        d["pairs"], d["keep"] = d["keep"], candidates
        launch(ended_loop, n_envs, candidates, d["follow"], active, d["ended"], d["any_ended"])
        launch(release_loop, n_envs, d["follow"], d["held"])
        launch(targets_loop, n_envs, d["held"], d["targets"])
        follow, targets = d["follow"], d["targets"]
        if d["any_ended"].copy_to_host()[0]:
            ended = d["ended"].copy_to_host()
            follow_h, targets_h = follow.copy_to_host(), targets.copy_to_host()
            for e, k in zip(*np.nonzero(ended & (self.nwp > 0))):  # (reading nwp brings the state to the host)
                self.iactwp[e, k] = self._find_active(int(e), int(k))
                self._direct(np.array([e]), np.array([k]))
            d = self._to_device()
            follow, targets = self._cuda.to_device(follow_h), self._cuda.to_device(targets_h)
        wn, we, haswind, any_wind = wind
        args = (d["phase"], wn, we, haswind, any_wind, self.dt, d["table"], d["types"], d["memo"], d["active"], follow.reshape(n))
        launch(post_kernel, n, d["F"], *args, *(targets[k].reshape(n) for k in range(4)))
