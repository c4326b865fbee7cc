"""MergeEnv-v0 task: scenario generation, LNAV intruders, FAF logic, observation, reward (docs/environments-v0.md §7)."""

from __future__ import annotations

import functools
import math

import gymnasium as gym
import numpy as np
import pytest

import bluesky_gym
from bluesky_gym.core import geo
from bluesky_gym.environments.merge.task import FAF_LAT, FAF_LON, RWY_LAT, RWY_LON, MergeConfig, MergeTask
from bluesky_gym.tasks.geometry import initial_bearing

from .conftest import NM, R_EARTH, seeded_task

_task = functools.partial(seeded_task, MergeTask)


def _haversine_km(lat1, lon1, lat2, lon2):
    p1, p2 = np.radians(lat1), np.radians(lat2)
    dp, dl = p2 - p1, np.radians(np.asarray(lon2) - lon1)
    a = np.sin(dp / 2) ** 2 + np.cos(p1) * np.cos(p2) * np.sin(dl / 2) ** 2
    return 2 * R_EARTH / 1000 * np.arcsin(np.sqrt(a))


def _wrap(a):
    return (np.asarray(a) + 180) % 360 - 180


def _north_of(lat: float, dist_nm: float) -> float:
    """Latitude dist_nm north of lat in the kwik metric."""
    return lat + math.degrees(dist_nm * NM / R_EARTH)


def _east_of(lat: float, lon: float, dist_nm: float) -> float:
    return lon + math.degrees(dist_nm * NM / (R_EARTH * math.cos(math.radians(lat))))


def _clear_traffic(task: MergeTask) -> None:
    """Move every intruder ~300 NM east of the FAF (no intrusions, never observed as close)."""
    s = task.sim
    s.lat[:, 1:] = FAF_LAT
    s.lon[:, 1:] = _east_of(FAF_LAT, FAF_LON, 300.0) + 0.01 * np.arange(1, s.max_aircraft)


def _place_ownship(task: MergeTask, lat: float, lon: float, hdg: float) -> None:
    s = task.sim
    s.lat[:, 0], s.lon[:, 0] = lat, lon
    s.hdg[:, 0] = s.trk[:, 0] = s.ap_trk[:, 0] = hdg


# --- constants and options -----------------------------------------------------------------------
def test_faf_is_200_km_north_of_the_runway() -> None:
    assert FAF_LAT == pytest.approx(54.161036, abs=1e-6) and FAF_LON == RWY_LON
    assert geo.kwikdist(FAF_LAT, FAF_LON, RWY_LAT, RWY_LON) == pytest.approx(200000 / 1852, rel=1e-9)


