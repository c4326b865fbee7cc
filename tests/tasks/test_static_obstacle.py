"""StaticObstacleEnv-v0: scenario, observation, per-sub-step reward and early return (docs/environments-v0.md §6)."""

from __future__ import annotations

import functools
import math

import gymnasium as gym
import numpy as np
import pytest
from matplotlib.path import Path

import bluesky_gym
from bluesky_gym.environments.static_obstacle.task import StaticObstacleConfig, StaticObstacleTask, obstacle_substep_end, sample_waypoint
from tests.oracle.geometry import points_in_polygons
from tests.oracle.static_obstacle import reference_substeps

from .conftest import great_circle, kwik, seeded_task

bluesky_gym.register_envs()

_task = functools.partial(seeded_task, StaticObstacleTask)


def wrap(x: float) -> float:
    return x - 360 if x > 180 else x + 360 if x < -180 else x


def set_square(task: StaticObstacleTask, e: int, i: int, lat: float, lon: float, half: float) -> None:
    """Replace obstacle i of episode e by a (lat, lon) square of half-width ``half`` degrees."""
    task.obstacle_nv[e, i] = 4
    task.obstacle_lat[e, i, :4] = [lat - half, lat - half, lat + half, lat + half]
    task.obstacle_lon[e, i, :4] = [lon - half, lon + half, lon + half, lon - half]


def clear_obstacles(task: StaticObstacleTask, e: int) -> None:
    task.obstacle_nv[e] = 0


def polygon_nm(task: StaticObstacleTask, e: int, i: int) -> np.ndarray:
    """Vertices of obstacle (e, i) back in (north, east) NM around its centre."""
    nv = task.obstacle_nv[e, i]
    c_lat, c_lon = task.obstacle_centre_lat[e, i], task.obstacle_centre_lon[e, i]
    north = (task.obstacle_lat[e, i, :nv] - c_lat) * 60
    east = (task.obstacle_lon[e, i, :nv] - c_lon) * 60 * math.cos(math.radians(c_lat))
    return np.stack([north, east], axis=1)


# --- options ----------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "options, name",
    [
        ({"num_obstacles": 0}, "num_obstacles"),
        ({"num_obstacles": 3.0}, "num_obstacles"),
        ({"obstacle_distance_min": -5}, "obstacle_distance_min"),
        ({"obstacle_distance_max": 20}, "obstacle_distance_max"),
        ({"obstacle_area_min": 0}, "obstacle_area_min"),
        ({"obstacle_area_max": 100}, "obstacle_area_max"),  # the circle-area draw needs 2 * 50 < max
        ({"obstacle_area_max": 8000}, "obstacle_area_max"),  # radius above 50 NM would leave [0, 1]
        ({"waypoint_distance_min": 170}, "waypoint_distance_max"),
        ({"waypoint_distance_max": 99.5}, "waypoint_distance_max"),
        ({"distance_margin_km": -1.0}, "distance_margin_km"),
    ],
)
def test_invalid_options_raise_value_error(options: dict, name: str) -> None:
    with pytest.raises(ValueError, match=name):
        StaticObstacleTask.make_config(options)
    with pytest.raises(ValueError, match=name):
        gym.make("StaticObstacleEnv-v0", **options)


def test_defaults_are_the_reference_values() -> None:
    c = StaticObstacleConfig()
    assert (c.num_obstacles, c.obstacle_distance_min, c.obstacle_distance_max) == (10, 20, 150)
    assert (c.obstacle_area_min, c.obstacle_area_max, c.waypoint_distance_min, c.waypoint_distance_max) == (50, 1000, 100, 170)
    assert c.distance_margin_km == 5.0
    t = StaticObstacleTask()
    assert (t.dt, t.action_frequency, t.max_episode_steps) == (1.0, 10, 100)


