r"""Reading BlueSky scenario files (``.scn``) into a typed, time-ordered list of commands.

A scenario line is ``HH:MM:SS.hh>COMMAND args`` (BlueSky 1.1.1's ``readscn``): ``#`` starts a
comment, blank lines are skipped, a line ending in ``\`` continues on the next one, and ``;``
separates several commands with the same time. The lines are sorted by time (stable, as BlueSky
does). Each command is parsed into one of the dataclasses below, with every value in SI units and
the line it came from; aircraft are named by callsign. A command may also be written callsign
first (``KL204 HDG 90``), as BlueSky's stack accepts.

Conflict detection and resolution commands become :class:`Asas` commands carrying BlueSky's ASAS
configuration after them (:mod:`~bluesky_gym.scenarios.asas`).

Every problem is a :class:`ScenarioError` naming the file, the line and the command.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from bluesky_gym.core.command_text import (
    is_latitude,
    parse_altitude,
    parse_heading,
    parse_latitude,
    parse_longitude,
    parse_number,
    parse_speed,
    parse_switch,
    parse_time,
    parse_vertical_speed,
    split_arguments,
)
from bluesky_gym.core.conflicts import PZ_HEIGHT
from bluesky_gym.core.resolution import AsasConfig
from bluesky_gym.core.units import FT
from bluesky_gym.scenarios.asas import ASAS_COMMANDS, AsasState

#: The only aircraft type the core flies until per-aircraft types are available.
DEFAULT_ACTYPE = "A320"


class ScenarioError(ValueError):
    """A scenario file that cannot be read or run; the message names file, line and command."""


@dataclass(frozen=True)
class Source:
    """Where a command comes from."""

    file: str
    line: int
    text: str

    def __str__(self) -> str:
        return f"{self.file}:{self.line}"


@dataclass(frozen=True)
class Position:
    """A position argument: a latitude/longitude [deg], or the current position of an aircraft."""

    lat: float = 0.0
    lon: float = 0.0
    aircraft: str | None = None


@dataclass(frozen=True)
class Command:
    """Base of every scenario command: its time [s] and source line."""

    time: float
    source: Source


@dataclass(frozen=True)
class Create(Command):
    """``CRE acid type lat lon [hdg alt spd]``: hdg [deg], alt [m], spd CAS [m/s] or Mach."""

    acid: str
    actype: str
    position: Position
    hdg: float = 0.0
    alt: float = 0.0
    spd: float = 0.0


@dataclass(frozen=True)
class CreateConflict(Command):
    """``CRECONFS acid type target dpsi dcpa tlosh [dh tlosv spd]``: deg, NM, s, m, s, m/s or Mach.

    ``spd`` None (omitted, or 0 as BlueSky reads it): the target's ground speed.
    """

    acid: str
    actype: str
    target: str
    dpsi: float
    dcpa: float
    tlosh: float
    dh: float | None = None
    tlosv: float | None = None
    spd: float | None = None


@dataclass(frozen=True)
class Delete(Command):
    """``DEL acid [acid ...]``."""

    acids: tuple[str, ...]


@dataclass(frozen=True)
class Heading(Command):
    """``HDG acid hdg`` [deg true]."""

    acid: str
    hdg: float


@dataclass(frozen=True)
class Speed(Command):
    """``SPD acid spd``: CAS [m/s] or Mach."""

    acid: str
    spd: float


@dataclass(frozen=True)
class Altitude(Command):
    """``ALT acid alt [vs]``: [m], [m/s] (None: not given)."""

    acid: str
    alt: float
    vs: float | None = None


@dataclass(frozen=True)
class VerticalSpeed(Command):
    """``VS acid vs`` [m/s]."""

    acid: str
    vs: float


@dataclass(frozen=True)
class AddWaypoint(Command):
    """``ADDWPT acid lat lon``: a fly-by waypoint appended to the route (before the destination)."""

    acid: str
    position: Position


@dataclass(frozen=True)
class Destination(Command):
    """``DEST acid lat lon``: the route's destination."""

    acid: str
    position: Position


@dataclass(frozen=True)
class Direct(Command):
    """``DIRECT acid wpname``: fly to a waypoint of the route (its 0-based index in the route)."""

    acid: str
    waypoint: int


@dataclass(frozen=True)
class Lnav(Command):
    """``LNAV acid ON/OFF``."""

    acid: str
    on: bool


