"""The -v1 environments: bounds that hold, clean checks, and one test per fixed -v0 defect.

Every fix test runs the same scenario on the -v0 and the -v1 id: it asserts the -v0 defect and its
absence in -v1, so it fails on -v0's behaviour.
"""

from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import bluesky_gym  # noqa: F401 - registers the ids
from bluesky_gym.core.units import FL, KTS, MPS2KT, NM2KM
from bluesky_gym.envs.registry import ENVIRONMENTS, entry
from bluesky_gym.tasks.geometry import ref_kwikdist

V1 = [e.id for e in ENVIRONMENTS if e.id.endswith("-v1")]


def _task(env_id: str, n: int, seed: int = 0, **options: object):
    """The batched task of ``env_id`` (its registered configuration plus ``options``), reset with seeds seed..seed+n-1."""
    row = entry(env_id)
    cls = row.task_class()
    task = cls(n, cls.make_config({**dict(row.options), **options}))
    task.seed(task.all_envs, [np.random.default_rng(seed + i) for i in range(n)])
    task.reset()
    return task


def test_a_v1_id_for_every_v0_id_and_v0_unchanged() -> None:
    v0 = [e.id for e in ENVIRONMENTS if e.id.endswith("-v0")]
    assert V1 == [i.replace("-v0", "-v1") for i in v0]
    assert len(V1) == 9  # the paper's seven, RealTrafficCREnv and DenseSectorCREnv
    for env_id in V1:
        assert gym.spec(env_id).kwargs["float32_spaces"] is True
        assert gym.spec(env_id).kwargs["env_id"] == env_id  # passed to the constructor, whose errors name it
        assert gym.spec(env_id.replace("-v1", "-v0")).kwargs == {}  # -v0: the defaults, the paper's MDP


@pytest.mark.parametrize("env_id", V1)
def test_observations_stay_within_finite_float32_bounds_over_long_random_runs(env_id: str) -> None:
    """64 episodes x up to 200 random steps (ended ones restarted): every observation finite and within its bound.

    The bound is checked on the task's own values before the safety clip of the environment, so a
    bound that does not hold fails here, and on what the batched environment returns.
    """
    n = 64
    venv = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point")
    space = venv.single_observation_space
    for box in [*space.spaces.values(), venv.single_action_space]:
        assert box.dtype == np.float32 and np.isfinite(box.low).all() and np.isfinite(box.high).all()
    obs, _ = venv.reset(seed=0)
    task = venv.unwrapped.task
    rng = np.random.default_rng(0)
    steps = min(task.time_limit, 200)
    for _ in range(steps):
        for key, value in task.observe().items():  # the task's values, unclipped
            box = space[key]
            assert np.isfinite(value).all(), key
            assert (value >= box.low).all() and (value <= box.high).all(), f"{key} leaves [{box.low.min()}, {box.high.max()}]"
        for key, value in obs.items():
            assert value.dtype == np.float32 and np.isfinite(value).all()
            assert (value >= space[key].low).all() and (value <= space[key].high).all(), key
        obs, *_ = venv.step(rng.uniform(-1, 1, (n, *venv.single_action_space.shape)).astype(np.float32))
    venv.close()


@pytest.mark.parametrize("env_id", V1)
def test_checkers_accept_v1_without_warnings(env_id: str) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        env = gym.make(env_id)
        check_env(env.unwrapped, skip_render_check=True)
        sb3_checker = pytest.importorskip("stable_baselines3.common.env_checker")
        sb3_checker.check_env(gym.make(env_id).unwrapped, warn=True)


# --- one test per fix --------------------------------------------------------------------------
@pytest.mark.parametrize("family", ["DescentEnv", "VerticalCREnv"])
def test_altitude_action_zero_holds_altitude(family: str) -> None:
    """bluesky-gym #59: a = 0 selects BlueSky's default 7.62 m/s and climbs in -v0; -v1 holds the altitude."""
    change = {}
    for version in ("v0", "v1"):
        task = _task(f"{family}-{version}", 4, seed=3)
        alt0 = task.sim.alt[:, 0].copy()
        for _ in range(5):
            task.step(np.zeros((4, 1)))
        change[version] = task.sim.alt[:, 0] - alt0
    assert (change["v0"] > 500).all()  # 150 s at 7.62 m/s
    assert (np.abs(change["v1"]) < 1.0).all()


