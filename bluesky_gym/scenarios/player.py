"""Playing parsed scenarios on any :class:`~bluesky_gym.core.physics.Physics`, one airspace per scenario.

:class:`ScenarioPlayer` gives every scenario of a batch its own airspace and every aircraft its own
slot (in creation order, as BlueSky lists its traffic). It applies the commands with BlueSky's
timing: the commands at time 0 run before the first recorded state; a command at time ``t > 0``
runs at the start of the first step that starts at or after ``t`` (BlueSky's scenario stack is
checked at the start of every step), so a command at a multiple of ``dt`` acts in the step that
ends at ``t + dt``. Identical scenarios (copies) are commanded together, in one call per command.
Conflict detection and resolution commands (``ASAS``, ``RESO MVP``, ...) reach a physics that
implements :class:`~bluesky_gym.core.physics.ConflictResolutionCommands`; on another physics a
scenario that switches resolution on is an error. An aircraft type BlueSky does not know flies as
BlueSky flies it, as the B744, with an :class:`UnknownAircraftTypeWarning` per type naming the
first line that creates one (:func:`unknown_types`).
"""

from __future__ import annotations

import inspect
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from bluesky_gym.core.aircraft import FALLBACK_TYPE, resolve_type
from bluesky_gym.core.physics import ConflictResolutionCommands, Physics, RouteCommands
from bluesky_gym.scenarios.parser import (
    DEFAULT_ACTYPE,
    AddWaypoint,
    Altitude,
    Asas,
    Command,
    Create,
    CreateConflict,
    Delete,
    Destination,
    Direct,
    Heading,
    Ignored,
    Lnav,
    Position,
    ScenarioError,
    ScenarioFile,
    Source,
    Speed,
    TimeStep,
    VerticalSpeed,
    Vnav,
)

#: Tolerance [s] when comparing command times with step start times (the clock is a sum of dt's).
TIME_EPS = 1e-9

#: Columns of a trajectory row, as in the BlueSky reference recordings (SI units).
TRAJECTORY_COLUMNS = (
    "t",
    "acid",
    "lat",
    "lon",
    "alt",
    "tas",
    "cas",
    "mach",
    "gs",
    "hdg",
    "trk",
    "vs",
    "gsnorth",
    "gseast",
    "ax",
    "selspd",
    "selalt",
    "selvs",
    "ap_trk",
    "ap_tas",
    "ap_vs",
    "ap_alt",
    "phase",
    "axmax",
    "vmin_cas",
    "vmax_cas",
    "swlnav",
    "swvnav",
    "iactwp",
    "windnorth",
    "windeast",
    "thrust",
    "drag",
    "fuelflow",
)
#: Physics attribute of each numeric column (``t`` and ``acid`` are not state).
COLUMN_FIELDS = {c: {"vmin_cas": "vmin", "vmax_cas": "vmax"}.get(c, c) for c in TRAJECTORY_COLUMNS[2:]}
#: Columns written as integers.
INTEGER_COLUMNS = frozenset({"phase", "swlnav", "swvnav", "iactwp"})


class UnknownAircraftTypeWarning(UserWarning):
    """A scenario creates an aircraft of a type BlueSky does not know; it flies as the B744 (BlueSky's fallback)."""


def unknown_types(scenarios: Sequence[ScenarioFile]) -> dict[str, Source]:
    """The aircraft types of ``scenarios`` that BlueSky does not know, each with the first line creating one.

    BlueSky 1.1.1 flies such an aircraft with the B744's performance data, without a word; the
    player and ``bluesky-gym replay`` keep that fallback and warn once per type. Rotorcraft are
    types of their own (BlueSky's rotor model), not unknown ones.

    Args:
        scenarios: Parsed scenarios, searched in order.

    Returns:
        Type name (upper case) -> the source line of its first ``CRE`` or ``CRECONFS``.
    """
    found: dict[str, Source] = {}
    checked: set[str] = {DEFAULT_ACTYPE, FALLBACK_TYPE}  # the default type needs no look-up (it would load the type data)
    for s in scenarios:
        for c in s.commands:
            if isinstance(c, (Create, CreateConflict)) and c.actype not in checked:
                checked.add(c.actype)
                if resolve_type(c.actype) == FALLBACK_TYPE:
                    found[c.actype] = c.source
    return found


def unknown_type_message(actype: str, source: Source) -> str:
    """The warning about an unknown aircraft type (see :func:`unknown_types`)."""
    return f"{source}: aircraft type {actype!r} is unknown to BlueSky; it flies as the {FALLBACK_TYPE} (BlueSky's fallback; line: {source.text!r})"


def slots_needed(scenario: ScenarioFile) -> int:
    """Aircraft slots a scenario uses (one per creation; slots are not reused after DEL)."""
    return len(scenario.callsigns)