def test_options_change_the_scenario() -> None:
    task = _task(seeds=[0, 1], num_obstacles=4, obstacle_distance_min=60, obstacle_distance_max=61, obstacle_area_max=400)
    assert task.observe()["restricted_area_radius"].shape == (2, 4)
    for e in range(2):
        for i in range(4):
            assert great_circle(52.0, 4.0, task.obstacle_centre_lat[e, i], task.obstacle_centre_lon[e, i])[1] == pytest.approx(60.0)
    assert task.obstacle_radius.max() < math.sqrt(400 / math.pi)


# --- scenario ---------------------------------------------------------------------------------------
def test_scenario_draws_over_200_seeds() -> None:
    n = 200
    task = _task(seeds=list(range(n)))
    sim = task.sim
    assert np.all(sim.lat[:, 0] == 52.0) and np.all(sim.lon[:, 0] == 4.0) and np.all(sim.alt[:, 0] == 350.0)
    np.testing.assert_allclose(sim.cas[:, 0], 150.0)
    centre_d, centre_b, areas = [], [], []
    for e in range(n):
        for i in range(10):
            b, d = great_circle(52.0, 4.0, task.obstacle_centre_lat[e, i], task.obstacle_centre_lon[e, i])
            centre_d.append(d)
            centre_b.append(b)
            # Circle area: an integer draw in [100, 1000) NM^2.
            areas.append(math.pi * task.obstacle_radius[e, i] ** 2)
            # Polygon: >= 3 vertices on that circle, sorted clockwise, shoelace area >= 50 NM^2.
            p = polygon_nm(task, e, i)
            assert len(p) >= 3
            np.testing.assert_allclose(np.hypot(p[:, 0], p[:, 1]), task.obstacle_radius[e, i], rtol=1e-9)
            assert np.all(np.diff(np.arctan2(p[:, 1], p[:, 0])) > 0)
            x, y = p[:, 0], p[:, 1]
            shoelace = abs(np.sum(x * np.roll(y, -1) - y * np.roll(x, -1))) / 2
            assert shoelace == pytest.approx(task.obstacle_area[e, i], rel=1e-9)
            assert task.obstacle_area[e, i] >= 50.0
        # The waypoint is outside every obstacle (BlueSky's own test: a matplotlib Path on (lat, lon)).
        wpt = [[task.wpt_lat[e], task.wpt_lon[e]]]
        for i in range(10):
            nv = task.obstacle_nv[e, i]
            border = Path(np.stack([task.obstacle_lat[e, i, :nv], task.obstacle_lon[e, i, :nv]], axis=1))
            assert not border.contains_points(wpt)[0]
        b, d = great_circle(52.0, 4.0, task.wpt_lat[e], task.wpt_lon[e])
        assert d == pytest.approx(round(d), abs=1e-6) and 100 <= round(d) <= 169
        assert b == pytest.approx(round(b) % 360, abs=1e-6)
        # The aircraft starts pointing at the waypoint (hdg and autopilot track).
        qdr, dist = kwik(52.0, 4.0, task.wpt_lat[e], task.wpt_lon[e])
        qdr %= 360.0  # headings are kept in [0, 360)
        assert sim.hdg[e, 0] == pytest.approx(qdr, abs=1e-9) and sim.ap_trk[e, 0] == sim.hdg[e, 0]
        assert task.start_wpt_km[e] == pytest.approx(dist, rel=1e-12)
    centre_d, centre_b, areas = np.array(centre_d), np.array(centre_b), np.array(areas)
    np.testing.assert_allclose(centre_d, np.round(centre_d), atol=1e-6)
    assert np.round(centre_d).min() == 20 and np.round(centre_d).max() == 149
    np.testing.assert_allclose(centre_b, np.round(centre_b) % 360, atol=1e-6)
    assert set(np.round(centre_b).astype(int) % 360) == set(range(360))
    np.testing.assert_allclose(areas, np.round(areas), atol=1e-6)
    assert np.round(areas).min() >= 100 and np.round(areas).max() <= 999
    # Real polygon areas are only guaranteed >= 50 and are typically well below the circle's.
    assert np.median(task.obstacle_area / (math.pi * task.obstacle_radius**2)) < 0.8
    obs = task.observe()
    np.testing.assert_allclose(obs["destination_waypoint_cos_drift"], 1.0)
    assert np.all((obs["restricted_area_radius"] > 0.11) & (obs["restricted_area_radius"] < 0.36))


