"""SSD conflict resolution on the native core: geometry, batching, priority codes, the missing extra.

The values themselves are checked to the bit against BlueSky 1.1.1's SSD plugin in
``test_ssd_bluesky.py`` (BlueSky venv); these tests need only the core and pyclipper.
"""

from __future__ import annotations

import sys

import numpy as np
import pytest

pytest.importorskip("pyclipper")

from bluesky_gym.core import Simulator
from bluesky_gym.core.conflicts import LOOKAHEAD, PZ_HEIGHT, PZ_RADIUS, Conflicts, detect
from bluesky_gym.core.extras import MissingDependencyError
from bluesky_gym.core.geo import qdrdist
from bluesky_gym.core.resolution import NO_VERTICAL_SOLUTION, RESO_FACTOR, AsasConfig, ResolutionSettings
from bluesky_gym.core.resolvers import RESOLVERS
from bluesky_gym.core.ssd import ADSB_RANGE, SSDResolver, check_priority, pair_indices, ssd
from bluesky_gym.core.units import NM


def _detect(sim: Simulator) -> Conflicts:
    return detect(sim.lat, sim.lon, sim.alt, sim.gs, sim.trk, sim.vs, sim.active, PZ_RADIUS, PZ_HEIGHT, LOOKAHEAD)


def _scene(n_envs: int = 1, max_aircraft: int = 5) -> Simulator:
    """An ownship heading east with a head-on intruder, one from the right and one far away, in every airspace (rotated per airspace)."""
    sim = Simulator(n_envs, max_aircraft, dt=1.0)
    env = np.arange(n_envs)
    sim.create(env, 0, 52.0, 4.0, 90.0 + 20.0 * env, 3000.0, 120.0)
    sim.creconfs(env, 0, 1, 180.0, 0.0, 200.0)
    sim.creconfs(env, 0, 2, 90.0, 1.0, 150.0)
    sim.create(env, 3, 50.0, 10.0, 0.0, 3000.0, 120.0)  # no conflict, beyond ADS-B range of the others
    sim.step()
    return sim


def _blueskys_pair_indices(ntraf: int) -> tuple[np.ndarray, np.ndarray]:
    """The plugin's ``qdrdist_matrix_indices``, as written there (an independent oracle of :func:`pair_indices`)."""
    tmp_range = np.arange(ntraf - 1, dtype=np.int32)
    ind1 = np.repeat(tmp_range, (tmp_range + 1)[::-1])
    ind2 = np.ones(ind1.shape[0], dtype=np.int32)
    inds = np.cumsum(tmp_range[1:][::-1] + 1)
    np.put(ind2, inds, np.arange(ntraf * -1 + 3, 1))
    ind2 = np.cumsum(ind2, out=ind2)
    return ind1, ind2


@pytest.mark.parametrize("n", [2, 3, 4, 7, 12])
def test_pairs_are_in_the_plugins_order(n: int) -> None:
    ind1, ind2 = pair_indices(n)
    theirs = _blueskys_pair_indices(n)
    np.testing.assert_array_equal(ind1, theirs[0])
    np.testing.assert_array_equal(ind2, theirs[1])


