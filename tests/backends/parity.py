"""Side-by-side runs of the native core and the real BlueSky backend, and their comparison.

Used by ``test_parity.py``; imports BlueSky only through the backend.

Comparison rule: a number ``a`` (native) and ``b`` (BlueSky) agree within ``tol`` when
``|a - b| <= tol * max(1, |a|, |b|)``: relative for magnitudes above 1, absolute below (values
near zero). With ``tol > 0`` angles in degrees are compared on the circle; ``tol == 0`` demands
the same bits. NaN equals NaN. Flags, integers, phases and the set of active aircraft must be
equal.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import gymnasium as gym
import numpy as np

from bluesky_gym.core import Physics
from bluesky_gym.core.units import FT, KTS

ANGLE_FIELDS = frozenset({"hdg", "trk", "ap_trk", "curlegdir", "next_qdr"})
CORE_TOL = 1e-9
ENV_TOL = 1e-6


def scaled_error(a: Any, b: Any, angle: bool = False) -> np.ndarray:
    """|a - b| / max(1, |a|, |b|) elementwise (0 where both are NaN, inf where one is)."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    with np.errstate(invalid="ignore"):
        d = np.abs(a - b)
        if angle:
            d = np.mod(d, 360.0)
            d = np.minimum(d, 360.0 - d)
        err = d / np.maximum(1.0, np.maximum(np.abs(a), np.abs(b)))
    both_nan = np.isnan(a) & np.isnan(b)
    err = np.where(both_nan, 0.0, np.where(np.isnan(a) | np.isnan(b), np.inf, err))
    return np.where(a == b, 0.0, err)  # equal infinities


@dataclass
class Deviation:
    """Largest scaled deviation seen per quantity, with where it occurred."""

    worst: dict[str, tuple[float, str]] = field(default_factory=dict)

    def add(self, name: str, err: float, where: str) -> None:
        if err > self.worst.get(name, (-1.0, ""))[0]:
            self.worst[name] = (float(err), where)

    @property
    def max(self) -> float:
        return max((e for e, _ in self.worst.values()), default=0.0)

    def summary(self, n: int = 6) -> str:
        items = sorted(self.worst.items(), key=lambda kv: -kv[1][0])[:n]
        return ", ".join(f"{k}={e:.2e} ({w})" for k, (e, w) in items if e > 0) or "bit-identical"


def compare_states(native: Physics, other: Physics, where: str, tol: float, dev: Deviation | None = None) -> None:
    """Assert that two single-airspace simulators hold the same aircraft in the same state.

    Every per-aircraft state array (and the active part of each route) of the active slots is
    compared. Exact for flags, integers and the active mask; ``tol`` (scaled) for floats.
    """
    act = native.active[0]
    np.testing.assert_array_equal(act, other.active[0], err_msg=f"{where}: active aircraft differ")
    names = list(native.state_fields())
    exact = [n for n in names if getattr(native, n).dtype.kind in "biu"]
    for name in exact:
        a, b = getattr(native, name)[0, act], getattr(other, name)[0, act]
        if not np.array_equal(a, b):
            raise AssertionError(f"{where}: {name} differs: native {a.tolist()} bluesky {b.tolist()}")
    floats = [n for n in names if n not in exact]
    slots = np.flatnonzero(act)
    rows_a = [getattr(native, n)[0, act] for n in floats]
    rows_b = [getattr(other, n)[0, act] for n in floats]
    for s in slots:  # the active part of each route
        n = int(native.nwp[0, s])
        for name in ("route_lat", "route_lon"):
            floats.append(f"{name}[slot {s}]")
            rows_a.append(getattr(native, name)[0, s, :n])
            rows_b.append(getattr(other, name)[0, s, :n])
    flat_a, flat_b = np.concatenate(rows_a), np.concatenate(rows_b)
    angle = np.concatenate([np.full(r.size, tol > 0 and f in ANGLE_FIELDS) for f, r in zip(floats, rows_a)])
    err = np.where(angle, scaled_error(flat_a, flat_b, angle=True), scaled_error(flat_a, flat_b))
    bounds = np.cumsum([0] + [r.size for r in rows_a])
    if dev is not None:
        for k, f in enumerate(floats):
            if bounds[k + 1] > bounds[k]:
                dev.add(f.split("[")[0], float(err[bounds[k] : bounds[k + 1]].max()), where)
    if err.size and err.max() > tol:
        i = int(np.argmax(err))
        k = int(np.searchsorted(bounds, i, side="right") - 1)
        j = i - bounds[k]
        what = floats[k] if "[" in floats[k] else f"{floats[k]}[slot {slots[j]}]"
        raise AssertionError(f"{where}: {what} native {flat_a[i]!r} bluesky {flat_b[i]!r} (scaled error {err[i]:.3g} > {tol})")