def waypoints_needed(scenario: ScenarioFile) -> int:
    """Route capacity a scenario needs (the most ADDWPT/DEST of one aircraft, at least 1)."""
    counts: dict[str, int] = {}
    for c in scenario.commands:
        if isinstance(c, (AddWaypoint, Destination)):
            counts[c.acid] = counts.get(c.acid, 0) + 1
    return max([1, *counts.values()])


def common_dt(scenarios: Sequence[ScenarioFile], dt: float | None) -> float:
    """The time step of a batch: ``dt`` if given, else the scenarios' ``DT`` (all equal), else 1 s.

    Raises:
        ScenarioError: The scenarios set different time steps, or one differs from ``dt``.
    """
    steps = {s.name: s.dt for s in scenarios if s.dt is not None}
    if dt is not None:
        bad = {n: v for n, v in steps.items() if v != dt}
        if bad:
            name, value = next(iter(bad.items()))
            raise ScenarioError(f"{name}: its DT {value} s differs from the requested time step {dt} s")
        return float(dt)
    values = set(steps.values())
    if len(values) > 1:
        raise ScenarioError(f"the scenarios of one batch must share one time step; their DT commands give {sorted(values)} s")
    return float(values.pop()) if values else 1.0


@dataclass
class _Group:
    """Airspaces playing the same scenario."""

    scenario: ScenarioFile
    envs: NDArray[np.int64]
    slot_of: dict[int, int]  # index of a creation command -> slot
    next_command: int = 0


