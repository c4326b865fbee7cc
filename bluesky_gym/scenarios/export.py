"""Writing environment episodes as BlueSky scenario files.

:class:`ScenarioRecorder` is a :class:`~bluesky_gym.core.physics.Physics` that passes every call on
to another physics and logs what the task did, per airspace and episode (an episode starts at
``reset_envs``). :meth:`ScenarioRecorder.scenario_text` turns one logged episode into a ``.scn``
that BlueSky (and ``bluesky-gym replay``) plays back:

* every aircraft is created (``CRE``) with its state when the episode's first step starts, so
  placements made by ``creconfs`` or direct writes at reset are included;
* every command the task gave is written at its time (relative to the episode start) as the stack
  command that does the same: ``HDG``, ``SPD``, ``ALT``, ``VS``, ``ADDWPT``, ``DEST``, ``DEL``;
  wind points as ``WIND lat lon dir spd``;
* the direct writes of the reference gym code are written as the commands that set the same
  values: ``set_autopilot(selalt, selvs)`` as ``VS`` then ``ALT`` (identical unless the two have
  opposite signs, where BlueSky's ``ALT`` resets the rate), ``swvnav=False`` as ``VNAV OFF``,
  ``ap_trk`` as ``HDG`` (identical without wind), and ``set_state`` after the first step as ``MOVE``.

Aircraft are named ``AC000``, ``AC001``, ... by slot, unless :meth:`ScenarioRecorder.set_callsigns`
names them (e.g. with their recorded callsigns). The text is written by :mod:`bluesky_gym.core.command_text`:
numbers with full precision and never an exponent, converted to BlueSky's units (ft, kt, fpm).
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from bluesky_gym.core.command_text import altitude, command, speed, timed, vertical_speed
from bluesky_gym.core.physics import Physics, RouteCommands
from bluesky_gym.core.state import aircraft_index
from bluesky_gym.core.units import KTS
from bluesky_gym.core.wind import WindField


def callsign(slot: int) -> str:
    """The callsign written for an aircraft slot (unless it was given another name)."""
    return f"AC{int(slot):03d}"


def unique_callsigns(names: Sequence[str], reserved: Sequence[str] = ()) -> list[str]:
    """Callsigns for slots ``0, 1, ...`` from ``names``: upper case, letters and digits only, unique.

    An empty name (after dropping other characters) becomes :func:`callsign` of its slot; a name
    already taken (by an earlier slot or in ``reserved``) gets ``_2``, ``_3``, ... appended.
    """
    out: list[str] = []
    taken: set[str] = set(reserved)
    for slot, name in enumerate(names):
        base = re.sub(r"[^A-Z0-9]", "", str(name).upper()) or callsign(slot)
        acid, k = base, 1
        while acid in taken:
            k += 1
            acid = f"{base}_{k}"
        taken.add(acid)
        out.append(acid)
    return out


@dataclass
class _Created:
    """A creation whose state is read when the episode's first step starts."""

    slot: int
    actype: str = "A320"
    line: str = ""


@dataclass
class Episode:
    """One logged episode of one airspace."""

    start: float  # s, physics clock at the reset
    entries: list[tuple[float, str | _Created]] = field(default_factory=list)
    steps: int = 0

    def lines(self) -> list[str]:
        """The episode's scenario lines, in time order."""
        out: list[str] = []
        for t, entry in self.entries:
            text = entry.line if isinstance(entry, _Created) else entry
            # one command per line: BlueSky's PCALL does not split ";" for commands due at once
            out.extend(timed(t, part) for part in text.split("\n") if part)
        return out


class _LoggedWind:
    """The inner physics' wind, logging ``add_points`` as ``WIND`` commands."""

    def __init__(self, owner: ScenarioRecorder) -> None:
        self._owner = owner

    def add_points(self, env: int, lat: ArrayLike, lon: ArrayLike, vnorth: ArrayLike, veast: ArrayLike) -> None:
        self._owner.inner.wind.add_points(env, lat, lon, vnorth, veast)
        for la, lo, vn, ve in zip(*(np.atleast_1d(np.asarray(x, dtype=np.float64)) for x in (lat, lon, vnorth, veast))):
            direction = math.degrees(math.atan2(-ve, -vn)) % 360.0  # where the wind comes from
            self._owner._add(int(env), command("WIND", la, lo, direction, math.hypot(vn, ve) / KTS))

    def __getattr__(self, name: str) -> Any:
        return getattr(self._owner.inner.wind, name)