# ----------------------------------------------------------------------------------------------
# Random core scenarios
# ----------------------------------------------------------------------------------------------
Event = Callable[[Physics], None]


@dataclass
class CoreScenario:
    """A random single-airspace scenario: time step, number of steps and events per step.

    Events are plain numbers bound into closures, so both simulators receive identical inputs.
    """

    seed: int
    dt: float
    steps: int
    max_aircraft: int
    events: dict[int, list[tuple[str, Event]]]


def random_core_scenario(seed: int, steps: int = 240, max_aircraft: int = 6, types: Sequence[str] | None = None) -> CoreScenario:
    """Draw a scenario exercising creation, every command, direct writes, creconfs, routes and wind.

    Geometry that depends on the state (waypoints near an aircraft, creconfs targets) is drawn
    when the event runs, from the native simulator, and then applied to both. With ``types``,
    every created aircraft gets a type drawn from it (from a generator of its own, so the rest of
    the scenario is the one of the same seed without types); without, every aircraft is an A320.
    """
    rng = np.random.default_rng(seed)
    trng = None if types is None else np.random.default_rng([seed, 12])
    dt = float(rng.choice([1.0, 1.0, 5.0]))
    events: dict[int, list[tuple[str, Event]]] = {}

    def at(step: int, label: str, ev: Event) -> None:
        events.setdefault(step, []).append((label, ev))

    # Initial traffic: 1-3 aircraft in one call, varied positions, headings, altitudes, speeds.
    n0 = int(rng.integers(1, 4))
    lat = rng.uniform(-60.0, 70.0, n0)
    lon = rng.uniform(-179.0, 190.0, n0)  # > 180 is wrapped once at creation
    hdg = rng.uniform(-180.0, 540.0, n0)  # stored as given
    alt = np.where(rng.random(n0) < 0.2, 0.0, rng.uniform(100.0, 11500.0, n0))
    spd = np.where(rng.random(n0) < 0.25, rng.uniform(0.3, 0.8, n0), rng.uniform(60.0, 170.0, n0))  # Mach or CAS
    slots = np.arange(n0)
    if trng is None:
        at(0, "create", lambda s, sl=slots, a=(lat, lon, hdg, alt, spd): s.create(0, sl, *a))
    else:
        t0 = [str(t) for t in trng.choice(list(types or ()), n0)]
        at(0, "create", lambda s, sl=slots, a=(lat, lon, hdg, alt, spd): s.create(0, sl, *a, actype=t0))
    if rng.random() < 0.4:  # wind from the start (constant, or a 2-D field of 3 points)
        at(0, "wind", _wind_event(rng, lat[0], lon[0]))

    kinds = ["hdg", "spd", "alt", "vs", "write_v", "write_h", "creconfs", "route", "dest", "wind", "create", "delete"]
    weights = np.array([4, 3, 2, 1, 3, 1, 2, 2, 1, 1, 1, 1], dtype=float)
    n_events = int(rng.integers(8, 20))
    for _ in range(n_events):
        step = int(rng.integers(0, steps))
        kind = str(rng.choice(kinds, p=weights / weights.sum()))
        actype = None if trng is None else str(trng.choice(list(types or ())))
        at(step, kind, _event(kind, np.random.default_rng(rng.integers(2**63)), max_aircraft, actype))
    return CoreScenario(seed, dt, steps, max_aircraft, events)


def _pick(sim: Physics, rng: np.random.Generator) -> int | None:
    active = np.flatnonzero(sim.active[0])
    return int(rng.choice(active)) if active.size else None


def _free(sim: Physics, rng: np.random.Generator) -> int | None:
    free = np.flatnonzero(~sim.active[0])
    return int(rng.choice(free)) if free.size else None