def test_waypoint_rejection_gives_up_at_the_1001st_try() -> None:
    class CountingRng:
        def __init__(self) -> None:
            self.rng = np.random.default_rng(0)
            self.calls = 0

        def integers(self, low: int, high: int) -> int:
            self.calls += 1
            return self.rng.integers(low, high)

    # One square covering everything within ~200 km of the start.
    lat = np.array([[50.0, 50.0, 54.0, 54.0]])
    lon = np.array([[1.0, 7.0, 7.0, 1.0]])
    rng = CountingRng()
    with pytest.raises(RuntimeError, match="1000 tries"):
        sample_waypoint(rng, 52.0, 4.0, lat, lon, np.array([4]), 100, 170)  # type: ignore[arg-type]
    assert rng.calls == 2 * 1001  # distance and bearing per try
    # Covering only the north: the sample lands in the south.
    north = np.array([[52.0, 52.0, 54.0, 54.0]])
    wlat, _ = sample_waypoint(np.random.default_rng(1), 52.0, 4.0, north, lon, np.array([4]), 100, 170)
    assert wlat < 52.0


def test_generation_raises_when_obstacles_cover_the_waypoint_range() -> None:
    task = StaticObstacleTask(
        1,
        StaticObstacleTask.make_config(
            {
                "num_obstacles": 40,
                "obstacle_distance_min": 0,
                "obstacle_distance_max": 1,
                "obstacle_area_min": 3900,
                "obstacle_area_max": 7850,
                "waypoint_distance_min": 5,
                "waypoint_distance_max": 6,
            }
        ),
    )
    task.seed(task.all_envs, [np.random.default_rng(0)])
    with pytest.raises(RuntimeError, match="1000 tries"):
        task.reset()


# --- observation ------------------------------------------------------------------------------------
def test_observation_matches_hand_computed_geometry() -> None:
    task = _task(seeds=[0])
    sim = task.sim
    sim.lat[0, 0], sim.lon[0, 0], sim.hdg[0, 0] = 52.2, 3.8, 200.0
    task.wpt_lat[0], task.wpt_lon[0] = 52.9, 4.1
    centres = [(52.2 + 0.1 * i, 3.0 + 0.2 * i) for i in range(10)]
    for i, (la, lo) in enumerate(centres):
        task.obstacle_centre_lat[0, i], task.obstacle_centre_lon[0, i] = la, lo
    g = task.measure()
    obs = task.observe(g)
    qdr, dist = kwik(52.2, 3.8, 52.9, 4.1)
    drift = wrap(200.0 - qdr)  # qdr about 15: drift about 185 wraps to about -175
    assert drift < -170
    assert obs["destination_waypoint_distance"][0, 0] == pytest.approx(dist / 170, rel=1e-12)
    assert obs["destination_waypoint_cos_drift"][0, 0] == pytest.approx(math.cos(math.radians(drift)), rel=1e-12)
    assert obs["destination_waypoint_sin_drift"][0, 0] == pytest.approx(math.sin(math.radians(drift)), rel=1e-12)
    np.testing.assert_array_equal(obs["restricted_area_radius"][0], task.obstacle_radius[0] / 50)
    for i, (la, lo) in enumerate(centres):
        qdr, dist = kwik(52.2, 3.8, la, lo)
        bearing = math.radians(wrap(200.0 - qdr))
        assert obs["restricted_area_distance"][0, i] == pytest.approx(dist / 170, rel=1e-12)
        assert obs["cos_difference_restricted_area_pos"][0, i] == pytest.approx(math.cos(bearing), rel=1e-12, abs=1e-15)
        assert obs["sin_difference_restricted_area_pos"][0, i] == pytest.approx(math.sin(bearing), rel=1e-12, abs=1e-15)
    # The next step's reward uses the waypoint values of this observation.
    task.reward(g)
    assert task.last_wpt_km[0] == pytest.approx(kwik(52.2, 3.8, 52.9, 4.1)[1], rel=1e-12)
    assert task.last_drift[0] == pytest.approx(drift, rel=1e-12)