def test_resolution_leaves_the_velocity_obstacles() -> None:
    """The aircraft in conflict take a velocity on the ring of their envelope, outside every enlarged protected zone's obstacle."""
    sim = _scene()
    c = _detect(sim)
    assert c.in_conflict[0, :3].all() and not c.in_conflict[0, 3]
    res = ssd(sim, c)
    slots = np.arange(3)
    ve = sim.gseast[0, slots] + res.dv[0, slots, 0]
    vn = sim.gsnorth[0, slots] + res.dv[0, slots, 1]
    speed = np.hypot(ve, vn)
    assert np.all(np.abs(res.dv[0, slots, :2]).sum(-1) > 1.0)  # all three changed their velocity
    # The resolved velocity lies in the ring [vmin, vmax] (float32 and clipper rounding aside) ...
    assert np.all(speed >= sim.vmin[0, slots] * (1 - 1e-6)) and np.all(speed <= sim.vmax[0, slots] * (1 + 1e-6))
    np.testing.assert_allclose(res.gs[0, slots], np.maximum(sim.vmin[0, slots], np.minimum(sim.vmax[0, slots], speed.astype(np.float32))))
    np.testing.assert_allclose((res.trk[0, slots] - np.degrees(np.arctan2(ve, vn)) + 180) % 360 - 180, 0.0, atol=1e-4)
    # ... and keeps every other aircraft's (unchanged) velocity out of the enlarged zone: the
    # predicted miss distance of each pair, in SSD's flat geometry, is at least the zone radius x
    # RFACH. SSD places the pair (i, j) by the WGS-84 bearing and distance from the lower slot to
    # the higher, mirrored for the other aircraft.
    hsepm = PZ_RADIUS * RESO_FACTOR
    for i in slots:
        for j in range(3):
            if i == j:
                continue
            a, b = min(i, j), max(i, j)
            qdr, dist = qdrdist(sim.lat[0, a], sim.lon[0, a], sim.lat[0, b], sim.lon[0, b])
            q = np.radians(qdr)
            mirror = 1.0 if i < j else -1.0
            dx, dy = mirror * dist * NM * np.sin(q), mirror * dist * NM * np.cos(q)
            du, dv = sim.gseast[0, j] - ve[i], sim.gsnorth[0, j] - vn[i]
            tcpa = -(du * dx + dv * dy) / (du * du + dv * dv)
            dcpa = np.hypot(dx + du * max(tcpa, 0.0), dy + dv * max(tcpa, 0.0))
            assert dcpa >= hsepm * (1 - 1e-6), (i, j, dcpa)
    # Horizontal only: the vertical speed and the selected altitude are the aircraft's own.
    np.testing.assert_array_equal(res.vs[0, :4], sim.vs[0, :4])
    np.testing.assert_array_equal(res.alt[0, :4], sim.selalt[0, :4])
    np.testing.assert_array_equal(res.tsolv[0, :4], NO_VERTICAL_SOLUTION)
    # Not in conflict: its heading (not its track) and its ground speed, capped by the envelope.
    assert res.trk[0, 3] == sim.hdg[0, 3] and res.gs[0, 3] == min(sim.vmax[0, 3], max(sim.vmin[0, 3], sim.gs[0, 3]))
    np.testing.assert_array_equal(res.dv[0, 3], 0.0)
    assert np.isnan(res.trk[0, 4]) and np.isnan(res.gs[0, 4])  # empty slot


def test_resolved_speed_is_float32_as_in_the_plugin() -> None:
    sim = _scene()
    res = ssd(sim, _detect(sim))
    ve = sim.gseast[0, :3] + res.dv[0, :3, 0]
    assert np.all(ve.astype(np.float32).astype(np.float64) == ve)


def test_batched_airspaces_equal_one_by_one() -> None:
    """Every airspace of a batch is resolved as it would be alone (the geometries differ by airspace)."""
    sim = _scene(n_envs=3)
    c = _detect(sim)
    res = ssd(sim, c)
    for e in range(3):
        # Airspace e alone: the same aircraft, rotated by 20 deg x e.
        alone = Simulator(1, 5, dt=1.0)
        alone.create(0, 0, 52.0, 4.0, 90.0 + 20.0 * e, 3000.0, 120.0)
        alone.creconfs(0, 0, 1, 180.0, 0.0, 200.0)
        alone.creconfs(0, 0, 2, 90.0, 1.0, 150.0)
        alone.create(0, 3, 50.0, 10.0, 0.0, 3000.0, 120.0)
        alone.step()
        one = ssd(alone, _detect(alone))
        np.testing.assert_array_equal(res.trk[e], one.trk[0])
        np.testing.assert_array_equal(res.gs[e], one.gs[0])
    assert not np.array_equal(res.trk[0], res.trk[1])


def test_resolution_factor_widens_the_obstacles() -> None:
    sim = _scene()
    c = _detect(sim)
    small = ssd(sim, c, ResolutionSettings(resofach=1.0))
    large = ssd(sim, c, ResolutionSettings(resofach=1.5))
    change = [np.hypot(*r.dv[0, 0, :2]) for r in (small, large)]
    assert change[1] > change[0]