def _wind_event(rng: np.random.Generator, lat0: float, lon0: float) -> Event:
    if rng.random() < 0.6:
        pts = ([lat0], [lon0], [rng.uniform(-25, 25)], [rng.uniform(-25, 25)])
    else:
        pts = (lat0 + rng.uniform(-2, 2, 3), lon0 + rng.uniform(-2, 2, 3), rng.uniform(-25, 25, 3), rng.uniform(-25, 25, 3))
    return lambda s: s.wind.add_points(0, *pts)


def _event(kind: str, rng: np.random.Generator, max_aircraft: int, actype: str | None = None) -> Event:
    """One event; its random numbers are drawn once (first call) and replayed on the other simulator.

    ``actype`` is the type of an aircraft the event creates (None: the default, A320).
    """
    typed: dict[str, Any] = {} if actype is None else {"actype": actype}
    memo: dict[str, Any] = {}

    def once(key: str, draw: Callable[[], Any]) -> Any:
        if key not in memo:
            memo[key] = draw()
        return memo[key]

    def ev(sim: Physics) -> None:
        slot = once("slot", lambda: _pick(sim, rng))
        if kind == "create":
            free = once("free", lambda: _free(sim, rng))
            if free is None:
                return
            a = once("args", lambda: (rng.uniform(40, 60), rng.uniform(-10, 20), rng.uniform(0, 360), rng.uniform(0, 11000), rng.uniform(70, 160)))
            sim.create(0, free, *a, **typed)
            return
        if kind == "wind":
            pts = once("pts", lambda: (rng.uniform(-60, 60, 1), rng.uniform(-170, 170, 1), rng.uniform(-25, 25, 1), rng.uniform(-25, 25, 1)))
            sim.wind.add_points(0, *pts)
            return
        if slot is None:
            return
        if kind == "hdg":
            sim.cmd_heading(0, slot, once("v", lambda: float(rng.uniform(-360, 720))))
        elif kind == "spd":
            v = once("v", lambda: float(rng.uniform(0.3, 0.85)) if rng.random() < 0.3 else float(rng.integers(120, 340)) * KTS)
            sim.cmd_speed(0, slot, v)
        elif kind == "alt":
            a = once("a", lambda: float(rng.choice([rng.uniform(0, 12500), rng.integers(10, 400) * 100 * FT])))
            vs = once("vs", lambda: None if rng.random() < 0.5 else float(rng.uniform(-20, 20)))
            sim.cmd_altitude(0, slot, a, vs)
        elif kind == "vs":
            sim.cmd_vertical_speed(0, slot, once("v", lambda: float(rng.uniform(-20, 20))))
        elif kind == "write_v":  # gym style: selalt 0 or 1e6 and a selvs (exactly 0 sometimes)
            v = once("v", lambda: 0.0 if rng.random() < 0.15 else float(rng.uniform(-12.5, 12.5)))
            sim.set_autopilot(0, slot, selalt=1e6 if v >= 0 else 0.0, selvs=v)
        elif kind == "write_h":  # static-obstacle style: heading and autopilot track written directly
            h = once("v", lambda: float(rng.uniform(0, 360)))
            sim.set_state(0, slot, hdg=h)
            sim.set_autopilot(0, slot, ap_trk=h)
        elif kind == "creconfs":
            free = once("free", lambda: _free(sim, rng))
            if free is None:
                return
            args = once(
                "args",
                lambda: dict(
                    dpsi=float(rng.uniform(0, 360)),
                    dcpa=float(rng.choice([rng.integers(0, 5), rng.uniform(0, 8)])),
                    tlosh=float(rng.uniform(60, 900)),
                    dh=None if rng.random() < 0.5 else float(rng.uniform(-1500, 1500)),
                    tlosv=None if rng.random() < 0.5 else float(rng.uniform(60, 900)),
                    spd=None if rng.random() < 0.6 else float(rng.uniform(90, 160)),
                ),
            )
            kw = dict(args)
            if kw["dh"] is None:  # tlosv is used only with dh
                kw["tlosv"] = None
            sim.creconfs(0, slot, free, kw["dpsi"], kw["dcpa"], kw["tlosh"], kw["dh"], kw["tlosv"], kw["spd"], **typed)
        elif kind == "route":
            room = sim.max_waypoints - int(sim.nwp[0, slot]) - (0 if sim.route_has_dest[0, slot] else 1)
            n = once("n", lambda: int(rng.integers(1, 3)))
            lat, lon = float(sim.lat[0, slot]), float(sim.lon[0, slot])
            pts = once("pts", lambda: (lat + rng.uniform(-0.6, 0.6, n), lon + rng.uniform(-0.6, 0.6, n)))
            for k in range(min(n, room)):
                sim.add_waypoint(0, slot, pts[0][k], pts[1][k])
        elif kind == "dest":
            # Only after a waypoint: a destination alone switches BlueSky's VNAV on (not in the core).
            if sim.nwp[0, slot] - sim.route_has_dest[0, slot] < 1:
                return
            if not sim.route_has_dest[0, slot] and sim.nwp[0, slot] >= sim.max_waypoints:
                return
            lat, lon = float(sim.lat[0, slot]), float(sim.lon[0, slot])
            d = once("d", lambda: (lat + float(rng.uniform(-0.8, 0.8)), lon + float(rng.uniform(-0.8, 0.8))))
            sim.set_destination(0, slot, d[0], d[1])
        elif kind == "delete":
            sim.delete(0, slot)

    return ev


