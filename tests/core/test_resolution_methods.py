"""The resolution-method framework and the Eby and Swarm methods on the native core.

Their values are checked against BlueSky 1.1.1's fixed plugins in ``test_resolution_methods_bluesky.py``
(BlueSky venv); these tests need only the core.
"""

from __future__ import annotations

import numpy as np
import pytest

from bluesky_gym.core import Simulator
from bluesky_gym.core.conflicts import LOOKAHEAD, PZ_HEIGHT, PZ_RADIUS, ConflictPairs, detect, detect_pairs
from bluesky_gym.core.eby import EbyResolver, dot3, eby, eby_pair, eby_pairs
from bluesky_gym.core.jit import PRIMITIVES, fma, python_form
from bluesky_gym.core.resolution import AsasConfig, ConflictResolver, MVPResolver, ResolutionSettings, mvp
from bluesky_gym.core.resolvers import RESOLVERS, resolver_class
from bluesky_gym.core.swarm import SWARM_RADIUS, SwarmResolver, swarm


def _detect(sim: Simulator):
    return detect(sim.lat, sim.lon, sim.alt, sim.gs, sim.trk, sim.vs, sim.active, PZ_RADIUS, PZ_HEIGHT, LOOKAHEAD)


def _traffic(n_envs: int = 2, m: int = 6, seed: int = 3) -> Simulator:
    """Ownships with creconfs intruders (some of each other), and a bystander far away, per airspace."""
    rng = np.random.default_rng(seed)
    sim = Simulator(n_envs, m, dt=1.0, pair_search="all-pairs")
    for e in range(n_envs):
        sim.create(e, 0, 52.0, 4.0, rng.uniform(0, 360), rng.uniform(3000, 8000), rng.uniform(120, 160))
        for s in range(1, m - 1):
            sim.creconfs(e, 0 if s < 3 else s - 1, s, rng.uniform(0, 360), rng.uniform(0, 3), rng.uniform(60, 300))
        sim.create(e, m - 1, 53.0, 5.0, 10.0, 4000.0, 130.0)
    sim.step()
    return sim


def test_the_registry_names_every_method_by_its_reso_name() -> None:
    assert set(RESOLVERS) == {"MVP", "EBY", "SWARM", "SSD"}
    for name, cls in RESOLVERS.items():
        assert issubclass(cls, ConflictResolver) and cls.name == name and resolver_class(name) is cls
    assert AsasConfig().method == "MVP" and AsasConfig(resolution=True).resolving is False  # no detector
    with pytest.raises(ValueError, match="resolution method 'FANCY' not known; choose one of MVP, EBY, SWARM, SSD"):
        resolver_class("FANCY")
    with pytest.raises(NotImplementedError, match="does not implement resolve"):
        ConflictResolver().update(_traffic(1))


def test_fma_is_one_rounding_in_every_form() -> None:
    """``fma`` rounds ``a * b + c`` once (unlike ``a * b + c``), compiled and in Python alike."""
    a, b, c = 1.0 + 2.0**-30, 1.0 - 2.0**-30, -1.0
    assert a * b + c == 0.0 and fma(a, b, c) == -(2.0**-60)  # the exact result
    assert PRIMITIVES["fma"] is fma
    rng = np.random.default_rng(0)
    for x in rng.normal(size=(200, 6)) * 1e3:
        assert dot3(*x) == python_form(dot3)(*x) == np.dot(x[:3], x[3:])  # numpy's BLAS ddot on this machine
    assert np.isnan(fma(np.inf, 0.0, 1.0))


def test_eby_kernel_is_its_python_form() -> None:
    rng = np.random.default_rng(1)
    for _ in range(200):
        args = (*rng.uniform([0, 100, -300, 0, 100, -5, 0, 100, -5], [360, 20000, 300, 360, 250, 5, 360, 250, 5]), PZ_RADIUS * 1.05)
        assert eby_pair(*args) == python_form(eby_pair)(*args)


def test_eby_is_symmetric_and_pushes_a_head_on_pair_apart() -> None:
    """A head-on pair: both listed ((0, 1) and (1, 0)), the two changes are opposite and sideways."""
    sim = Simulator(1, 3, dt=1.0)
    sim.create(0, 0, 52.0, 4.0, 90.0, 5000.0, 140.0)
    sim.creconfs(0, 0, 1, 180.0, 0.0, 120.0)
    sim.step()
    c = _detect(sim)
    assert c.conflict[0, 0, 1] and c.conflict[0, 1, 0]
    res = eby(sim, c)
    np.testing.assert_allclose(res.dv[0, 0], -res.dv[0, 1], rtol=1e-9, atol=1e-9)
    assert abs(res.dv[0, 0, 1]) > 1.0  # a north-south change for east-west traffic
    assert np.isnan(res.trk[0, 2]) and res.alt[0, 0] == 0.0  # empty slot; a level resolution: altitude 0
    # The speed is the EAS of the new ground speed (below the TAS at 5000 m), inside the CAS envelope.
    assert sim.vmin[0, 0] <= res.gs[0, 0] <= sim.vmax[0, 0] and res.gs[0, 0] < sim.tas[0, 0]


def test_eby_from_pairs_equals_eby_from_the_picture() -> None:
    sim = _traffic()
    c = _detect(sim)
    assert c.conflict.sum() > 4
    dense, pairs = eby(sim, c, ResolutionSettings(resofach=1.2)), eby_pairs(sim, ConflictPairs.from_dense(c), ResolutionSettings(resofach=1.2))
    grid = eby_pairs(sim, detect_pairs(sim.lat, sim.lon, sim.alt, sim.gs, sim.trk, sim.vs, sim.active, PZ_RADIUS, PZ_HEIGHT, LOOKAHEAD))
    for name in ("trk", "gs", "vs", "alt", "dv"):
        np.testing.assert_array_equal(getattr(dense, name), getattr(pairs, name))
    np.testing.assert_array_equal(grid.trk, eby(sim, c).trk)


