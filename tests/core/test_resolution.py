"""MVP conflict resolution on the native core: settings, geometry, channels, batching, resumption.

The values themselves are checked against BlueSky 1.1.1's ``RESO MVP`` in
``test_resolution_bluesky.py`` (BlueSky venv); these tests need only the core.
"""

from __future__ import annotations

import numpy as np
import pytest

from bluesky_gym.core import Simulator
from bluesky_gym.core.aircraft import aircraft_performance
from bluesky_gym.core.conflicts import LOOKAHEAD, PZ_HEIGHT, PZ_RADIUS, detect
from bluesky_gym.core.resolution import RESO_FACTOR, MVPResolver, ResolutionSettings, mvp, resume, vertical_speed_limits

A320 = aircraft_performance("A320")


def _detect(sim: Simulator, rpz: float = PZ_RADIUS):
    return detect(sim.lat, sim.lon, sim.alt, sim.gs, sim.trk, sim.vs, sim.active, rpz, PZ_HEIGHT, LOOKAHEAD)


def _head_on(n_envs: int = 1, dcpa: float = 0.0, dh: float | None = None, alt: float = 6000.0) -> Simulator:
    """Ownship at ``alt`` heading east with an intruder head-on (creconfs), in every airspace."""
    sim = Simulator(n_envs, 3, dt=1.0)
    env = np.arange(n_envs)
    sim.create(env, 0, 52.0, 4.0, 90.0, alt, 140.0)
    sim.creconfs(env, 0, 1, 180.0, dcpa, 180.0, dh, None if dh is None else 150.0)
    sim.step()
    return sim


@pytest.mark.parametrize(
    ("rmethh", "rmethv", "switches"),
    [
        (None, None, (True, False, False, False)),  # BlueSky's state after RESO MVP
        ("BOTH", None, (True, True, True, False)),
        ("ON", None, (True, True, True, False)),
        ("SPD", None, (True, True, False, False)),
        ("HDG", None, (True, False, True, False)),
        ("NONE", None, (False, False, False, False)),
        (None, "V/S", (False, False, False, True)),
        ("HDG", "ON", (False, False, False, True)),
        ("SPD", "OFF", (True, True, False, False)),
    ],
)
def test_settings_follow_bluesky_commands(rmethh: str | None, rmethv: str | None, switches: tuple[bool, ...]) -> None:
    s = ResolutionSettings.from_methods(rmethh, rmethv)
    assert (s.swresohoriz, s.swresospd, s.swresohdg, s.swresovert) == switches
    assert s.resofach == s.resofacv == RESO_FACTOR


def test_settings_refuse_bad_values() -> None:
    with pytest.raises(ValueError, match="RMETHH 'UP' not understood"):
        ResolutionSettings.from_methods("UP")
    with pytest.raises(ValueError, match="RMETHV 'HDG' not understood"):
        ResolutionSettings.from_methods(None, "HDG")
    with pytest.raises(ValueError, match="resofach must be a finite number > 0"):
        ResolutionSettings.from_methods(resofach=0.0)


def test_head_on_conflict_is_resolved_by_both_aircraft() -> None:
    """Both aircraft turn the same way (each to the same side of its own track); flying the resolutions clears the conflict."""
    sim = _head_on()
    c = _detect(sim)
    assert c.conflict[0, 0, 1] and c.conflict[0, 1, 0]
    res = mvp(sim, c, ResolutionSettings.from_methods("HDG"))
    turn = (res.trk[0, :2] - sim.trk[0, :2] + 180.0) % 360.0 - 180.0
    assert np.all(np.abs(turn) > 1.0) and np.sign(turn[0]) == np.sign(turn[1]), turn  # cooperative: they pass each other
    # HDG keeps the ground speed, but BlueSky caps it with the CAS envelope: 186 m/s at FL200 -> 163.
    assert np.all(sim.gs[0, :2] > sim.vmax[0, :2])
    np.testing.assert_array_equal(res.gs[0, :2], sim.vmax[0, :2])
    assert res.in_conflict[0, :2].all() and not res.in_conflict[0, 2]
    assert np.isnan(res.trk[0, 2])  # empty slot
    # The velocities MVP asks for give a miss distance beyond the protected zone.
    trk = np.radians(res.trk[0, :2])
    ve, vn = sim.gs[0, :2] * np.sin(trk), sim.gs[0, :2] * np.cos(trk)
    q = np.radians(c.qdr[0, 0, 1])
    dx, dy = c.dist[0, 0, 1] * np.sin(q), c.dist[0, 0, 1] * np.cos(q)
    du, dv = ve[1] - ve[0], vn[1] - vn[0]
    t = -(dx * du + dy * dv) / (du * du + dv * dv)
    miss = np.hypot(dx + du * t, dy + dv * t)
    assert miss > PZ_RADIUS, miss


