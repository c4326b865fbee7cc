"""The compiled observation/reward geometry equals the readable numpy oracle to the last bit."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from bluesky_gym.core.jit import python_form
from bluesky_gym.environments.horizontal_cr.task import HorizontalCRTask
from bluesky_gym.environments.merge import task as mg
from bluesky_gym.environments.merge.task import MergeTask
from bluesky_gym.environments.sector_cr import task as sc
from bluesky_gym.environments.sector_cr.task import SectorCRTask
from bluesky_gym.environments.vertical_cr.task import VerticalCRTask, intruder_relative_state
from bluesky_gym.tasks import compiled
from bluesky_gym.tasks.base import KPI_KEYS
from tests.oracle import tasks as oracle
from tests.oracle.geometry import points_in_polygons, ref_kwikdist, ref_kwikdist_matrix

N_ENVS = 6


def _task(task_class: type, seed: int) -> object:
    task = task_class(N_ENVS)
    task.seed(task.all_envs, [np.random.default_rng(seed + i) for i in range(N_ENVS)])
    task.reset()
    return task


def _assert_same(a: dict, b: dict, what: str) -> None:
    assert a.keys() == b.keys()
    for k in a:
        np.testing.assert_array_equal(np.asarray(a[k]), np.asarray(b[k]), err_msg=f"{what}: {k}", strict=True)


def _oracle_observation(task: object) -> dict:
    s = task.sim
    if isinstance(task, SectorCRTask):
        return oracle.sector_observation(s, task.wpt_lat[:, 0], task.wpt_lon[:, 0])
    if isinstance(task, MergeTask):
        return oracle.merge_observation(s, task.wpt_reach)
    if isinstance(task, HorizontalCRTask):
        return oracle.horizontal_cr_observation(s, task.wpt_lat, task.wpt_lon)
    return oracle.intruder_relative_state(s.lat, s.lon, s.hdg, s.gs)


def _task_observation(task: object) -> dict:
    if isinstance(task, VerticalCRTask):
        s = task.sim
        return intruder_relative_state(s.lat, s.lon, s.hdg, s.gs)
    return task.observe()


_SEPARATION = {
    SectorCRTask: (sc.INTRUSION_DISTANCE, None),
    MergeTask: (mg.INTRUSION_DISTANCE, None),
    HorizontalCRTask: (5.0, None),
    VerticalCRTask: (5.0, 1000 * 0.3048),
}


@pytest.mark.parametrize("task_class", [SectorCRTask, MergeTask, HorizontalCRTask, VerticalCRTask])
def test_task_geometry_equals_the_numpy_oracle_through_episodes(task_class: type) -> None:
    task = _task(task_class, 11)
    _assert_same(_task_observation(task), _oracle_observation(task), "reset")
    intrusion, vertical = _SEPARATION[task_class]
    rng = np.random.default_rng(3)
    ended = 0
    for step in range(160):
        res = task.step(rng.uniform(-1, 1, (N_ENVS, *task.action_spec.shape)))
        if task_class in (SectorCRTask, HorizontalCRTask):  # no state the reward changes is observed
            _assert_same(res.observation, _oracle_observation(task), f"step {step}")
        _assert_same(_task_observation(task), _oracle_observation(task), f"after step {step}")
        s = task.sim
        dist, los = task.ownship_separation()
        want_dist, want_los = oracle.kwik_separation(s.lat, s.lon, s.alt, s.active, intrusion, vertical)
        np.testing.assert_array_equal(dist, want_dist)
        np.testing.assert_array_equal(los, want_los)
        done = np.flatnonzero(res.terminated | res.truncated)
        if done.size:
            ended += done.size
            task.reset(done)
            _assert_same(_task_observation(task), _oracle_observation(task), f"reset at step {step}")
            # The observation of the reset episodes alone equals their rows of the full one.
            _assert_same(task.observe_envs(done), {k: v[done] for k, v in task.observe().items()}, f"reset rows at step {step}")
    assert ended > 0  # the comparison covered episode ends and resets


def _random_airspace(rng: np.random.Generator, n: int, m: int) -> tuple[np.ndarray, ...]:
    lat = 52.0 + rng.normal(0, 0.3, (n, m))
    lon = 4.0 + rng.normal(0, 0.3, (n, m))
    hdg = rng.uniform(-180, 360, (n, m))
    tas = rng.uniform(80, 250, (n, m))
    active = rng.uniform(size=(n, m)) < 0.8
    active[:, 0] = True
    return lat, lon, hdg, tas, active


def test_closest_intruders_keep_the_stable_order_of_ties_and_skip_empty_slots() -> None:
    rng = np.random.default_rng(0)
    lat, lon, hdg, tas, active = _random_airspace(rng, 200, 12)
    lat[:, 3] = lat[:, 5]  # two intruders at the same place: equal distances
    lon[:, 3] = lon[:, 5]
    active[:5, 1:9] = False  # fewer active intruders than observed ones in some airspaces
    own = np.empty((200, 4))
    out = np.empty((200, 7, 5))
    count = np.empty(200, np.int64)
    compiled.merge_observe(
        np.arange(200), np.zeros(200, np.int64), lat, lon, hdg, tas, active, np.full(200, 54.0), np.full(200, 4.7), mg.OBS_SCALES, own, out, count
    )
    # distances column: the numpy order (stable argsort, empty slots last) of kwikdist_matrix.
    d = ref_kwikdist_matrix(lat[:, :1], lon[:, :1], lat[:, 1:], lon[:, 1:])
    order = np.argsort(np.where(active[:, 1:], d, np.inf), axis=1, kind="stable")[:, :5]
    expected = np.take_along_axis(d, order, axis=1) / mg.OBS_SCALES[2]
    np.testing.assert_array_equal(out[:, 6], expected)
    np.testing.assert_array_equal(count, active[:, 1:].sum(axis=1))
    # The cases were exercised: equal distances, and fewer active intruders than observed ones.
    assert np.array_equal(d[:, 2], d[:, 4])
    assert (active[:5, 1:].sum(axis=1) < 5).all()


def _to_front(a: np.ndarray, own: np.ndarray) -> np.ndarray:
    """Each row of ``a`` (n, m) with slot ``own[e]`` moved to slot 0, the others in slot order."""
    m = a.shape[1]
    perm = np.array([[o, *[j for j in range(m) if j != o]] for o in own])
    return np.take_along_axis(a, perm, axis=1)


def test_functions_of_an_ownship_slot_equal_the_oracle_with_that_slot_moved_to_slot_0() -> None:
    """Any ownship slot sees the other slots in slot order, as the single-agent ownship sees slots 1.."""
    rng = np.random.default_rng(5)
    n, m = 60, 9
    lat, lon, hdg, tas, active = _random_airspace(rng, n, m)
    lat[:, 1:] = lat[:, :1] + rng.normal(0, 0.05, (n, m - 1))
    alt = rng.uniform(0, 3000, (n, m))
    gs = tas * 0.9
    own = rng.integers(0, m, n)
    active[np.arange(n), own] = True
    envs = np.arange(n)
    moved = SimpleNamespace(**{k: _to_front(v, own) for k, v in dict(lat=lat, lon=lon, hdg=hdg, tas=tas, active=active, alt=alt, gs=gs).items()})
    wlat, wlon = 52.0 + rng.normal(0, 0.3, n), 4.0 + rng.normal(0, 0.3, n)
    # SectorCR
    drift, feat, intr, cnt = np.empty(n), np.empty((n, 3)), np.empty((n, 7, sc.NUM_AC_STATE)), np.empty(n, np.int64)
    compiled.sector_observe(envs, own, lat, lon, hdg, tas, active, wlat, wlon, sc.FLAT_CENTER, sc.OBS_SCALES, drift, feat, intr, cnt)
    want = oracle.sector_observation(moved, wlat, wlon)
    got = sc.observation(SimpleNamespace(features=feat, intruders=intr))
    _assert_same(got, want, "sector")
    # Merge
    after = rng.uniform(size=n) < 0.5
    tlat, tlon = mg.target(after)
    feat, intr = np.empty((n, 4)), np.empty((n, 7, mg.NUM_AC_STATE))
    compiled.merge_observe(envs, own, lat, lon, hdg, tas, active, tlat, tlon, mg.OBS_SCALES, feat, intr, cnt)
    want = oracle.merge_observation(moved, after.astype(np.int64))
    got = mg.observation(SimpleNamespace(features=feat, intruders=intr, airspeed=tas[envs, own], after_faf=after))
    _assert_same(got, want, "merge")
    np.testing.assert_array_equal(cnt, moved.active[:, 1:].sum(axis=1))
    # Intruder geometry in slot order
    out = np.empty((5, n, m - 1))
    compiled.intruder_relative_state(envs, own, lat, lon, hdg, gs, active, False, out, cnt)
    want = oracle.intruder_relative_state(moved.lat, moved.lon, moved.hdg, moved.gs)
    _assert_same(dict(zip(want, out)), want, "intruders")
    # Kwik separation (the ownship's own slot is inf / False wherever it sits)
    for vertical in (np.nan, 300.0):
        dist, los = np.empty((n, m)), np.empty((n, m), bool)
        compiled.kwik_separation(envs, own, lat, lon, alt, active, 5.0, vertical, dist, los)
        want_d, want_l = oracle.kwik_separation(moved.lat, moved.lon, moved.alt, moved.active, 5.0, None if np.isnan(vertical) else vertical)
        np.testing.assert_array_equal(_to_front(dist, own), want_d)
        np.testing.assert_array_equal(_to_front(los, own), want_l)


def test_nearest_intruders_are_sorted_by_kwik_distance_with_empty_slots_last() -> None:
    rng = np.random.default_rng(6)
    n, m = 80, 7
    lat, lon, hdg, tas, active = _random_airspace(rng, n, m)
    own = rng.integers(0, m, n)
    active[np.arange(n), own] = True
    active[:10] = False
    active[np.arange(10), own[:10]] = True  # alone: every entry is padding
    out, cnt = np.empty((5, n, m - 1)), np.empty(n, np.int64)
    compiled.intruder_relative_state(np.arange(n), own, lat, lon, hdg, tas, active, True, out, cnt)
    d = ref_kwikdist(lat[np.arange(n), own][:, None], lon[np.arange(n), own][:, None], lat, lon)
    other = active.copy()
    other[np.arange(n), own] = False
    for e in range(n):
        k = int(cnt[e])
        assert k == other[e].sum()
        np.testing.assert_array_equal(out[0, e, :k], np.sort(d[e][other[e]]) * 1.852)
    assert (cnt[:10] == 0).all() and (cnt[10:] > 0).all()


def test_kwik_separation_matches_the_numpy_formula_with_and_without_vertical_margin() -> None:
    rng = np.random.default_rng(1)
    lat, lon, _, _, active = _random_airspace(rng, 50, 9)
    lat[:, 1:] = lat[:, :1] + rng.normal(0, 0.05, (50, 8))
    alt = rng.uniform(0, 3000, (50, 9))
    for vertical in (np.nan, 300.0):
        dist = np.empty((50, 9))
        los = np.empty((50, 9), bool)
        compiled.kwik_separation(np.arange(50), np.zeros(50, np.int64), lat, lon, alt, active, 5.0, vertical, dist, los)
        want_d, want_l = oracle.kwik_separation(lat, lon, alt, active, 5.0, None if np.isnan(vertical) else vertical)
        np.testing.assert_array_equal(dist, want_d)
        np.testing.assert_array_equal(los, want_l)
        assert los.any() and not los.all()


def test_ownship_in_polygons_matches_the_numpy_even_odd_test() -> None:
    rng = np.random.default_rng(2)
    n, k, v = 300, 4, 9
    poly_lat = 52.0 + rng.uniform(-0.5, 0.5, (n, k, v))
    poly_lon = 4.0 + rng.uniform(-0.5, 0.5, (n, k, v))  # self-intersecting too: even-odd rule
    nv = rng.integers(0, v + 1, (n, k))
    lat = 52.0 + rng.uniform(-0.5, 0.5, (n, 1))
    lon = 4.0 + rng.uniform(-0.5, 0.5, (n, 1))
    out = np.empty((n, k), bool)
    compiled.ownship_in_polygons(lat, lon, poly_lat, poly_lon, nv, out)
    np.testing.assert_array_equal(out, points_in_polygons(lat, lon, poly_lat, poly_lon, nv)[:, 0, :])
    assert out.any() and not out.all()
    # Any slot against its episode's first polygon.
    slots = np.empty(n, bool)
    compiled.slots_in_polygons(np.arange(n), np.zeros(n, np.int64), lat, lon, poly_lat[:, 0], poly_lon[:, 0], nv[:, 0], slots)
    np.testing.assert_array_equal(slots, out[:, 0])


def test_kwik_functions_equal_the_numpy_oracle_for_scalars_and_broadcast_arrays() -> None:
    from bluesky_gym.tasks import geometry
    from tests.oracle import geometry as oracle_geometry

    rng = np.random.default_rng(7)
    lat_a, lon_a = 52.0 + rng.normal(0, 1.0, (30, 1)), rng.uniform(-190, 190, (30, 1))  # longitudes across the date line too
    lat_b, lon_b = 52.0 + rng.normal(0, 1.0, (1, 8)), rng.uniform(-190, 190, (1, 8))
    for args in ((lat_a, lon_a, lat_b, lon_b), (52.1, 4.2, 53.3, 4.9), (lat_a[:, 0], lon_a[:, 0], 54.0, 4.7)):
        for name in ("ref_kwikdist",):
            got, want = getattr(geometry, name)(*args), getattr(oracle_geometry, name)(*args)
            np.testing.assert_array_equal(got, want, strict=True)
        for got, want in zip(geometry.ref_kwikqdrdist(*args), oracle_geometry.ref_kwikqdrdist(*args), strict=True):
            np.testing.assert_array_equal(got, want, strict=True)


@pytest.mark.parametrize("form", ["compiled", "python"])
def test_step_end_kernels_equal_the_numpy_oracle(form: str) -> None:
    """Truncation, the episode means, the KPIs and the -v1 clip, compiled and as plain Python, to the last bit."""
    k = {name: getattr(compiled, name) for name in ("truncation", "sample_means", "episode_kpis", "clip_to_bounds")}
    if form == "python":
        k = {name: python_form(fn) for name, fn in k.items()}
    rng = np.random.default_rng(9)
    n = 40
    steps = rng.integers(0, 12, n)
    terminated, cut = rng.uniform(size=n) < 0.3, rng.uniform(size=n) < 0.3
    got = np.empty(n, bool)
    k["truncation"](steps, 8, terminated, cut, got)
    want = oracle.truncation(steps, 8, terminated, cut)
    np.testing.assert_array_equal(got, want, strict=True)
    assert want.any() and (terminated & ((steps >= 8) | cut)).any()  # terminated ones at the limit or cut are not truncated

    total, count = rng.uniform(0, 30, n), rng.integers(0, 4, n)
    for empty in (0.0, np.nan):
        got_mean = np.empty(n)
        k["sample_means"](total, count, empty, got_mean)
        np.testing.assert_array_equal(got_mean, oracle.sample_means(total, count, empty), strict=True)
    assert (count == 0).any() and (count > 0).any()

    m = 5
    stats = (steps, rng.integers(0, 5, n), rng.integers(0, 5, n), np.where(rng.uniform(size=n) < 0.2, np.inf, rng.uniform(0, 9, n)),
             total, count, rng.uniform(0, 3e5, (n, m)), rng.uniform(0, 900, (n, m)), 5.0, 12)  # fmt: skip
    outs = [np.empty(n) for _ in range(7)]
    k["episode_kpis"](*stats, *outs)
    for got_kpi, want_kpi, key in zip(outs, oracle.episode_kpis(*stats), KPI_KEYS, strict=True):
        np.testing.assert_array_equal(got_kpi, want_kpi, err_msg=key, strict=True)

    # Signed zeros on a zero bound, values equal to a bound, NaN and infinities, beyond the bounds on both sides.
    special = np.array([-0.0, 0.0, -1.0, 1.0, np.nan, np.inf, -np.inf, -7.5, 7.5, 0.25])
    values = np.concatenate([np.tile(special, (3, 1)), rng.uniform(-3, 3, (20, special.size))])
    low = np.array([0.0, 0.0, -1.0, -1.0, -1.0, -2.0, -2.0, -4.0, -np.inf, -0.0])
    high = np.array([0.0, -0.0, 1.0, 1.0, 1.0, 2.0, 2.0, 50.0, 5.0, 0.0])
    clipped = np.empty_like(values)
    k["clip_to_bounds"](values, low, high, clipped)
    want_clip = oracle.clip_to_bounds(values, low, high)
    np.testing.assert_array_equal(clipped, want_clip, strict=True)
    np.testing.assert_array_equal(np.signbit(clipped), np.signbit(want_clip))  # the sign of every zero too
    k["clip_to_bounds"](values, low, high, values)  # in place
    np.testing.assert_array_equal(values, want_clip, strict=True)