def test_vertical_speed_difference_is_normalised() -> None:
    for version, scale in (("v0", 1.0), ("v1", 5.0)):
        task = _task(f"VerticalCREnv-{version}", 3, seed=1)
        task.step(np.full((3, 1), -0.6))
        vs = task.sim.vs
        np.testing.assert_allclose(task.observe()["z_difference_speed"], (vs[:, 1:] - vs[:, :1]) / scale, rtol=0, atol=1e-12)


@pytest.mark.parametrize("family", ["HorizontalCREnv", "PlanWaypointEnv"])
def test_aircraft_fly_airborne_at_the_scenario_speed(family: str) -> None:
    """-v0 starts at altitude 0, in the ground phase, capped at 89 m/s; -v1 at FL100 holds CAS 150 m/s."""
    cas = {}
    for version in ("v0", "v1"):
        task = _task(f"{family}-{version}", 3)
        for _ in range(6):
            task.step(np.zeros((3, 1)))
        active = task.sim.active
        cas[version] = task.sim.cas[active]
        assert np.all(task.sim.alt[active] == (100 * FL if version == "v1" else 0.0))
    assert np.allclose(cas["v0"], 89.0) and np.allclose(cas["v1"], 150.0, rtol=0, atol=0.01)  # intruders: the ownship GS


def test_plan_waypoint_reach_shows_in_the_same_step() -> None:
    """-v0 shows a waypoint as reached one observation late; -v1 in the observation of the step that reached it."""
    lag = {}
    for version in ("v0", "v1"):
        venv = gym.make_vec(f"PlanWaypointEnv-{version}", num_envs=32, vectorization_mode="vector_entry_point")
        venv.reset(seed=0)
        rng = np.random.default_rng(0)
        lag[version] = 0
        for _ in range(60):
            obs, _, te, tr, info = venv.step(rng.uniform(-1, 1, (32, 1)))
            live = ~(te | tr)
            shown = obs["waypoint_reached"].sum(axis=1)
            lag[version] += int(np.count_nonzero(shown[live] != info["waypoints_completed"][live]))
        venv.close()
    assert lag["v0"] > 0 and lag["v1"] == 0


@pytest.mark.parametrize("family", ["SectorCREnv", "StaticObstacleEnv"])
def test_flight_level_350_and_speed_step_in_knots(family: str) -> None:
    """ "FL350" was 350 m and the 20/3 "kt" speed step was 20/3 m/s in -v0."""
    for version, alt, step in (("v0", 350.0, 20 / 3), ("v1", 350 * FL, 20 / 3 * KTS)):
        task = _task(f"{family}-{version}", 2)
        active = task.sim.active
        assert np.all(task.sim.alt[active] == alt)
        cas = task.sim.cas[:, 0].copy()
        task.apply_action(np.array([[0.0, 1.0], [0.0, 1.0]]))
        # The command goes through knots as the reference's stack command does: x 1.94384 kt, x 0.514444 m/s.
        np.testing.assert_allclose(task.sim.selspd[:, 0], (cas + step) * MPS2KT * KTS, rtol=1e-12)


def _sector_episode(version: str, seed: int, leave: bool) -> tuple[float, bool, bool, dict[str, float], int]:
    """One SectorCR episode: straight at the own waypoint (a = 0), or turned away from it to leave early."""
    env = gym.make(f"SectorCREnv-{version}").unwrapped
    obs, _ = env.reset(seed=seed)
    total, te, tr, info, steps = 0.0, False, False, {}, 0
    while not (te or tr):
        drift = np.degrees(np.arctan2(float(obs["sin(drift)"][0]), float(obs["cos(drift)"][0])))
        a0 = (1.0 if drift >= 0 else -1.0) if leave and abs(drift) < 170 else 0.0
        obs, r, te, tr, info = env.step(np.array([a0, 0.0]))
        total += r
        steps += 1
    return total, te, tr, info, steps