# --- action -----------------------------------------------------------------------------------------
def test_action_maps_to_wrapped_heading_and_speed_in_mps() -> None:
    task = _task(seeds=[0, 1])
    task.sim.hdg[:, 0] = [170.0, 10.0]
    cas = task.sim.cas[:, 0].copy()
    task.apply_action(np.array([[1.0, -1.0], [-0.5, 0.5]]))
    np.testing.assert_array_equal(task.sim.ap_trk[:, 0], [-145.0, -12.5])  # wrap180(215), wrap180(-12.5)
    # (CAS + a * 20/3) * 1.94384 kts, converted back with 0.514444 m/s per kt: about CAS -/+ 6.67 m/s.
    np.testing.assert_allclose(task.sim.selspd[:, 0], cas + np.array([-20 / 3, 10 / 3]), rtol=1e-5)
    np.testing.assert_array_equal(task.sim.selspd[:, 0], (cas + np.array([-1.0, 0.5]) * (20 / 3)) * 1.94384 * 0.514444)


# --- reward -----------------------------------------------------------------------------------------
def test_reward_uses_stale_waypoint_values_and_live_position() -> None:
    task = _task(seeds=[3])
    sim = task.sim
    clear_obstacles(task, 0)
    task.last_wpt_km[0], task.last_drift[0] = 50.0, -30.0
    # Live position on the waypoint, stale distance 50 km: no reach.
    sim.lat[0, 0], sim.lon[0, 0] = task.wpt_lat[0], task.wpt_lon[0]
    r, te, comp = task.reward(task.measure())
    assert r[0] == pytest.approx(-0.01 * math.radians(30)) and not te[0]
    assert comp["reach"][0] == 0.0 and comp["intrusion"][0] == 0.0
    # Stale distance below 5 km: reached, whatever the live position.
    sim.lat[0, 0], sim.lon[0, 0] = 52.0, 4.0
    task.last_wpt_km[0], task.last_drift[0] = 4.99, -30.0
    r, te, comp = task.reward(task.measure())
    assert comp["reach"][0] == 1.0 and r[0] == pytest.approx(1 - 0.01 * math.radians(30)) and te[0]
    info = task.episode_info()
    assert info["waypoint_reached"][0] == 1 and info["crashed"][0] == 0


def test_intrusion_penalty_per_containing_obstacle() -> None:
    task = _task(seeds=[4])
    clear_obstacles(task, 0)
    task.last_wpt_km[0], task.last_drift[0] = 80.0, 0.0
    lat, lon = task.sim.lat[0, 0], task.sim.lon[0, 0]
    set_square(task, 0, 2, lat + 0.2, lon, 0.1)  # just north of the aircraft: outside
    r, te, _ = task.reward(task.measure())
    assert r[0] == 0.0 and not te[0] and task.episode_info()["crashed"][0] == 0
    set_square(task, 0, 5, lat, lon, 0.05)
    set_square(task, 0, 7, lat + 0.04, lon, 0.05)  # overlaps the aircraft too
    r, te, comp = task.reward(task.measure())
    assert r[0] == -10.0 and comp["intrusion"][0] == -10.0 and te[0]
    assert task.episode_info()["crashed"][0] == 1 and task.intrusions[0] == 2


