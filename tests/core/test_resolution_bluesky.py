"""MVP conflict resolution against BlueSky 1.1.1's own ``RESO MVP``, on the same states.

Needs the ``bluesky`` extra; skipped when BlueSky cannot be imported.

On the BlueSky backend (``BlueSkyPhysics``) with conflict detection and ``RESO MVP`` switched on,
BlueSky's ``traf.cd.update`` and ``traf.cr.resolve`` compute the resolution track, speed,
vertical speed and altitude of every aircraft; the package computes them from the backend's state
arrays with :func:`bluesky_gym.core.conflicts.detect` and :func:`bluesky_gym.core.resolution.mvp`.
They must agree within 1e-9 (track, speeds) and 1e-9 relative (altitude, which BlueSky
extrapolates over up to 1e9 s for aircraft without a vertical conflict).

* 100 seeded random conflict geometries (``creconfs`` intruders of the ownship and of each other,
  level or with altitude offsets, own speeds, climbing aircraft, a few steps flown with MVP on),
  each under one of the RMETHH / RMETHV / RFACH / RFACV settings, with ``ASAS CSTATEBASED`` (the
  detector the core implements, pair for pair).
* The same geometries with ``ASAS ON`` (BlueSky's Python STATEBASED detector, which misses some
  reverse pairs, docs/dynamics.md §5): BlueSky's own conflict list is fed to the resolution
  kernel, so the resolution itself is checked for that detector too.
* 24 mixed-type geometries (A320, B744, E190, A388, B738): BlueSky caps every aircraft with its own
  ``perf.vsmin``/``vsmax`` (:func:`~bluesky_gym.core.resolution.vertical_speed_limits`), not the A320's.
* The creconfs scenarios: the recorded ``s9`` scenario flown for 200 s with MVP resolving (also
  checking which aircraft follow their resolution, BlueSky's ``resumenav``), and HorizontalCR and
  VerticalCR episodes on the BlueSky backend, state by state.
* The ``mvp`` policy gives the same actions on the native and the BlueSky backend.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

pytest.importorskip("bluesky")

import gymnasium as gym

import bluesky_gym  # noqa: F401  (registers the environments)
from bluesky_gym.backends.bluesky_sim import BlueSkyPhysics
from bluesky_gym.core.aircraft import aircraft_performance
from bluesky_gym.core.conflicts import LOOKAHEAD, PZ_HEIGHT, PZ_RADIUS, Conflicts, detect
from bluesky_gym.core.resolution import MVPResolver, Resolution, ResolutionSettings, mvp, vertical_speed_limits
from bluesky_gym.core.units import FT, KTS

A320 = aircraft_performance("A320")

pytestmark = pytest.mark.bluesky

N_GEOMETRIES = 100
MAX_AC = 8
TOL = 1e-9

#: (RMETHH, RMETHV, RFACH, RFACV) settings cycled through by the random geometries (None: not given).
SETTINGS: tuple[tuple[str | None, str | None, float, float], ...] = (
    (None, None, 1.05, 1.05),
    ("BOTH", None, 1.05, 1.05),
    ("SPD", None, 1.05, 1.05),
    ("HDG", None, 1.05, 1.05),
    ("NONE", None, 1.05, 1.05),
    (None, "V/S", 1.05, 1.05),
    ("HDG", "V/S", 1.2, 0.9),
    ("NONE", "NONE", 1.0, 1.3),
)


@pytest.fixture
def physics() -> Iterator[BlueSkyPhysics]:
    sim = BlueSkyPhysics(MAX_AC, dt=1.0)
    yield sim
    _command_defaults(sim)
    sim.close()


def _command_defaults(sim: Any) -> None:
    """Back to BlueSky's defaults: no detection, no resolution, default switches and factors."""
    for line in ("RESO OFF", "ASAS OFF", "RMETHH BOTH", "RMETHV OFF", "RFACH 1.05", "RFACV 1.05"):
        sim.command(line)


def _configure(sim: Any, detector: str, rmethh: str | None, rmethv: str | None, rfach: float, rfacv: float) -> ResolutionSettings:
    """Switch BlueSky's detection and MVP on with these settings; return the package's equivalent."""
    sim.command(f"ASAS {detector}")
    sim.command("RESO MVP")
    # RESO MVP keeps the switches of an earlier selection: start from BlueSky's defaults.
    cr = sim.traffic.cr
    cr.swresohoriz, cr.swresospd, cr.swresohdg, cr.swresovert = True, False, False, False
    if rmethh is not None:
        sim.command(f"RMETHH {rmethh}")
    if rmethv is not None:
        sim.command(f"RMETHV {rmethv}")
    sim.command(f"RFACH {rfach}")
    sim.command(f"RFACV {rfacv}")
    return ResolutionSettings.from_methods(rmethh, rmethv, rfach, rfacv)