def test_sector_cr_leaving_early_is_no_longer_rewarded() -> None:
    """bluesky-gym #44: in -v0 turning away to leave the sector early ends the episode without penalty."""
    for seed in range(4):
        straight_v1 = _sector_episode("v1", seed, leave=False)
        away_v0 = _sector_episode("v0", seed, leave=True)
        away_v1 = _sector_episode("v1", seed, leave=True)
        # -v0: leaving truncates, no exit term; -v1: it terminates and costs 1 per step left.
        assert away_v0[2] and not away_v0[1] and "reward_exit" not in away_v0[3]
        assert away_v1[1] and not away_v1[2]
        assert away_v1[3]["reward_exit"] == -(200 - away_v1[4])
        assert away_v1[0] < straight_v1[0]
        # Flying at the own waypoint leaves through the exit: terminated, no exit penalty.
        assert straight_v1[1] and straight_v1[3]["reward_exit"] == 0.0


def test_static_obstacle_starts_clear_and_the_goal_is_within_reach() -> None:
    n = 64
    far = {}
    for version in ("v0", "v1"):
        task = _task(f"StaticObstacleEnv-{version}", n)
        centre_km = ref_kwikdist(task.sim.lat[:, :1], task.sim.lon[:, :1], task.obstacle_centre_lat, task.obstacle_centre_lon) * NM2KM
        clearance = centre_km - task.obstacle_radius * NM2KM  # from the start to each obstacle's circle
        # Straight-line time to the waypoint at the start TAS, in decision steps of 10 s.
        far[version] = task.start_wpt_km * 1000.0 / (task.sim.tas[:, 0] * task.dt * task.action_frequency)
        if version == "v0":
            assert (clearance < 5.0).any()
            assert (far["v0"] > task.time_limit).any()
        else:
            assert (clearance > 5.0).all() and task.inside_obstacles().sum() == 0
            assert (far["v1"] < 0.8 * task.time_limit).all()


def test_static_obstacle_reward_is_evaluated_on_the_state_after_the_step() -> None:
    """-v0 charges the drift of the previous observation (stale); -v1 the drift the step's own observation shows."""
    for version in ("v0", "v1"):
        env = gym.make(f"StaticObstacleEnv-{version}").unwrapped
        obs, _ = env.reset(seed=5)
        prev = obs
        for _ in range(3):
            obs, _, te, tr, info = env.step(np.array([0.8, 0.0]))
            assert not (te or tr)
            seen = prev if version == "v0" else obs
            drift = abs(np.arctan2(float(seen["destination_waypoint_sin_drift"][0]), float(seen["destination_waypoint_cos_drift"][0])))
            assert info["reward_drift"] == pytest.approx(-0.01 * drift, abs=1e-6)
            prev = obs


def test_merge_faf_is_reached_in_the_same_step() -> None:
    """bluesky-gym #13: -v0 shows the FAF reached one step late; -v1 in the step that reached it."""
    for version in ("v0", "v1"):
        env = gym.make(f"MergeEnv-{version}", spawn_distance_km=(40.0, 40.0), spawn_bearing_deg=0.0).unwrapped
        env.reset(seed=0)
        for _ in range(20):
            obs, r, te, tr, info = env.step(np.zeros(2))
            if info["faf_reach"] == 1:
                break
        assert info["faf_reach"] == 1 and info["reward_reach"] == 1.0
        assert obs["faf_reached"][0] == (1.0 if version == "v1" else 0.0)


