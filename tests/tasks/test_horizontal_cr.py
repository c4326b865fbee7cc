"""HorizontalCREnv-v0 task: reward, observation, one-step lag, scenario generation and options
(docs/environments-v0.md §3)."""

from __future__ import annotations

import functools

import gymnasium as gym
import numpy as np
import pytest

import bluesky_gym
from bluesky_gym.environments.horizontal_cr.task import HorizontalCRConfig, HorizontalCRTask
from tests.oracle import tasks as oracle

from .conftest import NM, R_EARTH, east_of, north_of, seeded_task

_task = functools.partial(seeded_task, HorizontalCRTask)


def _hand_built(task: HorizontalCRTask, wpt_north_m: float, hdg: float = 0.0) -> None:
    """Ownship at 52N 4E with heading ``hdg``, waypoint due north, intruders 60 km east."""
    s = task.sim
    s.lat[:, 0], s.lon[:, 0], s.hdg[:, 0] = 52.0, 4.0, hdg
    s.lat[:, 1:], s.lon[:, 1:] = 52.0, east_of(52.0, 4.0, 60_000.0)
    task.wpt_lat[:], task.wpt_lon[:] = north_of(52.0, wpt_north_m), 4.0


# --- reward ----------------------------------------------------------------------------------------
def test_command_reward_info_and_extra_track_equal_the_numpy_oracle_through_episodes() -> None:
    """The task's kernels (heading command, reward, episode sums, extra track) give the readable numpy forms' bits."""
    task = _task(6, waypoint_distance_min=12, waypoint_distance_max=30, tlosh_min=10, tlosh_max=200)
    rng = np.random.default_rng(5)
    sums, counts, intrusions = np.zeros(6), np.zeros(6, np.int64), np.zeros(6, np.int64)
    reached_any = ended = intruded = 0
    for step in range(40):
        heading_before, reached = task.ac_hdg.copy(), task.wpt_reach.copy()
        a = rng.uniform(-1, 1, (6, 1))
        res = task.step(a)
        np.testing.assert_array_equal(task.sim.ap_trk[:, 0], heading_before + a[:, 0] * 45.0, err_msg=f"step {step}: HDG")
        reward, count, components, abs_drift = oracle.horizontal_cr_reward(task.sim, task.wpt_lat, task.wpt_lon, reached)
        np.testing.assert_array_equal(res.reward, reward, err_msg=f"step {step}: reward", strict=True)
        for key, value in components.items():
            np.testing.assert_array_equal(res.info[f"reward_{key}"], value, err_msg=f"step {step}: {key}", strict=True)
        goal = reached | (components["reach"] > 0)
        np.testing.assert_array_equal(res.terminated, goal, err_msg=f"step {step}: terminated")
        np.testing.assert_array_equal(task.wpt_reach, goal, err_msg=f"step {step}: the reach flag")
        sums += abs_drift
        counts += 1
        intrusions += count
        np.testing.assert_array_equal(res.info["total_intrusions"], intrusions, err_msg=f"step {step}: total_intrusions", strict=True)
        np.testing.assert_array_equal(res.info["average_drift"], oracle.sample_means(sums, counts, 0.0), err_msg=f"step {step}")
        done = np.flatnonzero(res.terminated | res.truncated)
        reached_any += int(res.terminated.sum())
        intruded += int((count > 0).sum())
        if done.size:
            ended += done.size
            want = oracle.horizontal_cr_extra_track(task.sim.distflown, task.start_wpt_dist_km)
            np.testing.assert_array_equal(res.info["kpi_extra_track_km"], want, err_msg=f"step {step}: extra track", strict=True)
            task.reset(done)
            sums[done], counts[done], intrusions[done] = 0.0, 0, 0
    assert reached_any >= 2 and intruded >= 2 and ended >= 2  # the comparison covered waypoints reached, intrusions, ends and resets


