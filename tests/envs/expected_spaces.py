"""The specification's observation and action spaces, per id: key -> (shape, low, high)."""

import numpy as np

INF = np.inf
_F = (-INF, INF)


def _k(shape, *keys, bounds=_F):
    return {k: (shape, *bounds) for k in keys}


OBSERVATION = {
    "DescentEnv-v0": _k((1,), "altitude", "vz", "target_altitude", "runway_distance"),
    "VerticalCREnv-v0": {
        **_k((1,), "altitude", "vz", "target_altitude", "runway_distance"),
        **_k(
            (5,),
            "intruder_distance",
            "cos_difference_pos",
            "sin_difference_pos",
            "altitude_difference",
            "x_difference_speed",
            "y_difference_speed",
            "z_difference_speed",
        ),
    },
    "HorizontalCREnv-v0": {
        **_k((5,), "intruder_distance", "cos_difference_pos", "sin_difference_pos", "x_difference_speed", "y_difference_speed"),
        **_k((1,), "waypoint_distance", "cos_drift", "sin_drift"),
    },
    "PlanWaypointEnv-v0": {
        **_k((5,), "waypoint_distance", "cos_difference", "sin_difference"),
        **_k((5,), "waypoint_reached", bounds=(0.0, 1.0)),
    },
    "SectorCREnv-v0": {
        **_k((1,), "cos(drift)", "sin(drift)", "airspeed", bounds=(-1.0, 1.0)),
        **_k((4,), "x_r", "y_r", "vx_r", "vy_r", "cos(track)", "sin(track)", "distances"),
    },
    "StaticObstacleEnv-v0": {
        **_k((1,), "destination_waypoint_distance", "destination_waypoint_cos_drift", "destination_waypoint_sin_drift"),
        **_k((10,), "restricted_area_radius", bounds=(0.0, 1.0)),
        **_k((10,), "restricted_area_distance", "cos_difference_restricted_area_pos", "sin_difference_restricted_area_pos"),
    },
    "MergeEnv-v0": {
        **_k((1,), "cos(drift)", "sin(drift)", bounds=(-1.0, 1.0)),
        **_k((1,), "airspeed", "waypoint_dist"),
        **_k((1,), "faf_reached", bounds=(0.0, 1.0)),
        **_k((5,), "x_r", "y_r", "vx_r", "vy_r", "cos(track)", "sin(track)", "distances"),
    },
}

ACTION_SHAPE = {
    "DescentEnv-v0": (1,),
    "VerticalCREnv-v0": (1,),
    "HorizontalCREnv-v0": (1,),
    "PlanWaypointEnv-v0": (1,),
    "SectorCREnv-v0": (2,),
    "StaticObstacleEnv-v0": (2,),
    "MergeEnv-v0": (2,),
}

MAX_EPISODE_STEPS = {
    "DescentEnv-v0": 300,
    "VerticalCREnv-v0": 300,
    "PlanWaypointEnv-v0": 300,
    "HorizontalCREnv-v0": 300,
    "SectorCREnv-v0": 200,
    "StaticObstacleEnv-v0": 100,
    "MergeEnv-v0": 50,
}

REFERENCE_INFO_KEYS = {
    "DescentEnv-v0": {"total_reward", "final_altitude"},
    "VerticalCREnv-v0": {"total_reward", "total_intrusions", "final_altitude"},
    "HorizontalCREnv-v0": {"total_reward", "total_intrusions", "average_drift"},
    "PlanWaypointEnv-v0": {"total_reward", "waypoints_completed"},
    "SectorCREnv-v0": {"total_reward", "total_intrusions", "average_drift"},
    "StaticObstacleEnv-v0": {"total_reward", "waypoint_reached", "crashed", "average_drift"},
    "MergeEnv-v0": {"total_reward", "faf_reach", "average_drift", "total_intrusions"},
}