def _random_geometry(sim: BlueSkyPhysics, rng: np.random.Generator, types: tuple[str, ...] | None = None) -> None:
    """An ownship, intruders in conflict with it or with each other, maybe climbing, maybe flown a little.

    Every aircraft is an A320, or of a type drawn from ``types``.
    """
    hdg = rng.uniform(0.0, 360.0)
    alt = rng.uniform(2000.0, 9000.0)
    n_types = 0 if types is None else MAX_AC
    drawn = [str(t) for t in rng.choice(types, n_types)] if types is not None else [None] * MAX_AC
    sim.create(0, 0, rng.uniform(-60.0, 60.0), rng.uniform(-170.0, 170.0), hdg, alt, rng.uniform(110.0, 160.0), actype=drawn[0])
    n = int(rng.integers(1, MAX_AC))
    for slot in range(1, n + 1):
        target = 0 if slot == 1 or rng.random() < 0.6 else int(rng.integers(0, slot))
        dh = tlosv = spd = None
        if rng.random() < 0.5:
            dh = float(rng.uniform(-900.0, 900.0))
            tlosv = float(rng.uniform(20.0, 300.0))
        if rng.random() < 0.5:
            spd = float(rng.uniform(100.0, 170.0))
        dcpa = 0.0 if rng.random() < 0.15 else float(rng.uniform(0.0, 7.0))
        sim.creconfs(0, target, slot, rng.uniform(0.0, 360.0), dcpa, rng.uniform(10.0, 400.0), dh, tlosv, spd, actype=drawn[slot])
    for slot in range(n + 1):
        if rng.random() < 0.3:  # a climb or descent in progress (vertical speed, selected altitude)
            sim.cmd_altitude(0, slot, sim.alt[0, slot] + rng.uniform(-1500.0, 1500.0), rng.uniform(3.0, 12.0))
    sim.run(int(rng.integers(0, 4)))


def _bluesky_resolution(sim: BlueSkyPhysics) -> tuple[np.ndarray, ...]:
    """BlueSky's conflict detection and MVP resolution of the current state, in slot order."""
    traf = sim.traffic
    traf.cd.update(traf, traf)
    out = traf.cr.resolve(traf.cd, traf, traf)
    slots = np.flatnonzero(sim.active[0])
    idx = np.array(traf.id2idx([sim.acid(s) for s in slots]))
    res = []
    for values in out:
        full = np.full(sim.max_aircraft, np.nan)
        full[slots] = np.asarray(values, dtype=np.float64)[idx]
        res.append(full[None])
    return tuple(res)


def _ours(sim: BlueSkyPhysics, settings: ResolutionSettings, conflicts: Conflicts | None = None) -> tuple[Resolution, Conflicts]:
    if conflicts is None:
        conflicts = detect(sim.lat, sim.lon, sim.alt, sim.gs, sim.trk, sim.vs, sim.active, PZ_RADIUS, PZ_HEIGHT, LOOKAHEAD)
    perf = sim.traffic.perf
    # The limits MVP caps with are the package's A320 constants (asserted, not copied from BlueSky).
    assert np.all(perf.vsmin == A320.vsmin) and np.all(perf.vsmax == A320.vsmax)
    return mvp(sim, conflicts, settings), conflicts


def _bluesky_conflicts(sim: BlueSkyPhysics) -> Conflicts:
    """BlueSky's current conflict list as a package conflict picture."""
    cd = sim.traffic.cd
    m = sim.max_aircraft
    slot_of = {sim.acid(s): s for s in np.flatnonzero(sim.active[0])}
    conflict = np.zeros((1, m, m), bool)
    arrays = {k: np.zeros((1, m, m)) for k in ("qdr", "dist", "tcpa", "tlos")}
    for k, (own, intr) in enumerate(cd.confpairs):
        i, j = slot_of[own], slot_of[intr]
        conflict[0, i, j] = True
        for name, src in (("qdr", cd.qdr), ("dist", cd.dist), ("tcpa", cd.tcpa), ("tlos", cd.tLOS)):
            arrays[name][0, i, j] = np.asarray(src, dtype=np.float64).reshape(-1)[k]
    return Conflicts(conflict, np.zeros_like(conflict), arrays["qdr"], arrays["dist"], arrays["tcpa"], np.zeros((1, m, m)), arrays["tlos"])