def test_reward_drift_intrusion_and_reach() -> None:
    task = _task(3)
    _hand_built(task, wpt_north_m=50_000.0, hdg=30.0)
    s = task.sim
    s.lat[1, 2], s.lon[1, 2] = north_of(52.0, 4 * NM), 4.0  # env 1: one intruder at 4 NM
    s.lat[1, 4], s.lon[1, 4] = 52.0, east_of(52.0, 4.0, 6 * NM)  # and one at 6 NM (no intrusion)
    s.lat[2, 1], s.lon[2, 1] = north_of(52.0, 1 * NM), 4.0  # env 2: two intruders within 5 NM
    s.lat[2, 3], s.lon[2, 3] = 52.0, east_of(52.0, 4.0, -3 * NM)
    task.wpt_lat[2] = north_of(52.0, 4_000.0)  # and the waypoint within 5 km
    g = task.measure()
    task.observe(g)
    reward, terminated, comp = task.reward(g)
    drift = -0.1 * np.radians(30.0)
    np.testing.assert_allclose(comp["drift"], drift, rtol=1e-9)
    np.testing.assert_array_equal(comp["intrusion"], [0.0, -1.0, -2.0])
    np.testing.assert_array_equal(comp["reach"], [0.0, 0.0, 1.0])
    np.testing.assert_allclose(reward, [drift, drift - 1.0, 1.0 + drift - 2.0], rtol=1e-9)
    assert terminated.dtype == bool and terminated.tolist() == [False, False, True]
    np.testing.assert_array_equal(task.total_intrusions, [0, 1, 2])
    # The reach reward is paid once; the episode stays terminated.
    reward2, terminated2, comp2 = task.reward(task.measure())
    assert comp2["reach"][2] == 0.0 and terminated2[2]
    info = task.episode_info()
    np.testing.assert_allclose(info["average_drift"], np.radians(30.0), rtol=1e-12)
    np.testing.assert_array_equal(info["total_intrusions"], [0, 2, 4])


def test_average_drift_is_zero_at_reset_then_the_mean_abs_drift_in_radians() -> None:
    task = _task(2)
    info = task.episode_info()
    assert set(info) == {"total_reward", "total_intrusions", "average_drift"}
    np.testing.assert_array_equal(info["average_drift"], [0.0, 0.0])  # the reference gives NaN here
    _hand_built(task, wpt_north_m=80_000.0, hdg=20.0)
    task.reward(task.measure())
    task.sim.hdg[:, 0] = 340.0  # drift -20
    task.reward(task.measure())
    task.sim.hdg[:, 0] = 90.0  # drift 90
    task.reward(task.measure())
    np.testing.assert_allclose(task.episode_info()["average_drift"], np.radians((20 + 20 + 90) / 3), rtol=1e-12)


# --- one-step lag ----------------------------------------------------------------------------------
def test_reach_flag_is_updated_after_the_observation() -> None:
    task = _task(1)
    _hand_built(task, wpt_north_m=3_000.0)
    g = task.measure()
    obs = task.observe(g)
    assert obs["waypoint_distance"][0, 0] * 150 < 5.0
    assert not task.wpt_reach[0]  # observe() does not set it
    reward, terminated, _ = task.reward(g)
    assert task.wpt_reach[0] and terminated[0] and reward[0] > 0.5


def test_reach_is_decided_on_the_returned_observation_within_the_step() -> None:
    task = _task(1)
    # 89 m/s for 50 s covers ~4.45 km: from 8.5 km the waypoint is inside 5 km after one step.
    task.step(np.zeros((1, 1)))  # let the ownship settle at 89 m/s
    s = task.sim
    task.wpt_lat[0], task.wpt_lon[0] = north_of(s.lat[0, 0], 8_500.0), s.lon[0, 0]
    s.hdg[0, 0] = 0.0
    task.observe()
    res = task.step(np.zeros((1, 1)))
    assert res.observation["waypoint_distance"][0, 0] * 150 < 5.0
    assert res.terminated[0] and res.info["reward_reach"][0] == 1.0


def test_heading_command_uses_the_heading_of_the_last_observation() -> None:
    task = _task(2)
    task.sim.hdg[:, 0] = [10.0, 350.0]
    task.observe()
    task.sim.hdg[:, 0] = [100.0, 100.0]  # state changes without a new observation
    task.apply_action(np.array([[0.5], [1.0]]))
    np.testing.assert_allclose(task.sim.ap_trk[:, 0], [10.0 + 22.5, 350.0 + 45.0])  # 395: not wrapped


