"""PlanWaypointEnv-v0: scenario, observation, reward, one-step lag and options (docs/environments-v0.md §4)."""

from __future__ import annotations

import functools
import itertools
import math

import gymnasium as gym
import numpy as np
import pytest

import bluesky_gym
from bluesky_gym.environments.plan_waypoint.env import PlanWaypointEnv
from bluesky_gym.environments.plan_waypoint.task import PlanWaypointConfig, PlanWaypointTask
from tests.oracle import plan_waypoint as oracle

from .conftest import R_KM, great_circle, kwik, seeded_task

bluesky_gym.register_envs()

_task = functools.partial(seeded_task, PlanWaypointTask)


def place_waypoint(task: PlanWaypointTask, e: int, i: int, north_km: float, east_km: float = 0.0) -> None:
    """Put waypoint i at a kwik offset from the aircraft (north/east km)."""
    lat0 = task.sim.lat[e, 0]
    task.wpt_lat[e, i] = lat0 + math.degrees(north_km / R_KM)
    task.wpt_lon[e, i] = task.sim.lon[e, 0] + math.degrees(east_km / R_KM) / math.cos(math.radians(0.5 * (lat0 + task.wpt_lat[e, i])))


# --- options ----------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "options, name",
    [
        ({"num_waypoints": 0}, "num_waypoints"),
        ({"num_waypoints": 9}, "num_waypoints"),
        ({"num_waypoints": 2.0}, "num_waypoints"),
        ({"num_waypoints": True}, "num_waypoints"),
        ({"waypoint_distance_min": -1}, "waypoint_distance_min"),
        ({"waypoint_distance_max": 0}, "waypoint_distance_max"),
        ({"waypoint_distance_min": 40, "waypoint_distance_max": 40}, "waypoint_distance_max"),
        ({"distance_margin_km": 0.0}, "distance_margin_km"),
        ({"distance_margin_km": float("nan")}, "distance_margin_km"),
    ],
)
def test_invalid_options_raise_value_error(options: dict, name: str) -> None:
    with pytest.raises(ValueError, match=name):
        PlanWaypointTask.make_config(options)
    with pytest.raises(ValueError, match=name):
        gym.make("PlanWaypointEnv-v0", **options)


def test_defaults_are_the_reference_values() -> None:
    c = PlanWaypointConfig()
    assert (c.num_waypoints, c.waypoint_distance_min, c.waypoint_distance_max, c.distance_margin_km) == (5, 0, 75, 5.0)
    t = PlanWaypointTask()
    assert (t.dt, t.action_frequency, t.max_episode_steps) == (1.0, 10, 300)


def test_options_change_the_scenario() -> None:
    env = gym.make("PlanWaypointEnv-v0", num_waypoints=3, waypoint_distance_min=30, waypoint_distance_max=31)
    obs, _ = env.reset(seed=0)
    assert obs["waypoint_distance"].shape == (3,)
    assert env.observation_space["waypoint_reached"].shape == (3,)
    task = env.unwrapped.task
    assert np.all(task.wpt_draw_km == 30)
    np.testing.assert_allclose(obs["waypoint_distance"], 30 / 31, rtol=2e-3)  # kwik vs great circle


# --- scenario ---------------------------------------------------------------------------------------
def test_scenario_draws_over_200_seeds() -> None:
    task = _task(seeds=list(range(200)))
    sim = task.sim
    # A clean start: the creation point, heading north, on the ground, CAS 150 requested.
    assert np.all(sim.lat[:, 0] == 52.0) and np.all(sim.lon[:, 0] == 4.0)
    assert np.all(sim.hdg[:, 0] == 0.0) and np.all(sim.alt[:, 0] == 0.0)
    np.testing.assert_allclose(sim.cas[:, 0], 150.0)
    d, b = task.wpt_draw_km, task.wpt_draw_bearing
    assert d.dtype.kind == "i" and b.dtype.kind == "i"
    assert d.min() == 0 and d.max() == 74
    assert b.min() == 0 and b.max() == 358  # randint(0, 359): 359 is never drawn
    assert len(np.unique(d)) == 75
    for e in range(0, 200, 7):
        for i in range(5):
            bearing, dist = great_circle(52.0, 4.0, task.wpt_lat[e, i], task.wpt_lon[e, i])
            assert dist == pytest.approx(d[e, i], abs=1e-6)
            if d[e, i] > 0:
                assert (bearing - b[e, i] + 180) % 360 - 180 == pytest.approx(0.0, abs=1e-6)
    assert not task.wpt_reached.any()
    # Different seeds give different scenarios; the same seed the same one.
    assert len({tuple(row) for row in d.tolist()}) > 190
    again = _task(seeds=[17])
    np.testing.assert_array_equal(again.wpt_lat[0], task.wpt_lat[17])