def test_channels_follow_the_settings() -> None:
    sim = _head_on(dcpa=1.0, dh=200.0)
    c = _detect(sim)
    both = mvp(sim, c, ResolutionSettings.from_methods("BOTH"))
    spd = mvp(sim, c, ResolutionSettings.from_methods("SPD"))
    hdg = mvp(sim, c, ResolutionSettings.from_methods("HDG"))
    vert = mvp(sim, c, ResolutionSettings.from_methods(None, "V/S"))
    own = slice(0, 2)
    np.testing.assert_array_equal(spd.trk[0, own], sim.trk[0, own])
    np.testing.assert_array_equal(hdg.gs[0, own], np.clip(sim.gs[0, own], sim.vmin[0, own], sim.vmax[0, own]))
    np.testing.assert_array_equal(vert.trk[0, own], sim.trk[0, own])
    assert not np.array_equal(both.trk[0, own], sim.trk[0, own])
    # Vertical only: the intruder 200 m above climbs, the ownship is sent down (altitude below its own).
    assert vert.alt[0, 0] != sim.selalt[0, 0]
    np.testing.assert_array_equal(both.alt[0, own], sim.selalt[0, own])  # horizontal: follow the autopilot altitude
    assert np.all((vert.vs[0, own] >= A320.vsmin) & (vert.vs[0, own] <= A320.vsmax))
    # The margin matters: a larger factor asks for a larger turn.
    wide = mvp(sim, c, ResolutionSettings.from_methods("HDG", resofach=1.5))
    turn = (hdg.trk[0, 0] - sim.trk[0, 0] + 180.0) % 360.0 - 180.0
    turn_wide = (wide.trk[0, 0] - sim.trk[0, 0] + 180.0) % 360.0 - 180.0
    assert abs(turn_wide) > abs(turn) > 0.0


def test_batched_equals_single() -> None:
    """An airspace resolved among many gives the same values as resolved alone."""
    rng = np.random.default_rng(3)
    n = 6
    sim = Simulator(n, 4, dt=1.0)
    env = np.arange(n)
    sim.create(env, 0, 52.0, 4.0, rng.uniform(0, 360, n), rng.uniform(3000, 8000, n), 140.0)
    for slot in (1, 2):
        sim.creconfs(env, 0, slot, rng.uniform(0, 360, n), rng.uniform(0, 4, n), rng.uniform(60, 300, n), rng.uniform(-400, 400, n), 120.0)
    sim.step()
    settings = ResolutionSettings.from_methods(None, None)
    batch = mvp(sim, _detect(sim), settings)
    for e in range(n):
        one = Simulator(1, 4, dt=1.0)
        one.create(0, [0, 1, 2], sim.lat[e, :3], sim.lon[e, :3], sim.hdg[e, :3], sim.alt[e, :3], sim.cas[e, :3])
        for name in ("trk", "gs", "gsnorth", "gseast", "vs", "selalt", "ap_vs"):
            getattr(one, name)[0, :3] = getattr(sim, name)[e, :3]
        single = mvp(one, _detect(one), settings)
        for field in ("trk", "gs", "vs", "alt", "tsolv"):
            np.testing.assert_array_equal(getattr(single, field)[0, :3], getattr(batch, field)[e, :3], err_msg=f"{field} of airspace {e}")


def test_resume_keeps_pairs_until_past_cpa() -> None:
    sim = _head_on()
    c = _detect(sim)
    keep, follow = resume(sim, c.conflict)
    assert keep[0, 0, 1] and keep[0, 1, 0] and follow[0, :2].all()
    # Move the aircraft past each other: the pair ends.
    sim.run(400)
    keep, follow = resume(sim, c.conflict)
    assert not keep.any() and not follow.any()


