"""The reference policies decode observations and scale actions with the tasks' constants, never with copies."""

from __future__ import annotations

import ast
import importlib
import inspect
from types import ModuleType

import numpy as np
import pytest

from bluesky_gym.core.units import NM, NM2KM
from bluesky_gym.environments.descent import controller as descent_controller
from bluesky_gym.environments.descent import task as descent
from bluesky_gym.environments.horizontal_cr import task as horizontal_cr
from bluesky_gym.environments.merge import task as merge
from bluesky_gym.environments.plan_waypoint import task as plan_waypoint
from bluesky_gym.environments.plan_waypoint.controller import PlanWaypointController
from bluesky_gym.environments.real_traffic import task as rt
from bluesky_gym.environments.sector_cr import task as sector_cr
from bluesky_gym.environments.static_obstacle import task as static_obstacle
from bluesky_gym.environments.static_obstacle.controller import StaticObstacleController
from bluesky_gym.environments.vertical_cr import task as vertical_cr
from bluesky_gym.envs.registry import PAPER_ENVIRONMENTS, resolve
from bluesky_gym.training import make_vector_env, policies

#: The modules of the reference policies: the shared one and every environment's controller module.
POLICY_MODULES = [
    policies,
    *sorted({importlib.import_module(row.classical.partition(":")[0]) for row in PAPER_ENVIRONMENTS if row.classical}, key=str),
]

#: The task-owned scales the controllers use (observation scales, action steps, protected zones), in
#: the units the controllers use them in. The step length (30 s) is left out: it equals the
#: controllers' own 30 km alert distance.
TASK_SCALES: dict[str, float] = {
    "descent.ALT_MEAN": descent.ALT_MEAN,
    "descent.ALT_STD": descent.ALT_STD,
    "descent.RWY_DIS_MEAN": descent.RWY_DIS_MEAN,
    "descent.RWY_DIS_STD": descent.RWY_DIS_STD,
    "descent.ACTION_2_MS": descent.ACTION_2_MS,
    "vertical_cr.INTRUDER_DISTANCE_SCALE": vertical_cr.INTRUDER_DISTANCE_SCALE,
    "horizontal_cr.D_HEADING": horizontal_cr.D_HEADING,
    "horizontal_cr.DISTANCE_SCALE": horizontal_cr.DISTANCE_SCALE,
    "plan_waypoint.D_HEADING": plan_waypoint.D_HEADING,
    "PlanWaypointConfig.waypoint_distance_max": plan_waypoint.PlanWaypointConfig.waypoint_distance_max,
    "sector_cr.D_HEADING": sector_cr.D_HEADING,
    "sector_cr.POSITION_SCALE": sector_cr.POSITION_SCALE,
    "sector_cr.VX_SCALE": sector_cr.VX_SCALE,
    "sector_cr.VY_SCALE": sector_cr.VY_SCALE,
    "sector_cr.INTRUSION_DISTANCE [m]": sector_cr.INTRUSION_DISTANCE * NM,
    "merge.D_HEADING": merge.D_HEADING,
    "merge.POSITION_SCALE": merge.POSITION_SCALE,
    "merge.SPEED_SCALE": merge.SPEED_SCALE,
    "merge.INTRUSION_DISTANCE [m]": merge.INTRUSION_DISTANCE * NM,
    "static_obstacle.D_HEADING": static_obstacle.D_HEADING,
    "StaticObstacleConfig.waypoint_distance_max": static_obstacle.StaticObstacleConfig.waypoint_distance_max,
    "static_obstacle.RADIUS_SCALE_NM [km]": static_obstacle.RADIUS_SCALE_NM * NM2KM,
    "real_traffic.POSITION_SCALE [m]": rt.POSITION_SCALE * NM,
    "real_traffic.VELOCITY_SCALE": rt.VELOCITY_SCALE,
    "real_traffic.ALTITUDE_SCALE": rt.ALTITUDE_SCALE,
}


def _numeric_literals(module: object) -> list[tuple[int, float]]:
    """(line, value) of every int or float literal in a module's source (docstrings and comments are not literals)."""
    tree = ast.parse(inspect.getsource(module))  # type: ignore[arg-type]
    return [
        (node.lineno, float(node.value))
        for node in ast.walk(tree)
        if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)) and not isinstance(node.value, bool)
    ]


