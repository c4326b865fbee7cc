"""The reference policies: controller geometry on hand-made observations, and scores."""

from __future__ import annotations

import numpy as np
import pytest

from bluesky_gym.envs.registry import ENVIRONMENTS, entry
from bluesky_gym.registration import available_envs
from bluesky_gym.training.evaluation import evaluate, make_policy
from bluesky_gym.training.policies import (
    DescentController,
    HorizontalCRController,
    MergeController,
    PlanWaypointController,
    RandomPolicy,
    SectorCRController,
    StaticObstacleController,
    VerticalCRController,
    _cpa_turn,
    reference_policy,
)


def _deg(a: float) -> tuple[np.ndarray, np.ndarray]:
    return np.sin(np.radians([[a]])), np.cos(np.radians([[a]]))


def test_random_policy_is_seeded_and_in_bounds() -> None:
    obs = {"x": np.zeros((5, 3))}
    a = RandomPolicy(np.array([-1.0, -1.0]), np.array([1.0, 1.0]), seed=3).act(obs)
    b = RandomPolicy(np.array([-1.0, -1.0]), np.array([1.0, 1.0]), seed=3).act(obs)
    assert a.shape == (5, 2) and np.all(np.abs(a) <= 1) and np.array_equal(a, b)


def test_every_paper_env_has_a_classical_controller() -> None:
    paper = {
        "DescentEnv-v0",
        "VerticalCREnv-v0",
        "HorizontalCREnv-v0",
        "PlanWaypointEnv-v0",
        "SectorCREnv-v0",
        "StaticObstacleEnv-v0",
        "MergeEnv-v0",
        "RealTrafficCREnv-v0",
        "DenseSectorCREnv-v0",  # SectorCREnv's controller
    }
    # Every row names its controller; the -v1 ids (same observation scales where the controllers
    # read them) use their -v0 row's.
    assert {e.id for e in ENVIRONMENTS if e.classical} == paper | {e.replace("-v0", "-v1") for e in paper}
    assert all(entry(e).classical == entry(e.replace("-v0", "-v1")).classical for e in paper)
    assert all(type(reference_policy("classical", e.id, np.zeros(1), np.ones(1))).__name__ == e.classical.rpartition(":")[2] for e in ENVIRONMENTS)
    with pytest.raises(ValueError):
        reference_policy("greedy", "DescentEnv-v0", np.array([-1.0]), np.array([1.0]))


def _descent_obs(alt: float, target: float, rd_km: float) -> dict[str, np.ndarray]:
    return {
        "altitude": np.array([[(alt - 1500) / 3000]]),
        "vz": np.zeros((1, 1)),
        "target_altitude": np.array([[(target - 1500) / 3000]]),
        "runway_distance": np.array([[(rd_km - 100) / 200]]),
    }


def test_descent_holds_target_then_descends() -> None:
    c = DescentController()
    hold = c.act(_descent_obs(3000, 3000, 180))[0, 0]
    assert abs(hold) <= 0.02 and abs(hold) >= 0.01  # outside BlueSky's default-VS band
    assert c.act(_descent_obs(2500, 3000, 180))[0, 0] > 0.5  # below target: climb
    assert c.act(_descent_obs(3000, 3000, 20))[0, 0] == -1.0  # near the runway: dive


def test_vertical_avoids_an_intruder_at_its_level() -> None:
    c = VerticalCRController()
    obs = _descent_obs(3000, 3000, 180)
    obs.update(
        {
            "intruder_distance": np.array([[20 / 200, 150 / 200]]),
            "altitude_difference": np.array([[50 / 3000, 0.0]]),  # 50 m above, 20 km away
        }
    )
    assert c.act(obs)[0, 0] < -0.5  # closing in (no history): go below it
    obs["intruder_distance"] = np.array([[25 / 200, 150 / 200]])
    assert abs(c.act(obs)[0, 0]) <= 0.02  # moving away now: back to holding
    c.reset()
    obs["altitude_difference"] = np.array([[-50 / 3000, 0.0]])
    assert c.act(obs)[0, 0] > 0.5  # intruder below: climb


def test_horizontal_steers_to_goal_and_turns_away() -> None:
    c = HorizontalCRController()
    sd, cd = _deg(20.0)  # drift +20: the waypoint is to the left
    far = {
        "sin_drift": sd,
        "cos_drift": cd,
        "intruder_distance": np.full((1, 2), 100 / 150),
        "sin_difference_pos": np.zeros((1, 2)),
        "cos_difference_pos": np.ones((1, 2)),
    }
    assert c.act(far)[0, 0] == pytest.approx(-20 / 45)
    c.reset()
    sp, cp = _deg(30.0)  # intruder 30 deg to the left, 15 km ahead
    near = dict(
        far,
        intruder_distance=np.array([[15 / 150, 100 / 150]]),
        sin_difference_pos=np.array([[sp[0, 0], 0.0]]),
        cos_difference_pos=np.array([[cp[0, 0], 1.0]]),
    )
    assert c.act(near)[0, 0] == 1.0  # turn right
    c.reset()
    near["sin_difference_pos"] = -near["sin_difference_pos"]
    assert c.act(near)[0, 0] == -1.0  # intruder on the right: turn left


