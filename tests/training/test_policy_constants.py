"""The reference policies decode observations and scale actions with the tasks' constants, never with copies."""

from __future__ import annotations

import ast
import inspect

from bluesky_gym.core.units import NM, NM2KM
from bluesky_gym.tasks import descent, horizontal_cr, merge, plan_waypoint, sector_cr, static_obstacle, vertical_cr
from bluesky_gym.tasks import real_traffic as rt
from bluesky_gym.training import policies

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


def test_policies_declare_no_copy_of_a_task_scale() -> None:
    """No number in training/policies.py equals a scale a task owns: the controllers import them."""
    literals = _numeric_literals(policies)
    assert any(v == policies.GLIDE_SLOPE for _, v in literals)  # the controllers' own tuning is read
    copies = [f"line {line}: {value:g} == {name}" for line, value in literals for name, scale in TASK_SCALES.items() if value == scale]
    assert not copies, "training/policies.py re-declares task constants: " + "; ".join(copies)
