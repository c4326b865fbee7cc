"""The real BlueSky 1.1.1 simulator behind the :class:`~bluesky_gym.core.physics.Physics` interface.

:class:`BlueSkyPhysics` runs BlueSky in this process, headless (``bs.init(mode='sim',
detached=True)``, once per process), and exposes it with the same attributes and methods as the
native batched core, for one airspace (``n_envs == 1``):

* every aircraft slot is a BlueSky aircraft (``AC0``, ``AC1``, ... by slot number);
* commands take BlueSky's own command paths, as the reference environments use them: the stack
  commands ``HDG``, ``SPD``, ``ADDWPT`` and ``DEST`` (parsed and executed by BlueSky's stack at the
  moment of the call, so they act before the next step exactly as stacked text does), and the
  traffic methods ``traf.cre``, ``traf.creconfs``, ``ap.selaltcmd`` and ``ap.selvspdcmd``;
* the direct writes of the reference gym code (``selalt``, ``selvs``, ``swvnav``, ``ap_trk``,
  ``alt``, ``hdg``) go through :meth:`BlueSkyPhysics.set_autopilot` and
  :meth:`BlueSkyPhysics.set_state`, which write into ``bs.traf`` at once;
* the state arrays are read-only copies of ``bs.traf``, refreshed after every step, creation or
  command;
* ``wind.add_points`` adds BlueSky wind points (``traf.wind.addpointvne``).

BlueSky keeps its simulator in module-level singletons, so a process holds one open
:class:`BlueSkyPhysics` at a time. Run several BlueSky environments in parallel with one process
each, e.g. ``gymnasium.make_vec(env_id, num_envs=4, vectorization_mode="async",
backend="bluesky")``.

The ``bluesky`` extra (``pip install -e ".[bluesky]"``) installs BlueSky 1.1.1 with
``numpy<2.4``: BlueSky 1.1.1's scalar wind look-up, used by every ``creconfs``, fails on numpy 2.4.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import os
import tempfile
import warnings
import weakref
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from bluesky_gym.core.aircraft import DEFAULT_TYPE, resolve_type
from bluesky_gym.core.command_text import command, number
from bluesky_gym.core.extras import missing_extra
from bluesky_gym.core.resolution import AsasConfig
from bluesky_gym.core.state import STATE_FIELDS, AircraftState, aircraft_index
from bluesky_gym.core.units import FT, NM
from bluesky_gym.core.wind import WindField

Array = NDArray[np.float64]

ACTYPE = DEFAULT_TYPE  # the type of an aircraft created without one

#: Where BlueSky keeps a state array that is not ``bs.traf.<name>``: (object under ``bs.traf``, attribute).
_BLUESKY_NAMES: dict[str, tuple[str, str]] = {
    "mach": ("", "M"),
    **{f"ap_{a}": ("ap", a) for a in ("trk", "tas", "vs", "alt")},
    "turnphi": ("ap", "turnphi"),
    **{name: ("perf", name) for name in ("phase", "vmin", "vmax", "axmax", "thrust", "drag", "fuelflow")},
    **{f"actwp_{a}": ("actwp", a) for a in ("lat", "lon")},
    **{name: ("actwp", name) for name in ("curlegdir", "turndist", "next_qdr", "swlastwp")},
}
#: State arrays derived from BlueSky's routes and slots, or kept by the backend (the fuel burned),
#: rather than read from one of its arrays.
_DERIVED = frozenset({"active", "iactwp", "nwp", "route_has_dest", "fuelburn"})
# State array -> (object under bs.traf, or "" for bs.traf itself; attribute). These are read
# after every step, creation and command.
TRAFFIC_FIELDS: tuple[tuple[str, str, str], ...] = tuple(
    (name, *_BLUESKY_NAMES.get(name, ("", name))) for name, _, _ in STATE_FIELDS if name not in _DERIVED
)

_TRAFFIC_SOURCE = {name: (owner, attr) for name, owner, attr in TRAFFIC_FIELDS}

_owner: weakref.ReferenceType[BlueSkyPhysics] | None = None


def _type_list(actype: str | Sequence[str] | NDArray[np.str_] | None, n: int) -> list[str]:
    """``n`` type names from one name, one per aircraft, or None (A320); a non-string is refused."""
    names = [ACTYPE] * n if actype is None else [actype] * n if isinstance(actype, str) else [str(a) for a in actype]
    if len(names) != n:
        raise ValueError(f"actype: expected one type or {n} types (one per aircraft), got {len(names)}")
    for name in set(names):
        resolve_type(name)  # refuses non-strings
    return names


def load_bluesky() -> ModuleType:
    """Import BlueSky and initialise it headless (once per process).

    Returns:
        The ``bluesky`` module, with ``bluesky.sim`` and ``bluesky.traf`` ready.

    Raises:
        ImportError: BlueSky is not installed, or numpy is too new for BlueSky 1.1.1.
    """
    try:
        import bluesky
    except ImportError as exc:
        raise missing_extra("the 'bluesky' backend needs the BlueSky simulator (bluesky-simulator 1.1.1)", "bluesky") from exc
    major, minor = (int(x) for x in np.__version__.split(".")[:2])
    if (major, minor) >= (2, 4):
        raise missing_extra(f"BlueSky 1.1.1 needs numpy<2.4 (its wind look-up, used by every creconfs, fails on numpy {np.__version__})", "bluesky")
    if bluesky.sim is None:
        out = io.StringIO()
        workdir = bluesky_workdir()
        if workdir is not None:
            workdir.mkdir(parents=True, exist_ok=True)
        try:
            with _first_start_lock(workdir), contextlib.redirect_stdout(out):
                bluesky.init(mode="sim", detached=True, workdir=None if workdir is None else str(workdir))
        except Exception as exc:
            raise RuntimeError(f"BlueSky failed to start; its start-up output was:\n{out.getvalue()}") from exc
    module: ModuleType = bluesky
    return module


#: Environment variable naming BlueSky's working directory (settings, navigation cache, output);
#: unset: BlueSky's own choice, ``~/bluesky``. The tests point it to a temporary directory.
WORKDIR_ENV = "BLUESKY_GYM_BLUESKY_WORKDIR"


def bluesky_workdir() -> Path | None:
    """BlueSky's working directory from :data:`WORKDIR_ENV`, or None (BlueSky's default, ``~/bluesky``)."""
    value = os.environ.get(WORKDIR_ENV)
    return Path(value) if value else None


@contextlib.contextmanager
def _first_start_lock(workdir: Path | None = None) -> Iterator[None]:
    """Serialise BlueSky's first start-up between processes.

    On its first start BlueSky creates its working directory (``~/bluesky`` unless ``workdir``
    is given) and writes its navigation database cache there; processes starting together (test
    workers, vector env workers) would race on both. After a start-up has completed under the
    lock, a marker file in the temporary directory lets later start-ups skip it.
    """
    base = workdir if workdir is not None else Path.home() / "bluesky"
    key = hashlib.sha1(str(base).encode()).hexdigest()[:12]
    marker = Path(tempfile.gettempdir()) / f"bluesky-gym-bluesky-ready-{key}"
    if marker.exists() and (base / "settings.cfg").exists():
        yield
        return
    try:
        import fcntl
    except ImportError:  # not POSIX: no inter-process lock
        yield
        return
    with open(Path(tempfile.gettempdir()) / f"bluesky-gym-bluesky-start-{key}.lock", "a") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        try:
            yield
            marker.touch()
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


class BlueSkyWind(WindField):
    """Wind of a :class:`BlueSkyPhysics`: BlueSky's own wind field (``bs.traf.wind``).

    The definition points are also kept in the :class:`~bluesky_gym.core.wind.WindField`
    bookkeeping (``has_wind``, ``count``, ...); wind values come from BlueSky's ``getdata``.

    Args:
        bluesky: The initialised ``bluesky`` module.
    """

    def __init__(self, bluesky: ModuleType) -> None:
        super().__init__(1)
        self._bs = bluesky

    def clear(self, envs: ArrayLike | slice | None = None) -> None:
        """Remove all wind points (BlueSky has one wind field)."""
        super().clear(envs)
        self._bs.traf.wind.clear()

    def add_points(self, env: int, lat: ArrayLike, lon: ArrayLike, vnorth: ArrayLike, veast: ArrayLike) -> None:
        """Add wind definition points: ``traf.wind.addpointvne`` with 2-D (1, points) components.

        Args:
            env: Airspace index (must be 0).
            lat: Latitudes [deg].
            lon: Longitudes [deg].
            vnorth: North components [m/s] (direction blown to).
            veast: East components [m/s].
        """
        if int(env) != 0:
            raise IndexError("the 'bluesky' backend has one airspace (env 0)")
        super().add_points(env, lat, lon, vnorth, veast)
        lat, lon, vn, ve = (np.atleast_1d(np.asarray(x, dtype=np.float64)).ravel() for x in (lat, lon, vnorth, veast))
        # BlueSky 1.1.1 needs sized lat/lon and (1, npoints) wind arrays [docs/dynamics.md §6.1].
        self._bs.traf.wind.addpointvne(lat.copy(), lon.copy(), vn.reshape(1, -1).copy(), ve.reshape(1, -1).copy())

    def _getdata(self, lat: ArrayLike, lon: ArrayLike) -> tuple[Array, Array]:
        lat = np.asarray(lat, dtype=np.float64)
        lon = np.asarray(lon, dtype=np.float64)
        shape = np.broadcast_shapes(lat.shape, lon.shape)
        flat_lat = np.broadcast_to(lat, shape).ravel().copy()
        flat_lon = np.broadcast_to(lon, shape).ravel().copy()
        if flat_lat.size == 0:
            return np.zeros(shape), np.zeros(shape)
        vn, ve = self._bs.traf.wind.getdata(flat_lat, flat_lon)
        return np.asarray(vn, dtype=np.float64).reshape(shape), np.asarray(ve, dtype=np.float64).reshape(shape)

    def at(self, env: ArrayLike, lat: ArrayLike, lon: ArrayLike) -> tuple[Array, Array]:
        """Wind (north, east) [m/s] from BlueSky at positions (``env`` must be 0)."""
        if np.any(np.asarray(env) != 0):
            raise IndexError("the 'bluesky' backend has one airspace (env 0)")
        return self._getdata(lat, lon)

    def at_all(self, lat: Array, lon: Array) -> tuple[Array, Array]:
        """Wind from BlueSky at positions shaped (1, aircraft)."""
        return self._getdata(lat, lon)


class _ReadOnly:
    """A state array of :class:`BlueSkyPhysics`: a read-only view of the copy read from ``bs.traf``."""

    def __init__(self, name: str) -> None:
        self.name = name

    def __get__(self, obj: BlueSkyPhysics | None, owner: type) -> Any:
        if obj is None:
            return self
        return obj._views[self.name]


class BlueSkyPhysics(AircraftState):
    """One airspace simulated by the real BlueSky 1.1.1, implementing :class:`~bluesky_gym.core.physics.Physics`.

    The state arrays, their shapes (``(1, max_aircraft)``) and meaning are those of
    :class:`~bluesky_gym.core.Simulator`; only active slots hold BlueSky aircraft. They are
    read-only: state changes go through the commands. Aircraft are A320s unless created with
    another type (OpenAP performance, as in the native core).

    Args:
        max_aircraft: Aircraft slots.
        dt: Simulation time step [s] (stacked as ``DT`` at every reset).
        max_waypoints: Route capacity per aircraft (BlueSky has none; kept for the interface).

    Raises:
        ImportError: BlueSky is not installed (``pip install -e ".[bluesky]"``).
        RuntimeError: Another :class:`BlueSkyPhysics` is open in this process.
    """

    closed: bool
    # The read-only state arrays are those of AircraftState, (1, max_aircraft), and the routes.
    route_lat: Array
    route_lon: Array

    def __init__(self, max_aircraft: int, dt: float = 1.0, max_waypoints: int = 4) -> None:
        global _owner
        bluesky = load_bluesky()
        other = _owner() if _owner is not None else None
        if other is not None and not other.closed:
            raise RuntimeError(
                "BlueSky has one simulator per process (bluesky.sim and bluesky.traf are module-level singletons), "
                "and this process already has an open 'bluesky' backend; close() that environment first. "
                "To run several BlueSky environments in parallel use one process per environment, e.g. "
                'gymnasium.make_vec(env_id, num_envs=4, vectorization_mode="async", backend="bluesky") '
                "(gymnasium.vector.AsyncVectorEnv), or use the native backend, which batches many environments in one process"
            )
        if max_aircraft < 1:
            raise ValueError(f"max_aircraft must be >= 1, got {max_aircraft}")
        if not dt > 0:
            raise ValueError(f"dt must be > 0 s, got {dt}")
        self.n_envs = 1
        self.max_aircraft = int(max_aircraft)
        self.max_waypoints = int(max_waypoints)
        self.dt = float(dt)
        self.simt = 0.0
        shape = (1, self.max_aircraft)
        #: Values of empty slots.
        self._defaults: dict[str, tuple[type, float]] = {name: (dtype, value) for name, dtype, value in STATE_FIELDS}
        # The state read from bs.traf (writable here) and the read-only views handed out.
        self._data: dict[str, np.ndarray] = {name: np.full(shape, value, dtype=dtype) for name, dtype, value in STATE_FIELDS}
        self._data["route_lat"] = np.zeros((*shape, self.max_waypoints))
        self._data["route_lon"] = np.zeros((*shape, self.max_waypoints))
        self._views: dict[str, np.ndarray] = {}
        for name, arr in self._data.items():
            view = arr.view()
            view.flags.writeable = False
            self._views[name] = view
        self._bs = bluesky
        self.closed = False
        _owner = weakref.ref(self)
        from bluesky.stack import argparser
        from bluesky.stack.cmdparser import Command
        from bluesky.tools import aero
        from bluesky.tools.misc import txt2hdg, txt2spd

        self._commands = Command.cmddict
        self._nextarg = argparser.getnextarg
        self._kts = float(aero.kts)
        self._txt2spd = txt2spd
        self._txt2hdg = txt2hdg
        self.wind = BlueSkyWind(bluesky)
        from bluesky.tools import geo as bs_geo
        from bluesky.tools.geo import _geo

        #: Which of BlueSky's geo function sets its LNAV uses: "compiled" (BlueSky's default
        #: setting) or "python" (when ``bluesky.tools.geo`` was imported before ``bs.init``, as the
        #: reference gym environments do). They differ in the last bits; see ``Simulator(geo=...)``.
        self.geo = "python" if bs_geo.qdrdist is _geo.qdrdist else "compiled"
        self._acid = [f"AC{k}" for k in range(self.max_aircraft)]
        # ASAS methods set_conflict_resolution selected (BlueSky keeps settings per method and process).
        self._asas_methods: set[str] = set()
        self._slots = np.zeros(0, dtype=np.int64)  # active slots, in BlueSky's traffic order
        self._tidx = np.zeros(0, dtype=np.int64)  # their BlueSky traffic indices
        self.reset_envs()

    # ------------------------------------------------------------------------------------------
    # Airspace management
    # ------------------------------------------------------------------------------------------
    @property
    def traffic(self) -> Any:
        """BlueSky's traffic object (``bluesky.traf``)."""
        self._check_open()
        return self._bs.traf

    def acid(self, slot: int) -> str:
        """The BlueSky callsign of an aircraft slot."""
        return self._acid[int(slot)]

    def reset_envs(self, envs: ArrayLike | None = None) -> None:
        """Delete all traffic and wind (``traf.reset()``) and stack the time step again (``DT dt;FF``)."""
        self._check_open()
        if envs is not None:
            self._index(envs, 0)
        self._undo_conflict_resolution()
        self._bs.traf.reset()
        for name, (_dtype, value) in self._defaults.items():
            self._data[name][...] = value
        self._data["route_lat"][...] = 0.0
        self._data["route_lon"][...] = 0.0
        self.wind.clear()
        self._remap()
        self.command(command("DT", self.dt))
        self.command("FF")  # start the simulation (state OP), as the reference envs' "DT dt;FF"
        self.simt = float(self._bs.sim.simt)  # BlueSky's clock runs on across resets (traf.reset keeps it)

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
        """Create aircraft with ``traf.cre(acids, types, lat, lon, hdg, alt, spd)``.

        BlueSky 1.1.1's OpenAP model gives all aircraft of one ``traf.cre`` call the performance
        data of the last one's type, so a mixed batch is created in runs of equal type (one call
        per run, in slot order): every aircraft flies with its own type's data, as on the core.

        Args:
            env: Airspace index of each new aircraft (0).
            slot: Slot index of each new aircraft (must be free).
            lat: Latitude [deg].
            lon: Longitude [deg].
            hdg: Heading [deg].
            alt: Altitude [m].
            spd: CAS [m/s], or Mach when 0.1 < spd < 2.
            actype: Aircraft type, one for all or one per aircraft (None: A320). Unknown types fly
                as BlueSky's B744; rotorcraft fly BlueSky's rotor model.
        """
        env, slot = self._begin(env, slot)
        if np.any(self.active[env, slot]) or np.unique(slot).size != slot.size:
            raise ValueError("create: an aircraft already exists in one of the requested slots")
        n = slot.size
        if n == 0:
            return
        types = _type_list(actype, n)
        values = [np.broadcast_to(np.asarray(x, dtype=np.float64), (n,)).copy() for x in (lat, lon, hdg, alt, spd)]
        acids = [self._acid[s] for s in slot]
        start = 0
        for stop in range(1, n + 1):
            if stop == n or types[stop].upper() != types[start].upper():
                ok = self._bs.traf.cre(acids[start:stop], types[start:stop], *(v[start:stop] for v in values))
                if ok is not True:
                    raise RuntimeError(f"BlueSky traf.cre failed: {ok}")
                start = stop
        self._defaults_for(slot)
        self._data["active"][0, slot] = True
        self._remap()
        self._sync_out()

    def delete(self, env: ArrayLike, slot: ArrayLike) -> None:
        """Delete aircraft (``traf.delete``); free slots are ignored."""
        env, slot = self._begin(env, slot)
        slot = np.unique(slot[self.active[env, slot]])
        if slot.size == 0:
            return
        idx = np.array(self._bs.traf.id2idx([self._acid[s] for s in slot]), dtype=np.int64)
        self._bs.traf.delete(idx)
        self._data["active"][0, slot] = False
        self._remap()
        self._sync_out()

    # ------------------------------------------------------------------------------------------
    # Commands
    # ------------------------------------------------------------------------------------------
    def command(self, line: str) -> None:
        """Execute one BlueSky stack command now, with BlueSky's parser and command objects.

        This is what ``bs.sim.step()`` does first with stacked text, so a command acts before the
        next step exactly as if it had been stacked. The arrays are refreshed afterwards.

        Args:
            line: The command text, e.g. ``"HDG AC0 90"``.

        Raises:
            RuntimeError: BlueSky rejected the command.
        """
        self._check_open()
        cmd, args = self._nextarg(line)
        cmdobj = self._commands.get(cmd.upper())
        if cmdobj is None:
            raise RuntimeError(f"BlueSky has no command {cmd!r} (in {line!r})")
        try:
            ok, text = cmdobj(args)
        except Exception as exc:  # BlueSky's argument parsers raise on bad arguments
            raise RuntimeError(f"BlueSky rejected {line!r}: {str(exc).strip()}") from exc
        if not ok:
            raise RuntimeError(f"BlueSky rejected {line!r}: {text}")
        self._sync_out()

    def set_conflict_resolution(self, env: ArrayLike, config: AsasConfig) -> None:
        """Switch BlueSky's own ASAS to ``config`` with its stack commands (``ASAS``, ``RESO``, ``RFACH``, ``ZONER``, ``RMETHH``, ...).

        The factors are given before and after the zones, so that a zone change does not rescale them.
        """
        if np.any(np.asarray(env) != 0):
            raise IndexError("the BlueSky backend has one airspace (env 0)")
        if config.resolution and config.method != "MVP":
            raise ValueError(
                f"RESO {config.method} is a BlueSky plugin that crashes on its first resolution in BlueSky 1.1.1; "
                "the BlueSky backend resolves with RESO MVP (the native core flies it, with the fix, docs/backends.md)"
            )
        self._asas_methods |= {config.detector or "OFF", "MVP" if config.resolution else "OFF"}
        self.command(command("ASAS", config.detector or "OFF"))
        self.command(command("RESO", "MVP" if config.resolution else "OFF"))
        s = config.settings
        factors = (command("RFACH", s.resofach), command("RFACV", s.resofacv))
        methods = {0: ("RMETHH BOTH",), 1: ("RMETHH SPD",), 2: ("RMETHH HDG",), 3: ("RMETHV V/S",), 4: ("RMETHH NONE", "RMETHV NONE")}
        lines = [*factors, command("ZONER", config.rpz / NM), command("ZONEDH", config.hpz / FT), command("DTLOOK", config.lookahead), *factors]
        if config.resolution:
            lines += methods[s.mode]
        for line in lines:
            self.command(line)

    def _undo_conflict_resolution(self) -> None:
        """Give every ASAS method :meth:`set_conflict_resolution` selected its defaults back, and switch detection and resolution off.

        BlueSky keeps these settings per method across ``traf.reset()`` (and for the next backend of
        the process), so a reset airspace would otherwise go on resolving.
        """
        methods, self._asas_methods = self._asas_methods, set()
        if not methods:
            return
        for detector in sorted(methods - {"MVP"}):
            self.set_conflict_resolution(0, AsasConfig(None if detector == "OFF" else detector, resolution="MVP" in methods))
        self._asas_methods = set()
        self.command("ASAS OFF")
        self.command("RESO OFF")

    def cmd_heading(self, env: ArrayLike, slot: ArrayLike, hdg: ArrayLike) -> None:
        """Stack ``HDG acid hdg`` [deg] (a track with wind above 50 ft; LNAV off)."""
        env, slot = self._begin(env, slot)
        hdg = np.broadcast_to(np.asarray(hdg, dtype=np.float64), slot.shape)
        for s, h in zip(slot, hdg):
            text = number(h)
            if self._txt2hdg(text) != h:  # pragma: no cover - positional text always round-trips
                raise ValueError(f"heading {h!r} cannot be written exactly as a BlueSky HDG argument")
            self.command(command("HDG", self._acid_of(s), text))

    def cmd_speed(self, env: ArrayLike, slot: ArrayLike, casmach: ArrayLike) -> None:
        """Stack ``SPD acid kts`` for a CAS [m/s], or the Mach number; VNAV speed off.

        The knots text is chosen so that BlueSky's conversion (``kts * 0.514444``) gives back
        exactly the requested CAS; where no text does (Mach above 1, tiny speeds), the SPD
        command's function ``ap.selspdcmd`` is called with the SI value instead.
        """
        env, slot = self._begin(env, slot)
        casmach = np.broadcast_to(np.asarray(casmach, dtype=np.float64), slot.shape)
        for s, v in zip(slot, casmach):
            text = self._speed_text(float(v))
            if text is not None:
                self.command(command("SPD", self._acid_of(s), text))
            else:
                self._bs.traf.ap.selspdcmd(self._tidx_of(s), float(v))
                self._sync_out()

    def cmd_altitude(self, env: ArrayLike, slot: ArrayLike, alt: ArrayLike, vs: ArrayLike | None = None) -> None:
        """``ap.selaltcmd(idx, alt [m], vs [m/s])``, the ALT command in SI; VNAV off."""
        env, slot = self._begin(env, slot)
        alt = np.broadcast_to(np.asarray(alt, dtype=np.float64), slot.shape)
        vs_arr = None if vs is None else np.broadcast_to(np.asarray(vs, dtype=np.float64), slot.shape)
        for k, s in enumerate(slot):
            v = None if vs_arr is None else float(vs_arr[k])
            self._bs.traf.ap.selaltcmd(self._tidx_of(s), float(alt[k]), v)
        self._sync_out()

    def cmd_vertical_speed(self, env: ArrayLike, slot: ArrayLike, vs: ArrayLike) -> None:
        """``ap.selvspdcmd(idx, vs [m/s])``, the VS command in SI; VNAV off."""
        env, slot = self._begin(env, slot)
        vs = np.broadcast_to(np.asarray(vs, dtype=np.float64), slot.shape)
        for s, v in zip(slot, vs):
            self._bs.traf.ap.selvspdcmd(self._tidx_of(s), float(v))
        self._sync_out()

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
        """Write ``traf.selalt``, ``traf.selvs``, ``traf.swvnav`` and ``traf.ap.trk`` directly, as the reference gym code does.

        Each argument left None stays unchanged; values broadcast over ``(env, slot)``.
        """
        env, slot = self._begin(env, slot)
        self._write(slot, selalt=selalt, selvs=selvs, swvnav=swvnav, ap_trk=ap_trk)

    def set_state(self, env: ArrayLike, slot: ArrayLike, *, alt: ArrayLike | None = None, hdg: ArrayLike | None = None) -> None:
        """Write ``traf.alt`` [m] and ``traf.hdg`` [deg] directly (None = unchanged)."""
        env, slot = self._begin(env, slot)
        self._write(slot, alt=alt, hdg=hdg)

    def _write(self, slot: NDArray[np.int64], **values: ArrayLike | None) -> None:
        """Assign values into BlueSky's arrays (``TRAFFIC_FIELDS`` names) for the aircraft in ``slot``.

        Only the written arrays are read back. (BlueSky may alias arrays: after a step without
        wind ``traf.trk`` is ``traf.hdg``, so a heading write also moves the track until the next
        step recomputes it; the state arrays show that from the next command or step on.)
        """
        idx = np.array([self._tidx_of(s) for s in slot], dtype=np.int64)
        traf = self._bs.traf
        parents = {"": traf, "ap": traf.ap}
        for name, value in values.items():
            if value is None:
                continue
            owner, attr = _TRAFFIC_SOURCE[name]
            arr = getattr(parents[owner], attr)
            arr[idx] = np.broadcast_to(np.asarray(value, dtype=arr.dtype), idx.shape)
            self._data[name][0, slot] = arr[idx]

    def add_waypoint(self, env: ArrayLike, slot: ArrayLike, lat: ArrayLike, lon: ArrayLike) -> None:
        """Stack ``ADDWPT acid lat lon``: a fly-by waypoint (before the destination); LNAV on."""
        env, slot = self._begin(env, slot)
        self._check_route_room(env, slot)
        lat = np.broadcast_to(np.asarray(lat, dtype=np.float64), slot.shape)
        lon = np.broadcast_to(np.asarray(lon, dtype=np.float64), slot.shape)
        for s, la, lo in zip(slot, lat, lon):
            self.command(command("ADDWPT", self._acid_of(s), la, lo))

    def set_destination(self, env: ArrayLike, slot: ArrayLike, lat: ArrayLike, lon: ArrayLike) -> None:
        """Stack ``DEST acid lat lon``.

        Unlike the native core, BlueSky switches VNAV on when the destination is the route's only
        waypoint and then descends towards it (altitude constraint 0) [docs/dynamics.md §2.7].
        """
        env, slot = self._begin(env, slot)
        has_dest = self.route_has_dest[env, slot]
        self._check_route_room(env[~has_dest], slot[~has_dest])
        lat = np.broadcast_to(np.asarray(lat, dtype=np.float64), slot.shape)
        lon = np.broadcast_to(np.asarray(lon, dtype=np.float64), slot.shape)
        for s, la, lo in zip(slot, lat, lon):
            self.command(command("DEST", self._acid_of(s), la, lo))

    def cmd_direct(self, env: ArrayLike, slot: ArrayLike, waypoint: ArrayLike) -> None:
        """Stack ``DIRECT acid wpname`` with the name of route waypoint ``waypoint`` (0-based)."""
        env, slot = self._begin(env, slot)
        wp = np.broadcast_to(np.asarray(waypoint, dtype=np.int64), slot.shape)
        for s, w in zip(slot, wp):
            route = self._bs.traf.ap.route[self._tidx_of(s)]
            if not 0 <= w < route.nwp:
                raise ValueError("DIRECT: waypoint index outside the aircraft's route")
            self.command(command("DIRECT", self._acid_of(s), str(route.wpname[w])))

    def cmd_lnav(self, env: ArrayLike, slot: ArrayLike, on: ArrayLike) -> None:
        """Stack ``LNAV acid ON/OFF``."""
        env, slot = self._begin(env, slot)
        flags = np.broadcast_to(np.asarray(on, dtype=bool), slot.shape)
        for s, f in zip(slot, flags):
            self.command(command("LNAV", self._acid_of(s), bool(f)))

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
        """Create intruders with ``traf.creconfs(acid, actype, target, dpsi, dcpa, tlosh, dH, tlosv, spd)``, one at a time.

        Args:
            env: Airspace of each intruder (0).
            target: Slot of the target aircraft.
            slot: Free slot for the intruder.
            dpsi: Track difference intruder - target [deg].
            dcpa: Distance at the closest point of approach [NM].
            tlosh: Time to horizontal loss of separation [s].
            dh: Altitude offset [m], or None.
            tlosv: Time to vertical loss of separation [s], or None (= tlosh).
            spd: Intruder CAS [m/s] or Mach, or None (the target's ground speed).
            actype: Intruder type, one for all or one per intruder (None: A320).
        """
        env, target = self._begin(env, target)
        _, slot = self._index(env, slot)
        n = slot.size
        types = _type_list(actype, n)
        if not np.all(self.active[env, target]):
            raise ValueError("creconfs: a target slot holds no aircraft")
        if np.any(self.active[env, slot]) or np.unique(slot).size != n:
            raise ValueError("creconfs: an aircraft already exists in one of the requested slots")

        def per(x: ArrayLike | None) -> list[float | None]:
            if x is None:
                return [None] * n
            return [float(v) for v in np.broadcast_to(np.asarray(x, dtype=np.float64), (n,))]

        for t, s, a, c, th, h, tv, v, typ in zip(target, slot, per(dpsi), per(dcpa), per(tlosh), per(dh), per(tlosv), per(spd), types):
            with warnings.catch_warnings():
                # BlueSky 1.1.1's scalar wind look-up converts a 1-element array with float().
                warnings.filterwarnings("ignore", "Conversion of an array with ndim > 0", DeprecationWarning)
                self._bs.traf.creconfs(self._acid[s], typ, self._tidx_of(t), a, c, th, h, tv, v)
            self._defaults_for(np.array([s]))
            self._data["active"][0, s] = True
            self._remap()
        self._sync_out()

    # ------------------------------------------------------------------------------------------
    # Stepping
    # ------------------------------------------------------------------------------------------
    def step(self) -> None:
        """Run one ``bs.sim.step()`` and read the state back."""
        self._check_open()
        self._bs.sim.step()
        self._burn()
        self.simt = float(self._bs.sim.simt)
        self._sync_out(routes=False)

    def _burn(self) -> None:
        """Add the fuel of the step just run (``perf.fuelflow`` times dt) to ``fuelburn``, as the core's kernel does (BlueSky keeps no such total)."""
        slots, idx = self._slots, self._tidx
        if slots.size:
            burned = self._data["fuelburn"]
            burned[0, slots] = burned[0, slots] + self._bs.traf.perf.fuelflow[idx] * self.dt

    def run(self, n_steps: int, trace: bool = False, stop: Callable[[np.ndarray], ArrayLike] | None = None) -> np.ndarray | None:
        """Advance by ``n_steps`` BlueSky steps (same result as calling :meth:`step` n times).

        The state is read back after the last step (after every step with ``trace`` or ``stop``).
        With ``stop``, it is called after every step with the track so far and the run ends at
        the first step it reports as the end (BlueSky cannot be rewound); the positions of the
        steps not taken are NaN. See :meth:`bluesky_gym.core.physics.Physics.run`.
        """
        if n_steps < 0:
            raise ValueError(f"n_steps must be >= 0, got {n_steps}")
        self._check_open()
        if not (trace or stop is not None):
            for _ in range(int(n_steps)):
                self._bs.sim.step()
                self._burn()
            self.simt = float(self._bs.sim.simt)
            self._sync_out(routes=False)
            return None
        track = np.full((int(n_steps), 2, self.n_envs, self.max_aircraft), np.nan)
        for k in range(int(n_steps)):
            self.step()
            track[k, 0], track[k, 1] = self.lat, self.lon
            if stop is not None:
                ended = np.asarray(stop(track[: k + 1]), dtype=np.int64).reshape(-1)
                if ended.shape != (1,) or not 0 <= ended[0] <= k + 1:
                    raise ValueError(f"stop must return (n_envs,) = (1,) step counts in [0, {k + 1}]")
                if ended[0] and ended[0] != k + 1:
                    raise ValueError(f"stop reported an end after {ended[0]} steps only after step {k + 1}; BlueSky cannot be rewound")
                if ended[0]:
                    break
        return track

    def close(self) -> None:
        """Delete this backend's traffic and wind and give the process's simulator free for another one.

        BlueSky itself stays initialised (it cannot be initialised twice in a process).
        """
        global _owner
        if self.closed:
            return
        self._undo_conflict_resolution()
        self._bs.traf.reset()
        self._data["active"][:] = False
        self.closed = True
        if _owner is not None and _owner() is self:
            _owner = None

    # ------------------------------------------------------------------------------------------
    # Synchronisation between the arrays and bs.traf
    # ------------------------------------------------------------------------------------------
    def _check_open(self) -> None:
        if self.closed:
            raise RuntimeError("this BlueSky backend has been closed")

    def _begin(self, env: ArrayLike, slot: ArrayLike) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        """Check that the backend is open and validate the indices."""
        self._check_open()
        return self._index(env, slot)

    def _index(self, env: ArrayLike, slot: ArrayLike) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        return aircraft_index(env, slot, self.n_envs, self.max_aircraft)

    def _check_route_room(self, env: NDArray[np.int64], slot: NDArray[np.int64]) -> None:
        if np.any(self.nwp[env, slot] >= self.max_waypoints):
            raise ValueError(f"route full: at most {self.max_waypoints} waypoints per aircraft (max_waypoints)")

    def state_fields(self) -> Sequence[str]:
        """Names of the per-aircraft state arrays."""
        return [name for name, _, _ in STATE_FIELDS]

    def aircraft_type(self, env: ArrayLike, slot: ArrayLike) -> list[str]:
        """Type names of aircraft as BlueSky holds them (``traf.type``, upper case).

        Args:
            env: Airspace indices (0).
            slot: Aircraft slots (holding aircraft).
        """
        env, slot = self._begin(env, slot)
        return [str(self._bs.traf.type[self._tidx_of(s)]).upper() for s in slot]

    def _acid_of(self, slot: int) -> str:
        if not self.active[0, slot]:
            raise ValueError(f"slot {int(slot)} holds no aircraft")
        return self._acid[int(slot)]

    def _tidx_of(self, slot: int) -> int:
        if not self.active[0, slot]:
            raise ValueError(f"slot {int(slot)} holds no aircraft")
        return int(self._tidx[np.flatnonzero(self._slots == slot)[0]])

    def _speed_text(self, v: float) -> str | None:
        """Text for the SPD command that BlueSky parses back to exactly ``v``, or None."""
        if not np.isfinite(v):
            raise ValueError(f"speed must be finite, got {v}")
        if 0.1 < v < 2.0:
            candidates = [v]  # Mach: written as is (parsed as Mach below 1)
        else:
            k = v / self._kts
            candidates = [k]
            lo = hi = k
            for _ in range(4):
                lo, hi = np.nextafter(lo, -np.inf), np.nextafter(hi, np.inf)
                candidates += [hi, lo]
        for c in candidates:
            text = number(c)
            if self._txt2spd(text) == v:
                return text
        return None

    def _defaults_for(self, slot: NDArray[np.int64]) -> None:
        for name, (_dtype, value) in self._defaults.items():
            self._data[name][0, slot] = value
        self._data["route_lat"][0, slot] = 0.0
        self._data["route_lon"][0, slot] = 0.0

    def _remap(self) -> None:
        """Recompute the BlueSky traffic index of every active slot."""
        slots = np.flatnonzero(self.active[0])
        idx = np.array(self._bs.traf.id2idx([self._acid[s] for s in slots]), dtype=np.int64)
        if np.any(idx < 0) or len(self._bs.traf.id) != slots.size:
            raise RuntimeError("BlueSky traffic and the backend's slots disagree (was bs.traf changed from outside?)")
        order = np.argsort(idx)
        self._slots, self._tidx = slots[order], idx[order]

    def _sync_out(self, routes: bool = True) -> None:
        """Read the state of every aircraft from ``bs.traf`` into the arrays.

        Args:
            routes: Read the route geometry even if no route changed length (only commands change
                routes; steps move ``iactwp``).
        """
        slots, idx = self._slots, self._tidx
        if not slots.size:
            return
        traf = self._bs.traf
        data = self._data
        parents = {"": traf, "ap": traf.ap, "perf": traf.perf, "actwp": traf.actwp}
        for name, owner, attr in TRAFFIC_FIELDS:
            data[name][0, slots] = getattr(parents[owner], attr)[idx]
        plans = traf.ap.route
        data["iactwp"][0, slots] = [plans[i].iactwp for i in idx]
        if routes or np.any(data["nwp"][0, slots] != [plans[i].nwp for i in idx]):
            for s, i in zip(slots, idx):
                r = plans[i]
                nwp = int(r.nwp)
                if nwp > self.max_waypoints:
                    raise ValueError(f"route full: at most {self.max_waypoints} waypoints per aircraft (max_waypoints)")
                data["nwp"][0, s] = nwp
                data["route_has_dest"][0, s] = nwp > 0 and r.wptype[-1] == r.dest
                data["route_lat"][0, s, :nwp] = r.wplat
                data["route_lon"][0, s, :nwp] = r.wplon
                data["route_lat"][0, s, nwp:] = 0.0
                data["route_lon"][0, s, nwp:] = 0.0


for _name in (*(name for name, _, _ in STATE_FIELDS), "route_lat", "route_lon"):
    setattr(BlueSkyPhysics, _name, _ReadOnly(_name))
del _name