# --- observation -----------------------------------------------------------------------------------
def test_observation_matches_hand_computed_geometry() -> None:
    task = _task(1)
    _hand_built(task, wpt_north_m=30_000.0, hdg=90.0)
    s = task.sim
    s.gs[0, 0] = 89.0
    # Intruder 1: 15 km due east, flying west at 80 m/s. Intruder 2: 45 km due north, flying north at 89 m/s.
    s.lat[0, 1], s.lon[0, 1], s.hdg[0, 1], s.gs[0, 1] = 52.0, east_of(52.0, 4.0, 15_000.0), 270.0, 80.0
    s.lat[0, 2], s.lon[0, 2], s.hdg[0, 2], s.gs[0, 2] = north_of(52.0, 45_000.0), 4.0, 0.0, 89.0
    obs = task.observe()
    assert set(obs) == {
        "intruder_distance",
        "cos_difference_pos",
        "sin_difference_pos",
        "x_difference_speed",
        "y_difference_speed",
        "waypoint_distance",
        "cos_drift",
        "sin_drift",
    }
    assert all(v.dtype == np.float64 for v in obs.values())
    np.testing.assert_allclose(obs["intruder_distance"][0, :2], [15 / 150, 45 / 150], rtol=1e-9)
    # wrap180(hdg - qdr): heading east, intruder east -> 0; intruder north -> 90 (to the left).
    np.testing.assert_allclose(obs["cos_difference_pos"][0, :2], [1.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(obs["sin_difference_pos"][0, :2], [0.0, 1.0], atol=1e-9)
    # x = -cos(hdg_own - hdg_int) gs_int / 150; y = (gs_own - sin(hdg_own - hdg_int) gs_int) / 150.
    np.testing.assert_allclose(obs["x_difference_speed"][0, :2], [80 / 150, 0.0], atol=1e-12)
    np.testing.assert_allclose(obs["y_difference_speed"][0, :2], [89 / 150, 0.0], atol=1e-12)
    np.testing.assert_allclose(obs["waypoint_distance"][0], [30 / 150], rtol=1e-9)
    np.testing.assert_allclose(obs["cos_drift"][0], [0.0], atol=1e-9)  # drift = wrap180(90 - 0) = 90
    np.testing.assert_allclose(obs["sin_drift"][0], [1.0], atol=1e-12)


# --- scenario generation ---------------------------------------------------------------------------
def test_generation_ranges_over_200_seeds() -> None:
    n = 200
    task = _task(n)
    s = task.sim
    assert s.active.shape == (n, 6) and s.active.all()
    for arr, lo, hi in ((task.conflict_dpsi, 45, 314), (task.conflict_dcpa, 0, 4), (task.conflict_tlosh, 100, 999)):
        assert np.all(arr == np.round(arr)) and arr.min() >= lo and arr.max() <= hi
        assert arr.min() <= lo + (hi - lo) // 10 and arr.max() >= hi - (hi - lo) // 10  # the range is used
    d = task.wpt_distance_drawn
    assert np.all(d == np.round(d)) and d.min() == 100 and d.max() == 149
    # Ownship and intruders at 52N 4E / altitude 0 (ground phase), ownship heading north.
    assert np.all(s.alt == 0.0) and np.all(s.hdg[:, 0] == 0.0)
    assert np.all(s.lat[:, 0] == 52.0) and np.all(s.lon[:, 0] == 4.0)
    # Waypoint due north on the great circle at the drawn distance; initial drift 0.
    np.testing.assert_array_equal(task.wpt_lon, 4.0)
    np.testing.assert_allclose(task.wpt_lat, 52.0 + np.degrees(d / 6371.0), rtol=0, atol=1e-12)
    assert np.all(task.waypoint_geometry()[1] == 0.0)
    # Intruders: track offset dpsi, ownship ground speed (150 m/s at creation), CPA at dcpa.
    np.testing.assert_allclose(((s.hdg[:, 1:] - task.conflict_dpsi) + 180) % 360 - 180, 0.0, atol=1e-9)
    np.testing.assert_allclose(s.gs[:, 1:], 150.0, rtol=1e-6)
    dn = np.radians(s.lat[:, 1:] - 52.0) * R_EARTH
    de = np.radians(s.lon[:, 1:] - 4.0) * R_EARTH * np.cos(np.radians(52.0))
    vn = s.gs[:, 1:] * np.cos(np.radians(s.hdg[:, 1:])) - 150.0
    ve = s.gs[:, 1:] * np.sin(np.radians(s.hdg[:, 1:]))
    tcpa = -(dn * vn + de * ve) / (vn**2 + ve**2)
    np.testing.assert_allclose(np.hypot(dn + vn * tcpa, de + ve * tcpa), task.conflict_dcpa * NM, rtol=0.01, atol=60.0)
    assert np.all(tcpa > task.conflict_tlosh)


def test_draw_order_is_the_reference_order() -> None:
    """(dpsi, dcpa, tlosh) per intruder, then the waypoint distance, from the episode generator."""
    for seed in (1, 8, 99):
        task = _task(1, seeds=[seed])
        rng = np.random.default_rng(seed)
        for i in range(5):
            draws = (rng.integers(45, 315), rng.integers(0, 5), rng.integers(100, 1000))
            assert (task.conflict_dpsi[0, i], task.conflict_dcpa[0, i], task.conflict_tlosh[0, i]) == draws
        assert task.wpt_distance_drawn[0] == rng.integers(100, 150)


def test_ground_phase_speed_of_89_mps() -> None:
    """Created at altitude 0 the aircraft are in OpenAP's ground phase and slow to 89 m/s (kept)."""
    task = _task(3)
    task.step(np.zeros((3, 1)))
    np.testing.assert_allclose(task.sim.tas, 89.0, atol=1e-6)
    assert np.all(task.sim.alt == 0.0)


# --- options and spaces ----------------------------------------------------------------------------
def test_defaults_are_the_reference() -> None:
    c = HorizontalCRConfig()
    assert (c.num_intruders, c.dpsi_min, c.dpsi_max, c.dcpa_min, c.dcpa_max) == (5, 45, 315, 0, 5)
    assert (c.tlosh_min, c.tlosh_max, c.waypoint_distance_min, c.waypoint_distance_max) == (100, 1000, 100, 150)


@pytest.mark.parametrize(
    ("options", "match"),
    [
        ({"num_intruders": 0}, "num_intruders"),
        ({"num_intruders": 51}, "num_intruders"),
        ({"num_intruders": True}, "num_intruders must be an integer"),
        ({"dpsi_max": 30}, "dpsi_max"),
        ({"dpsi_max": 361}, "dpsi_max"),
        ({"dcpa_min": -2}, "dcpa_min"),
        ({"dcpa_max": 0}, "dcpa_max"),
        ({"tlosh_min": 0}, "tlosh_min"),
        ({"tlosh_max": 100}, "tlosh_max"),
        ({"waypoint_distance_min": 5}, "waypoint_distance_min"),
        ({"waypoint_distance_max": 100}, "waypoint_distance_max"),
        ({"waypoint_distance_max": 120.5}, "waypoint_distance_max must be an integer"),
    ],
)
def test_invalid_options_raise(options: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        HorizontalCRTask.make_config(options)


def test_options_change_the_scenario_and_the_spaces() -> None:
    bluesky_gym.register_envs()
    env = gym.make("HorizontalCREnv-v0", num_intruders=2, waypoint_distance_min=40, waypoint_distance_max=41, tlosh_min=500, tlosh_max=501)
    obs, info = env.reset(seed=4)
    assert obs["cos_difference_pos"].shape == (2,) and env.observation_space["x_difference_speed"].shape == (2,)
    assert info["average_drift"] == 0.0
    task = env.unwrapped.task
    assert task.sim.max_aircraft == 3 and task.wpt_distance_drawn[0] == 40
    np.testing.assert_array_equal(task.conflict_tlosh[0], [500, 500])
    np.testing.assert_allclose(obs["waypoint_distance"], [40 / 150], rtol=2e-3)  # normalisation stays 150 km
    env.close()


# --- KPIs ------------------------------------------------------------------------------------------
def test_ownship_separation_drift_and_extra_track() -> None:
    task = _task(1)
    _hand_built(task, wpt_north_m=50_000.0, hdg=350.0)
    s = task.sim
    s.lat[0, 1], s.lon[0, 1] = north_of(52.0, 4.5 * NM), 4.0
    s.lat[0, 2], s.lon[0, 2] = 52.0, east_of(52.0, 4.0, 5.5 * NM)
    s.active[0, 4] = False
    dist, los = task.ownship_separation()
    assert dist[0, 0] == np.inf and dist[0, 4] == np.inf
    np.testing.assert_allclose(dist[0, 1:3], [4.5, 5.5], rtol=1e-9)
    assert los[0].tolist() == [False, True, False, False, False, False]
    np.testing.assert_allclose(task.measure().drift_deg, [-10.0], rtol=1e-9)
    s.distflown[0, 0] = 200_000.0
    np.testing.assert_allclose(task.extra_track_km(), 200.0 - (task.start_wpt_dist_km - 5.0))