@dataclass(frozen=True)
class Vnav(Command):
    """``VNAV acid OFF`` (VNAV ON is outside the core)."""

    acid: str


@dataclass(frozen=True)
class TimeStep(Command):
    """``DT dt`` [s]."""

    dt: float


@dataclass(frozen=True)
class Asas(Command):
    """A conflict detection or resolution command (``ASAS``, ``RESO``, ``ZONER``, ``RMETHH``, ...; see :mod:`~bluesky_gym.scenarios.asas`).

    ``config`` is BlueSky's ASAS configuration after the command (the file's earlier ASAS commands included).
    """

    name: str
    config: AsasConfig


@dataclass(frozen=True)
class Ignored(Command):
    """A command with no effect on the aircraft (display, simulation control)."""

    name: str


#: Commands accepted and ignored: they change no aircraft state (see docs/scenarios.md).
DISPLAY_COMMANDS = frozenset(
    {"PAN", "ZOOM", "SWRAD", "TRAIL", "TRAILS", "SYMBOL", "ECHO", "SCEN", "LABEL", "FILTERALT", "MAP", "COLOR", "COLOUR", "PLUGIN", "PLUGINS"}
)
#: Simulation control: a replay always runs in fast time for its whole duration.
CONTROL_COMMANDS = frozenset({"FF", "OP", "HOLD", "REALTIME", "DTMULT", "RTF", "SEED"})
#: Conflict detection and resolution commands, with BlueSky's aliases (see :mod:`~bluesky_gym.scenarios.asas`).
DETECTION_COMMANDS = frozenset(ASAS_COMMANDS)
#: Commands that are parsed into typed commands.
TYPED_COMMANDS = frozenset({"CRE", "CREATE", "CRECONFS", "DEL", "DELETE", "HDG", "HEADING", "TURN", "SPD", "SPEED", "ALT", "VS"}) | frozenset(
    {"ADDWPT", "DEST", "DIRECT", "LNAV", "VNAV", "DT", "NOISE"}
)
#: Every command word this reader knows.
KNOWN_COMMANDS = TYPED_COMMANDS | DISPLAY_COMMANDS | CONTROL_COMMANDS | DETECTION_COMMANDS

#: BlueSky's reader skips lines shorter than this (continuation lines included); this reader refuses them.
MIN_LINE = 10
_TIMESTAMP = re.compile(r"^\s*(\d+):(\d+):(\d+(?:\.\d*)?)\s*>(.*)$")


@dataclass
class _Context:
    """State of the reader while it goes through the commands in time order."""

    file: str
    alive: set[str] = field(default_factory=set)
    routes: dict[str, list[str]] = field(default_factory=dict)  # acid -> waypoint names (destination last)
    asas: AsasState = field(default_factory=AsasState)


@dataclass(frozen=True)
class ScenarioFile:
    """A parsed scenario: its name and its commands in time order."""

    name: str
    commands: tuple[Command, ...]

    @property
    def callsigns(self) -> list[str]:
        """Every callsign created, in creation order (a callsign re-created after DEL counts again)."""
        return [c.acid for c in self.commands if isinstance(c, (Create, CreateConflict))]

    @property
    def dt(self) -> float | None:
        """The time step set by a ``DT`` command at time 0, if any."""
        steps = [c.dt for c in self.commands if isinstance(c, TimeStep)]
        return steps[-1] if steps else None

    @property
    def end_time(self) -> float:
        """Time of the last command [s]."""
        return max((c.time for c in self.commands), default=0.0)


