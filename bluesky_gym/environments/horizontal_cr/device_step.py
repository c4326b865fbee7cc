"""HorizontalCR's step on the device: its command, measure, observation and reward kernels in the shared device pipeline.

With ``gym.make_vec(id, device="cuda")`` the physics always runs on the device
(:class:`~bluesky_gym.core.DeviceSimulator`). For HorizontalCR (``-v0`` and ``-v1``, without wind;
its registry row's ``device_step``) the rest of the step runs there too: the pipeline of
:class:`~bluesky_gym.envs.device.DeviceStep` (actions, physics, statistics, truncation, KPIs,
autoreset) with HorizontalCR's stages (:class:`HorizontalCRDeviceStep`):

* the action: :func:`~bluesky_gym.tasks.compiled.command_heading` (the heading
  at the last observation + 45 a), one launch;
* measure: :func:`~bluesky_gym.tasks.compiled.intruder_relative_state`,
  :func:`~bluesky_gym.tasks.compiled.goal_geometry`,
  :func:`~bluesky_gym.environments.horizontal_cr.task.waypoint_progress` and
  :func:`~bluesky_gym.tasks.compiled.kwik_separation`, one launch each;
* the observation: the measured tensors scaled
  (:func:`~bluesky_gym.environments.horizontal_cr.task.observation`); the observed heading is
  kept as the next action's reference;
* reward, the reach flag, the termination and the episode sums:
  :func:`~bluesky_gym.environments.horizontal_cr.task.row_reward` and
  :func:`~bluesky_gym.environments.horizontal_cr.task.episode_reward`, one launch each;
* the info's ``average_drift`` (:func:`~bluesky_gym.tasks.compiled.sample_means`), one launch; in
  a step where an episode ends, the shared extra track KPI (the shortest path to the capture circle
  as the nominal route).

These are the kernels the CPU task runs (their CUDA forms): no rule of the task is written here a
second time. Under numba-cuda's simulator (``NUMBA_ENABLE_CUDASIM=1``) the outputs equal the CPU
vector environment's bit for bit (``tests/device/test_device_step_horizontal_cr.py``).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, ClassVar

import numpy as np

from bluesky_gym.environments.horizontal_cr import task as hc
from bluesky_gym.envs.device import DeviceStep
from bluesky_gym.tasks import compiled
from bluesky_gym.tasks.base import StepGeometry, Task

__all__ = ["HorizontalCRDeviceStep"]


class HorizontalCRDeviceStep(DeviceStep):
    """HorizontalCR's step on the device (the module docstring; the arguments: :class:`~bluesky_gym.envs.device.DeviceStep`'s)."""

    task_class: ClassVar[type[Task]] = hc.HorizontalCRTask
    task: hc.HorizontalCRTask
    heading_step: float = hc.D_HEADING

    def host_arrays(self) -> dict[str, np.ndarray]:
        """The waypoints, the reach flags, the action's reference heading, the start's distance to the waypoint and the info's sums."""
        t = self.task
        names = ("wpt_lat", "wpt_lon", "wpt_reach", "ac_hdg", "total_intrusions", "drift_rad_sum", "drift_rad_n")
        return {k: getattr(t, k) for k in names}

    def command(self, action: Any) -> None:
        """:meth:`~bluesky_gym.environments.horizontal_cr.task.HorizontalCRTask.apply_action` on the device (one launch).

        The kernel :func:`~bluesky_gym.tasks.compiled.command_heading`.
        """
        ap_trk, swlnav = self.sim.device_arrays("ap_trk", "swlnav")
        self.launch(compiled.command_heading, self.n, self.envs, self.own, self.arrays["ac_hdg"], action, float(self.heading_step), ap_trk, swlnav)

    def measure(self, envs: Any, own: Any) -> hc.HorizontalCRGeometry:
        """:func:`bluesky_gym.environments.horizontal_cr.task.measure` of rows ``envs`` on the device (four launches)."""
        p, m = int(envs.shape[0]), self.m
        torch = self.torch
        lat, lon, hdg, gs, alt, active = self.sim.device_arrays("lat", "lon", "hdg", "gs", "alt", "active")
        a = self.arrays
        rows: Callable[[Any], Any] = (lambda x: x) if envs is self.envs else (lambda x: x[envs].contiguous())
        intruders, n_others = self.empty(5, p, m - 1), self.empty(p, dtype=torch.int64)
        self.launch(compiled.intruder_relative_state, p, envs, own, lat, lon, hdg, gs, active, False, intruders, n_others)
        drift, dist_nm, waypoint_km, heading, cos_drift, sin_drift = (self.empty(p) for _ in range(6))
        newly, goal = self.empty(p, dtype=torch.bool), self.empty(p, dtype=torch.bool)
        self.launch(compiled.goal_geometry, p, envs, own, lat, lon, hdg, rows(a["wpt_lat"]), rows(a["wpt_lon"]), drift, dist_nm)
        progress = (waypoint_km, heading, cos_drift, sin_drift, newly, goal)
        self.launch(hc.waypoint_progress, p, envs, own, hdg, drift, dist_nm, rows(a["wpt_reach"]), hc.DISTANCE_MARGIN, *progress)
        separation, los = self.empty(p, m), self.empty(p, m, dtype=torch.bool)
        self.launch(compiled.kwik_separation, p, envs, own, lat, lon, alt, active, hc.INTRUSION_DISTANCE, np.nan, separation, los)
        waypoint = (heading, waypoint_km, cos_drift, sin_drift, newly)
        return hc.HorizontalCRGeometry(envs, separation, los, drift, goal, own, intruders, n_others, *waypoint)

    def observe(self, g: StepGeometry) -> dict[str, Any]:
        """:meth:`~bluesky_gym.environments.horizontal_cr.task.HorizontalCRTask.observe`: the observed heading kept, the observation scaled."""
        assert isinstance(g, hc.HorizontalCRGeometry)
        self.arrays["ac_hdg"][g.envs] = g.heading
        return hc.observation(g)

    def reward(self, g: StepGeometry) -> tuple[Any, Any, dict[str, Any]]:
        """Reach, drift and intrusion terms; the reach flag, the termination and the episode sums (two launches)."""
        assert isinstance(g, hc.HorizontalCRGeometry)
        n, a = self.n, self.arrays
        reward, reach, drift_c, intrusion_c = (self.empty(n) for _ in range(4))
        count, terminated = self.empty(n, dtype=self.torch.int64), self.empty(n, dtype=self.torch.bool)
        penalties = (hc.REACH_REWARD, hc.DRIFT_PENALTY, hc.INTRUSION_PENALTY)
        self.launch(hc.row_reward, n, g.newly_reached, g.drift_deg, g.los, *penalties, reward, reach, drift_c, intrusion_c, count)
        sums = (a["drift_rad_sum"], a["drift_rad_n"], a["total_intrusions"])
        self.launch(hc.episode_reward, n, self.envs, g.drift_deg, count, g.goal_reached, a["wpt_reach"], *sums, terminated)
        return reward, terminated, {"reach": reach, "drift": drift_c, "intrusion": intrusion_c}

    def episode_info(self) -> dict[str, Any]:
        """:meth:`bluesky_gym.environments.horizontal_cr.task.HorizontalCRTask.episode_info` on the device (one launch)."""
        a = self.arrays
        average_drift = self.sample_mean("drift_rad_sum", "drift_rad_n", hc.AVERAGE_DRIFT_EMPTY)
        return {"total_reward": self.stats["total_reward"].clone(), "total_intrusions": a["total_intrusions"].clone(), "average_drift": average_drift}