def _assert_same(ours: Resolution, theirs: tuple[np.ndarray, ...], where: str) -> None:
    trk, tas, vs, alt = theirs
    dtrk = (ours.trk - trk + 180.0) % 360.0 - 180.0
    live = np.isfinite(trk)
    np.testing.assert_array_equal(np.isfinite(ours.trk), live, err_msg=where)
    assert np.all(np.abs(dtrk[live]) <= TOL), f"{where}: track differs by {np.max(np.abs(dtrk[live]))} deg"
    np.testing.assert_allclose(ours.gs[live], tas[live], rtol=0.0, atol=TOL, err_msg=f"{where}: speed")
    np.testing.assert_allclose(ours.vs[live], vs[live], rtol=0.0, atol=TOL, err_msg=f"{where}: vertical speed")
    np.testing.assert_allclose(ours.alt[live], alt[live], rtol=TOL, atol=TOL, err_msg=f"{where}: altitude")


def test_random_geometries_cstatebased(physics: BlueSkyPhysics) -> None:
    """100 random conflict geometries: the package's detection + MVP equals BlueSky's CSTATEBASED + MVP."""
    rng = np.random.default_rng(20241114)
    conflicts_seen = 0
    for k in range(N_GEOMETRIES):
        physics.reset_envs()
        settings = _configure(physics, "CSTATEBASED", *SETTINGS[k % len(SETTINGS)])
        _random_geometry(physics, rng)
        theirs = _bluesky_resolution(physics)
        ours, conflicts = _ours(physics, settings)
        inconf = np.zeros(physics.max_aircraft, bool)
        slots = np.flatnonzero(physics.active[0])
        inconf[slots] = np.asarray(physics.traffic.cd.inconf, bool)[physics.traffic.id2idx([physics.acid(s) for s in slots])]
        np.testing.assert_array_equal(conflicts.in_conflict[0], inconf, err_msg=f"geometry {k}: conflict list")
        conflicts_seen += int(conflicts.conflict.sum())
        _assert_same(ours, theirs, f"geometry {k} {SETTINGS[k % len(SETTINGS)]}")
    assert conflicts_seen > 2 * N_GEOMETRIES  # the geometries do produce conflicts


#: Types of different vertical-speed envelopes (OpenAP; the B744 is also BlueSky's fallback type).
MIXED_TYPES = ("A320", "B744", "E190", "A388", "B738")


def test_mixed_types_are_capped_with_each_aircraft_envelope(physics: BlueSkyPhysics) -> None:
    """BlueSky's MVP caps each aircraft's vertical speed with its own ``perf.vsmin``/``vsmax`` (per type, not global).

    With every aircraft's limits from its type (:func:`vertical_speed_limits`, MVPResolver's
    default), the package's MVP equals BlueSky's on 24 mixed-type geometries with vertical
    resolutions; with the A320's limits for all it does not.
    """
    rng = np.random.default_rng(11)
    vertical = [s for s in SETTINGS if s[1] is not None or s[0] == "NONE"]
    differs = 0
    for k in range(24):
        physics.reset_envs()
        settings = _configure(physics, "CSTATEBASED", *vertical[k % len(vertical)])
        _random_geometry(physics, rng, MIXED_TYPES)
        vsmin, vsmax = vertical_speed_limits(physics)
        slots = np.flatnonzero(physics.active[0])
        idx = physics.traffic.id2idx([physics.acid(s) for s in slots])
        np.testing.assert_array_equal(np.asarray(physics.traffic.perf.vsmin)[idx], vsmin[0, slots])
        np.testing.assert_array_equal(np.asarray(physics.traffic.perf.vsmax)[idx], vsmax[0, slots])
        theirs = _bluesky_resolution(physics)
        conflicts = detect(
            physics.lat, physics.lon, physics.alt, physics.gs, physics.trk, physics.vs, physics.active, PZ_RADIUS, PZ_HEIGHT, LOOKAHEAD
        )
        _assert_same(mvp(physics, conflicts, settings, vsmin=vsmin, vsmax=vsmax), theirs, f"mixed geometry {k}")
        a320 = mvp(physics, conflicts, settings)
        live = np.isfinite(theirs[2])
        differs += int(np.any(np.abs(a320.vs[live] - theirs[2][live]) > TOL))
    assert differs > 0  # the A320's limits for every aircraft would not be BlueSky's