# --- stepping ---------------------------------------------------------------------------------------
def test_step_returns_the_last_substep_reward_and_averages_every_sample() -> None:
    env = gym.make("StaticObstacleEnv-v0").unwrapped
    _, info0 = env.reset(seed=8)
    assert info0["average_drift"] == 0.0  # the reference gives NaN here
    task = env.task
    clear_obstacles(task, 0)
    task.sim.hdg[0, 0] += 20.0  # drift of 20 deg in the observation the first step uses
    g0 = task.measure()
    task.remember(g0)
    obs0 = task.observe(g0)
    d0 = math.atan2(obs0["destination_waypoint_sin_drift"][0, 0], obs0["destination_waypoint_cos_drift"][0, 0])
    assert abs(d0) == pytest.approx(math.radians(20), rel=1e-9)
    _, r1, te, _, info1 = env.step(np.array([0.0, 0.0]))
    assert not te and r1 == pytest.approx(-0.01 * abs(d0), rel=1e-12)  # not 10 sub-steps' worth
    assert info1["total_reward"] == r1 and info1["average_drift"] == pytest.approx(abs(d0), rel=1e-12)
    assert task.drift_count[0] == 10
    d1 = math.radians(abs(task.last_drift[0]))
    _, r2, _, _, info2 = env.step(np.array([0.0, 0.0]))
    assert r2 == pytest.approx(-0.01 * d1, rel=1e-12)
    assert info2["average_drift"] == pytest.approx((abs(d0) + d1) / 2, rel=1e-12)
    assert info2["total_reward"] == pytest.approx(r1 + r2)


def test_waypoint_capture_is_detected_one_step_late() -> None:
    env = gym.make("StaticObstacleEnv-v0").unwrapped
    env.reset(seed=6)
    task = env.task
    clear_obstacles(task, 0)
    lat, lon, hdg = task.sim.lat[0, 0], task.sim.lon[0, 0], task.sim.hdg[0, 0]
    # Straight ahead at 6 km (about 1.5 km is flown per step).
    task.wpt_lat[0], task.wpt_lon[0] = _point(lat, lon, 6.0, hdg)
    task.remember(task.measure())
    t0 = task.sim.simt
    obs1, r1, te1, _, _ = env.step(np.array([0.0, 0.0]))
    assert not te1 and task.last_wpt_km[0] < 5.0 and r1 <= 0.0
    assert obs1["destination_waypoint_distance"][0] * 170 < 5.0
    _, r2, te2, _, info2 = env.step(np.array([0.0, 0.0]))
    assert te2 and info2["waypoint_reached"] == 1 and r2 > 0.99 and info2["kpi_success"] == 1.0
    assert task.sim.simt - t0 == pytest.approx(11.0)  # the second step stopped after its first sub-step


def _point(lat: float, lon: float, d_km: float, bearing: float) -> tuple[float, float]:
    from bluesky_gym.tasks.geometry import point_at_distance

    la, lo = point_at_distance(lat, lon, d_km, bearing)
    return float(la), float(lo)


def _crash_course(seed: int, k: int) -> tuple[StaticObstacleTask, list[tuple[float, float]]]:
    """A single episode whose only obstacle is entered during sub-step k (0-based) of step 1."""
    probe = _task(seeds=[seed])
    clear_obstacles(probe, 0)
    probe.apply_action(np.zeros((1, 2)))
    path = [(probe.sim.lat[0, 0], probe.sim.lon[0, 0])]
    for _ in range(10):
        probe.sim.step()
        path.append((probe.sim.lat[0, 0], probe.sim.lon[0, 0]))
    return probe, path


def _arm(task: StaticObstacleTask, e: int, path: list[tuple[float, float]], k: int) -> None:
    """Give episode e one obstacle: a parallelogram whose near edge lies between sub-steps k-1 and k."""
    clear_obstacles(task, e)
    (la0, lo0), (la1, lo1) = path[k], path[k + 1]  # positions after sub-steps k-1 and k (1-based path)
    v = np.array([la1 - la0, lo1 - lo0])
    perp = np.array([-v[1], v[0]]) * 5
    p1 = np.array([la1, lo1]) - 0.5 * v
    corners = [p1 + perp, p1 - perp, p1 + 20 * v - perp, p1 + 20 * v + perp]
    task.obstacle_nv[e, 0] = 4
    task.obstacle_lat[e, 0, :4] = [c[0] for c in corners]
    task.obstacle_lon[e, 0, :4] = [c[1] for c in corners]