def test_merge_fixes_units_and_airspeed() -> None:
    v0, v1 = _task("MergeEnv-v0", 2), _task("MergeEnv-v1", 2)
    assert ref_kwikdist(v1.airspace.faf_lat, v1.airspace.faf_lon, 52.36239301495972, 4.713195734579777) == pytest.approx(200.0, rel=2e-3)
    assert ref_kwikdist(v0.airspace.faf_lat, v0.airspace.faf_lon, 52.36239301495972, 4.713195734579777) == pytest.approx(200 / NM2KM, rel=2e-3)
    assert v1.airspace.faf_margin_nm == 10 / NM2KM and v1.airspace.goal_margin_nm == 20 / NM2KM
    assert v0.airspace.faf_margin_nm == 10.0
    np.testing.assert_allclose(v1.observe()["airspeed"][:, 0], (v1.sim.tas[:, 0] - 150) / 150, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(v0.observe()["airspeed"][:, 0], v0.sim.tas[:, 0])
    assert v1.time_limit == 100 and v0.time_limit == 50


def test_v1_renders_and_has_kpis() -> None:
    pytest.importorskip("pygame")
    for env_id in ("MergeEnv-v1", "SectorCREnv-v1"):
        env = gym.make(env_id, render_mode="rgb_array")
        env.reset(seed=0)
        frame = env.render()
        assert frame.ndim == 3 and frame.std() > 0
        env.close()


def test_real_traffic_v1_has_the_float32_finite_spaces_that_v0_lacks() -> None:
    """RealTrafficCREnv-v0: float64 spaces with infinite bounds (check_env warns twice); -v1: float32, finite.

    That -v1 passes the checkers without a warning is test_checkers_accept_v1_without_warnings.
    """
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", UserWarning)
        check_env(gym.make("RealTrafficCREnv-v0").unwrapped, skip_render_check=True)
    said = [str(w.message) for w in caught if issubclass(w.category, UserWarning)]
    assert any("minimum value is -infinity" in m for m in said) and any("maximum value is infinity" in m for m in said)
    v0, v1 = gym.make("RealTrafficCREnv-v0"), gym.make("RealTrafficCREnv-v1")
    assert not np.isfinite(v0.observation_space["ownship"].low).any()
    for key in ("ownship", "intruders"):
        box = v1.observation_space[key]
        assert box.dtype == np.float32 and np.isfinite(box.low).all() and np.isfinite(box.high).all() and len(box.shape) == 1
    # the same values: -v1's intruders are -v0's rows, intruder by intruder
    o0, _ = v0.reset(seed=4)
    o1, _ = v1.reset(seed=4)
    np.testing.assert_array_equal(o1["intruders"], o0["intruders"].reshape(-1).astype(np.float32))
    np.testing.assert_array_equal(o1["ownship"], o0["ownship"].astype(np.float32))
    assert gym.spec("RealTrafficCREnv-v1").kwargs == {"env_id": "RealTrafficCREnv-v1", "float32_spaces": True}  # the id, for its errors


def test_real_traffic_v1_position_bound_follows_the_scenario_options() -> None:
    """A larger radius or a longer window reaches further: the declared bound of the intruder offsets grows with them."""
    small = gym.make("RealTrafficCREnv-v1").observation_space["intruders"].high[0]
    wide = gym.make("RealTrafficCREnv-v1", radius_nm=200.0, window_s=1200.0).observation_space["intruders"].high[0]
    assert wide > small >= 25.0


def test_real_traffic_v1_bounds_hold_with_an_agent_steering_hard() -> None:
    """Full deflections held for whole episodes (the ownship leaves its route as fast as it can): the task's values stay within the bounds."""
    n = 16
    task = _task("RealTrafficCREnv-v1", n, seed=3)
    spec = task.observation_spec
    rng = np.random.default_rng(1)
    sides = rng.choice([-1.0, 1.0], size=(n, 2))
    for _ in range(task.time_limit):
        for key, value in task.observe().items():
            assert np.isfinite(value).all() and (value >= spec[key].low).all() and (value <= spec[key].high).all(), key
        task.step(sides)
