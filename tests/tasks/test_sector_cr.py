"""SectorCREnv-v0 task: scenario generation, observation, reward, truncation and options (docs/environments-v0.md §5)."""

from __future__ import annotations

import functools
import math

import gymnasium as gym
import numpy as np
import pytest
from matplotlib.path import Path

import bluesky_gym
from bluesky_gym.environments.sector_cr.task import CENTER, SectorCRConfig, SectorCRTask
from bluesky_gym.tasks.geometry import initial_bearing, nm_to_latlon

from .conftest import NM, R_EARTH, seeded_task

_task = functools.partial(seeded_task, SectorCRTask)
COS_C = math.cos(math.radians(CENTER[0]))


def _latlon(north_nm: float, east_nm: float) -> tuple[float, float]:
    """Position at (north, east) NM from the sector centre in the reference's flat projection."""
    return CENTER[0] + north_nm / 60, CENTER[1] + east_nm / (60 * COS_C)


def _place(task: SectorCRTask, env: int, slot: int, north_nm: float, east_nm: float, hdg: float, tas: float) -> None:
    s = task.sim
    s.active[env, slot] = True
    s.lat[env, slot], s.lon[env, slot] = _latlon(north_nm, east_nm)
    s.hdg[env, slot] = hdg
    s.tas[env, slot] = tas


def _empty_scene(task: SectorCRTask, env: int = 0) -> None:
    """Deactivate every intruder of ``env``; the tests then place their own."""
    task.sim.active[env, 1:] = False


# --- options -----------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("options", "match"),
    [
        ({"ac_density_mode": "gaussian"}, "ac_density_mode"),
        ({"ac_density_mode": 1}, "ac_density_mode"),
        ({"ac_density_range": (0.007, 0.003)}, "ac_density_range"),
        ({"ac_density_range": (0.0, 0.003)}, "ac_density_range"),
        ({"ac_density_range": 0.005}, "ac_density_range"),
        ({"ac_density_range": (0.003, 0.005, 0.007)}, "ac_density_range"),
        ({"ac_density_range": (0.003, float("nan"))}, "ac_density_range"),
        ({"ac_density_mu": 0.0}, "ac_density_mu"),
        ({"ac_density_sigma": -0.001}, "ac_density_sigma"),
        ({"poly_area_range": (3750, 2400)}, "poly_area_range"),
        ({"poly_area_range": (3500, 3750)}, "poly_area_range"),
        ({"poly_area_range": (-1, 3750)}, "poly_area_range"),
        ({"ac_density_mu": 0.1, "ac_density_sigma": 0.02}, "at most"),
    ],
)
def test_invalid_options_raise(options: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        SectorCRTask.make_config(options)


def test_options_through_gym_make() -> None:
    bluesky_gym.register_envs()
    env = gym.make("SectorCREnv-v0", ac_density_mode="uniform", poly_area_range=[1000, 1500])
    cfg = env.unwrapped.config
    assert cfg.ac_density_mode == "uniform" and cfg.poly_area_range == (1000, 1500)
    env.reset(seed=1)
    assert 1000 <= env.unwrapped.task.poly_area[0] < 1500
    env.close()
    with pytest.raises(ValueError, match="ac_density_mode"):
        gym.make("SectorCREnv-v0", ac_density_mode="Normal")


def test_slots_cover_the_worst_case() -> None:
    # normal: density clipped at 0.005 + 5 * 0.001; uniform: at most 0.007; area < 3750 NM^2.
    assert SectorCRTask(1).sim.max_aircraft == math.ceil(0.010 * 3750) == 38
    assert SectorCRTask(1, SectorCRConfig(ac_density_mode="uniform")).sim.max_aircraft == math.ceil(0.007 * 3750)
    # A tiny sector still holds the minimum of 5 aircraft.
    assert SectorCRTask(1, SectorCRConfig(poly_area_range=(10, 20))).sim.max_aircraft == 5


# --- scenario generation ----------------------------------------------------------------------------
@pytest.mark.parametrize("mode", ["normal", "uniform"])
def test_scenarios_over_200_seeds(mode: str) -> None:
    n = 200
    task = _task(n, ac_density_mode=mode)
    s = task.sim
    radius = math.sqrt(3750 / math.pi)
    for e in range(n):
        nv = task.n_vertices[e]
        poly = task.poly_nm[e, :nv]
        # Convex polygon on the circle, sorted clockwise by bearing, area in range.
        np.testing.assert_allclose(np.hypot(poly[:, 0], poly[:, 1]), radius, rtol=1e-12)
        assert np.all(np.diff(np.arctan2(poly[:, 1], poly[:, 0])) > 0)
        x, y = poly[:, 0], poly[:, 1]
        area = 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))
        assert 2400 <= task.poly_area[e] < 3750
        assert task.poly_area[e] == pytest.approx(area, rel=1e-12)
        # Number of aircraft: max(ceil(density * area), 5); exactly those slots are active.
        num_ac = task.num_ac[e]
        density = min(task.density[e], 0.005 + 5 * 0.001) if mode == "normal" else task.density[e]
        assert num_ac == max(math.ceil(density * task.poly_area[e]), 5)
        assert np.array_equal(s.active[e], np.arange(s.max_aircraft) < num_ac)
        # Start points inside the sector (independent point-in-polygon test on lat/lon).
        path = Path(np.stack([task.poly_lat[e, :nv], task.poly_lon[e, :nv]], axis=1))
        assert path.contains_points(np.stack([s.lat[e, :num_ac], s.lon[e, :num_ac]], axis=1)).all()
        # Waypoints on the perimeter, in perimeter order from vertex 0.
        wpts = task.wpt_nm[e, :num_ac]
        p1, p2 = poly, np.roll(poly, -1, axis=0)
        seg = p2 - p1
        t = np.clip(np.einsum("wkj,kj->wk", wpts[:, None] - p1[None], seg) / np.sum(seg**2, axis=1), 0, 1)
        dist = np.linalg.norm(wpts[:, None] - (p1[None] + t[..., None] * seg[None]), axis=-1)
        edge = np.argmin(dist, axis=1)
        assert dist.min(axis=1).max() < 1e-9
        lengths = np.linalg.norm(seg, axis=1)
        position = np.concatenate(([0.0], np.cumsum(lengths)))[edge] + t[np.arange(num_ac), edge] * lengths[edge]
        assert np.all(np.diff(position) >= -1e-9)
        np.testing.assert_allclose(nm_to_latlon(CENTER, wpts), np.stack([task.wpt_lat[e, :num_ac], task.wpt_lon[e, :num_ac]], 1))
        # Everyone heads for its own waypoint by great-circle initial bearing, 350 m, CAS 150.
        hdg = initial_bearing(s.lat[e, :num_ac], s.lon[e, :num_ac], task.wpt_lat[e, :num_ac], task.wpt_lon[e, :num_ac])
        np.testing.assert_allclose(s.hdg[e, :num_ac], hdg, atol=1e-9)
        np.testing.assert_allclose(s.alt[e, :num_ac], 350.0)
        np.testing.assert_allclose(s.cas[e, :num_ac], 150.0, rtol=1e-12)
    if mode == "normal":
        assert abs(task.density.mean() - 0.005) < 3e-4
        assert abs(task.density.std() - 0.001) < 3e-4
    else:
        assert task.density.min() >= 0.003 and task.density.max() < 0.007
        assert task.density.std() == pytest.approx(0.004 / math.sqrt(12), rel=0.2)