# The -v1 versions: float32, finite bounds that hold (docs/environments-v1.md).
OBSERVATION_V1 = {
    "DescentEnv-v1": {
        **_k((1,), "altitude", "target_altitude", bounds=(-1.0, 5.0)),
        **_k((1,), "runway_distance", bounds=(-1.0, 1.0)),
        **_k((1,), "vz", bounds=(-4.0, 4.0)),
    },
    "VerticalCREnv-v1": {
        **_k((1,), "altitude", "target_altitude", bounds=(-1.0, 5.0)),
        **_k((5,), "altitude_difference", bounds=(-5.0, 5.0)),
        **_k((5,), "cos_difference_pos", "sin_difference_pos", bounds=(-1.0, 1.0)),
        **_k((5,), "intruder_distance", bounds=(0.0, 5.0)),
        **_k((1,), "runway_distance", bounds=(-1.0, 1.0)),
        **_k((1,), "vz", bounds=(-4.0, 4.0)),
        **_k((5,), "x_difference_speed", "y_difference_speed", bounds=(-4.0, 4.0)),
        **_k((5,), "z_difference_speed", bounds=(-8.0, 8.0)),
    },
    "PlanWaypointEnv-v1": {
        **_k((5,), "cos_difference", "sin_difference", bounds=(-1.0, 1.0)),
        **_k((5,), "waypoint_distance", bounds=(0.0, 11.0)),
        **_k((5,), "waypoint_reached", bounds=(0.0, 1.0)),
    },
    "HorizontalCREnv-v1": {
        **_k((5,), "cos_difference_pos", "sin_difference_pos", bounds=(-1.0, 1.0)),
        **_k((1,), "cos_drift", "sin_drift", bounds=(-1.0, 1.0)),
        **_k((5,), "intruder_distance", bounds=(0.0, 40.0)),
        **_k((1,), "waypoint_distance", bounds=(0.0, 40.0)),
        **_k((5,), "x_difference_speed", "y_difference_speed", bounds=(-4.0, 4.0)),
    },
    "SectorCREnv-v1": {
        **_k((1,), "airspeed", "cos(drift)", "sin(drift)", bounds=(-1.0, 1.0)),
        **_k((4,), "cos(track)", "sin(track)", bounds=(-1.0, 1.0)),
        **_k((4,), "distances", bounds=(-4.0, 50.0)),
        **_k((4,), "vx_r", bounds=(-16.0, 16.0)),
        **_k((4,), "vy_r", bounds=(-8.0, 8.0)),
        **_k((4,), "x_r", "y_r", bounds=(-50.0, 50.0)),
    },
    "StaticObstacleEnv-v1": {
        **_k((10,), "cos_difference_restricted_area_pos", "sin_difference_restricted_area_pos", bounds=(-1.0, 1.0)),
        **_k((1,), "destination_waypoint_cos_drift", "destination_waypoint_sin_drift", bounds=(-1.0, 1.0)),
        **_k((1,), "destination_waypoint_distance", bounds=(0.0, 3.0)),
        **_k((10,), "restricted_area_distance", bounds=(0.0, 3.0)),
        **_k((10,), "restricted_area_radius", bounds=(0.0, 1.0)),
    },
    "MergeEnv-v1": {
        **_k((1,), "airspeed", "cos(drift)", "sin(drift)", bounds=(-1.0, 1.0)),
        **_k((5,), "cos(track)", "sin(track)", bounds=(-1.0, 1.0)),
        **_k((5,), "distances", bounds=(0.0, 8.0)),
        **_k((1,), "faf_reached", bounds=(0.0, 1.0)),
        **_k((5,), "vx_r", "vy_r", "x_r", "y_r", bounds=(-4.0, 4.0)),
        **_k((1,), "waypoint_dist", bounds=(0.0, 8.0)),
    },
}
OBSERVATION.update(OBSERVATION_V1)
ACTION_SHAPE.update({k.replace("-v0", "-v1"): v for k, v in list(ACTION_SHAPE.items())})
MAX_EPISODE_STEPS.update({k.replace("-v0", "-v1"): v for k, v in list(MAX_EPISODE_STEPS.items())})
MAX_EPISODE_STEPS["MergeEnv-v1"] = 100  # the FAF at 200 NM needs up to ~66 steps
REFERENCE_INFO_KEYS.update({k.replace("-v0", "-v1"): v for k, v in list(REFERENCE_INFO_KEYS.items())})
# DenseSectorCREnv: SectorCREnv's observation and action, with a traffic flow (its own info keys too).
for _v in ("-v0", "-v1"):
    OBSERVATION["DenseSectorCREnv" + _v] = OBSERVATION["SectorCREnv" + _v]
    ACTION_SHAPE["DenseSectorCREnv" + _v] = (2,)
    MAX_EPISODE_STEPS["DenseSectorCREnv" + _v] = 200
    REFERENCE_INFO_KEYS["DenseSectorCREnv" + _v] = {"total_reward", "total_intrusions", "average_drift", "traffic", "spawned", "spawns_dropped"}
# RealTrafficCREnv: listed and checked whether its recorded data are prepared or not (the tests play
# synthetic stand-ins of the sample collections, tests/conftest.py).
OBSERVATION["RealTrafficCREnv-v0"] = {**_k((6,), "ownship"), **_k((5, 7), "intruders")}
# -v1: a bound per entry. ownship: route deviation +-10, cos and sin, CAS error +-20, altitude error
# +-5, vertical speed +-4; intruders, the 5 rows of 7 as one vector: offsets +-25 (30 NM + 4 x
# 700 kt x 600 s, / 20 NM), relative velocity +-4, relative altitude +-5, distance [0, 25], present [0, 1].
_OWN = np.array([10.0, 1.0, 1.0, 20.0, 5.0, 4.0])
_INTRUDER_LOW = np.tile([-25.0, -25.0, -4.0, -4.0, -5.0, 0.0, 0.0], 5)
_INTRUDER_HIGH = np.tile([25.0, 25.0, 4.0, 4.0, 5.0, 25.0, 1.0], 5)
OBSERVATION["RealTrafficCREnv-v1"] = {**_k((6,), "ownship", bounds=(-_OWN, _OWN)), **_k((35,), "intruders", bounds=(_INTRUDER_LOW, _INTRUDER_HIGH))}
for _id in ("RealTrafficCREnv-v0", "RealTrafficCREnv-v1"):
    MAX_EPISODE_STEPS[_id] = 60
    ACTION_SHAPE[_id] = (2,)
    REFERENCE_INFO_KEYS[_id] = {"total_reward", "total_intrusions", "average_route_deviation_nm"}
#: dtype of the observation and action spaces.
DTYPE = {k: (np.float32 if k.endswith("-v1") else np.float64) for k in OBSERVATION}