def read_lines(text: str, file: str) -> list[tuple[float, Source]]:
    """The timed command lines of a scenario text, sorted by time (stable).

    Args:
        text: The file's content.
        file: Its name, for the error messages.

    Returns:
        (time [s], source) per command; ``;``-separated commands become one entry each.
    """
    out: list[tuple[float, Source]] = []
    pending = ""
    first = 0
    for number, raw in enumerate(text.splitlines(), start=1):
        if raw.strip() and not raw.strip().startswith("#") and len(raw.strip()) < MIN_LINE:
            raise ScenarioError(
                f"{file}:{number}: line {raw.strip()!r} is shorter than {MIN_LINE} characters, which BlueSky ignores; join it to the line before"
            )
        line = raw.split("#", 1)[0].strip()
        if not line:
            if pending:
                raise ScenarioError(f"{file}:{first}: a line continued with '\\' is followed by an empty line")
            continue
        if not pending:
            first = number
        line = pending + line
        if line.endswith("\\"):
            pending = line[:-1].strip() + " "
            continue
        pending = ""
        m = _TIMESTAMP.match(line)
        if m is None:
            raise ScenarioError(f"{file}:{first}: expected 'HH:MM:SS.hh>COMMAND args', got {line!r}")
        hours, minutes, seconds, rest = m.groups()
        if int(minutes) >= 60 or float(seconds) >= 60.0:
            raise ScenarioError(f"{file}:{first}: invalid time stamp {line.split('>', 1)[0].strip()!r} (minutes and seconds below 60)")
        t = 3600.0 * int(hours) + 60.0 * int(minutes) + float(seconds)
        parts = [part.strip() for part in rest.split(";") if part.strip()]
        if not parts:
            raise ScenarioError(f"{file}:{first}: a time stamp without a command: {line!r}")
        out.extend((t, Source(file, first, part)) for part in parts)
    if pending:
        raise ScenarioError(f"{file}:{first}: the last line ends with '\\' (continuation of nothing)")
    out.sort(key=lambda item: item[0])
    return out


def parse_scenario(text: str, name: str = "<scenario>") -> ScenarioFile:
    """Parse the text of a ``.scn`` file.

    Args:
        text: The file's content.
        name: Its name, for error messages and for :attr:`ScenarioFile.name`.

    Raises:
        ScenarioError: A line or command that cannot be read or is not supported.
    """
    ctx = _Context(name)
    commands = [_parse_command(t, src, ctx) for t, src in read_lines(text, name)]
    return ScenarioFile(name, tuple(commands))