def test_resolver_holds_resolution_until_past_cpa_and_resets() -> None:
    sim = _head_on(n_envs=2, alt=1000.0)  # TAS below the CAS envelope's top: the speed stays
    resolver = MVPResolver(ResolutionSettings.from_methods("HDG"))
    cmd = resolver.update(sim)
    assert cmd.follow[:, :2].all() and not cmd.follow[:, 2].any()
    assert np.all(np.abs(cmd.track_change[:, :2]) > 1.0)
    np.testing.assert_allclose(cmd.cas_change[:, :2], 0.0, atol=1e-9)  # HDG: same speed
    resolver.reset(np.array([True, False]))
    assert not resolver.pairs[0].any() and resolver.pairs[1].any()
    sim.run(400)
    cmd = resolver.update(sim)
    assert not cmd.follow.any()


@pytest.mark.parametrize(
    "args",
    [
        (90.0, 0.0, 0.0, 0.0, 0.0, -100.0, 0.0, 0.0),  # co-located: 0/0 in the head-on rule
        (90.0, 5000.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0),  # no relative motion: tcpa 0
        (45.0, 8000.0, 30.0, 10.0, 0.0, -150.0, -150.0, 2.0),  # same altitude, climbing apart: tsolv 0
        (10.0, 12000.0, 60.0, 20.0, 150.0, -200.0, 10.0, 0.0),  # level, ordinary
    ],
)
def test_pair_kernel_compiled_and_plain_python_agree_on_edge_cases(args: tuple[float, ...]) -> None:
    """Zero divisors give numpy's inf / NaN in both forms (the plain form does not raise)."""
    from bluesky_gym.core.jit import python_form
    from bluesky_gym.core.resolution import mvp_pair

    rest = (PZ_RADIUS * RESO_FACTOR, PZ_HEIGHT * RESO_FACTOR, LOOKAHEAD)
    compiled = np.array(mvp_pair(*args, *rest))
    plain = np.array(python_form(mvp_pair)(*args, *rest))
    np.testing.assert_array_equal(compiled, plain)


def test_each_aircraft_is_capped_with_its_own_vertical_envelope() -> None:
    """BlueSky caps with every aircraft's own perf.vsmin/vsmax: a B744's resolution with the B744's, an A320's with the A320's.

    BlueSky's equality is checked in test_resolution_bluesky.py (mixed-type geometries).
    """
    b744 = aircraft_performance("B744")
    assert b744.vsmin != A320.vsmin
    sim = Simulator(2, 3, dt=1.0)
    sim.create([0, 1], 0, 52.0, 4.0, 90.0, 6000.0, 140.0, actype=["B744", "A320"])
    sim.creconfs([0, 1], 0, 1, 180.0, 1.0, 180.0, 50.0, 150.0)  # small vertical changes: capped at vsmin
    sim.step()
    vsmin, vsmax = vertical_speed_limits(sim)
    np.testing.assert_array_equal(vsmin[:, :2], [[b744.vsmin, A320.vsmin], [A320.vsmin, A320.vsmin]])
    np.testing.assert_array_equal(vsmax[:, :2], [[b744.vsmax, A320.vsmax], [A320.vsmax, A320.vsmax]])
    assert np.isnan(vsmin[:, 2]).all() and np.isnan(vsmax[:, 2]).all()  # empty slots
    settings = ResolutionSettings.from_methods(None, "V/S")
    cmd = MVPResolver(settings).update(sim)  # the resolver's default: every aircraft's own envelope
    assert cmd.follow[:, 0].all()
    np.testing.assert_array_equal(cmd.vs[:, 0], [b744.vsmin, A320.vsmin])
    np.testing.assert_array_equal(cmd.vs[:, :2], mvp(sim, _detect(sim), settings, vsmin=vsmin, vsmax=vsmax).vs[:, :2])
    assert mvp(sim, _detect(sim), settings).vs[0, 0] == A320.vsmin  # mvp() alone defaults to the A320's