class ScenarioRecorder:
    """A physics that logs every command of the task on top of another physics.

    Args:
        inner: The physics that does the work (native or BlueSky).

    Everything not listed here (state arrays, dimensions, clock) is read from ``inner``.
    """

    def __init__(self, inner: Physics) -> None:
        self.inner = inner
        self.episodes: list[list[Episode]] = [[] for _ in range(inner.n_envs)]
        self._names: list[dict[int, str]] = [{} for _ in range(inner.n_envs)]
        self._pending: list[tuple[int, _Created]] = []
        self._wind = _LoggedWind(self)

    def __getattr__(self, name: str) -> Any:
        if name == "inner":  # not set yet (during unpickling or a failed __init__)
            raise AttributeError(name)
        return getattr(self.inner, name)

    @property
    def wind(self) -> WindField:
        """The inner wind, with ``add_points`` logged."""
        return self._wind  # type: ignore[return-value]

    # --- logging --------------------------------------------------------------------------------
    def _episode(self, env: int) -> Episode:
        if not self.episodes[env]:
            self.episodes[env].append(Episode(self.inner.simt))
        return self.episodes[env][-1]

    def _add(self, env: int, text: str) -> None:
        ep = self._episode(env)
        ep.entries.append((self.inner.simt - ep.start, text))

    def _index(self, env: ArrayLike, slot: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        return aircraft_index(env, slot, self.inner.n_envs, self.inner.max_aircraft)

    def acid(self, env: int, slot: int) -> str:
        """The callsign written for slot ``slot`` of airspace ``env``."""
        return self._names[env].get(slot) or callsign(slot)

    def set_callsigns(self, env: int, names: Sequence[str]) -> list[str]:
        """Name the aircraft of slots ``0 .. len(names) - 1`` of airspace ``env`` in the written scenario.

        Call it after :meth:`reset_envs` (a reset restores the slot names ``AC000``, ...) and before
        the aircraft are created. The names are made valid and unique by :func:`unique_callsigns`.

        Returns:
            The callsigns used, one per slot.
        """
        acids = unique_callsigns(names, [callsign(s) for s in range(len(names), self.inner.max_aircraft)])
        self._names[int(env)] = dict(enumerate(acids))
        return acids

    def _flush(self) -> None:
        """Write the creations of the starting step with the aircraft's current state."""
        p = self.inner
        for env, created in self._pending:
            s = created.slot
            if p.active[env, s]:
                position = (p.lat[env, s], p.lon[env, s], p.hdg[env, s])
                created.line = command("CRE", self.acid(env, s), created.actype, *position, altitude(p.alt[env, s]), p.cas[env, s] / KTS)
        self._pending.clear()

    def _each(self, env: ArrayLike, slot: ArrayLike, fmt: Callable[[int, int, int], str]) -> None:
        e, s = self._index(env, slot)
        for k in range(e.size):
            self._add(int(e[k]), fmt(k, int(e[k]), int(s[k])))

    # --- Physics ------------------------------------------------------------------------------------
    def reset_envs(self, envs: ArrayLike | None = None) -> None:
        """Reset airspaces in the inner physics and start a new logged episode for each."""
        self.inner.reset_envs(envs)
        idx = range(self.inner.n_envs) if envs is None else np.atleast_1d(np.asarray(envs, dtype=np.int64))
        for e in idx:
            self.episodes[int(e)].append(Episode(self.inner.simt))
            self._names[int(e)] = {}
        self._pending = [(e, c) for e, c in self._pending if e not in set(int(i) for i in idx)]

    def create(
        self,
        env: ArrayLike,
        slot: ArrayLike,
        lat: ArrayLike = 52.0,
        lon: ArrayLike = 4.0,
        hdg: ArrayLike = 0.0,
        alt: ArrayLike = 0.0,
        spd: ArrayLike = 0.0,
        **kwargs: Any,
    ) -> None:
        """Create aircraft (logged as ``CRE`` with their state at the next step).

        Further keywords (an aircraft type ``actype``, where the inner physics takes one) are passed on.
        """
        self.inner.create(env, slot, lat, lon, hdg, alt, spd, **kwargs)
        self._created(env, slot, kwargs.get("actype"))

    def _created(self, env: ArrayLike, slot: ArrayLike, actype: Any = None) -> None:
        e, s = self._index(env, slot)
        types = np.broadcast_to(np.asarray("A320" if actype is None else actype, dtype=object), e.shape)
        for k in range(e.size):
            created = _Created(int(s[k]), str(types[k]).upper())
            ep = self._episode(int(e[k]))
            ep.entries.append((self.inner.simt - ep.start, created))
            self._pending.append((int(e[k]), created))

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
        **kwargs: Any,
    ) -> None:
        """Create conflicting intruders (logged as ``CRE`` with their placed state); further keywords are passed on."""
        self.inner.creconfs(env, target, slot, dpsi, dcpa, tlosh, dh, tlosv, spd, **kwargs)
        e, s = self._index(env, slot)
        self._created(e, s, kwargs.get("actype"))

    def delete(self, env: ArrayLike, slot: ArrayLike) -> None:
        """``DEL``."""
        e, s = self._index(env, slot)
        alive = self.inner.active[e, s].copy()
        self.inner.delete(e, s)
        self._each(e[alive], s[alive], lambda k, e_, s_: command("DEL", self.acid(e_, s_)))

    def cmd_heading(self, env: ArrayLike, slot: ArrayLike, hdg: ArrayLike) -> None:
        """``HDG``."""
        self.inner.cmd_heading(env, slot, hdg)
        h = np.broadcast_to(np.asarray(hdg, dtype=np.float64), self._index(env, slot)[0].shape)
        self._each(env, slot, lambda k, e, s: command("HDG", self.acid(e, s), h[k]))

    def cmd_speed(self, env: ArrayLike, slot: ArrayLike, casmach: ArrayLike) -> None:
        """``SPD``."""
        self.inner.cmd_speed(env, slot, casmach)
        v = np.broadcast_to(np.asarray(casmach, dtype=np.float64), self._index(env, slot)[0].shape)
        self._each(env, slot, lambda k, e, s: command("SPD", self.acid(e, s), speed(v[k])))

    def cmd_altitude(self, env: ArrayLike, slot: ArrayLike, alt: ArrayLike, vs: ArrayLike | None = None) -> None:
        """``ALT alt [vs]``."""
        self.inner.cmd_altitude(env, slot, alt, vs)
        shape = self._index(env, slot)[0].shape
        a = np.broadcast_to(np.asarray(alt, dtype=np.float64), shape)
        v = None if vs is None else np.broadcast_to(np.asarray(vs, dtype=np.float64), shape)

        def fmt(k: int, e: int, s: int) -> str:
            rate = () if v is None or v[k] == 0 else (vertical_speed(v[k]),)
            return command("ALT", self.acid(e, s), altitude(a[k]), *rate)

        self._each(env, slot, fmt)

    def cmd_vertical_speed(self, env: ArrayLike, slot: ArrayLike, vs: ArrayLike) -> None:
        """``VS``."""
        self.inner.cmd_vertical_speed(env, slot, vs)
        v = np.broadcast_to(np.asarray(vs, dtype=np.float64), self._index(env, slot)[0].shape)
        self._each(env, slot, lambda k, e, s: command("VS", self.acid(e, s), vertical_speed(v[k])))

    def add_waypoint(self, env: ArrayLike, slot: ArrayLike, lat: ArrayLike, lon: ArrayLike) -> None:
        """``ADDWPT``."""
        self.inner.add_waypoint(env, slot, lat, lon)
        shape = self._index(env, slot)[0].shape
        la, lo = (np.broadcast_to(np.asarray(x, dtype=np.float64), shape) for x in (lat, lon))
        self._each(env, slot, lambda k, e, s: command("ADDWPT", self.acid(e, s), la[k], lo[k]))

    def set_destination(self, env: ArrayLike, slot: ArrayLike, lat: ArrayLike, lon: ArrayLike) -> None:
        """``DEST``."""
        self.inner.set_destination(env, slot, lat, lon)
        shape = self._index(env, slot)[0].shape
        la, lo = (np.broadcast_to(np.asarray(x, dtype=np.float64), shape) for x in (lat, lon))
        self._each(env, slot, lambda k, e, s: command("DEST", self.acid(e, s), la[k], lo[k]))

    def cmd_direct(self, env: ArrayLike, slot: ArrayLike, waypoint: ArrayLike) -> None:
        """``DIRECT``, written with BlueSky's name of the ``k``-th waypoint added by ``ADDWPT`` (callsign + ``k``)."""
        if not isinstance(self.inner, RouteCommands):
            raise TypeError(f"{type(self.inner).__name__} has no DIRECT command")
        self.inner.cmd_direct(env, slot, waypoint)
        w = np.broadcast_to(np.asarray(waypoint, dtype=np.int64), self._index(env, slot)[0].shape)
        self._each(env, slot, lambda k, e, s: command("DIRECT", self.acid(e, s), f"{self.acid(e, s)}{int(w[k]) + 1:03d}"))

    def cmd_lnav(self, env: ArrayLike, slot: ArrayLike, on: ArrayLike) -> None:
        """``LNAV ON/OFF``."""
        if not isinstance(self.inner, RouteCommands):
            raise TypeError(f"{type(self.inner).__name__} has no LNAV command")
        self.inner.cmd_lnav(env, slot, on)
        f = np.broadcast_to(np.asarray(on, dtype=bool), self._index(env, slot)[0].shape)
        self._each(env, slot, lambda k, e, s: command("LNAV", self.acid(e, s), bool(f[k])))

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
        """Direct autopilot writes, logged as ``VS``/``ALT``/``VNAV OFF``/``HDG``."""
        self.inner.set_autopilot(env, slot, selalt=selalt, selvs=selvs, swvnav=swvnav, ap_trk=ap_trk)
        shape = self._index(env, slot)[0].shape

        def arr(x: ArrayLike | None) -> np.ndarray | None:
            return None if x is None else np.broadcast_to(np.asarray(x), shape)

        a, v, n, t = arr(selalt), arr(selvs), arr(swvnav), arr(ap_trk)

        def fmt(k: int, e: int, s: int) -> str:
            acid = self.acid(e, s)
            parts = []
            if n is not None:
                parts.append(command("VNAV", acid, bool(n[k])))
            if v is not None:
                parts.append(command("VS", acid, vertical_speed(v[k])))
            if a is not None:
                parts.append(command("ALT", acid, altitude(a[k])))
            if t is not None:
                parts.append(command("HDG", acid, float(t[k])))
            return "\n".join(parts)

        self._each(env, slot, fmt)

    def set_state(self, env: ArrayLike, slot: ArrayLike, *, alt: ArrayLike | None = None, hdg: ArrayLike | None = None) -> None:
        """Direct state writes: part of the ``CRE`` line at reset, ``MOVE`` later."""
        self.inner.set_state(env, slot, alt=alt, hdg=hdg)
        e, s = self._index(env, slot)
        pending = {(pe, c.slot) for pe, c in self._pending}
        later = np.array([(int(a), int(b)) not in pending for a, b in zip(e, s)], dtype=bool)
        p = self.inner
        self._each(
            e[later],
            s[later],
            lambda k, e_, s_: command("MOVE", self.acid(e_, s_), p.lat[e_, s_], p.lon[e_, s_], altitude(p.alt[e_, s_]), p.hdg[e_, s_]),
        )

    def step(self) -> None:
        """Advance the inner physics by one step."""
        self._flush()
        self.inner.step()

    def run(self, n_steps: int, trace: bool = False, stop: Callable[[np.ndarray], ArrayLike] | None = None) -> np.ndarray | None:
        """Advance the inner physics (see :meth:`Physics.run`)."""
        self._flush()
        return self.inner.run(n_steps, trace, stop)

    # --- output -----------------------------------------------------------------------------------
    def scenario_text(self, env: int = 0, episode: int = -1, title: str = "") -> str:
        """One logged episode of airspace ``env`` as ``.scn`` text (the last one by default).

        Raises:
            ValueError: Nothing was logged for that airspace and episode.
        """
        self._flush()
        episodes = [ep for ep in self.episodes[env] if ep.entries]
        if not episodes:
            raise ValueError(f"no episode was logged in airspace {env}")
        try:
            ep = episodes[episode]
        except IndexError:
            raise ValueError(f"airspace {env} has {len(episodes)} logged episode(s), not episode {episode}") from None
        head = [
            f"# {title}" if title else "# BlueSky-Gym episode",
            "# Written by bluesky_gym.scenarios.export; play it in BlueSky with PCALL or IC.",
            "",
            timed(0.0, command("DT", self.inner.dt)),
        ]
        return "\n".join([*head, *ep.lines()]) + "\n"

    def logged_episodes(self, env: int = 0) -> int:
        """Number of episodes with commands logged in airspace ``env``."""
        return sum(1 for ep in self.episodes[env] if ep.entries)

    def write(self, path: str | Path, env: int = 0, episode: int = -1, title: str = "") -> Path:
        """Write :meth:`scenario_text` to ``path``; returns it."""
        p = Path(path)
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(self.scenario_text(env, episode, title))
        return p
