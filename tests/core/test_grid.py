"""The grid's pair search: exactly the conflicts, quantities and MVP resolutions of the all-pairs detection, with far fewer pairs evaluated."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from bluesky_gym.core import Simulator
from bluesky_gym.core import conflicts as cd
from bluesky_gym.core.conflicts import LOOKAHEAD, PZ_HEIGHT, PZ_RADIUS, ConflictPairs, detect, detect_grid, detect_pairs, resolve_pair_search
from bluesky_gym.core.geo import kwikpos
from bluesky_gym.core.resolution import AsasConfig, MVPResolver, ResolutionSettings, mvp, mvp_pairs
from bluesky_gym.core.units import NM

FIELDS = ("env", "own", "intruder", "los", "qdr", "dist", "tcpa", "dcpa", "tlos")


def assert_same_pairs(a: ConflictPairs, b: ConflictPairs) -> None:
    assert a.n_aircraft == b.n_aircraft
    for f in FIELDS:
        x, y = getattr(a, f), getattr(b, f)
        assert x.dtype == y.dtype and x.shape == y.shape, f
        if x.dtype == np.float64:
            np.testing.assert_array_equal(x.view(np.int64), y.view(np.int64), err_msg=f)  # to the bit, NaN included
        else:
            np.testing.assert_array_equal(x, y, err_msg=f)


def traffic(rng: np.random.Generator, n_envs: int, m: int, lat0: float, lon0: float, half_lat: float, half_lon: float) -> dict[str, Any]:
    shape = (n_envs, m)
    return {
        "lat": lat0 + rng.uniform(-half_lat, half_lat, shape),
        "lon": lon0 + rng.uniform(-half_lon, half_lon, shape),
        "alt": rng.uniform(9000.0, 10500.0, shape),
        "gs": rng.uniform(0.0, 280.0, shape),
        "trk": rng.uniform(0.0, 360.0, shape),
        "vs": rng.choice([0.0, 0.0, 8.0, -12.0], shape),
        "active": rng.random(shape) < 0.9,
    }


def args(t: dict[str, Any]) -> tuple[Any, ...]:
    return t["lat"], t["lon"], t["alt"], t["gs"], t["trk"], t["vs"], t["active"]


# Dense and sparse traffic; across the antimeridian (whose longitudes the detection does not wrap); at the poles; at the equator.
CASES = {
    "dense": (3, 150, 52.0, 4.0, 0.6, 1.0),
    "sparse": (2, 300, 52.0, 4.0, 8.0, 12.0),
    "antimeridian": (1, 300, 10.0, 180.0, 1.5, 2.5),
    "poles": (2, 200, 88.8, 0.0, 1.2, 180.0),
    "south pole": (1, 200, -89.0, 30.0, 1.0, 150.0),
    "equator": (1, 300, 0.0, 0.0, 1.5, 1.5),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_grid_finds_the_conflicts_of_all_pairs_to_the_bit(case: str) -> None:
    t = traffic(np.random.default_rng(sorted(CASES).index(case)), *CASES[case])
    t["lon"] = (t["lon"] + 180.0) % 360.0 - 180.0
    want = ConflictPairs.from_dense(detect(*args(t)))
    assert want.env.size > 0
    assert_same_pairs(detect_grid(*args(t)), want)
    for rpz, hpz, look in ((2.0 * NM, 200.0, 60.0), (8.0 * NM, 600.0, 600.0), (PZ_RADIUS, PZ_HEIGHT, 0.0), (PZ_RADIUS, PZ_HEIGHT, -5.0)):
        assert_same_pairs(detect_grid(*args(t), rpz, hpz, look), ConflictPairs.from_dense(detect(*args(t), rpz, hpz, look)))


def test_pairs_at_the_edge_of_the_look_ahead_and_across_band_borders() -> None:
    """Head-on pairs entering the zone just before and just after the look-ahead, around every band border."""
    gs = 250.0
    # Pairs whose loss of separation starts at the look-ahead (plus or minus a little): distance rpz + 2 gs (T +- dt).
    offsets = np.array([-1.0, -1e-3, -1e-6, 0.0, 1e-6, 1e-3, 1.0])
    n = offsets.size
    lat_own = 40.0 + np.linspace(0.0, 9.0, 4 * n)  # ownships from 40 to 49 deg, across the bands
    lon_own = -170.0 + 12.0 * np.arange(4 * n)  # the pairs far apart from each other
    dist_nm = (PZ_RADIUS + 2.0 * gs * (LOOKAHEAD + np.tile(offsets, 4))) / NM
    brg = np.repeat([0.0, 90.0, 45.0, 180.0], n)
    lat_int, lon_int = kwikpos(lat_own, lon_own, brg, dist_nm)
    lat = np.concatenate((lat_own, lat_int))[None, :]
    lon = np.concatenate((lon_own, lon_int))[None, :]
    trk = np.concatenate((brg, (brg + 180.0) % 360.0))[None, :]
    state = (lat, lon, np.full(lat.shape, 9000.0), np.full(lat.shape, gs), trk, np.zeros(lat.shape), np.ones(lat.shape, bool))
    want = ConflictPairs.from_dense(detect(*state))
    assert 0 < want.env.size < 2 * lat_own.size  # some of the pairs conflict, not all
    assert_same_pairs(detect_grid(*state), want)


def test_grid_with_non_finite_and_out_of_range_states_evaluates_every_pair() -> None:
    t = traffic(np.random.default_rng(7), 3, 120, 52.0, 4.0, 0.8, 1.2)
    t["gs"][0, 3] = np.nan
    t["alt"][1, 5] = np.inf
    t["lat"][2, 7] = 95.0
    t["active"][:, [3, 5, 7]] = True
    want = ConflictPairs.from_dense(detect(*args(t)))
    assert_same_pairs(detect_grid(*args(t)), want)
    empty = detect_grid(*args({**t, "active": np.zeros_like(t["active"])}))
    assert empty.env.size == 0


def test_grid_evaluates_far_fewer_pairs_than_all() -> None:
    t = traffic(np.random.default_rng(3), 1, 2000, 0.0, 0.0, 8.0, 8.0)
    work = cd.GridWork()
    got = detect_grid(*args(t), work=work)
    assert_same_pairs(got, ConflictPairs.from_dense(detect(*args(t))))
    assert got.env.size > 0 and 0 < work.evaluated < 0.01 * 2000 * 1999


def test_grid_layers_of_altitude_and_reused_work_arrays_give_the_same_pairs() -> None:
    """Level traffic (one layer of altitude per vertical reach), then climbing traffic, several airspaces, through one GridWork.

    Each call starts from the order of the last one, of other traffic or of fewer aircraft: the
    pairs do not depend on it; a crowded airspace outgrows the first room for conflicts.
    """
    rng = np.random.default_rng(21)
    work = cd.GridWork()
    for case in range(6):
        t = traffic(rng, 2, 400, 0.0, 0.0, 2.0, 2.0)
        t["alt"] = rng.uniform(6000.0, 12000.0, t["alt"].shape)
        if case % 2 == 0:
            t["vs"][...] = 0.0  # about 20 layers of altitude
        if case == 4:
            t["lat"][1] = rng.uniform(-0.05, 0.05, 400)  # crowded: more conflicts than the first room
            t["lon"][1] = rng.uniform(-0.05, 0.05, 400)
            t["alt"][1] = 9000.0
        if case == 5:
            t["active"][0, :300] = False
        want = ConflictPairs.from_dense(detect(*args(t)))
        assert want.env.size > 0
        got = detect_grid(*args(t), work=work)
        assert_same_pairs(got, want)
        row = work.row[: t["active"].size + 1]
        np.testing.assert_array_equal(np.diff(row), np.bincount(got.flat_own, minlength=t["active"].size))
    assert work.cand.shape[1] > cd.GRID_PAIRS


def test_mvp_from_pairs_is_mvp_to_the_bit() -> None:
    from types import SimpleNamespace

    rng = np.random.default_rng(11)
    t = traffic(rng, 2, 150, 52.0, 4.0, 0.6, 1.0)
    shape = t["active"].shape
    trk = np.radians(t["trk"])
    state = SimpleNamespace(
        active=t["active"], lat=t["lat"], lon=t["lon"], alt=t["alt"], gs=t["gs"], trk=t["trk"], vs=t["vs"],
        gseast=t["gs"] * np.sin(trk), gsnorth=t["gs"] * np.cos(trk), tas=t["gs"], selalt=t["alt"] + rng.choice([0.0, 600.0], shape),
        ap_vs=rng.uniform(0.0, 10.0, shape), vmin=np.full(shape, 50.0), vmax=np.full(shape, 260.0),
    )  # fmt: skip
    for settings in (ResolutionSettings(), ResolutionSettings.from_methods("SPD"), ResolutionSettings.from_methods(rmethv="V/S")):
        want = mvp(state, detect(*args(t)), settings)
        got = mvp_pairs(state, detect_pairs(*args(t)), settings)
        assert int(want.in_conflict.sum()) > 10
        for f in ("trk", "gs", "vs", "alt", "dv", "tsolv", "in_conflict"):
            np.testing.assert_array_equal(getattr(got, f), getattr(want, f), err_msg=f)
    with pytest.raises(ValueError, match="airspaces of 10 aircraft, the state has 150"):
        mvp_pairs(state, detect_pairs(*(a[:, :10] for a in args(t))))


def _fly(pair_search: str, steps: int) -> Simulator:
    rng = np.random.default_rng(5)
    n_envs, m = 4, 90
    sim = Simulator(n_envs, m, dt=1.0, pair_search=pair_search)
    env, slot = np.meshgrid(np.arange(n_envs), np.arange(m), indexing="ij")
    sim.create(env.ravel(), slot.ravel(), 52.0 + rng.uniform(-0.6, 0.6, env.size), 4.0 + rng.uniform(-0.9, 0.9, env.size),
               rng.uniform(0.0, 360.0, env.size), rng.uniform(9000.0, 10000.0, env.size), rng.uniform(120.0, 140.0, env.size))  # fmt: skip
    sim.add_waypoint(np.zeros(10, np.int64), np.arange(10), 52.5, 4.5)
    sim.set_conflict_resolution([0, 3], AsasConfig(detector="CSTATEBASED", resolution=True))
    sim.set_conflict_resolution([1], AsasConfig(detector="STATEBASED", resolution=True, settings=ResolutionSettings.from_methods("HDG")))
    sim.run(steps // 2)
    sim.delete(np.array([0, 3]), np.array([4, 7]))
    sim.reset_envs([1])
    sim.set_conflict_resolution([2], AsasConfig(detector="CSTATEBASED", resolution=True))
    sim.run(steps - steps // 2)
    return sim


def test_simulator_flies_the_same_with_either_pair_search() -> None:
    every, grid = _fly("all-pairs", 60), _fly("grid", 60)
    np.testing.assert_array_equal(grid._float_block.view(np.int64), every._float_block.view(np.int64))
    np.testing.assert_array_equal(grid.active, every.active)
    np.testing.assert_array_equal(grid._reso_held.view(np.int64), every._reso_held.view(np.int64))
    keys = np.flatnonzero(every._reso_pairs.reshape(-1))
    assert keys.size > 0
    # a resolution is kept only for the aircraft that follow one (they have a pair being resolved)
    following = every._reso_pairs.any(axis=-1)
    np.testing.assert_array_equal(np.isnan(every._reso_held).any(axis=0), ~following)
    np.testing.assert_array_equal(np.isnan(every._reso_held).all(axis=0), ~following)
    np.testing.assert_array_equal(grid._reso_keys, keys)
    assert grid._reso_pairs.size == 0


def test_resolver_with_pair_lists_forgets_airspaces() -> None:
    resolver = MVPResolver(pair_search="grid")
    resolver.held = np.zeros((4, 3, 5))
    resolver.pair_keys = np.array([1, 30, 60, 70], np.int64)  # airspaces 0, 1, 2, 2
    resolver.reset(np.array([2]))
    np.testing.assert_array_equal(resolver.pair_keys, [1, 30])
    assert np.isnan(resolver.held[:, 2]).all() and not np.isnan(resolver.held[:, :2]).any()
    resolver.reset()
    assert resolver.pair_keys.size == 0
    with pytest.raises(ValueError, match="pair_search 'cells' not known"):
        MVPResolver(pair_search="cells")


def test_pair_search_choice() -> None:
    assert resolve_pair_search("auto", cd.GRID_MIN_AIRCRAFT - 1) == "all-pairs"
    assert resolve_pair_search("auto", cd.GRID_MIN_AIRCRAFT) == "grid"
    assert resolve_pair_search("grid", 2) == "grid" and resolve_pair_search("all-pairs", 10**5) == "all-pairs"
    assert Simulator(1, 20).pair_search == "all-pairs" and Simulator(1, cd.GRID_MIN_AIRCRAFT).pair_search == "grid"
    with pytest.raises(ValueError, match="pair_search 'kd-tree' not known; choose one of auto, all-pairs, grid"):
        Simulator(1, 20, pair_search="kd-tree")