@pytest.mark.parametrize(
    ("options", "match"),
    [
        ({"num_aircraft": 5}, "num_aircraft"),
        ({"num_aircraft": 20.0}, "num_aircraft"),
        ({"num_aircraft": 1000}, "num_aircraft"),
        ({"spawn_distance_km": (200.0, 50.0)}, "spawn_distance_km"),
        ({"spawn_distance_km": (-1.0, 50.0)}, "spawn_distance_km"),
        ({"spawn_distance_km": 100.0}, "spawn_distance_km"),
        ({"intruder_distance_km": (20.0, float("inf"))}, "intruder_distance_km"),
        ({"spawn_bearing_deg": -1.0}, "spawn_bearing_deg"),
        ({"spawn_bearing_deg": 181.0}, "spawn_bearing_deg"),
        ({"ac_speed": 0.8}, "ac_speed"),
        ({"ac_speed": 200.0}, "ac_speed"),
        ({"altitude": 0.0}, "altitude"),
        ({"altitude": 12000.0}, "altitude"),
    ],
)
def test_invalid_options_raise(options: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        MergeTask.make_config(options)


def test_options_through_gym_make() -> None:
    bluesky_gym.register_envs()
    env = gym.make("MergeEnv-v0", num_aircraft=8, spawn_distance_km=[60, 70], ac_speed=150.0)
    obs, _ = env.reset(seed=0)
    task = env.unwrapped.task
    assert task.config.spawn_distance_km == (60, 70) and task.sim.max_aircraft == 8
    assert obs["x_r"].shape == (5,)
    assert 60 <= _haversine_km(FAF_LAT, FAF_LON, task.sim.lat[0, 0], task.sim.lon[0, 0]) <= 70
    env.close()
    assert MergeConfig().num_aircraft == 20


# --- scenario generation ----------------------------------------------------------------------------
def test_scenarios_over_200_seeds() -> None:
    n = 200
    task = _task(n)
    s = task.sim
    assert s.active.all() and s.max_aircraft == 20
    d = _haversine_km(FAF_LAT, FAF_LON, s.lat, s.lon)
    b = _wrap(initial_bearing(FAF_LAT, FAF_LON, s.lat, s.lon))
    assert d[:, 0].min() >= 50 - 1e-6 and d[:, 0].max() <= 200 + 1e-6
    assert d[:, 1:].min() >= 20 - 1e-6 and d[:, 1:].max() <= 500 + 1e-6
    assert d[:, 0].max() > 190 and d[:, 0].min() < 60 and d[:, 1:].min() < 25 and d[:, 1:].max() > 490
    assert np.abs(b).max() <= 15 + 1e-9 and np.abs(b).max() > 14.5
    # Heading b - 180 (stored unwrapped, pointing back at the FAF), 10000 m, CAS 100 m/s.
    np.testing.assert_allclose(s.hdg + 180, b, atol=1e-9)
    assert (s.hdg < -150).all()
    np.testing.assert_allclose(s.alt, 10000.0)
    np.testing.assert_allclose(s.cas, 100.0, rtol=1e-12)
    # Intruders fly LNAV: FAF, then the runway as destination; the ownship has no route.
    assert not s.swlnav[:, 0].any() and (s.nwp[:, 0] == 0).all()
    assert s.swlnav[:, 1:].all() and (s.nwp[:, 1:] == 2).all() and (s.iactwp[:, 1:] == 0).all()
    assert not s.swvnav.any()
    # Stored as BlueSky's route stores positions: (lat + 90) % 180 - 90, (lon + 180) % 360 - 180.
    np.testing.assert_array_equal(s.route_lat[:, 1:, 0], (FAF_LAT + 90.0) % 180.0 - 90.0)
    np.testing.assert_array_equal(s.route_lon[:, 1:, 0], (FAF_LON + 180.0) % 360.0 - 180.0)
    np.testing.assert_array_equal(s.route_lat[:, 1:, 1], (RWY_LAT + 90.0) % 180.0 - 90.0)
    np.testing.assert_array_equal(s.route_lon[:, 1:, 1], (RWY_LON + 180.0) % 360.0 - 180.0)
    np.testing.assert_array_equal(s.actwp_lat[:, 1:], (FAF_LAT + 90.0) % 180.0 - 90.0)


def test_intruders_follow_lnav_to_the_faf_then_the_runway() -> None:
    task = _task(4, seeds=[3, 4, 5, 6])
    s = task.sim
    qdr0, dist0 = geo.qdrdist(s.lat[:, 1:], s.lon[:, 1:], FAF_LAT, FAF_LON)
    # Created on heading b - 180, which differs from the great-circle course to the FAF.
    assert np.abs(_wrap(s.hdg[:, 1:] - qdr0)).max() > 0.5
    zero = np.zeros((4, 2))
    for _ in range(4):
        task.step(zero)
    qdr, dist = geo.qdrdist(s.lat[:, 1:], s.lon[:, 1:], FAF_LAT, FAF_LON)
    before = s.iactwp[:, 1:] == 0
    assert before.sum() > 60
    assert np.abs(_wrap(s.trk[:, 1:] - qdr))[before].max() < 0.02
    assert (dist < dist0)[before].all()
    # Later, intruders that passed the FAF turn towards the runway (due south).
    for _ in range(36):
        task.step(zero)
    after = s.iactwp[:, 1:] == 1
    assert after.sum() >= 5
    qdr_rwy, _ = geo.qdrdist(s.lat[:, 1:], s.lon[:, 1:], RWY_LAT, RWY_LON)
    active_leg = after & s.swlnav[:, 1:]
    assert np.abs(_wrap(s.trk[:, 1:] - qdr_rwy))[active_leg].max() < 0.1
    assert np.abs(_wrap(s.trk[:, 1:] - 180))[active_leg].max() < 1.0
    np.testing.assert_array_equal(s.alt, 10000.0)  # VNAV stays off: nobody descends


# --- FAF logic (one-step lag) ----------------------------------------------------------------------
def test_faf_flag_lags_one_step_and_goal_terminates() -> None:
    task = _task(1, seeds=[2])
    _clear_traffic(task)
    # 5 NM north of the FAF, heading south: within 10 NM at the next observation.
    _place_ownship(task, _north_of(FAF_LAT, 5.0), FAF_LON, 180.0)
    res = task.step(np.zeros((1, 2)))
    assert res.observation["faf_reached"][0, 0] == 0.0  # built before the reward set the flag
    assert res.observation["waypoint_dist"][0, 0] * 250 < 10  # distance to the FAF
    assert res.info["reward_reach"][0] == 1.0 and res.info["faf_reach"][0] == 1
    assert not res.terminated[0] and not res.truncated[0]
    res = task.step(np.zeros((1, 2)))
    assert res.observation["faf_reached"][0, 0] == 1.0
    rwy = geo.kwikdist(task.sim.lat[0, 0], task.sim.lon[0, 0], RWY_LAT, RWY_LON)
    assert res.observation["waypoint_dist"][0, 0] == pytest.approx(rwy / 250, rel=1e-12)  # now the runway
    assert res.info["reward_reach"][0] == 0.0 and res.info["faf_reach"][0] == 1 and not res.terminated[0]
    # Within 20 NM of the runway (after the FAF): terminated, faf_reach 2, success KPI.
    _place_ownship(task, _north_of(RWY_LAT, 22.0), RWY_LON, 180.0)  # ~4.5 NM per step
    res = task.step(np.zeros((1, 2)))
    assert res.observation["waypoint_dist"][0, 0] * 250 < 20
    assert res.terminated[0] and not res.truncated[0]
    assert res.info["faf_reach"][0] == 2 and res.info["reward_reach"][0] == 0.0
    assert res.observation["faf_reached"][0, 0] == 1.0  # the observed flag is 0/1 only
    assert res.info["kpi_success"][0] == 1.0 and res.info["kpi_time_to_goal_s"][0] == 3 * 50.0
    assert np.isfinite(res.info["kpi_extra_track_km"][0])


def test_runway_margin_does_not_count_before_the_faf() -> None:
    task = _task(1, seeds=[2])
    _clear_traffic(task)
    # 15 NM north of the runway but the FAF was never reached: no termination, FAF target kept.
    _place_ownship(task, _north_of(RWY_LAT, 15.0), RWY_LON, 0.0)
    res = task.step(np.zeros((1, 2)))
    assert not res.terminated[0] and res.info["faf_reach"][0] == 0
    faf = geo.kwikdist(task.sim.lat[0, 0], task.sim.lon[0, 0], FAF_LAT, FAF_LON)
    assert res.observation["waypoint_dist"][0, 0] == pytest.approx(faf / 250, rel=1e-12)


# --- reward and observation -------------------------------------------------------------------------
def test_reward_drift_and_intrusions_against_all_intruders() -> None:
    task = _task(2, seeds=[0, 1])
    _clear_traffic(task)
    lat0 = _north_of(FAF_LAT, 100.0)
    _place_ownship(task, lat0, FAF_LON, 200.0)  # the FAF is due south (qdr 180): drift 20 deg
    s = task.sim
    # env 0: intruders at 3 and 3.9 NM (inside 4 NM) in slots 7 and 19, one at 4.1 NM.
    for slot, d_nm in ((7, 3.0), (19, 3.9), (12, 4.1)):
        s.lat[0, slot], s.lon[0, slot] = _north_of(lat0, d_nm), FAF_LON
    g = task.measure()
    obs = task.observe(g)
    assert obs["sin(drift)"][:, 0] == pytest.approx(math.sin(math.radians(20)))
    reward, terminated, comp = task.reward(g)
    drift = -0.1 * math.radians(20)
    np.testing.assert_allclose(comp["drift"], drift, rtol=1e-12)
    np.testing.assert_array_equal(comp["intrusion"], [-2.0, 0.0])
    np.testing.assert_array_equal(comp["reach"], [0.0, 0.0])
    np.testing.assert_allclose(reward, [drift - 2.0, drift], rtol=1e-12)
    assert not terminated.any()
    np.testing.assert_array_equal(task.total_intrusions, [2, 0])
    dist, los = task.ownship_separation()
    assert np.isinf(dist[:, 0]).all() and los[0].sum() == 2 and not los[1].any()
    info = task.episode_info()
    np.testing.assert_allclose(info["average_drift"], math.radians(20), rtol=1e-12)


def test_observation_hand_built_and_sorted() -> None:
    task = _task(1, seeds=[4])
    _clear_traffic(task)
    lat0 = _north_of(FAF_LAT, 80.0)
    _place_ownship(task, lat0, FAF_LON, 170.0)
    s = task.sim
    s.tas[0, 0] = 170.0
    # (slot: offset north NM, offset east NM, hdg, tas), deliberately unsorted; all other
    # intruders are ~300 NM away.
    intruders = {
        9: (7.0, 0.0, 180.0, 160.0),
        2: (0.0, -2.0, 90.0, 150.0),
        15: (-4.0, 0.0, 0.0, 165.0),
        4: (0.0, 9.0, 270.0, 170.0),
        11: (1.0, 0.0, 200.0, 140.0),
        6: (0.0, 12.0, 180.0, 170.0),  # 6th closest: not observed
    }
    for slot, (dn, de, hdg, tas) in intruders.items():
        s.lat[0, slot] = _north_of(lat0, dn)
        s.lon[0, slot] = _east_of(lat0, FAF_LON, de)
        s.hdg[0, slot], s.tas[0, slot] = hdg, tas
    obs = task.observe()
    order = [11, 2, 15, 9, 4]
    vx_own, vy_own = 170.0 * math.cos(math.radians(170)), 170.0 * math.sin(math.radians(170))
    for k, slot in enumerate(order):
        dn, de, hdg, tas = intruders[slot]
        assert obs["distances"][0, k] == pytest.approx(math.hypot(dn, de) / 250, rel=1e-9)
        assert obs["x_r"][0, k] == pytest.approx(dn * NM / 1e6, abs=1e-12)
        assert obs["y_r"][0, k] == pytest.approx(de * NM / 1e6, abs=1e-12)
        dvx = tas * math.cos(math.radians(hdg)) - vx_own
        dvy = tas * math.sin(math.radians(hdg)) - vy_own
        assert obs["vx_r"][0, k] == pytest.approx(dvx / 150, abs=1e-12)
        assert obs["vy_r"][0, k] == pytest.approx(dvy / 150, abs=1e-12)
        assert obs["cos(track)"][0, k] == pytest.approx(math.cos(math.atan2(dvy, dvx)), abs=1e-12)
        assert obs["sin(track)"][0, k] == pytest.approx(math.sin(math.atan2(dvy, dvx)), abs=1e-12)
    assert obs["airspeed"][0, 0] == 170.0  # raw TAS
    assert obs["waypoint_dist"][0, 0] == pytest.approx(80.0 / 250, rel=1e-9)
    assert obs["cos(drift)"][0, 0] == pytest.approx(math.cos(math.radians(-10)), abs=1e-12)
    assert obs["sin(drift)"][0, 0] == pytest.approx(math.sin(math.radians(-10)), abs=1e-12)
    assert obs["faf_reached"][0, 0] == 0.0
    assert all(v.dtype == np.float64 for v in obs.values())


def test_action_mapping() -> None:
    task = _task(2, seeds=[1, 2])
    s = task.sim
    s.hdg[:, 0] = [-170.0, 175.0]  # the ownship starts with an unwrapped heading b - 180
    cas = s.cas[:, 0].copy()
    task.apply_action(np.array([[-1.0, 1.0], [1.0, -0.25]]))
    np.testing.assert_allclose(s.ap_trk[:, 0], [175.0, -170.0])  # wrap180(hdg + 15 a0)
    expected = (cas + np.array([1.0, -0.25]) * 20) * 1.94384 * 0.514444
    np.testing.assert_array_equal(s.selspd[:, 0], expected)


def test_info_at_reset_and_episode_end() -> None:
    bluesky_gym.register_envs()
    env = gym.make("MergeEnv-v0")
    obs, info = env.reset(seed=0)
    assert info == {"total_reward": 0.0, "faf_reach": 0, "average_drift": 0.0, "total_intrusions": 0}
    assert obs["faf_reached"].dtype == np.float64
    env.close()
