"""Behaviour of the BlueSky backend itself: lifecycle, synchronisation, wind, errors, vectorisation."""

from __future__ import annotations

import re
import sys
import types

import gymnasium as gym
import numpy as np
import pytest

import bluesky_gym  # noqa: F401  (registers the environments)
from bluesky_gym.backends import make_physics
from bluesky_gym.core.extras import install_hint
from bluesky_gym.environments.descent.task import DescentTask


def test_missing_bluesky_raises_install_hint(monkeypatch: pytest.MonkeyPatch) -> None:
    from bluesky_gym.backends.bluesky_sim import load_bluesky

    monkeypatch.setitem(sys.modules, "bluesky", None)  # makes "import bluesky" fail
    with pytest.raises(ImportError, match=re.escape(install_hint("bluesky"))):
        load_bluesky()
    with pytest.raises(ImportError, match=re.escape('"bluesky-simulator==1.1.1"')):
        make_physics("bluesky", DescentTask.dt, 1, 1, 2)


def test_numpy_too_new_raises_install_hint(monkeypatch: pytest.MonkeyPatch) -> None:
    from bluesky_gym.backends.bluesky_sim import load_bluesky

    monkeypatch.setitem(sys.modules, "bluesky", types.ModuleType("bluesky"))
    monkeypatch.setattr(np, "__version__", "2.4.0")
    with pytest.raises(ImportError, match=r"numpy<2\.4"):
        load_bluesky()


def test_backend_implements_physics_without_the_native_core() -> None:
    """BlueSkyPhysics is not a Simulator: it implements every command of the Physics protocol itself."""
    from bluesky_gym.backends.bluesky_sim import BlueSkyPhysics, BlueSkyWind
    from bluesky_gym.core import Physics, Simulator, WindField

    assert not issubclass(BlueSkyPhysics, Simulator)
    commands = {n for n in vars(Physics) if not n.startswith("_") and callable(getattr(Physics, n))}
    assert {"step", "run", "create", "creconfs", "cmd_heading", "set_autopilot", "set_state"} <= commands
    missing = {n for n in commands if n not in vars(BlueSkyPhysics)}
    assert not missing, f"Physics commands BlueSkyPhysics lacks: {sorted(missing)}"
    arrays = set(Physics.__annotations__) - {"n_envs", "max_aircraft", "max_waypoints", "dt", "simt", "geo", "wind"}
    assert arrays and arrays <= set(vars(BlueSkyPhysics))
    public = {n for n in vars(WindField) if not n.startswith("_") and callable(getattr(WindField, n))}
    assert public and not {n for n in public if n not in vars(BlueSkyWind)}


def test_several_airspaces_are_refused() -> None:
    with pytest.raises(ValueError, match="AsyncVectorEnv"):
        make_physics("bluesky", DescentTask.dt, 2, 1, 2)


# ----------------------------------------------------------------------------------------------
# With BlueSky installed
# ----------------------------------------------------------------------------------------------
needs_bluesky = pytest.mark.bluesky


def _bs():
    pytest.importorskip("bluesky")
    import bluesky

    return bluesky


@pytest.fixture
def physics():
    _bs()
    from bluesky_gym.backends.bluesky_sim import BlueSkyPhysics

    sim = BlueSkyPhysics(3, dt=1.0, max_waypoints=3)
    yield sim
    sim.close()


@needs_bluesky
def test_one_open_backend_per_process(physics) -> None:
    from bluesky_gym.backends.bluesky_sim import BlueSkyPhysics

    with pytest.raises(RuntimeError, match=r"one simulator per process.*vectorization_mode=\"async\""):
        BlueSkyPhysics(1)
    with pytest.raises(RuntimeError, match="AsyncVectorEnv"):
        gym.make("DescentEnv-v0", backend="bluesky")
    physics.close()
    again = BlueSkyPhysics(1)  # free again after close()
    again.close()


@needs_bluesky
def test_close_releases_traffic_and_refuses_use(physics) -> None:
    bs = _bs()
    physics.create(0, [0, 1], 52.0, 4.0, 0.0, 3000.0, 150.0)
    assert bs.traf.ntraf == 2
    physics.close()
    physics.close()  # idempotent
    assert bs.traf.ntraf == 0 and physics.closed
    with pytest.raises(RuntimeError, match="closed"):
        physics.step()