def ulp_sources(sim: Physics) -> list[str]:
    """The known sources of last-bit differences present in a simulator's airspace (see test_parity.py)."""
    out = []
    if np.any(sim.active[0] & (sim.nwp[0] > 0)):
        out.append("route")
    if sim.wind.count[0] >= 2:
        out.append("wind field")
    return out


def run_core_scenario(sc: CoreScenario, natives: dict[str, Physics], bluesky: Physics, tol: float = CORE_TOL) -> Deviation:
    """Replay a scenario on each native simulator and on BlueSky, comparing after every event and step.

    The event's random draws are taken from the first native simulator and replayed on the others.
    The states must be bit-identical until the first route or multi-point wind field appears (the
    known sources of last-bit differences); from then on they must agree within ``tol``.
    """
    dev = Deviation()
    sims = [*natives.values(), bluesky]
    first = next(iter(natives.values()))
    exact = True

    def check(where: str) -> None:
        nonlocal exact
        exact = exact and not ulp_sources(first)
        note = "" if exact else " (route/wind field present)"
        for kernel, nat in natives.items():
            compare_states(nat, bluesky, f"seed {sc.seed} {kernel} {where}{note}", 0.0 if exact else tol, dev)

    for step in range(sc.steps + 1):
        for label, ev in sc.events.get(step, []):
            for s in sims:
                ev(s)
            check(f"t={step * sc.dt:g} after {label}")
        if step == sc.steps:
            break
        for s in sims:
            s.step()
        check(f"t={(step + 1) * sc.dt:g}")
    return dev


# ----------------------------------------------------------------------------------------------
# Environment episodes
# ----------------------------------------------------------------------------------------------
def compare_values(a: Any, b: Any, where: str, tol: float, dev: Deviation | None = None, key: str = "") -> None:
    """Assert equal structure and values (numbers within ``tol``, scaled) of observations, rewards and infos.

    ``key`` names the quantity in ``dev`` (e.g. ``obs/altitude``).
    """
    if isinstance(a, dict):
        if not isinstance(b, dict) or set(a) != set(b):
            raise AssertionError(f"{where} {key}: keys differ: {sorted(a)} vs {sorted(b) if isinstance(b, dict) else b!r}")
        for k in a:
            compare_values(a[k], b[k], where, tol, dev, f"{key}/{k}" if key else str(k))
        return
    if isinstance(a, (tuple, list)):
        if not isinstance(b, (tuple, list)) or len(a) != len(b):
            raise AssertionError(f"{where} {key}: native {a!r} bluesky {b!r}")
        names = STEP_NAMES if len(a) == len(STEP_NAMES) else RESET_NAMES if len(a) == len(RESET_NAMES) else None
        for k, (x, y) in enumerate(zip(a, b)):
            compare_values(x, y, where, tol, dev, names[k] if names and not key else f"{key}/{k}")
        return
    if isinstance(a, (bool, np.bool_, str)) or a is None:
        if a != b or type(a) is not type(b):
            raise AssertionError(f"{where} {key}: native {a!r} bluesky {b!r}")
        return
    aa, bb = np.asarray(a), np.asarray(b)
    if aa.shape != bb.shape or aa.dtype.kind != bb.dtype.kind:
        raise AssertionError(f"{where} {key}: shape/dtype differ: {aa.shape} {aa.dtype} vs {bb.shape} {bb.dtype}")
    if aa.dtype.kind in "biu":
        if not np.array_equal(aa, bb):
            raise AssertionError(f"{where} {key}: native {a!r} bluesky {b!r}")
        return
    err = scaled_error(aa, bb)
    worst = float(err.max(initial=0.0))
    if dev is not None:
        dev.add(key, worst, where)
    if worst > tol:
        raise AssertionError(f"{where} {key}: native {a!r} bluesky {b!r} (scaled error {worst:.3g} > {tol})")