def test_random_geometries_asas_on(physics: BlueSkyPhysics) -> None:
    """With ``ASAS ON`` (Python STATEBASED), MVP on BlueSky's own conflict list equals BlueSky's."""
    rng = np.random.default_rng(7)
    for k in range(N_GEOMETRIES):
        physics.reset_envs()
        settings = _configure(physics, "ON", *SETTINGS[k % len(SETTINGS)])
        _random_geometry(physics, rng)
        theirs = _bluesky_resolution(physics)
        ours, _ = _ours(physics, settings, _bluesky_conflicts(physics))
        _assert_same(ours, theirs, f"geometry {k} {SETTINGS[k % len(SETTINGS)]}")


def test_creconfs_scenario_s9_with_mvp(physics: BlueSkyPhysics) -> None:
    """The recorded s9 creconfs scenario, flown 200 s with MVP resolving: every state agrees."""
    settings = _configure(physics, "CSTATEBASED", None, None, 1.05, 1.05)
    physics.create(0, 0, 52.0, 4.0, 45.0, 200 * 100 * FT, 250 * KTS)
    physics.creconfs(0, 0, 1, 90.0, 1.0, 120.0)
    physics.creconfs(0, 0, 2, 200.0, 0.0, 150.0, None, None, 200 * KTS)
    physics.creconfs(0, 0, 3, 300.0, 2.0, 100.0, 500.0, 90.0)
    resolver = MVPResolver(settings)
    resolving = following = 0
    for t in range(200):
        theirs = _bluesky_resolution(physics)
        ours, conflicts = _ours(physics, settings)
        _assert_same(ours, theirs, f"s9 t={t}")
        resolving += int(conflicts.in_conflict.any())
        follow = resolver.update(physics).follow[0]
        physics.step()  # BlueSky's ASAS sees the same state in this step, then resumenav decides who follows
        active = np.zeros(physics.max_aircraft, bool)
        slots = np.flatnonzero(physics.active[0])
        active[slots] = np.asarray(physics.traffic.cr.active, bool)[physics.traffic.id2idx([physics.acid(s) for s in slots])]
        np.testing.assert_array_equal(follow, active, err_msg=f"s9 t={t}: who follows the resolution")
        following += int(follow.any())
    assert resolving > 10 and following > resolving  # resolutions are held after the conflicts end
    # MVP did act: the ownship left its 45 deg track.
    assert abs(physics.trk[0, 0] - 45.0) > 1.0


@pytest.mark.parametrize(("env_id", "settings"), [("HorizontalCREnv-v0", ("HDG", None)), ("VerticalCREnv-v0", (None, "V/S"))])
def test_creconfs_env_scenarios(env_id: str, settings: tuple[str | None, str | None]) -> None:
    """HorizontalCR and VerticalCR scenarios (creconfs intruders) on the BlueSky backend, step by step."""
    env = gym.make(env_id, backend="bluesky")
    try:
        sim = env.unwrapped.task.sim
        checked = 0
        for seed in range(3):
            env.reset(seed=seed)
            reso = _configure(sim, "CSTATEBASED", *settings, 1.05, 1.05)
            env.action_space.seed(seed)
            for step in range(6):
                theirs = _bluesky_resolution(sim)
                ours, conflicts = _ours(sim, reso)
                _assert_same(ours, theirs, f"{env_id} seed {seed} step {step}")
                checked += int(conflicts.in_conflict.any())
                _, _, terminated, truncated, _ = env.step(env.action_space.sample())
                if terminated or truncated:
                    break
        assert checked > 0
    finally:
        _command_defaults(env.unwrapped.task.sim)
        env.close()


@pytest.mark.parametrize("env_id", ["HorizontalCREnv-v0", "SectorCREnv-v0"])
def test_mvp_policy_flies_the_same_episode_on_both_backends(env_id: str) -> None:
    """The mvp policy reads the state through the Physics interface: same seed, same actions on native and BlueSky."""
    from bluesky_gym.training.policies import MVPPolicy

    actions: dict[str, list[np.ndarray]] = {}
    resolving = 0
    for backend in ("native", "bluesky"):
        env = gym.make(env_id, backend=backend)
        policy = MVPPolicy(env_id)
        policy.bind(env)
        obs, _ = env.reset(seed=5)
        actions[backend] = []
        for _ in range(12):
            a = policy.act({k: v[None] for k, v in obs.items()})[0]
            resolving += int(policy.resolver.pairs.any())
            actions[backend].append(a)
            obs, _, terminated, truncated, _ = env.step(a)
            if terminated or truncated:
                break
        env.close()
    np.testing.assert_allclose(np.array(actions["bluesky"]), np.array(actions["native"]), rtol=0.0, atol=1e-9)
    assert resolving > 0  # MVP resolved during the compared steps
