"""PlanWaypoint's step on the device: its command, measure, observation and reward kernels in the shared device pipeline.

With ``gym.make_vec(id, device="cuda")`` the physics always runs on the device
(:class:`~bluesky_gym.core.DeviceSimulator`). For PlanWaypoint (``-v0`` and ``-v1``, without wind;
its registry row's ``device_step``) the rest of the step runs there too: the pipeline of
:class:`~bluesky_gym.envs.device.DeviceStep` (actions, physics, statistics, truncation, KPIs,
autoreset) with PlanWaypoint's stages (:class:`PlanWaypointDeviceStep`), each one launch of a
kernel of :mod:`bluesky_gym.environments.plan_waypoint.task`:

* the heading command: :func:`~bluesky_gym.tasks.compiled.command_heading`;
* measure: :func:`~bluesky_gym.environments.plan_waypoint.task.waypoint_measure` (no traffic: the
  separations are inf and there is no loss of separation, as on the CPU);
* the observation: :func:`~bluesky_gym.environments.plan_waypoint.task.waypoint_observation`;
* reward and the reach flags: :func:`~bluesky_gym.environments.plan_waypoint.task.waypoint_reward`;
* the info's ``waypoints_completed``: :func:`~bluesky_gym.environments.plan_waypoint.task.count_reached`;
* the ``kpi_extra_track_km`` of ended episodes: the shared one (the episodes' shortest tours).

Every option of the task runs there (any number of waypoints, distances, capture radius,
``airborne_start``, ``reach_same_step``, the ``-v1`` bounds); a ``wind`` option, effects or added
observation terms keep the task's step on the host (:meth:`~bluesky_gym.envs.device.DeviceStep.supports`).

These are the kernels the CPU task runs (their CUDA forms): no rule of the task is written here a
second time. The waypoints and the shortest tour of new episodes are drawn on the host
(:meth:`~bluesky_gym.environments.plan_waypoint.task.PlanWaypointTask.generate`) and uploaded for
those episodes only. Under numba-cuda's simulator (``NUMBA_ENABLE_CUDASIM=1``) the outputs equal
the CPU vector environment's bit for bit (``tests/device/test_device_step_plan_waypoint.py``).
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from bluesky_gym.environments.plan_waypoint import task as pw
from bluesky_gym.envs.device import DeviceStep, TensorIO
from bluesky_gym.tasks import compiled
from bluesky_gym.tasks.base import StepGeometry, Task

__all__ = ["PlanWaypointDeviceStep"]


class PlanWaypointDeviceStep(DeviceStep):
    """PlanWaypoint's step on the device (the module docstring; the arguments: :class:`~bluesky_gym.envs.device.DeviceStep`'s)."""

    task_class: ClassVar[type[Task]] = pw.PlanWaypointTask
    task: pw.PlanWaypointTask

    def __init__(self, task: pw.PlanWaypointTask, io: TensorIO) -> None:
        super().__init__(task, io)

    def host_arrays(self) -> dict[str, np.ndarray]:
        """The waypoints and their reach flags."""
        t = self.task
        return {"wpt_lat": t.wpt_lat, "wpt_lon": t.wpt_lon, "wpt_reached": t.wpt_reached}

    def command(self, action: Any) -> None:
        """The heading action as the HDG command from each aircraft's heading now (:func:`~bluesky_gym.tasks.compiled.command_heading`)."""
        hdg, ap_trk, swlnav = self.sim.device_arrays("hdg", "ap_trk", "swlnav")
        self.launch(compiled.command_heading, self.n, self.envs, self.own, hdg[:, 0], action, pw.D_HEADING, ap_trk, swlnav)

    def measure(self, envs: Any, own: Any) -> pw.PlanWaypointMeasurement:
        """:meth:`~bluesky_gym.environments.plan_waypoint.task.PlanWaypointTask.measure` of rows ``envs`` on the device (one launch)."""
        p, w = int(envs.shape[0]), self.task.config.num_waypoints
        bool_ = self.torch.bool
        lat, lon, hdg = self.sim.device_arrays("lat", "lon", "hdg")
        a = self.arrays
        dist_km, drift = self.empty(p, w), self.empty(p, w)
        before, new, goal = self.empty(p, w, dtype=bool_), self.empty(p, w, dtype=bool_), self.empty(p, dtype=bool_)
        margin = float(self.task.config.distance_margin_km)
        self.launch(
            pw.waypoint_measure, p, envs, lat, lon, hdg, a["wpt_lat"], a["wpt_lon"], a["wpt_reached"], margin, dist_km, drift, before, new, goal
        )
        separation, los = self.no_traffic(p)
        return pw.PlanWaypointMeasurement(
            envs=envs,
            separation_nm=separation,
            los=los,
            drift_deg=None,
            goal_reached=goal,
            dist_km=dist_km,
            drift=drift,
            reached_before=before,
            newly_reached=new,
        )

    def observe(self, g: StepGeometry) -> dict[str, Any]:
        """:meth:`~bluesky_gym.environments.plan_waypoint.task.PlanWaypointTask.observe` on the device (one launch)."""
        assert isinstance(g, pw.PlanWaypointMeasurement)
        c = self.task.config
        rows, w = (int(s) for s in g.dist_km.shape)
        out = {key: self.empty(rows, w) for key in pw.OBSERVATION_KEYS}
        self.launch(
            pw.waypoint_observation,
            rows,
            g.dist_km,
            g.drift,
            g.reached_before,
            g.newly_reached,
            c.reach_same_step,
            float(c.waypoint_distance_max),
            *out.values(),
        )
        return out

    def reward(self, g: StepGeometry) -> tuple[Any, Any, dict[str, Any]]:
        """+1 per newly reached waypoint, recorded in the reach flags; terminated when all are reached (one launch)."""
        assert isinstance(g, pw.PlanWaypointMeasurement)
        reward, reach = self.empty(self.n), self.empty(self.n)
        self.launch(pw.waypoint_reward, self.n, g.envs, g.newly_reached, pw.REACH_REWARD, self.arrays["wpt_reached"], reward, reach)
        return reward, g.goal_reached, {"reach": reach}

    def episode_info(self) -> dict[str, Any]:
        """:meth:`~bluesky_gym.environments.plan_waypoint.task.PlanWaypointTask.episode_info` on the device (one launch)."""
        completed = self.empty(self.n, dtype=self.torch.int64)
        self.launch(pw.count_reached, self.n, self.arrays["wpt_reached"], completed)
        return {"total_reward": self.stats["total_reward"].clone(), "waypoints_completed": completed}