def test_start_points_cover_the_sector() -> None:
    """Rejection sampling is uniform: the start points' mean is near the polygon's centroid."""
    task = _task(1, ac_density_range=(0.05, 0.05), ac_density_mode="uniform", poly_area_range=(2000, 3000))
    # ~100+ aircraft per episode; pool 30 episodes of the same polygon by resampling the start points.
    nv = task.n_vertices[0]
    poly = task.poly_nm[0, :nv]
    rng = np.random.default_rng(5)
    pts = np.concatenate([np.stack(task._sample_inside(np.array([0]), np.array([200]), [rng])[0], axis=1) for _ in range(30)])
    north = (pts[:, 0] - CENTER[0]) * 60
    east = (pts[:, 1] - CENTER[1]) * 60 * COS_C
    x, y = poly[:, 0], poly[:, 1]
    cross = x * np.roll(y, -1) - np.roll(x, -1) * y
    a = cross.sum() / 2
    cx, cy = ((x + np.roll(x, -1)) * cross).sum() / (6 * a), ((y + np.roll(y, -1)) * cross).sum() / (6 * a)
    assert abs(north.mean() - cx) < 0.5 and abs(east.mean() - cy) < 0.5


# --- observation -------------------------------------------------------------------------------
def test_observation_hand_built_and_sorted() -> None:
    task = _task(2, seeds=[3, 4])
    _empty_scene(task, 0)
    # Ownship 2 NM north of the centre, heading 60, TAS 162 m/s; its waypoint due east of it
    # (same latitude: kwik bearing exactly 90), so drift = -30 deg.
    _place(task, 0, 0, 2.0, 0.0, 60.0, 162.0)
    task.wpt_lat[0, 0], task.wpt_lon[0, 0] = _latlon(2.0, 20.0)
    # Intruders (slot: north, east offsets from the ownship [NM], hdg, tas), deliberately unsorted.
    intruders = {
        1: (6.0, 0.0, 180.0, 150.0),  # 6 NM
        2: (0.0, -3.0, 90.0, 140.0),  # 3 NM
        3: (10.0, 10.0, 0.0, 150.0),  # 14.1 NM (5th: not observed)
        4: (-4.0, 3.0, 270.0, 155.0),  # 5 NM
        5: (1.0, 0.0, 45.0, 150.0),  # 1 NM
    }
    for slot, (dn, de, hdg, tas) in intruders.items():
        _place(task, 0, slot, 2.0 + dn, de, hdg, tas)
    # An inactive slot right next to the ownship must be ignored.
    task.sim.lat[0, 6], task.sim.lon[0, 6] = _latlon(2.1, 0.0)
    obs = task.observe()
    order = [5, 2, 4, 1]
    vx_own, vy_own = 162.0 * math.cos(math.radians(60)), 162.0 * math.sin(math.radians(60))
    for k, slot in enumerate(order):
        dn, de, hdg, tas = intruders[slot]
        assert obs["x_r"][0, k] == pytest.approx(dn * NM / 13000, abs=1e-9)
        assert obs["y_r"][0, k] == pytest.approx(de * NM / 13000, abs=1e-9)
        assert obs["distances"][0, k] == pytest.approx((math.hypot(dn, de) * NM - 50000) / 15000, abs=1e-9)
        dvx = tas * math.cos(math.radians(hdg)) - vx_own
        dvy = tas * math.sin(math.radians(hdg)) - vy_own
        assert obs["vx_r"][0, k] == pytest.approx(dvx / 32, abs=1e-9)
        assert obs["vy_r"][0, k] == pytest.approx(dvy / 66, abs=1e-9)
        assert obs["cos(track)"][0, k] == pytest.approx(math.cos(math.atan2(dvy, dvx)), abs=1e-12)
        assert obs["sin(track)"][0, k] == pytest.approx(math.sin(math.atan2(dvy, dvx)), abs=1e-12)
    assert obs["cos(drift)"][0, 0] == pytest.approx(math.cos(math.radians(-30)), abs=1e-12)
    assert obs["sin(drift)"][0, 0] == pytest.approx(-0.5, abs=1e-12)
    # Airspeed (TAS - 150) / 6 = 2.0: outside the declared [-1, 1] bound, kept as in the reference.
    assert obs["airspeed"][0, 0] == pytest.approx(2.0)
    assert task.observation_spec["airspeed"].high == 1.0
    assert all(v.dtype == np.float64 and v.shape[0] == 2 for v in obs.values())