def test_reset_after_truncation_starts_clean() -> None:
    env = PlanWaypointEnv(max_episode_steps=3)
    first, _ = env.reset(seed=5)
    for _ in range(3):
        _, _, te, tr, _ = env.step(np.array([1.0]))
    assert tr and not te
    again, _ = env.reset(seed=5)
    for k in first:
        np.testing.assert_array_equal(first[k], again[k])
    assert env.task.sim.lat[0, 0] == 52.0 and env.task.sim.hdg[0, 0] == 0.0


# --- observation ------------------------------------------------------------------------------------
def test_observation_matches_hand_computed_geometry() -> None:
    task = _task(seeds=[0])
    sim = task.sim
    sim.lat[0, 0], sim.lon[0, 0], sim.hdg[0, 0] = 52.3, 4.7, 350.0
    pts = [(52.0, 4.65), (52.5, 5.2), (52.31, 4.69), (51.9, 3.9), (52.3, 4.7)]
    for i, (la, lo) in enumerate(pts):
        task.wpt_lat[0, i], task.wpt_lon[0, i] = la, lo
    task.wpt_reached[0] = [False, True, False, False, False]
    obs = task.observe()
    for i, (la, lo) in enumerate(pts):
        qdr, dist = kwik(52.3, 4.7, la, lo)
        drift = 350.0 - qdr
        drift = drift - 360 if drift > 180 else drift + 360 if drift < -180 else drift
        m = 0.0 if i == 1 else 1.0
        assert obs["waypoint_distance"][0, i] == pytest.approx(m * dist / 75, rel=1e-12, abs=1e-15)
        assert obs["cos_difference"][0, i] == pytest.approx(m * math.cos(math.radians(drift)), rel=1e-12, abs=1e-15)
        assert obs["sin_difference"][0, i] == pytest.approx(m * math.sin(math.radians(drift)), rel=1e-12, abs=1e-15)
    # Waypoint 0 is almost due south, qdr about -174: drift 350 + 174 = 524 wraps once to about 164.
    assert obs["cos_difference"][0, 0] < -0.9 and obs["sin_difference"][0, 0] > 0.2
    # The masked waypoint 1 (north-east, drift about -30): 0 * cos > 0 is +0.0, 0 * sin < 0 is -0.0.
    assert obs["cos_difference"][0, 1] == 0.0 and not np.signbit(obs["cos_difference"][0, 1])
    assert obs["sin_difference"][0, 1] == 0.0 and np.signbit(obs["sin_difference"][0, 1])
    np.testing.assert_array_equal(obs["waypoint_reached"][0], [0.0, 1.0, 0.0, 0.0, 0.0])
    assert all(v.dtype == np.float64 for v in obs.values())
    # On the waypoint the bearing is atan2(0, 0) = 0, so the drift is wrap180(350) = -10.
    assert obs["waypoint_distance"][0, 4] == 0.0 and obs["sin_difference"][0, 4] == pytest.approx(math.sin(math.radians(-10)))