def test_episode_ending_mid_step_returns_that_substep_in_a_batch() -> None:
    seeds, crash, k = [31, 32, 33], 1, 4
    _, path = _crash_course(seeds[crash], k)
    batch = _task(seeds=seeds)
    alone = [_task(seeds=[s]) for s in seeds]
    for e in range(3):
        clear_obstacles(batch, e)
        clear_obstacles(alone[e], 0)
    _arm(batch, crash, path, k)
    _arm(alone[crash], 0, path, k)
    for t in (batch, *alone):
        t.remember(t.measure())
    action = np.zeros((3, 2))
    action[:, 0] = [0.3, 0.0, -0.4]
    res = batch.step(action)
    singles = [alone[e].step(action[e : e + 1]) for e in range(3)]
    np.testing.assert_array_equal(res.terminated, [False, True, False])
    for e in range(3):
        s = singles[e]
        assert res.reward[e] == s.reward[0] and res.terminated[e] == s.terminated[0]
        for key in res.observation:
            np.testing.assert_array_equal(res.observation[key][e], s.observation[key][0], err_msg=f"episode {e} {key}")
        for key in s.info:
            np.testing.assert_array_equal(res.info[key][e], s.info[key][0], err_msg=f"episode {e} info {key}")
    # The crashed episode's observation is that of sub-step k (k + 1 sim steps), not of the last one.
    assert alone[crash].sim.simt == pytest.approx(k + 1)
    lat_k, lon_k = path[k + 1]
    assert batch.sim.lat[crash, 0] == lat_k and batch.sim.lon[crash, 0] == lon_k
    _, dist = kwik(lat_k, lon_k, batch.wpt_lat[crash], batch.wpt_lon[crash])
    assert res.observation["destination_waypoint_distance"][crash, 0] == pytest.approx(dist / 170, rel=1e-12)
    assert res.info["crashed"][crash] == 1 and res.info["kpi_obstacle_intrusions"][crash] == 1.0
    assert res.reward[crash] == pytest.approx(-5.0 + res.info["reward_drift"][crash])
    assert batch.drift_count.tolist() == [10, k + 1, 10]
    # The other episodes ran all ten sub-steps.
    assert alone[0].sim.simt == pytest.approx(10.0) and alone[2].sim.simt == pytest.approx(10.0)
    # Ended episodes report their KPIs at sub-step k: distance flown over k + 1 seconds.
    assert res.info["kpi_track_distance_km"][crash] == pytest.approx(alone[crash].sim.distflown[0, 0] / 1000)
    assert res.info["kpi_track_distance_km"][crash] < 0.6 * res.info["kpi_track_distance_km"][0]


def test_vector_env_resets_a_crashed_episode_and_keeps_the_others() -> None:
    venv = gym.make_vec("StaticObstacleEnv-v0", num_envs=2, vectorization_mode="vector_entry_point")
    venv.reset(seed=40)
    task = venv.unwrapped.task
    clear_obstacles(task, 0)
    clear_obstacles(task, 1)
    set_square(task, 1, 0, task.sim.lat[1, 0], task.sim.lon[1, 0], 0.1)
    obs, r, te, tr, info = venv.step(np.zeros((2, 2)))
    assert te.tolist() == [False, True]
    assert info["final_info"]["crashed"][1] == 1 and r[1] < -4.9
    assert obs["destination_waypoint_cos_drift"][1, 0] == pytest.approx(1.0)  # a fresh episode
    assert task.sim.lat[1, 0] == 52.0 and task.drift_count[1] == 0