# --- reward ------------------------------------------------------------------------------------
def test_reward_drift_and_intrusions() -> None:
    task = _task(2, seeds=[8, 9])
    for e in range(2):
        _empty_scene(task, e)
        _place(task, e, 0, 0.0, 0.0, 60.0, 152.0)
        task.wpt_lat[e, 0], task.wpt_lon[e, 0] = _latlon(0.0, 20.0)  # due east: drift -30 deg
    s = task.sim
    # env 0: 3 NM and 4.9 NM kwik (inside 5 NM), 5.1 NM (outside); an inactive slot at 1 NM.
    for slot, d_nm in ((1, 3.0), (2, 4.9), (3, 5.1)):
        s.active[0, slot] = True
        s.lat[0, slot], s.lon[0, slot] = s.lat[0, 0] + math.degrees(d_nm * NM / R_EARTH), s.lon[0, 0]
    s.lat[0, 4], s.lon[0, 4] = s.lat[0, 0], s.lon[0, 0] + 0.01
    # env 1: nobody near.
    g = task.measure()
    obs = task.observe(g)
    assert obs["cos(drift)"][:, 0] == pytest.approx(math.cos(math.radians(30)))
    reward, terminated, comp = task.reward(g)
    drift = -0.1 * math.radians(30)
    np.testing.assert_allclose(comp["drift"], drift, rtol=1e-12)
    np.testing.assert_array_equal(comp["intrusion"], [-2.0, 0.0])
    np.testing.assert_allclose(reward, [drift - 2.0, drift], rtol=1e-12)
    assert not terminated.any() and terminated.dtype == bool
    np.testing.assert_array_equal(task.total_intrusions, [2, 0])
    info = task.episode_info()
    np.testing.assert_allclose(info["average_drift"], math.radians(30), rtol=1e-12)
    dist, los = task.ownship_separation()
    assert np.isinf(dist[0, 0]) and np.isinf(dist[0, 4]) and los[0].sum() == 2 and not los[1].any()