class ScenarioPlayer:
    """Play scenarios on a physics, one airspace per scenario.

    Args:
        scenarios: The parsed scenarios; scenario ``k`` plays in airspace ``k`` (the same object
            listed several times is commanded once per command for all its airspaces).
        physics: A physics with at least ``len(scenarios)`` airspaces and enough slots and route
            capacity (:func:`slots_needed`, :func:`waypoints_needed`), freshly reset.
        supports_actype: Whether ``physics.create`` and ``physics.creconfs`` take an ``actype``
            argument (default: read from their signatures); without it every aircraft must be an A320.

    Raises:
        ScenarioError: The physics is too small, or a command cannot run on it.

    Warns:
        UnknownAircraftTypeWarning: Once per aircraft type BlueSky does not know (it flies as the B744).
    """

    def __init__(self, scenarios: Sequence[ScenarioFile], physics: Physics, supports_actype: bool | None = None) -> None:
        if len(scenarios) > physics.n_envs:
            raise ScenarioError(f"{len(scenarios)} scenarios need {len(scenarios)} airspaces, the physics has {physics.n_envs}")
        self.physics = physics
        self.scenarios = list(scenarios)
        if supports_actype is None:
            supports_actype = all("actype" in inspect.signature(f).parameters for f in (physics.create, physics.creconfs))
        self.supports_actype = supports_actype
        if supports_actype:
            for actype, source in unknown_types(list({id(s): s for s in self.scenarios}.values())).items():
                warnings.warn(unknown_type_message(actype, source), UnknownAircraftTypeWarning, stacklevel=2)
        groups: dict[int, list[int]] = {}
        for k, s in enumerate(self.scenarios):
            groups.setdefault(id(s), []).append(k)
        self.groups: list[_Group] = []
        for envs in groups.values():
            s = self.scenarios[envs[0]]
            if slots_needed(s) > physics.max_aircraft:
                raise ScenarioError(f"{s.name}: creates {slots_needed(s)} aircraft, the physics has {physics.max_aircraft} slots")
            if waypoints_needed(s) > physics.max_waypoints:
                raise ScenarioError(f"{s.name}: needs {waypoints_needed(s)} route waypoints, the physics has {physics.max_waypoints}")
            creations = [i for i, c in enumerate(s.commands) if isinstance(c, (Create, CreateConflict))]
            self.groups.append(_Group(s, np.array(envs, dtype=np.int64), {i: k for k, i in enumerate(creations)}))
        #: Per airspace: callsign of each slot ("" when never used).
        self.acids: list[list[str]] = [[""] * physics.max_aircraft for _ in range(physics.n_envs)]
        self._alive: list[dict[str, int]] = [{} for _ in range(physics.n_envs)]
        self.steps_done = 0
        self._index_cache: tuple[NDArray[np.int64], NDArray[np.int64], list[str]] | None = None
        self.apply_due(0.0)

    # ------------------------------------------------------------------------------------------
    def apply_due(self, t: float) -> int:
        """Apply every command of every scenario with a time <= ``t`` not yet applied; returns how many."""
        n = 0
        for g in self.groups:
            cmds = g.scenario.commands
            while g.next_command < len(cmds) and cmds[g.next_command].time <= t + TIME_EPS:
                self._apply(g, g.next_command, cmds[g.next_command])
                g.next_command += 1
                n += 1
        return n

    def next_command_time(self) -> float:
        """Time of the earliest command not yet applied (inf when none is left)."""
        return min((g.scenario.commands[g.next_command].time for g in self.groups if g.next_command < len(g.scenario.commands)), default=np.inf)

    def step(self) -> None:
        """Apply the commands due at the current time, then advance one step."""
        self.apply_due(self.steps_done * self.physics.dt)
        self.physics.step()
        self.steps_done += 1

    def advance(self, n_steps: int) -> None:
        """Advance ``n_steps`` steps, applying commands on time, in as few ``Physics.run`` calls as possible."""
        end = self.steps_done + int(n_steps)
        dt = self.physics.dt
        while self.steps_done < end:
            self.apply_due(self.steps_done * dt)
            nxt = self.next_command_time()
            # steps until the step that starts at or after the next command
            due = end if not np.isfinite(nxt) else max(self.steps_done + 1, int(np.ceil((nxt - TIME_EPS) / dt)))
            k = min(end, due) - self.steps_done
            self.physics.run(k)
            self.steps_done += k

    # ------------------------------------------------------------------------------------------
    def slots(self, env: int) -> list[tuple[int, str]]:
        """(slot, callsign) of the aircraft alive in airspace ``env``, in creation order."""
        return sorted(((s, a) for a, s in self._alive[env].items()), key=lambda x: x[0])

    def snapshot(self, t: float) -> list[list[object]]:
        """Trajectory rows of every alive aircraft at time ``t`` (see :data:`TRAJECTORY_COLUMNS`), airspace by airspace."""
        envs, slots, acids = self._alive_index()
        p = self.physics
        columns: list[list[object]] = [[t] * len(acids), list(acids)]
        for c in TRAJECTORY_COLUMNS[2:]:
            values = getattr(p, COLUMN_FIELDS[c])[envs, slots]
            columns.append(values.astype(np.int64).tolist() if c in INTEGER_COLUMNS else values.astype(np.float64).tolist())
        return [list(row) for row in zip(*columns)]

    def scenario_of_rows(self) -> list[int]:
        """The airspace of each row :meth:`snapshot` returns now."""
        return self._alive_index()[0].tolist()

    def _alive_index(self) -> tuple[NDArray[np.int64], NDArray[np.int64], list[str]]:
        if self._index_cache is None:
            pairs = [(env, slot, acid) for env in range(len(self.scenarios)) for slot, acid in self.slots(env)]
            self._index_cache = (
                np.array([x[0] for x in pairs], dtype=np.int64),
                np.array([x[1] for x in pairs], dtype=np.int64),
                [x[2] for x in pairs],
            )
        return self._index_cache

    # ------------------------------------------------------------------------------------------
    def _slot(self, g: _Group, cmd: Command, acid: str) -> int:
        slot = self._alive[int(g.envs[0])].get(acid)
        if slot is None:  # the reader checks this; a guard for hand-built command lists
            raise ScenarioError(f"{cmd.source}: no aircraft {acid!r} at t={cmd.time:g} s")
        return slot

    def _position(self, g: _Group, cmd: Command, pos: Position) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        if pos.aircraft is None:
            return np.full(g.envs.size, pos.lat), np.full(g.envs.size, pos.lon)
        s = self._slot(g, cmd, pos.aircraft)
        return self.physics.lat[g.envs, s].copy(), self.physics.lon[g.envs, s].copy()

    def _check_type(self, cmd: Command, actype: str) -> dict[str, Any]:
        if self.supports_actype:
            return {"actype": actype}
        if actype != DEFAULT_ACTYPE:
            raise ScenarioError(
                f"{cmd.source}: aircraft type {actype!r}: aircraft types other than {DEFAULT_ACTYPE} need a physics with per-aircraft types "
                f"(create(..., actype=)); line: {cmd.source.text!r}"
            )
        return {}

    def _apply(self, g: _Group, index: int, cmd: Command) -> None:
        p, envs = self.physics, g.envs
        try:
            if isinstance(cmd, Create):
                slot = g.slot_of[index]
                lat, lon = self._position(g, cmd, cmd.position)
                p.create(envs, slot, lat, lon, cmd.hdg, cmd.alt, cmd.spd, **self._check_type(cmd, cmd.actype))
                self._check_created(g, cmd, slot)
                self._born(g, cmd.acid, slot)
            elif isinstance(cmd, CreateConflict):
                slot = g.slot_of[index]
                extra = self._check_type(cmd, cmd.actype)
                p.creconfs(envs, self._slot(g, cmd, cmd.target), slot, cmd.dpsi, cmd.dcpa, cmd.tlosh, cmd.dh, cmd.tlosv, cmd.spd, **extra)
                self._check_created(g, cmd, slot)
                self._born(g, cmd.acid, slot)
            elif isinstance(cmd, Delete):
                for acid in cmd.acids:
                    p.delete(envs, self._slot(g, cmd, acid))
                    for e in envs:
                        del self._alive[int(e)][acid]
                    self._index_cache = None
            elif isinstance(cmd, Heading):
                p.cmd_heading(envs, self._slot(g, cmd, cmd.acid), cmd.hdg)
            elif isinstance(cmd, Speed):
                p.cmd_speed(envs, self._slot(g, cmd, cmd.acid), cmd.spd)
            elif isinstance(cmd, Altitude):
                p.cmd_altitude(envs, self._slot(g, cmd, cmd.acid), cmd.alt, cmd.vs)
            elif isinstance(cmd, VerticalSpeed):
                p.cmd_vertical_speed(envs, self._slot(g, cmd, cmd.acid), cmd.vs)
            elif isinstance(cmd, AddWaypoint):
                p.add_waypoint(envs, self._slot(g, cmd, cmd.acid), *self._position(g, cmd, cmd.position))
            elif isinstance(cmd, Destination):
                p.set_destination(envs, self._slot(g, cmd, cmd.acid), *self._position(g, cmd, cmd.position))
            elif isinstance(cmd, Vnav):
                p.set_autopilot(envs, self._slot(g, cmd, cmd.acid), swvnav=False)
            elif isinstance(cmd, (Direct, Lnav)):
                if not isinstance(p, RouteCommands):
                    raise ScenarioError(f"{cmd.source}: this physics has no DIRECT/LNAV commands; line: {cmd.source.text!r}")
                if isinstance(cmd, Direct):
                    p.cmd_direct(envs, self._slot(g, cmd, cmd.acid), cmd.waypoint)
                else:
                    p.cmd_lnav(envs, self._slot(g, cmd, cmd.acid), cmd.on)
            elif isinstance(cmd, TimeStep):
                if abs(cmd.dt - p.dt) > TIME_EPS:
                    raise ScenarioError(f"{cmd.source}: DT {cmd.dt} s differs from the replay's time step {p.dt} s")
            elif isinstance(cmd, Asas):
                if isinstance(p, ConflictResolutionCommands):
                    p.set_conflict_resolution(envs, cmd.config)
                elif cmd.config.resolving:
                    raise ScenarioError(f"{cmd.source}: this physics cannot fly conflict resolution (RESO MVP); line: {cmd.source.text!r}")
            elif not isinstance(cmd, Ignored):  # pragma: no cover - every command class is handled above
                raise ScenarioError(f"{cmd.source}: no player for {type(cmd).__name__}")
        except ScenarioError:
            raise
        except (ValueError, RuntimeError, IndexError) as exc:
            raise ScenarioError(f"{cmd.source}: {cmd.source.text!r} failed: {exc}") from exc

    def _nonfinite(self, envs: NDArray[np.int64], slots: NDArray[np.int64]) -> list[str]:
        """The trajectory columns in which any of the aircraft (``envs[k]``, ``slots[k]``) is not finite."""
        p = self.physics
        return [c for c, f in COLUMN_FIELDS.items() if not np.all(np.isfinite(np.asarray(getattr(p, f)[envs, slots], dtype=np.float64)))]

    def _check_created(self, g: _Group, cmd: Create | CreateConflict, slot: int) -> None:
        """Refuse a creation that gives the new aircraft a state that is not finite (the reader refuses NaN and infinities; huge values remain)."""
        bad = ", ".join(self._nonfinite(g.envs, np.full(g.envs.size, slot, dtype=np.int64)))
        if not bad:
            return
        if isinstance(cmd, CreateConflict):
            why = f"the conflict geometry has no finite solution for the state of {cmd.target} (the intruder's {bad} would not be finite)"
        else:
            why = f"the new aircraft's {bad} would not be finite"
        raise ScenarioError(f"{cmd.source}: {cmd.acid}: {why}; line: {cmd.source.text!r}")

    def check_finite(self, t: float) -> None:
        """Raise when an alive aircraft's state is not finite (a value no command or step should give).

        Args:
            t: The current time [s], for the message.

        Raises:
            ScenarioError: Naming the scenario, the aircraft and the columns.
        """
        envs, slots, acids = self._alive_index()
        if not envs.size or not self._nonfinite(envs, slots):
            return
        for env, slot, acid in zip(envs.tolist(), slots.tolist(), acids):
            bad = self._nonfinite(np.array([env]), np.array([slot]))
            if bad:
                raise ScenarioError(f"{self.scenarios[env].name}: at t = {t:g} s the state of {acid} is not finite ({', '.join(bad)})")

    def _born(self, g: _Group, acid: str, slot: int) -> None:
        self._index_cache = None
        for e in g.envs:
            self._alive[int(e)][acid] = slot
            self.acids[int(e)][slot] = acid