# --- the batched sub-step path against the reference's one-airspace loop ---------------------------
class _ReferenceLoopTask(StaticObstacleTask):
    """One airspace stepped sub-step by sub-step as the reference does (tests.oracle.static_obstacle)."""

    def transition(self):
        reward, terminated, components = reference_substeps(self)
        g = self.measure()
        self.remember(g)  # the waypoint values of this observation, for the next step
        return reward, terminated, components, self.observe(g)


def test_batched_substeps_equal_the_reference_loop_of_each_episode() -> None:
    seeds = [70, 71, 72, 73, 74, 75]
    options = {"num_obstacles": 14, "obstacle_area_max": 1500}  # crowded: crashes at every sub-step index
    batch = _task(seeds=seeds, **options)
    alone = []
    for s in seeds:
        t = _ReferenceLoopTask(1, StaticObstacleTask.make_config(options))
        t.seed(t.all_envs, [np.random.default_rng(s)])
        t.reset()
        alone.append(t)
    rng = np.random.default_rng(5)
    ended_at, ends = set(), 0
    for step in range(120):
        action = rng.uniform(-1, 1, (len(seeds), 2))
        res = batch.step(action)
        for e, t in enumerate(alone):
            t0 = t.sim.simt
            s = t.step(action[e : e + 1])
            assert res.reward[e] == s.reward[0] and res.terminated[e] == s.terminated[0] and res.truncated[e] == s.truncated[0]
            for key in s.observation:
                np.testing.assert_array_equal(res.observation[key][e], s.observation[key][0], err_msg=f"step {step} episode {e} {key}")
            assert s.info.keys() <= res.info.keys()
            for key in s.info:
                np.testing.assert_array_equal(res.info[key][e], s.info[key][0], err_msg=f"step {step} episode {e} info {key}")
            if s.terminated[0] or s.truncated[0]:
                ended_at.add(round(t.sim.simt - t0))
                ends += 1
                t.reset()
        done = np.flatnonzero(res.terminated | res.truncated)
        batch.reset(done)
    assert ends > 10 and len(ended_at) >= 5  # episodes ended after many different sub-step counts


@pytest.mark.parametrize("stale_goal", [False, True])
def test_substep_end_is_the_first_substep_inside_an_obstacle(stale_goal: bool) -> None:
    """obstacle_substep_end against the numpy even-odd test, sub-step by sub-step; -v0 ends the stale goals at once."""
    rng = np.random.default_rng(4)
    steps, n, k, v = 7, 120, 5, 8
    poly_lat = 52.0 + rng.uniform(-0.3, 0.3, (n, k, v))
    poly_lon = 4.0 + rng.uniform(-0.3, 0.3, (n, k, v))
    nv = rng.integers(0, v + 1, (n, k))
    track = np.empty((steps, 2, n, 1))
    track[:, 0] = 52.0 + rng.uniform(-0.4, 0.4, (steps, n, 1))
    track[:, 1] = 4.0 + rng.uniform(-0.4, 0.4, (steps, n, 1))
    track[0, 0, :, 0] = poly_lat[:, 0, 0]  # on a vertex's latitude
    last_wpt_km = rng.uniform(0.0, 10.0, n)
    wpt_reached = rng.uniform(size=n) < 0.1
    ended_at = np.zeros(n, np.int64)
    ended_at[:3] = [2, 5, 7]  # ended earlier: left as they are
    given = ended_at.copy()
    obstacle_substep_end(track[:, 0], track[:, 1], 1, poly_lat, poly_lon, nv, stale_goal, last_wpt_km, wpt_reached, 5.0, ended_at)
    inside = np.stack([points_in_polygons(track[s, 0], track[s, 1], poly_lat, poly_lon, nv)[:, 0, :].any(axis=1) for s in range(steps)])
    expected = np.where(inside.any(axis=0), inside.argmax(axis=0) + 1, 0)
    if stale_goal:
        expected[wpt_reached | (last_wpt_km < 5.0)] = 1
    expected[:3] = given[:3]
    np.testing.assert_array_equal(ended_at, expected)
    assert (expected[3:] == 0).any() and (expected[3:] > 1).any() and (expected[3:] == 1).any()