def test_info_and_drift_over_an_episode() -> None:
    bluesky_gym.register_envs()
    env = gym.make("SectorCREnv-v0")
    obs, info = env.reset(seed=12)
    assert info["average_drift"] == 0.0 and info["total_intrusions"] == 0  # a number at reset (reference: NaN)
    drifts = []
    rng = np.random.default_rng(0)
    for _ in range(30):
        obs, r, te, tr, info = env.step(rng.uniform(-1, 1, 2))
        drift = abs(math.atan2(obs["sin(drift)"][0], obs["cos(drift)"][0]))
        drifts.append(drift)
        assert info["reward_drift"] == pytest.approx(-0.1 * drift, abs=1e-12)
        assert r == pytest.approx(info["reward_drift"] + info["reward_intrusion"], abs=1e-12)
        assert te is False
        if tr:
            break
    assert info["average_drift"] == pytest.approx(np.mean(drifts), abs=1e-12)
    env.close()


# --- action ------------------------------------------------------------------------------------
def test_action_mapping_uses_mps_speed_step() -> None:
    task = _task(2, seeds=[1, 2])
    s = task.sim
    s.hdg[:, 0] = [170.0, 10.0]
    cas = s.cas[:, 0].copy()
    task.apply_action(np.array([[1.0, 1.0], [-1.0, -0.5]]))
    np.testing.assert_allclose(s.ap_trk[:, 0], [192.5 - 360, -12.5])  # wrap180(hdg + 22.5 a0)
    # SPD (CAS + 20/3 a1) * 1.94384 kt, converted back with 0.514444 m/s per kt.
    expected = (cas + np.array([1.0, -0.5]) * 20 / 3) * 1.94384 * 0.514444
    np.testing.assert_array_equal(s.selspd[:, 0], expected)
    assert abs(s.selspd[0, 0] - cas[0] - 6.6666) < 1e-3  # +6.67 m/s, not 6.67 kt


# --- truncation ----------------------------------------------------------------------------------
def test_truncated_when_leaving_the_sector() -> None:
    bluesky_gym.register_envs()
    env = gym.make("SectorCREnv-v0").unwrapped
    env.reset(seed=5)
    s = env.task.sim
    # The centre is inside any sector of >= 2400 NM^2 on a 3750 NM^2 circle (more than half of it).
    s.lat[0, 0], s.lon[0, 0] = CENTER
    _, _, te, tr, info = env.step(np.zeros(2))
    assert te is False and tr is False
    s.lat[0, 0] = CENTER[0] + 1.0  # 60 NM north: outside the 34.5 NM circle
    _, _, te, tr, info = env.step(np.zeros(2))
    assert te is False and tr is True
    assert "kpi_los_count" in info and "kpi_success" not in info
    with pytest.raises(RuntimeError, match="ended"):
        env.step(np.zeros(2))
    env.reset(seed=5)  # a clean new episode inside its sector
    assert env.task.agent_inside()[0]


def test_inside_test_matches_an_independent_polygon_test() -> None:
    n = 16
    task = _task(n)
    rng = np.random.default_rng(3)
    s = task.sim
    north = rng.uniform(-40, 40, n)
    east = rng.uniform(-40, 40, n)
    s.lat[:, 0], s.lon[:, 0] = _latlon(north, east)
    expected = np.array(
        [
            Path(np.stack([task.poly_lat[e, : task.n_vertices[e]], task.poly_lon[e, : task.n_vertices[e]]], 1)).contains_point(
                (s.lat[e, 0], s.lon[e, 0])
            )
            for e in range(n)
        ]
    )
    assert 0 < expected.sum() < n
    np.testing.assert_array_equal(task.truncate(task.measure()), ~expected)


def test_vector_env_resets_truncated_episodes() -> None:
    bluesky_gym.register_envs()
    venv = gym.make_vec("SectorCREnv-v0", num_envs=2, vectorization_mode="vector_entry_point")
    venv.reset(seed=0)
    task = venv.unwrapped.task
    task.sim.lat[1, 0] = CENTER[0] + 1.0
    obs, r, te, tr, info = venv.step(np.zeros((2, 2)))
    np.testing.assert_array_equal(tr, [False, True])
    assert not te.any()
    assert task.agent_inside().all() and task.stats.steps[1] == 0
    venv.close()
