"""StaticObstacle's step on the device: its sub-steps, measure, observation and reward kernels in the shared device pipeline.

With ``gym.make_vec(id, device="cuda")`` the physics always runs on the device
(:class:`~bluesky_gym.core.DeviceSimulator`). For StaticObstacle (``-v0`` and ``-v1``, without
wind; its registry row's ``device_step``) the rest of the step runs there too: the pipeline of
:class:`~bluesky_gym.envs.device.DeviceStep` (actions, statistics, truncation, KPIs, autoreset)
with StaticObstacle's stages (:class:`StaticObstacleDeviceStep`):

* the sub-steps (:meth:`StaticObstacleDeviceStep.advance`): an episode stops at the sub-step
  that ends it, as :meth:`~bluesky_gym.environments.static_obstacle.task.StaticObstacleTask.advance`
  does. The CPU runs the sub-steps in one traced physics call and rewinds the episodes that
  ended early; the device runs them one physics step at a time, each followed by
  :func:`~bluesky_gym.environments.static_obstacle.task.obstacle_substep_end` (the CPU's stop
  rule, on the positions after that sub-step) and
  :func:`~bluesky_gym.environments.static_obstacle.task.hold_ended` (which keeps the state of the
  episodes that ended there); after the last,
  :func:`~bluesky_gym.environments.static_obstacle.task.restore_ended` gives them that state
  back, and (``-v0``) :func:`~bluesky_gym.environments.static_obstacle.task.obstacle_drift_samples`
  adds the sub-steps' |drift| samples;
* measure: :func:`~bluesky_gym.environments.static_obstacle.task.obstacle_measure`, one launch;
* the observation: views of the measured tensors (:func:`~bluesky_gym.environments.static_obstacle.task.observation`);
* reward, termination and the episode's flags and sums:
  :func:`~bluesky_gym.environments.static_obstacle.task.obstacle_reward`, one launch;
* the info's ``average_drift`` (:func:`~bluesky_gym.tasks.compiled.sample_means`), one launch;
  the KPIs' extra track is the shared one (the start-to-waypoint distance as the nominal route).

These are the kernels the CPU task runs (their CUDA forms): no rule of the task is written here a
second time. Under numba-cuda's simulator (``NUMBA_ENABLE_CUDASIM=1``) the outputs equal the CPU
vector environment's bit for bit (``tests/device/test_device_step_static_obstacle.py``).
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from bluesky_gym.core.state import FLOAT_FIELDS
from bluesky_gym.environments.static_obstacle import task as so
from bluesky_gym.envs.device import DeviceStep, TensorIO
from bluesky_gym.tasks.base import StepGeometry, Task

__all__ = ["StaticObstacleDeviceStep"]

#: The task's per-episode host arrays the device step reads or updates (:meth:`StaticObstacleDeviceStep.host_arrays`).
HOST_ARRAYS = (
    "wpt_lat",
    "wpt_lon",
    "obstacle_centre_lat",
    "obstacle_centre_lon",
    "obstacle_radius",
    "obstacle_lat",
    "obstacle_lon",
    "obstacle_nv",
    "last_wpt_km",
    "last_drift",
    "wpt_reached",
    "crashed",
    "intrusions",
    "drift_sum_rad",
    "drift_count",
)


class StaticObstacleDeviceStep(DeviceStep):
    """StaticObstacle's step on the device (the module docstring; the arguments: :class:`~bluesky_gym.envs.device.DeviceStep`'s)."""

    task_class: ClassVar[type[Task]] = so.StaticObstacleTask
    task: so.StaticObstacleTask

    def __init__(self, task: so.StaticObstacleTask, io: TensorIO) -> None:
        super().__init__(task, io)
        self.heading_step, self.speed_step = so.D_HEADING, so.speed_change(task.config)
        torch, n, m = self.torch, self.n, self.m
        #: (n_envs,) the sub-step at which each episode ended in this decision step (0: it ran them all).
        self.ended_at = self.empty(n, dtype=torch.int64)
        #: The state of the episodes that ended before the last sub-step, as they ended.
        self.held = self.empty(len(FLOAT_FIELDS), n, m)

    def host_arrays(self) -> dict[str, np.ndarray]:
        """The obstacles, the waypoint, the last observation's waypoint terms and the episode's flags and sums."""
        return {name: getattr(self.task, name) for name in HOST_ARRAYS}

    def advance(self) -> None:
        """The sub-steps one physics step at a time; each episode stops at the sub-step that ends it (see the module docstring)."""
        t, a, n, m = self.task, self.arrays, self.n, self.m
        c = t.config
        substeps = int(t.action_frequency)
        stale_goal = not c.step_reward
        self.ended_at.zero_()
        for k in range(1, substeps + 1):
            self.sim.step()
            lat, lon = self.sim.device_arrays("lat", "lon")
            self.launch(
                so.obstacle_substep_end,
                n,
                lat.reshape(1, n, m),
                lon.reshape(1, n, m),
                k,
                a["obstacle_lat"],
                a["obstacle_lon"],
                a["obstacle_nv"],
                stale_goal,
                a["last_wpt_km"],
                a["wpt_reached"],
                float(c.distance_margin_km),
                self.ended_at,
            )
            if k < substeps:  # (an episode that ends at the last sub-step keeps the state it has)
                self.launch(so.hold_ended, n, self.ended_at, k, self.sim.device_state(), self.held)
        self.launch(so.restore_ended, n, self.ended_at, substeps, self.sim.device_state(), self.held)
        if stale_goal:  # -v0: the sub-steps' |drift| samples (-v1 samples once per decision step, in the reward)
            self.launch(so.obstacle_drift_samples, n, a["last_drift"], self.ended_at, substeps, a["drift_sum_rad"], a["drift_count"])

    def measure(self, envs: Any, own: Any) -> so.StaticObstacleMeasurement:
        """:meth:`~bluesky_gym.environments.static_obstacle.task.StaticObstacleTask.measure` of rows ``envs`` on the device (one launch)."""
        p, torch, c, a = int(envs.shape[0]), self.torch, self.task.config, self.arrays
        lat, lon, hdg = self.sim.device_arrays("lat", "lon", "hdg")
        wpt_km, drift, stale = self.empty(p), self.empty(p), self.empty(p)
        count, reached, goal = self.empty(p, dtype=torch.int64), self.empty(p, dtype=torch.bool), self.empty(p, dtype=torch.bool)
        waypoint_obs, obstacle_obs = self.empty(p, 3), self.empty(4, p, c.num_obstacles)
        self.launch(
            so.obstacle_measure,
            p,
            envs,
            lat,
            lon,
            hdg,
            *(a[k] for k in ("wpt_lat", "wpt_lon", "obstacle_centre_lat", "obstacle_centre_lon", "obstacle_radius")),
            *(a[k] for k in ("obstacle_lat", "obstacle_lon", "obstacle_nv", "last_wpt_km", "last_drift", "wpt_reached")),
            float(c.distance_margin_km),
            bool(c.step_reward),
            float(c.waypoint_distance_max),
            wpt_km,
            drift,
            count,
            reached,
            stale,
            goal,
            waypoint_obs,
            obstacle_obs,
        )
        separation, los = self.no_traffic(p)
        return so.StaticObstacleMeasurement(
            envs=envs,
            separation_nm=separation,
            los=los,
            drift_deg=drift,
            goal_reached=goal,
            wpt_km=wpt_km,
            obstacle_count=count,
            newly_reached=reached,
            stale_drift_rad=stale,
            waypoint_obs=waypoint_obs,
            obstacle_obs=obstacle_obs,
        )

    def observe(self, g: StepGeometry) -> dict[str, Any]:
        """:func:`~bluesky_gym.environments.static_obstacle.task.observation`: views of the measured tensors."""
        assert isinstance(g, so.StaticObstacleMeasurement)
        return so.observation(g)

    def reward(self, g: StepGeometry) -> tuple[Any, Any, dict[str, Any]]:
        """Reach, drift and intrusion terms, termination and the episode's flags and sums (one launch)."""
        assert isinstance(g, so.StaticObstacleMeasurement)
        n, a = self.n, self.arrays
        reward, reach, drift, intrusion, terminated = self.empty(n), self.empty(n), self.empty(n), self.empty(n), self.empty(n, dtype=self.torch.bool)
        self.launch(
            so.obstacle_reward,
            n,
            g.envs,
            g.newly_reached,
            g.obstacle_count,
            g.stale_drift_rad,
            g.goal_reached,
            g.wpt_km,
            g.drift_deg,
            bool(self.task.config.step_reward),
            *(a[k] for k in ("wpt_reached", "crashed", "intrusions", "last_wpt_km", "last_drift", "drift_sum_rad", "drift_count")),
            reward,
            reach,
            drift,
            intrusion,
            terminated,
        )
        return reward, terminated, {"reach": reach, "drift": drift, "intrusion": intrusion}

    def episode_info(self) -> dict[str, Any]:
        """:meth:`~bluesky_gym.environments.static_obstacle.task.StaticObstacleTask.episode_info` on the device (one launch)."""
        a, int64 = self.arrays, self.torch.int64
        average_drift = self.sample_mean("drift_sum_rad", "drift_count", so.AVERAGE_DRIFT_EMPTY)
        return {
            "total_reward": self.stats["total_reward"].clone(),
            "waypoint_reached": a["wpt_reached"].to(int64),
            "crashed": a["crashed"].to(int64),
            "average_drift": average_drift,
        }

    def kpis(self) -> dict[str, Any]:
        """The common KPIs plus ``kpi_obstacle_intrusions`` (the restricted areas the aircraft was inside at the end)."""
        out = super().kpis()
        out["kpi_obstacle_intrusions"] = self.arrays["intrusions"].to(self.torch.float64)
        return out