def read_scenario(path: str | Path) -> ScenarioFile:
    """Read and parse a ``.scn`` file (see :func:`parse_scenario`)."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8", errors="replace")
    except OSError as exc:
        raise ScenarioError(f"{p}: cannot read the scenario file ({exc.strerror or exc})") from None
    return parse_scenario(text, str(p))


# ----------------------------------------------------------------------------------------------
# Commands
# ----------------------------------------------------------------------------------------------
class _Args:
    """The arguments of one command, consumed in order, with errors that name the command."""

    def __init__(self, cmd: str, args: list[str], src: Source, usage: str) -> None:
        self.cmd, self.args, self.src, self.usage = cmd, args, src, usage
        self.i = 0

    def fail(self, message: str) -> ScenarioError:
        return ScenarioError(f"{self.src}: {self.cmd}: {message} (usage: {self.usage}; line: {self.src.text!r})")

    def more(self) -> bool:
        return self.i < len(self.args) and any(a for a in self.args[self.i :])

    def peek(self) -> str:
        return self.args[self.i] if self.i < len(self.args) else ""

    def take(self, what: str, conv: Callable[[str], object] | None = None, optional: bool = False) -> object:
        text = self.peek()
        self.i += 1
        if not text:
            if optional:
                return None
            raise self.fail(f"missing argument {what}")
        if conv is None:
            return text
        try:
            return conv(text)
        except ValueError as exc:
            raise self.fail(str(exc)) from None

    def done(self) -> None:
        if self.more():
            raise self.fail(f"too many arguments: {' '.join(a for a in self.args[self.i :] if a)!r}")


def _acid(a: _Args, ctx: _Context) -> str:
    acid = str(a.take("acid")).upper()
    if acid not in ctx.alive:
        raise a.fail(f"no aircraft {acid!r} at this time")
    return acid


def _position(a: _Args, ctx: _Context) -> Position:
    first = str(a.take("lat/lon"))
    if first.upper() in ctx.alive:
        return Position(aircraft=first.upper())
    if not is_latitude(first):
        raise a.fail(
            f"position {first!r} is not a latitude/longitude or an aircraft (navaids, airports and waypoint names need BlueSky's navigation database)"
        )
    try:
        lat = parse_latitude(first)
    except ValueError as exc:
        raise a.fail(str(exc)) from None
    lon = a.take("lon", parse_longitude)
    return Position(lat, float(lon))  # type: ignore[arg-type]


USAGE = {
    "CRE": "CRE acid,type,lat,lon,[hdg,alt,spd]",
    "CRECONFS": "CRECONFS acid,type,targetid,dpsi,cpa,tlos_hor,[dH,tlos_ver,spd]",
    "DEL": "DEL acid[,acid...]",
    "HDG": "HDG acid,hdg",
    "SPD": "SPD acid,spd",
    "ALT": "ALT acid,alt,[vspd]",
    "VS": "VS acid,vspd",
    "ADDWPT": "ADDWPT acid,lat,lon",
    "DEST": "DEST acid,lat,lon",
    "DIRECT": "DIRECT acid,wpname",
    "LNAV": "LNAV acid,ON/OFF",
    "VNAV": "VNAV acid,OFF",
    "DT": "DT dt",
    "NOISE": "NOISE OFF",
}
_ALIASES = {"CREATE": "CRE", "DELETE": "DEL", "HEADING": "HDG", "TURN": "HDG", "SPEED": "SPD"}


def _parse_command(t: float, src: Source, ctx: _Context) -> Command:
    words = split_arguments(src.text)
    if not words or not words[0]:
        raise ScenarioError(f"{src}: empty command in {src.text!r}")
    cmd = words[0].upper()
    args = words[1:]
    if cmd not in KNOWN_COMMANDS and cmd in ctx.alive and args:
        # "KL204 HDG 90" is "HDG KL204 90"
        cmd, args = args[0].upper(), [words[0], *args[1:]]
    cmd = _ALIASES.get(cmd, cmd)
    if cmd in DISPLAY_COMMANDS or cmd in CONTROL_COMMANDS:
        return Ignored(t, src, cmd)
    if cmd in DETECTION_COMMANDS:
        try:
            return Asas(t, src, ASAS_COMMANDS[cmd], ctx.asas.apply(ASAS_COMMANDS[cmd], args, t))
        except ValueError as exc:
            raise ScenarioError(f"{src}: {cmd}: {exc} (line: {src.text!r})") from None
    if cmd not in TYPED_COMMANDS:
        raise ScenarioError(f"{src}: unsupported command {cmd!r} (see docs/scenarios.md for the supported commands; line: {src.text!r})")
    a = _Args(cmd, args, src, USAGE[cmd])
    out: Command
    if cmd == "CRE":
        acid = str(a.take("acid")).upper()
        if acid in ctx.alive:
            raise a.fail(f"aircraft {acid!r} already exists")
        actype = str(a.take("type")).upper()
        pos = _position(a, ctx)
        hdg, alt, spd = (a.take(w, f, optional=True) for w, f in (("hdg", parse_heading), ("alt", parse_altitude), ("spd", parse_speed)))
        a.done()
        hdg, alt, spd = (0.0 if x is None else float(x) for x in (hdg, alt, spd))  # type: ignore[arg-type]
        out = Create(t, src, acid, actype, pos, hdg, alt, spd)
        ctx.alive.add(acid)
        ctx.routes[acid] = []
    elif cmd == "CRECONFS":
        acid = str(a.take("acid")).upper()
        if acid in ctx.alive:
            raise a.fail(f"aircraft {acid!r} already exists")
        actype = str(a.take("type")).upper()
        target = _acid(a, ctx)
        dpsi = a.take("dpsi", parse_heading)
        dcpa = a.take("cpa", lambda text: parse_number(text, "a distance in NM"))
        tlosh = a.take("tlos_hor", parse_time)
        dh = a.take("dH", parse_altitude, optional=True)
        tlosv = a.take("tlos_ver", parse_time, optional=True)
        spd = a.take("spd", parse_speed, optional=True)
        a.done()
        if spd == 0.0:  # BlueSky's "if spd:": a speed of 0 gives the target's ground speed, as an omitted one
            spd = None
        if dh is not None:
            which = "tlos_hor (tlos_ver omitted)" if tlosv is None else "tlos_ver"
            _check_vertical_conflict(a, float(dh), float(tlosh if tlosv is None else tlosv), which)  # type: ignore[arg-type]
        out = CreateConflict(t, src, acid, actype, target, dpsi, dcpa, tlosh, dh, tlosv, spd)  # type: ignore[arg-type]
        ctx.alive.add(acid)
        ctx.routes[acid] = []
    elif cmd == "DEL":
        acids = []
        while a.more():
            acids.append(_acid(a, ctx))
        if not acids:
            raise a.fail("missing argument acid")
        for acid in acids:
            ctx.alive.discard(acid)
        out = Delete(t, src, tuple(acids))
    elif cmd == "HDG":
        acid = _acid(a, ctx)
        out = Heading(t, src, acid, a.take("hdg", parse_heading))  # type: ignore[arg-type]
        a.done()
    elif cmd == "SPD":
        acid = _acid(a, ctx)
        out = Speed(t, src, acid, a.take("spd", parse_speed))  # type: ignore[arg-type]
        a.done()
    elif cmd == "ALT":
        acid = _acid(a, ctx)
        alt = a.take("alt", parse_altitude)
        vs = a.take("vspd", parse_vertical_speed, optional=True)
        a.done()
        out = Altitude(t, src, acid, alt, vs)  # type: ignore[arg-type]
    elif cmd == "VS":
        acid = _acid(a, ctx)
        out = VerticalSpeed(t, src, acid, a.take("vspd", parse_vertical_speed))  # type: ignore[arg-type]
        a.done()
    elif cmd in ("ADDWPT", "DEST"):
        acid = _acid(a, ctx)
        pos = _position(a, ctx)
        if a.more():
            raise a.fail(
                "altitude and speed constraints and named insert positions are not supported by the core (its routes are lat/lon fly-by waypoints)"
            )
        route = ctx.routes[acid]
        if cmd == "ADDWPT":
            name = f"{acid}{len([w for w in route if w != '*DEST*']) + 1:03d}"
            route.insert(len(route) - 1 if route and route[-1] == "*DEST*" else len(route), name)
            out = AddWaypoint(t, src, acid, pos)
        else:
            if not (route and route[-1] == "*DEST*"):
                route.append("*DEST*")
            out = Destination(t, src, acid, pos)
    elif cmd == "DIRECT":
        acid = _acid(a, ctx)
        wp = str(a.take("wpname")).upper()
        a.done()
        names = ctx.routes[acid]
        if wp not in names:
            raise a.fail(f"waypoint {wp!r} is not in the route of {acid} (its waypoints: {', '.join(names) or 'none'})")
        out = Direct(t, src, acid, names.index(wp))
    elif cmd == "LNAV":
        acid = _acid(a, ctx)
        on = a.take("ON/OFF", parse_switch)
        a.done()
        if on and not ctx.routes[acid]:
            raise a.fail(f"{acid} has no waypoints or destination")
        out = Lnav(t, src, acid, bool(on))
    elif cmd == "VNAV":
        acid = _acid(a, ctx)
        on = a.take("ON/OFF", parse_switch)
        a.done()
        if on:
            raise a.fail("VNAV ON is not supported: the core flies routes laterally only (see docs/dynamics.md)")
        out = Vnav(t, src, acid)
    elif cmd == "DT":
        dt = a.take("dt", lambda text: parse_number(text, "a time step"))
        a.done()
        if not (isinstance(dt, float) and dt > 0):
            raise a.fail(f"dt must be > 0 s, got {dt}")
        if t > 0:
            raise a.fail("DT is only supported at time 0 (every scenario of a batch shares one clock)")
        out = TimeStep(t, src, dt)
    else:  # NOISE: accepted when it switches off what the core does not model
        on = a.take("ON/OFF", str)
        a.done()
        if str(on).upper() not in ("OFF", "FALSE", "0"):
            raise a.fail(f"{cmd} {on}: turbulence noise is not supported by the core")
        out = Ignored(t, src, cmd)
    return out


def _check_vertical_conflict(a: _Args, dh: float, tlosv: float, which: str) -> None:
    """Refuse a ``CRECONFS`` whose intruder would get no finite vertical speed.

    BlueSky gives the intruder ``vs = vs_target - sign(dH) (|dH| - hpz) / tlos_ver`` (hpz: the
    protected zone's half height, 1000 ft); with ``tlos_ver`` 0 that is NaN or infinite, and the
    aircraft's state turns NaN.
    """
    if tlosv == 0.0 or not math.isfinite((abs(dh) - PZ_HEIGHT) / tlosv):
        raise a.fail(
            f"no finite conflict geometry: the intruder's vertical speed (|dH| - {PZ_HEIGHT / FT:g} ft) / tlos_ver with dH {dh / FT:g} ft "
            f"and {which} {tlosv:g} s is not a finite number; give a time to vertical loss of separation other than 0"
        )


def parse_scenarios(paths: Sequence[str | Path]) -> list[ScenarioFile]:
    """Read several ``.scn`` files (see :func:`read_scenario`)."""
    return [read_scenario(p) for p in paths]