@needs_bluesky
def test_traced_run_and_run_with_stop(physics) -> None:
    bs = _bs()
    physics.create(0, [0, 1], [52.0, 52.5], 4.0, [0.0, 90.0], 3000.0, 150.0)
    track = physics.run(3, trace=True)
    assert track.shape == (3, 2, 1, 3)
    np.testing.assert_array_equal(track[-1, 0], physics.lat)
    np.testing.assert_array_equal(track[-1, 1], physics.lon)
    assert (np.diff(track[:, 0, 0, 0]) > 0).all() and (np.diff(track[:, 1, 0, 1]) > 0).all()  # north, east
    assert not hasattr(physics, "snapshot") and not hasattr(physics, "restore")
    # stop: called after every step with the track so far; BlueSky stops at the reported end.
    seen = []

    def stop(tr: np.ndarray) -> np.ndarray:
        seen.append(tr.shape[0])
        return np.array([tr.shape[0] if tr.shape[0] == 2 else 0])

    t0 = bs.sim.simt
    track = physics.run(5, stop=stop)
    assert seen == [1, 2] and bs.sim.simt == t0 + 2 * physics.dt == physics.simt
    assert np.isfinite(track[:2]).all() and np.isnan(track[2:]).all()
    np.testing.assert_array_equal(track[1, 0], physics.lat)
    with pytest.raises(ValueError, match="cannot be rewound"):
        physics.run(3, stop=lambda tr: np.array([1 if tr.shape[0] == 2 else 0]))


@needs_bluesky
def test_reset_clears_traffic_and_wind_and_sets_dt() -> None:
    bs = _bs()
    from bluesky_gym.backends.bluesky_sim import BlueSkyPhysics

    sim = BlueSkyPhysics(2, dt=5.0)
    try:
        sim.create(0, 0, 52.0, 4.0, 0.0, 3000.0, 150.0)
        sim.wind.add_points(0, [52.0], [4.0], [3.0], [4.0])
        assert bs.traf.wind.winddim == 1
        sim.step()
        assert sim.simt == pytest.approx(bs.sim.simt) and bs.sim.simdt == 5.0
        sim.reset_envs()
        assert bs.traf.ntraf == 0 and bs.traf.wind.winddim == 0 and not sim.wind.any and not sim.active.any()
        t0 = sim.simt
        sim.step()  # the simulation runs without traffic too
        assert sim.simt == t0 + 5.0
    finally:
        sim.close()


@needs_bluesky
def test_slots_map_to_aircraft_after_deletion(physics) -> None:
    bs = _bs()
    physics.create(0, [2, 0, 1], [50.0, 51.0, 52.0], 4.0, 0.0, 3000.0, 150.0)
    physics.delete(0, 0)
    assert bs.traf.id == [physics.acid(2), physics.acid(1)]
    physics.create(0, 0, 53.0, 4.0, 0.0, 3000.0, 150.0)
    physics.step()
    for s, lat0 in zip((0, 1, 2), (53.0, 52.0, 50.0)):
        i = bs.traf.id2idx(physics.acid(s))
        assert physics.lat[0, s] == bs.traf.lat[i] and abs(physics.lat[0, s] - lat0) < 0.01
    with pytest.raises(ValueError, match="already exists"):
        physics.create(0, 1, 52.0, 4.0, 0.0, 3000.0, 150.0)


@needs_bluesky
def test_direct_writes_reach_bluesky_before_the_step(physics) -> None:
    bs = _bs()
    physics.create(0, [0, 1], 52.0, [4.0, 5.0], 0.0, 3000.0, 150.0)
    physics.set_autopilot(0, 1, selalt=0.0, selvs=-12.5)
    physics.set_state(0, 0, hdg=33.0)
    physics.set_autopilot(0, 0, ap_trk=33.0)
    physics.step()
    i0, i1 = bs.traf.id2idx(physics.acid(0)), bs.traf.id2idx(physics.acid(1))
    assert bs.traf.selvs[i1] == -12.5 and bs.traf.selalt[i1] == 0.0
    assert physics.vs[0, 1] == pytest.approx(-1.524) and physics.vs[0, 0] == 0.0  # the ramp started
    assert bs.traf.ap.trk[i0] == 33.0 and physics.hdg[0, 0] == 33.0
    # A command reads the written state: ALT without vs resets an opposite selvs.
    physics.set_autopilot(0, 0, selvs=5.0)
    assert bs.traf.selvs[i0] == 5.0 and physics.selvs[0, 0] == 5.0  # written at once
    physics.cmd_altitude(0, 0, 1000.0)
    assert bs.traf.selvs[i0] == 0.0 and physics.selvs[0, 0] == 0.0


@needs_bluesky
def test_state_arrays_are_read_only(physics) -> None:
    """State changes go through the commands: writing the arrays (which would not reach BlueSky) is refused."""
    physics.create(0, 0, 52.0, 4.0, 0.0, 3000.0, 150.0)
    for name in ("active", "nwp", "selalt", "hdg", "lat", "route_lat"):
        with pytest.raises(ValueError, match="read-only"):
            getattr(physics, name)[0, 0] = 1
    physics.set_state(0, 0, alt=1000.0)
    assert physics.alt[0, 0] == 1000.0