# --- action and physics -----------------------------------------------------------------------------
def test_heading_action_is_unwrapped_hdg_plus_45a() -> None:
    task = _task(seeds=[0, 1])
    task.sim.hdg[:, 0] = [10.0, 350.0]
    task.apply_action(np.array([[-1.0], [0.5]]))
    np.testing.assert_array_equal(task.sim.ap_trk[:, 0], [-35.0, 372.5])
    assert not task.sim.swlnav[:, 0].any()
    for _ in range(40):
        task.sim.step()
    np.testing.assert_allclose(task.sim.hdg[:, 0], [325.0, 12.5], atol=1e-9)


def test_aircraft_stays_on_the_ground_at_89_mps() -> None:
    task = _task(seeds=[3])
    for _ in range(5):
        task.step(np.zeros((1, 1)))
    assert task.sim.alt[0, 0] == 0.0
    assert task.sim.tas[0, 0] == pytest.approx(89.0, abs=1e-6)


# --- reward, termination, one-step lag ----------------------------------------------------------------
def test_reward_counts_each_newly_reached_waypoint_once() -> None:
    task = _task(seeds=[2])
    for i, north in enumerate([4.99, 5.01, -3.0, 40.0, 60.0]):
        place_waypoint(task, 0, i, north)
    r, te, comp = task.reward(task.measure())
    assert r[0] == 2.0 and comp["reach"][0] == 2.0 and not te[0]
    np.testing.assert_array_equal(task.wpt_reached[0], [True, False, True, False, False])
    assert task.episode_info()["waypoints_completed"][0] == 2
    r, te, _ = task.reward(task.measure())
    assert r[0] == 0.0 and not te[0]
    for i in (1, 3, 4):
        place_waypoint(task, 0, i, 0.0, 1.0)
    r, te, _ = task.reward(task.measure())
    assert r[0] == 3.0 and te[0] and task.measure().goal_reached[0]


def test_reach_flag_shows_one_step_late() -> None:
    env = gym.make("PlanWaypointEnv-v0").unwrapped
    env.reset(seed=4)
    task = env.task
    place_waypoint(task, 0, 0, 6.0)  # straight ahead (heading 0): reached during step 1
    for i in range(1, 5):
        place_waypoint(task, 0, i, -60.0, 10.0 * i)
    obs1, r1, te1, _, info1 = env.step(np.array([0.0]))
    _, dist_now = kwik(task.sim.lat[0, 0], task.sim.lon[0, 0], task.wpt_lat[0, 0], task.wpt_lon[0, 0])
    assert dist_now < 5.0
    assert r1 == 1.0 and not te1 and info1["waypoints_completed"] == 1
    assert obs1["waypoint_reached"][0] == 0.0  # not yet shown
    assert obs1["waypoint_distance"][0] == pytest.approx(dist_now / 75, rel=1e-12)  # not yet masked
    obs2, r2, _, _, info2 = env.step(np.array([0.0]))
    assert r2 == 0.0 and info2["waypoints_completed"] == 1 and info2["total_reward"] == 1.0
    assert obs2["waypoint_reached"][0] == 1.0 and obs2["waypoint_distance"][0] == 0.0


def test_episode_ends_when_all_reached_with_kpis() -> None:
    env = gym.make("PlanWaypointEnv-v0", num_waypoints=2).unwrapped
    env.reset(seed=9)
    task = env.task
    place_waypoint(task, 0, 0, 3.0)
    place_waypoint(task, 0, 1, 7.0)  # 5.6 km left after step 1, 4.4 km after step 2
    task.tour_km[0] = task._shortest_tour_km(np.array([0]))[0]
    assert task.tour_km[0] == pytest.approx(7.0, rel=1e-9)
    _, r, te, _, info = env.step(np.array([0.0]))
    assert r == 1.0 and not te
    _, r, te, _, info = env.step(np.array([0.0]))
    assert r == 1.0 and te and info["waypoints_completed"] == 2
    assert info["kpi_success"] == 1.0 and info["kpi_time_to_goal_s"] == 20.0
    assert info["kpi_extra_track_km"] == pytest.approx(task.sim.distflown[0, 0] / 1000 - 7.0)
    assert math.isnan(info["kpi_mean_abs_drift_deg"])  # no single heading goal