STEP_NAMES = ("obs", "reward", "terminated", "truncated", "info")
RESET_NAMES = ("obs", "info")


def run_env_episodes(
    env_id: str,
    episodes: list[tuple[int, int]],
    time_limit: int,
    tol: float = ENV_TOL,
    wrap: Callable[[gym.Env], gym.Env] | None = None,
    options: dict[str, Any] | None = None,
) -> tuple[Deviation, int]:
    """Run seeded episodes with seeded random actions on both backends side by side.

    Observations, rewards, terminated/truncated and infos are compared after every reset and step:
    bit for bit while the episode has no route or multi-point wind field (the known sources of
    last-bit differences, see ``ulp_sources``), within ``tol`` (scaled) from then on.

    Args:
        env_id: Environment id (made with ``gym.make(env_id, backend=..., time_limit=time_limit)``).
        episodes: (seed, steps) per episode; an episode stops at termination or truncation, or is
            abandoned after ``steps`` decision steps (the next reset then starts a clean episode).
        time_limit: Truncation limit of both environments.
        tol: Scaled tolerance.
        wrap: Applied to both environments (e.g. a wind wrapper).
        options: Scenario options given to both ``gym.make`` calls.

    Returns:
        The deviations seen and the number of steps compared.
    """
    dev = Deviation()
    steps = 0
    envs = {b: gym.make(env_id, backend=b, time_limit=time_limit, **(options or {})) for b in ("native", "bluesky")}
    sim = envs["native"].unwrapped.task.sim
    bsim = envs["bluesky"].unwrapped.task.sim
    if type(bsim).__name__ != "BlueSkyPhysics":
        raise AssertionError(f"{env_id}: backend='bluesky' gave physics {type(bsim).__name__}")
    if wrap is not None:
        envs = {b: wrap(e) for b, e in envs.items()}
    try:
        for seed, n in episodes:
            out = {b: e.reset(seed=seed) for b, e in envs.items()}
            exact = not ulp_sources(sim)
            compare_values(out["native"], out["bluesky"], f"{env_id} seed {seed} reset", 0.0 if exact else tol, dev)
            rng = np.random.default_rng([seed, 7])
            space = envs["native"].action_space
            for t in range(n):
                action = rng.uniform(space.low, space.high).astype(space.dtype)
                clocks = (sim.simt, bsim.simt, bsim._bs.sim.simt)
                res = {b: e.step(action.copy()) for b, e in envs.items()}
                steps += 1
                # BlueSky itself advanced, by as many sub-steps as the native core.
                advanced = (sim.simt - clocks[0], bsim.simt - clocks[1], bsim._bs.sim.simt - clocks[2])
                if not (advanced[0] > 0 and advanced[0] == advanced[1] == advanced[2]):
                    raise AssertionError(f"{env_id} seed {seed} step {t + 1}: simulated time advanced by {advanced} (native, backend, BlueSky)")
                exact = exact and not ulp_sources(sim)
                compare_values(res["native"], res["bluesky"], f"{env_id} seed {seed} step {t + 1}", 0.0 if exact else tol, dev)
                if res["native"][2] or res["native"][3]:
                    break
    finally:
        for e in envs.values():
            e.close()
    return dev, steps