def test_aircraft_beyond_adsb_range_are_ignored() -> None:
    """An intruder farther than 65 NM draws no obstacle: alone in range, an aircraft in conflict gets the whole ring.

    As in the plugin, it then moves to the nearest point of the ring's edge (the resolution is the
    closest point on the edges of the diagram, even from inside it): here the outer circle (vmax),
    straight ahead.
    """
    sim = _scene()
    c = _detect(sim)
    assert c.dist[0, 0, 3] > ADSB_RANGE
    # Aircraft 3 is declared in conflict (as if by a longer look-ahead) but has nobody within range.
    forced = Conflicts(c.conflict.copy(), c.los, c.qdr, c.dist, c.tcpa, c.dcpa, c.tlos)
    forced.conflict[0, 3, 0] = True
    res = ssd(sim, forced)
    ve, vn = sim.gseast[0, 3] + res.dv[0, 3, 0], sim.gsnorth[0, 3] + res.dv[0, 3, 1]
    assert sim.vmax[0, 3] * np.cos(np.pi / 180) <= np.hypot(ve, vn) <= sim.vmax[0, 3]  # on the 180-gon of the outer circle
    assert abs(np.degrees(np.arctan2(ve, vn)) - sim.trk[0, 3]) < 1.0


def test_priority_codes() -> None:
    assert check_priority("") == "" and check_priority("RS1") == "RS1"
    with pytest.raises(ValueError, match=r"SSD priority code 'RS5' is not supported; SSD resolves with BlueSky's default rule"):
        check_priority("RS5")
    with pytest.raises(ValueError, match=r"SSD priority code 'RS10' not understood"):
        check_priority("RS10")
    sim = _scene()
    with pytest.raises(ValueError, match="RS2"):
        ssd(sim, _detect(sim), priocode="RS2")


def test_conflicts_of_another_shape_are_refused() -> None:
    sim = _scene()
    other = _detect(_scene(n_envs=2))
    with pytest.raises(ValueError, match="conflicts are shaped"):
        ssd(sim, other)


def test_missing_pyclipper_names_the_extra(monkeypatch: pytest.MonkeyPatch) -> None:
    sim = _scene()
    c = _detect(sim)
    monkeypatch.setitem(sys.modules, "pyclipper", None)  # import pyclipper fails
    with pytest.raises(MissingDependencyError, match=r"SSD conflict resolution needs pyclipper.*'ssd' extra"):
        ssd(sim, c)


def _flown(pair_search: str, method: str = "SSD", steps: int = 240) -> tuple[Simulator, int, float]:
    """The scene of :func:`_scene` flown with ``RESO method`` (CSTATEBASED).

    Returns:
        The simulator, the steps in loss of separation and the ownship's largest turn from its track [deg].
    """
    sim = Simulator(1, 5, dt=1.0, pair_search=pair_search)
    sim.create(0, 0, 52.0, 4.0, 90.0, 3000.0, 120.0)
    sim.creconfs(0, 0, 1, 180.0, 0.0, 200.0)
    sim.creconfs(0, 0, 2, 90.0, 1.0, 150.0)
    sim.set_conflict_resolution(0, AsasConfig("CSTATEBASED", True, method=method))
    los = 0
    turn = 0.0
    for _ in range(steps):
        sim.step()
        los += int(_detect(sim).los.any())
        turn = max(turn, abs((sim.trk[0, 0] - 90.0 + 180.0) % 360.0 - 180.0))
    return sim, los, turn


def test_simulator_flies_reso_ssd() -> None:
    """``RESO SSD`` is a registered method: the simulator flies it and the head-on conflicts end without a loss of separation."""
    assert RESOLVERS["SSD"] is SSDResolver
    _, los, turn = _flown("all-pairs")
    unresolved = Simulator(1, 5, dt=1.0)
    unresolved.create(0, 0, 52.0, 4.0, 90.0, 3000.0, 120.0)
    unresolved.creconfs(0, 0, 1, 180.0, 0.0, 200.0)
    unresolved.creconfs(0, 0, 2, 90.0, 1.0, 150.0)
    lost = 0
    for _ in range(240):
        unresolved.step()
        lost += int(_detect(unresolved).los.any())
    assert lost > 0 and los == 0
    assert turn > 5.0  # the ownship turned away


def test_grid_pair_search_flies_the_same() -> None:
    """SSD from the conflicts as pairs (``pair_search="grid"``) flies the same states to the bit."""
    a, _, _ = _flown("all-pairs", steps=120)
    b, _, _ = _flown("grid", steps=120)
    for name in ("lat", "lon", "trk", "gs", "alt"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