def test_swarm_blends_avoidance_alignment_and_centering() -> None:
    """Without conflicts Swarm still steers everyone (alignment, centering); a lone aircraft keeps its own velocity."""
    sim = Simulator(1, 4, dt=1.0)
    sim.create(0, [0, 1], [52.0, 52.1], [4.0, 4.0], [100.0, 80.0], 5000.0, 150.0)  # 6 NM apart, diverging, same direction
    sim.create(0, 2, 53.5, 6.0, 270.0, 5000.0, 150.0)  # alone (beyond SWARM_RADIUS)
    sim.step()
    c = _detect(sim)
    assert not c.conflict.any()
    settings = ResolutionSettings()
    res = swarm(sim, c, mvp(sim, c, settings))
    # Both are steered (alignment pulls each towards the other's track; centering uses STATEBASED's
    # compiled bearings, which give the higher slot the bearing of the pair seen from the lower one).
    assert abs(res.trk[0, 0] - 100.0) > 1.0 and abs(res.trk[0, 1] - 80.0) > 1.0
    assert 80.0 < res.trk[0, 0] < 100.0  # slot 0 sees its neighbour where it is
    assert res.trk[0, 2] == pytest.approx(sim.ap_trk[0, 2] - 360.0) or res.trk[0, 2] == pytest.approx(sim.ap_trk[0, 2])
    assert res.gs[0, 2] == pytest.approx(sim.cas[0, 2]) and res.vs[0, 2] == 0.0 and res.alt[0, 2] == 0.0
    assert SWARM_RADIUS > 0 and np.isnan(res.trk[0, 3])


def test_swarm_makes_every_aircraft_follow_after_a_resolution() -> None:
    """BlueSky's Swarm: after a resolution every aircraft of the airspace follows (a bystander too); MVP: only the pairs."""
    sim = _traffic(n_envs=1)
    follow = {}
    for cls in (MVPResolver, SwarmResolver):
        follow[cls.name] = cls(ResolutionSettings()).update(sim).follow[0]
    assert follow["SWARM"].all() and not follow["MVP"][-1] and follow["MVP"][0]
    swarm_resolver = SwarmResolver()
    swarm_resolver.update(sim)
    swarm_resolver.reset(np.array([0]))
    assert not swarm_resolver.following.any()


def test_swarm_needs_every_pair() -> None:
    with pytest.raises(ValueError, match="RESO SWARM needs pair_search 'all-pairs', got 'grid'"):
        SwarmResolver(pair_search="grid")
    sim = Simulator(1, 2, pair_search="grid")
    with pytest.raises(ValueError, match="RESO SWARM needs pair_search 'all-pairs', this simulator has 'grid'"):
        sim.set_conflict_resolution(0, AsasConfig("CSTATEBASED", True, method="SWARM"))
    with pytest.raises(ValueError, match="resolution method 'FANCY' not known"):
        sim.set_conflict_resolution(0, AsasConfig("CSTATEBASED", True, method="FANCY"))


@pytest.mark.parametrize("method", ["EBY", "SWARM"])
def test_simulator_flies_the_method_as_its_resolver_decides(method: str) -> None:
    """Simulator.step with RESO method: per airspace, as one resolver of each airspace alone; airspaces with MVP are unaffected."""
    batch = _traffic(n_envs=3)
    alone = [_traffic(n_envs=3) for _ in range(2)]
    batch.set_conflict_resolution([0, 1], AsasConfig("CSTATEBASED", True, method=method))
    batch.set_conflict_resolution(2, AsasConfig("CSTATEBASED", True))
    alone[0].set_conflict_resolution([0, 1, 2], AsasConfig("CSTATEBASED", True, method=method))
    alone[1].set_conflict_resolution([0, 1, 2], AsasConfig("CSTATEBASED", True))
    for _ in range(40):
        for s in (batch, *alone):
            s.step()
    for name in ("lat", "lon", "alt", "trk", "tas", "vs"):
        np.testing.assert_array_equal(getattr(batch, name)[:2], getattr(alone[0], name)[:2], err_msg=name)
        np.testing.assert_array_equal(getattr(batch, name)[2], getattr(alone[1], name)[2], err_msg=name)
    assert np.abs(batch.trk[:2] - alone[1].trk[:2]).max() > 0.1  # not MVP's flight


def test_eby_flies_the_same_with_the_grid_search() -> None:
    sims = []
    for pair_search in ("all-pairs", "grid"):
        sim = Simulator(2, 6, dt=1.0, pair_search=pair_search)
        ref = _traffic()
        for e in range(2):
            for s in np.flatnonzero(ref.active[e]):
                sim.create(e, int(s), ref.lat[e, s], ref.lon[e, s], ref.hdg[e, s], ref.alt[e, s], ref.cas[e, s])
        sim.set_conflict_resolution([0, 1], AsasConfig("CSTATEBASED", True, method="EBY"))
        for _ in range(30):
            sim.step()
        sims.append(sim)
    for name in ("lat", "lon", "alt", "trk", "tas"):
        np.testing.assert_array_equal(getattr(sims[0], name), getattr(sims[1], name), err_msg=name)
    assert isinstance(resolver_class("EBY")(), EbyResolver)