def test_plan_waypoint_goes_to_the_nearest_open_waypoint() -> None:
    s, c = np.sin(np.radians([[10.0, -30.0, 50.0]])), np.cos(np.radians([[10.0, -30.0, 50.0]]))
    obs = {
        "waypoint_distance": np.array([[10 / 75, 20 / 75, 0.0]]),
        "waypoint_reached": np.array([[1.0, 0.0, 0.0]]),
        "sin_difference": s,
        "cos_difference": c,
    }
    # Waypoint 0 is reached and waypoint 2 is within the capture radius: fly to waypoint 1.
    assert PlanWaypointController().act(obs)[0, 0] == pytest.approx(30 / 45)


def test_cpa_turn_geometry() -> None:
    # North/east metres. Head-on, intruder 20 km north passing 2 km east of the ownship: the
    # ownship (flying north) should turn left, away from it.
    alert, turn = _cpa_turn(np.array([[20000.0]]), np.array([[2000.0]]), np.array([[-300.0]]), np.array([[0.0]]), 9260.0, 180.0)
    assert alert[0] and turn[0] == -1.0
    alert, turn = _cpa_turn(np.array([[20000.0]]), np.array([[-2000.0]]), np.array([[-300.0]]), np.array([[0.0]]), 9260.0, 180.0)
    assert alert[0] and turn[0] == 1.0
    # Diverging, or a wide miss: no alert.
    alert, _ = _cpa_turn(np.array([[20000.0]]), np.array([[0.0]]), np.array([[300.0]]), np.array([[0.0]]), 9260.0, 180.0)
    assert not alert[0]
    alert, _ = _cpa_turn(np.array([[20000.0]]), np.array([[15000.0]]), np.array([[-300.0]]), np.array([[0.0]]), 9260.0, 180.0)
    assert not alert[0]


def test_sector_and_merge_turn_away_and_otherwise_steer() -> None:
    sd, cd = _deg(0.0)
    base = {"sin(drift)": sd, "cos(drift)": cd}
    conflict = dict(base, x_r=np.array([[20000 / 13000]]), y_r=np.array([[2000 / 13000]]), vx_r=np.array([[-300 / 32]]), vy_r=np.array([[0.0]]))
    assert SectorCRController().act(conflict)[0].tolist() == [-1.0, 0.0]
    clear = dict(conflict, y_r=np.array([[40000 / 13000]]))
    assert SectorCRController().act(clear)[0].tolist() == [0.0, 0.0]
    merge = dict(base, x_r=np.array([[20000 / 1e6]]), y_r=np.array([[-2000 / 1e6]]), vx_r=np.array([[-300 / 150]]), vy_r=np.array([[0.0]]))
    assert MergeController().act(merge)[0].tolist() == [1.0, 0.0]


def test_static_obstacle_goes_around() -> None:
    def obs(obstacle_deg: float, dist_km: float) -> dict[str, np.ndarray]:
        so, co = _deg(obstacle_deg)
        sg, cg = _deg(0.0)
        return {
            "destination_waypoint_distance": np.array([[120 / 170]]),
            "destination_waypoint_sin_drift": sg,
            "destination_waypoint_cos_drift": cg,
            "restricted_area_radius": np.array([[10 / 50]]),  # 10 NM = 18.5 km
            "restricted_area_distance": np.array([[dist_km / 170]]),
            "sin_difference_restricted_area_pos": so,
            "cos_difference_restricted_area_pos": co,
        }

    free = StaticObstacleController().act(obs(90.0, 40.0))[0]
    assert free.tolist() == [0.0, 1.0]  # obstacle off to the side: straight to the goal, full speed
    blocked = StaticObstacleController().act(obs(0.0, 40.0))[0]
    # Dead ahead at 40 km, radius 18.5 km + 3 km margin: the smallest clear turn (5 deg steps) is
    # 35 deg, where the centre's lateral offset 40 sin(35) = 22.9 km exceeds 21.5 km.
    assert abs(blocked[0]) == pytest.approx(35 / 45) and blocked[1] == 1.0


@pytest.mark.parametrize("env_id", available_envs())
def test_classical_beats_random(env_id: str) -> None:
    random = evaluate(env_id, make_policy("random", env_id), 24)
    classical = evaluate(env_id, make_policy("classical", env_id), 24)
    assert classical.mean_return > random.mean_return
