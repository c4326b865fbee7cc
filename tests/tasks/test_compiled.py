"""The compiled observation/reward geometry equals the numpy path to the last bit."""

from __future__ import annotations

import numpy as np
import pytest

from bluesky_gym.core import Simulator
from bluesky_gym.tasks import compiled
from bluesky_gym.tasks.horizontal_cr import HorizontalCRTask
from bluesky_gym.tasks.merge import MergeTask
from bluesky_gym.tasks.sector_cr import SectorCRTask
from tests.oracle.task_geometry import points_in_polygons, ref_kwikdist, ref_kwikdist_matrix

pytestmark = pytest.mark.skipif(not compiled.AVAILABLE, reason="numba (extra 'fast') not installed")

N_ENVS = 6


def _task(task_class: type, kernel: str, seed: int) -> object:
    probe = task_class(N_ENVS)
    sim = Simulator(N_ENVS, probe.sim.max_aircraft, dt=task_class.dt, max_waypoints=probe.sim.max_waypoints, kernel=kernel)
    task = task_class(N_ENVS, backend=sim)
    task.seed(task.all_envs, [np.random.default_rng(seed + i) for i in range(N_ENVS)])
    task.reset()
    return task


def _assert_same(a: dict, b: dict, what: str) -> None:
    assert a.keys() == b.keys()
    for k in a:
        np.testing.assert_array_equal(np.asarray(a[k]), np.asarray(b[k]), err_msg=f"{what}: {k}", strict=True)


# StaticObstacle and VerticalCR have one geometry path, compared with the oracles in their own test modules.
@pytest.mark.parametrize("task_class", [SectorCRTask, MergeTask, HorizontalCRTask])
def test_compiled_episodes_equal_numpy_episodes(task_class: type) -> None:
    ref, fast = _task(task_class, "numpy", 11), _task(task_class, "fused", 11)
    assert not ref.compiled and fast.compiled
    _assert_same(ref.observe(), fast.observe(), "reset")
    rng = np.random.default_rng(3)
    ended = 0
    for step in range(160):
        action = rng.uniform(-1, 1, (N_ENVS, *ref.action_spec.shape))
        ra, rb = ref.step(action), fast.step(action)
        _assert_same(ra.observation, rb.observation, f"step {step}")
        _assert_same(ra.info, rb.info, f"step {step} info")
        np.testing.assert_array_equal(ra.reward, rb.reward)
        np.testing.assert_array_equal(ra.terminated, rb.terminated)
        np.testing.assert_array_equal(ra.truncated, rb.truncated)
        done = np.flatnonzero(ra.terminated | ra.truncated)
        if done.size:
            ended += done.size
            ref.reset(done)
            fast.reset(done)
            _assert_same(ref.observe(), fast.observe(), f"reset at step {step}")
            # The observation of the reset episodes alone equals their rows of the full one.
            _assert_same(fast.observe_envs(done), {k: v[done] for k, v in ref.observe().items()}, f"reset rows at step {step}")
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
    from bluesky_gym.tasks.merge import _OBS_SCALES

    rng = np.random.default_rng(0)
    lat, lon, hdg, tas, active = _random_airspace(rng, 200, 12)
    lat[:, 3] = lat[:, 5]  # two intruders at the same place: equal distances
    lon[:, 3] = lon[:, 5]
    active[:5, 1:9] = False  # fewer active intruders than observed ones in some airspaces
    own = np.empty((200, 4))
    out = np.empty((200, 7, 5))
    compiled.merge_observe(np.arange(200), lat, lon, hdg, tas, active, np.full(200, 54.0), np.full(200, 4.7), _OBS_SCALES, own, out)
    # distances column: the numpy order (stable argsort, empty slots last) of kwikdist_matrix.
    d = ref_kwikdist_matrix(lat[:, :1], lon[:, :1], lat[:, 1:], lon[:, 1:])
    order = np.argsort(np.where(active[:, 1:], d, np.inf), axis=1, kind="stable")[:, :5]
    expected = np.take_along_axis(d, order, axis=1) / _OBS_SCALES[2]
    np.testing.assert_array_equal(out[:, 6], expected)
    # The cases were exercised: equal distances, and fewer active intruders than observed ones.
    assert np.array_equal(d[:, 2], d[:, 4])
    assert (active[:5, 1:].sum(axis=1) < 5).all()


def test_kwik_separation_matches_the_numpy_formula_with_and_without_vertical_margin() -> None:
    rng = np.random.default_rng(1)
    lat, lon, _, _, active = _random_airspace(rng, 50, 9)
    lat[:, 1:] = lat[:, :1] + rng.normal(0, 0.05, (50, 8))
    alt = rng.uniform(0, 3000, (50, 9))
    expected = np.where(active, ref_kwikdist(lat[:, :1], lon[:, :1], lat, lon), np.inf)
    expected[:, 0] = np.inf
    for vertical in (np.nan, 300.0):
        dist = np.empty((50, 9))
        los = np.empty((50, 9), bool)
        compiled.kwik_separation(lat, lon, alt, active, 5.0, vertical, dist, los)
        np.testing.assert_array_equal(dist, expected)
        want = expected < 5.0
        if not np.isnan(vertical):
            want &= np.abs(alt[:, :1] - alt) < vertical
        np.testing.assert_array_equal(los, want)
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


def test_polygon_counts_along_a_track_match_the_numpy_test() -> None:
    """The latitude-range shortcut of ownship_polygon_counts gives the full even-odd test's counts."""
    rng = np.random.default_rng(4)
    steps, n, k, v = 7, 120, 5, 8
    poly_lat = 52.0 + rng.uniform(-0.3, 0.3, (n, k, v))
    poly_lon = 4.0 + rng.uniform(-0.3, 0.3, (n, k, v))
    nv = rng.integers(0, v + 1, (n, k))
    track = np.empty((steps, 2, n, 1))
    track[:, 0] = 52.0 + rng.uniform(-0.4, 0.4, (steps, n, 1))
    track[:, 1] = 4.0 + rng.uniform(-0.4, 0.4, (steps, n, 1))
    track[0, 0, :, 0] = poly_lat[:, 0, 0]  # on a vertex's latitude: the range bounds themselves
    counts = np.empty((steps, n), np.int64)
    compiled.ownship_polygon_counts(track, poly_lat, poly_lon, nv, counts)
    for s in range(steps):
        inside = points_in_polygons(track[s, 0], track[s, 1], poly_lat, poly_lon, nv)[:, 0, :]
        np.testing.assert_array_equal(counts[s], inside.sum(axis=1), err_msg=f"step {s}")
    assert counts.any() and (counts == 0).any()