@needs_bluesky
def test_commands_use_the_stack_and_report_errors(physics) -> None:
    bs = _bs()
    physics.create(0, 0, 52.0, 4.0, 0.0, 3000.0, 150.0)
    physics.cmd_speed(0, 0, 250 * 0.514444)  # knots text chosen so that BlueSky gets exactly this CAS
    physics.cmd_heading(0, 0, -30.000000000000004)
    assert physics.selspd[0, 0] == 250 * 0.514444
    assert physics.ap_trk[0, 0] == -30.000000000000004
    physics.cmd_speed(0, 0, 0.78)  # Mach
    assert physics.selspd[0, 0] == 0.78
    physics.cmd_speed(0, 0, 1.2)  # Mach above 1: no text form, the SPD function is called
    assert physics.selspd[0, 0] == 1.2
    physics.command(f"ALT {physics.acid(0)} FL100")
    assert physics.selalt[0, 0] == pytest.approx(3048.0)
    with pytest.raises(RuntimeError, match="no command"):
        physics.command("NOSUCHCOMMAND 1")
    with pytest.raises(RuntimeError, match="rejected.*not found"):
        physics.command("HDG NOSUCHAIRCRAFT 90")
    with pytest.raises(RuntimeError, match="rejected"):
        physics.command(f"DEST {physics.acid(0)} NOWHERE_XYZ")
    with pytest.raises(ValueError, match="holds no aircraft"):
        physics.cmd_heading(0, 2, 90.0)
    assert bs.traf.ntraf == 1


@needs_bluesky
def test_routes_are_read_back(physics) -> None:
    physics.create(0, 0, 52.0, 4.0, 0.0, 3000.0, 150.0)
    physics.add_waypoint(0, 0, 52.3, 4.0)
    physics.set_destination(0, 0, 52.3, 4.5)
    physics.add_waypoint(0, 0, 52.5, 4.2)  # inserted before the destination
    assert physics.nwp[0, 0] == 3 and physics.route_has_dest[0, 0] and physics.swlnav[0, 0]
    np.testing.assert_allclose(physics.route_lat[0, 0], [52.3, 52.5, 52.3], rtol=0, atol=1e-12)
    np.testing.assert_allclose(physics.route_lon[0, 0], [4.0, 4.2, 4.5], rtol=0, atol=1e-12)
    with pytest.raises(ValueError, match="route full"):
        physics.add_waypoint(0, 0, 53.0, 4.0)
    for _ in range(200):
        physics.step()
    assert physics.iactwp[0, 0] >= 1


@needs_bluesky
def test_wind_points_go_to_bluesky(physics) -> None:
    bs = _bs()
    physics.create(0, 0, 52.0, 4.0, 0.0, 3000.0, 150.0)
    physics.wind.add_points(0, [52.0, 53.0], [4.0, 5.0], [-10.0, 5.0], [15.0, 2.0])
    w = bs.traf.wind
    assert w.winddim == 2 and w.vnorth.shape == (1, 2)
    vn, ve = physics.wind.at(np.array([0, 0]), np.array([52.0, 53.0]), np.array([4.0, 5.0]))
    np.testing.assert_allclose(vn, [-10.0, 5.0]) and np.testing.assert_allclose(ve, [15.0, 2.0])
    physics.cmd_heading(0, 0, 90.0)
    physics.step()
    assert physics.windnorth[0, 0] != 0.0 and physics.gs[0, 0] != physics.tas[0, 0]
    with pytest.raises(IndexError):
        physics.wind.add_points(1, [52.0], [4.0], [1.0], [1.0])


@needs_bluesky
def test_async_vector_env_runs_one_bluesky_per_process() -> None:
    """gym.make_vec(..., vectorization_mode="async", backend="bluesky"): each episode equals the native one."""
    _bs()
    venv = gym.make_vec("DescentEnv-v0", num_envs=2, vectorization_mode="async", backend="bluesky")
    natives = [gym.make("DescentEnv-v0") for _ in range(2)]
    try:
        obs, _ = venv.reset(seed=[11, 12])
        nobs = [e.reset(seed=s)[0] for e, s in zip(natives, (11, 12))]
        for k in obs:
            np.testing.assert_allclose(obs[k], np.stack([o[k] for o in nobs]), rtol=1e-9, atol=1e-9)
        rng = np.random.default_rng(5)
        for _ in range(8):
            a = rng.uniform(-1, 1, (2, 1))
            obs, rew, term, trunc, _ = venv.step(a)
            res = [e.step(a[i]) for i, e in enumerate(natives)]
            for k in obs:
                np.testing.assert_allclose(obs[k], np.stack([r[0][k] for r in res]), rtol=1e-9, atol=1e-9)
            np.testing.assert_allclose(rew, [r[1] for r in res], rtol=1e-9, atol=1e-9)
            assert list(term) == [r[2] for r in res] and list(trunc) == [r[3] for r in res]
    finally:
        venv.close()
        for e in natives:
            e.close()
