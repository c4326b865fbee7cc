"""StaticObstacle's decision step written out as the reference runs it, for one airspace (oracle).

The reference steps the simulator one sub-step at a time, evaluates the reward after each, and
returns at once when the episode ends. The package runs the sub-steps of a whole batch in one
traced physics call with a stop rule; the tests compare the two bit for bit.
"""

from __future__ import annotations

import numpy as np

from tests.oracle.geometry import points_in_polygons

REACH_REWARD = 1.0
DRIFT_PENALTY = -0.01  # per rad of |drift|
INTRUSION_PENALTY = -5.0  # per obstacle containing the aircraft


def reference_substeps(task) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """Run one decision step's sub-steps of a one-airspace task; reward, done and components of the last one."""
    assert task.n_envs == 1
    sim = task.sim
    for _ in range(task.action_frequency):
        sim.step()
        # The waypoint terms use the values of the last observation (stale), the obstacles the live position.
        new = (task.last_wpt_km < task.config.distance_margin_km) & ~task.wpt_reached
        task.wpt_reached |= new
        reach = np.where(new, REACH_REWARD, 0.0)
        drift_rad = np.abs(np.deg2rad(task.last_drift))
        drift = drift_rad * DRIFT_PENALTY
        task.drift_sum_rad += drift_rad
        task.drift_count += 1
        inside = points_in_polygons(sim.lat[:, :1], sim.lon[:, :1], task.obstacle_lat, task.obstacle_lon, task.obstacle_nv)[:, 0, :]
        count = inside.sum(axis=1)
        intrusion = count * INTRUSION_PENALTY
        task.crashed |= count > 0
        task.intrusions += count
        reward = reach + drift + intrusion
        done = task.wpt_reached | (count > 0)
        if done[0]:
            break
    return reward, done, {"reach": reach, "drift": drift, "intrusion": intrusion}