def test_the_scale_list_is_distinct_from_trivial_numbers() -> None:
    """Every listed scale is a real, non-trivial number (0 and 1 would match every clip bound)."""
    assert all(abs(v) not in (0.0, 1.0) for v in TASK_SCALES.values()), TASK_SCALES


def test_every_controller_module_is_checked() -> None:
    assert len(POLICY_MODULES) == 9  # training/policies.py and the eight environments' controller.py
    assert all(resolve(row.classical).__module__ in {m.__name__ for m in POLICY_MODULES} for row in PAPER_ENVIRONMENTS if row.classical)


@pytest.mark.parametrize("module", POLICY_MODULES, ids=lambda m: m.__name__)
def test_policies_declare_no_copy_of_a_task_scale(module: ModuleType) -> None:
    """No number in a controller module equals a scale a task owns: the controllers import them."""
    literals = _numeric_literals(module)
    copies = [f"line {line}: {value:g} == {name}" for line, value in literals for name, scale in TASK_SCALES.items() if value == scale]
    assert not copies, f"{module.__name__} re-declares task constants: " + "; ".join(copies)


def test_the_literal_scan_reads_the_controllers_tuning() -> None:
    """The scan sees a module's own numbers (the descent controller's glide slope), so a copied scale would be seen too."""
    assert any(v == descent_controller.GLIDE_SLOPE for _, v in _numeric_literals(descent_controller))


def _bound(controller: policies.Policy, env_id: str, **options: float) -> policies.Policy:
    venv = make_vector_env(env_id, 1, **options)
    try:
        controller.bind(venv)
    finally:
        venv.close()
    return controller


@pytest.mark.parametrize("env_id", ["PlanWaypointEnv-v0", "PlanWaypointEnv-v1"])
def test_plan_waypoint_controller_decodes_with_its_environments_scale(env_id: str) -> None:
    """Waypoint 0 is 0.04 units away: 3 km (captured) at the default 75 km scale, 6 km (open) at 150 km."""
    drift = np.radians([[30.0, -30.0]])  # waypoint 0 to the left (turn left, a < 0), waypoint 1 to the right
    obs = {
        "waypoint_distance": np.array([[0.04, 0.5]]),
        "waypoint_reached": np.zeros((1, 2)),
        "sin_difference": np.sin(drift),
        "cos_difference": np.cos(drift),
    }
    default = _bound(PlanWaypointController(), env_id)
    wide = _bound(PlanWaypointController(), env_id, waypoint_distance_max=150)
    np.testing.assert_allclose(PlanWaypointController().act(obs), [[30.0 / 45.0]])  # unbound: the default scale
    np.testing.assert_allclose(default.act(obs), [[30.0 / 45.0]])
    np.testing.assert_allclose(wide.act(obs), [[-30.0 / 45.0]])


@pytest.mark.parametrize("env_id", ["StaticObstacleEnv-v0", "StaticObstacleEnv-v1"])
def test_static_obstacle_controller_decodes_with_its_environments_scale(env_id: str) -> None:
    """An obstacle dead ahead at 0.2 units blocks the path at the default 170 km scale (34 km), not at 400 km (80 km)."""
    ahead = np.zeros((1, 1))
    obs = {
        "destination_waypoint_distance": np.array([[0.5]]),
        "destination_waypoint_sin_drift": ahead,
        "destination_waypoint_cos_drift": np.ones((1, 1)),
        "restricted_area_radius": np.array([[0.02]]),
        "restricted_area_distance": np.array([[0.2]]),
        "sin_difference_restricted_area_pos": ahead,
        "cos_difference_restricted_area_pos": np.ones((1, 1)),
    }
    default = _bound(StaticObstacleController(), env_id)
    far = _bound(StaticObstacleController(), env_id, waypoint_distance_max=400)
    assert default.act(obs)[0, 0] != 0.0  # turns around the obstacle
    assert far.act(obs)[0, 0] == 0.0  # straight to the goal