def test_shortest_tour_matches_brute_force() -> None:
    task = _task(seeds=[21, 22, 23])
    for e in range(3):
        nodes = [(52.0, 4.0)] + list(zip(task.wpt_lat[e], task.wpt_lon[e], strict=True))
        best = min(
            sum(kwik(*nodes[a], *nodes[b])[1] for a, b in zip((0, *order), order, strict=False)) for order in itertools.permutations(range(1, 6))
        )
        assert task.tour_km[e] == pytest.approx(best, rel=1e-12)


def test_shortest_tour_in_chunks_for_eight_waypoints() -> None:
    task = _task(seeds=list(range(7)), num_waypoints=8)  # 8! orders: a few episodes per chunk
    for e in range(7):
        assert task.tour_km[e] == task._shortest_tour_km(np.array([e]))[0]
    assert len(set(task.tour_km.tolist())) == 7
    # Visiting in the drawn order is never shorter than the optimum.
    for e in range(7):
        lat = [52.0, *task.wpt_lat[e]]
        lon = [4.0, *task.wpt_lon[e]]
        drawn = sum(kwik(lat[j], lon[j], lat[j + 1], lon[j + 1])[1] for j in range(8))
        assert task.tour_km[e] <= drawn + 1e-9


# --- the kernels against the numpy oracle ----------------------------------------------------------
@pytest.mark.parametrize("env_options", [{}, {"airborne_start": True, "reach_same_step": True}])
def test_step_kernels_equal_the_numpy_oracle_through_episodes(env_options: dict) -> None:
    """Measure, observation, reward, reach flags, ``waypoints_completed`` and the extra track, to the last bit (signed zeros too)."""
    n = 8
    task = _task(seeds=list(range(n)), num_waypoints=2, waypoint_distance_max=9, **env_options)
    task.time_limit = 12
    c = task.config
    rng = np.random.default_rng(4)
    reached = goals = ended = 0
    for step in range(60):
        s = task.sim
        flags = task.wpt_reached.copy()
        want = oracle.measure(s.lat, s.lon, s.hdg, task.wpt_lat, task.wpt_lon, flags, c.distance_margin_km)
        g = task.measure()
        for got, key in (
            (g.dist_km, "dist_km"),
            (g.drift, "drift"),
            (g.reached_before, "before"),
            (g.newly_reached, "new"),
            (g.goal_reached, "goal"),
        ):
            np.testing.assert_array_equal(got, want[key], err_msg=f"step {step} {key}", strict=True)
        obs, want_obs = task.observe(g), oracle.observation(want, c.reach_same_step, c.waypoint_distance_max)
        assert list(obs) == list(want_obs)
        for key in obs:
            np.testing.assert_array_equal(obs[key], want_obs[key], err_msg=f"step {step} {key}", strict=True)
            np.testing.assert_array_equal(np.signbit(obs[key]), np.signbit(want_obs[key]), err_msg=f"step {step} {key}: signed zeros")
        r, te, comp = task.reward(g)
        np.testing.assert_array_equal(r, oracle.reward(want, 1.0), strict=True)
        np.testing.assert_array_equal(comp["reach"], r, strict=True)
        np.testing.assert_array_equal(te, want["goal"], strict=True)
        np.testing.assert_array_equal(task.wpt_reached, flags | want["new"])
        np.testing.assert_array_equal(task.episode_info()["waypoints_completed"], task.wpt_reached.sum(axis=1), strict=True)
        np.testing.assert_array_equal(task.extra_track_km(), oracle.extra_track_km(s.distflown, task.tour_km), strict=True)
        reached += int(want["new"].sum())
        goals += int(want["goal"].sum())
        res = task.step(rng.uniform(-1.5, 1.5, (n, 1)))
        done = np.flatnonzero(res.terminated | res.truncated)
        ended += done.size
        task.reset(done)
    assert reached > 0 and goals > 0 and ended > goals  # reaches, goals and time limits covered
