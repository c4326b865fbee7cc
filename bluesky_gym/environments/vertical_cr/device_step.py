"""VerticalCR's step on the device: Descent's device step with the intruders' kernels.

With ``gym.make_vec(id, device="cuda")`` the physics always runs on the device
(:class:`~bluesky_gym.core.DeviceSimulator`). For VerticalCR (``-v0`` and ``-v1``, without wind;
its registry row's ``device_step``) the rest of the step runs there too: the pipeline of
:class:`~bluesky_gym.envs.device.DeviceStep` with Descent's stages
(:class:`~bluesky_gym.environments.descent.device_step.DescentDeviceStep`: the action, the extra
track) and VerticalCR's own (:class:`VerticalCRDeviceStep`):

* measure: :func:`~bluesky_gym.environments.vertical_cr.task.vertical_cr_measure`,
  :func:`~bluesky_gym.tasks.compiled.kwik_separation` (the 5 NM / 1000 ft cylinder) and
  :func:`~bluesky_gym.tasks.compiled.intruder_relative_state`, one launch each;
* the observation: scalings of the measured tensors (:func:`~bluesky_gym.environments.vertical_cr.task.observation`);
* reward, termination, the final altitude and the intrusion count:
  :func:`~bluesky_gym.environments.vertical_cr.task.vertical_cr_reward` (one launch).

These are the kernels the CPU task runs (their CUDA forms): no rule of the task is written here a
second time. Under numba-cuda's simulator (``NUMBA_ENABLE_CUDASIM=1``) the outputs equal the CPU
vector environment's bit for bit (``tests/device/test_device_step_vertical_cr.py``).
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from bluesky_gym.environments.descent.device_step import DescentDeviceStep
from bluesky_gym.environments.vertical_cr import task as vt
from bluesky_gym.tasks import compiled
from bluesky_gym.tasks.base import StepGeometry, Task

__all__ = ["VerticalCRDeviceStep"]


class VerticalCRDeviceStep(DescentDeviceStep):
    """VerticalCR's step on the device (the module docstring; the arguments: :class:`~bluesky_gym.envs.device.DeviceStep`'s)."""

    task_class: ClassVar[type[Task]] = vt.VerticalCRTask
    task: vt.VerticalCRTask

    def host_arrays(self) -> dict[str, np.ndarray]:
        """The descent arrays and the intrusion counts."""
        return {**super().host_arrays(), "total_intrusions": self.task.total_intrusions}

    def measure(self, envs: Any, own: Any) -> vt.VerticalCRMeasurement:
        """:meth:`~bluesky_gym.environments.vertical_cr.task.VerticalCRTask.measure` of rows ``envs`` on the device (three launches)."""
        p, m = int(envs.shape[0]), self.m
        k = m - 1
        torch = self.torch
        lat, lon, alt, vs, hdg, gs, active = self.sim.device_arrays("lat", "lon", "alt", "vs", "hdg", "gs", "active")
        alt_r, vs_r, runway_km, goal = self.empty(p), self.empty(p), self.empty(p), self.empty(p, dtype=torch.bool)
        alt_difference, vs_difference = self.empty(p, k), self.empty(p, k)
        runway_distance_km = float(self.task.config.runway_distance_km)
        self.launch(
            vt.vertical_cr_measure, p, envs, own, lat, lon, alt, vs, runway_distance_km, alt_r, vs_r, runway_km, goal, alt_difference, vs_difference
        )
        separation, los = self.empty(p, m), self.empty(p, m, dtype=torch.bool)
        self.launch(compiled.kwik_separation, p, envs, own, lat, lon, alt, active, vt.INTRUSION_DISTANCE, vt.VERTICAL_MARGIN, separation, los)
        intruders, count = self.empty(len(vt.INTRUDER_STATE), p, k), self.empty(p, dtype=torch.int64)
        self.launch(compiled.intruder_relative_state, p, envs, own, lat, lon, hdg, gs, active, False, intruders, count)
        return vt.VerticalCRMeasurement(
            envs=envs,
            separation_nm=separation,
            los=los,
            drift_deg=None,
            goal_reached=goal,
            alt=alt_r,
            vs=vs_r,
            runway_km=runway_km,
            intruders=dict(zip(vt.INTRUDER_STATE, intruders, strict=True)),
            alt_difference=alt_difference,
            vs_difference=vs_difference,
        )

    def observe(self, g: StepGeometry) -> dict[str, Any]:
        """:func:`~bluesky_gym.environments.vertical_cr.task.observation`: scalings of the measured tensors."""
        assert isinstance(g, vt.VerticalCRMeasurement)
        return vt.observation(g, self.arrays["target_alt"], bool(self.task.config.normalise_vertical_speed))

    def reward(self, g: StepGeometry) -> tuple[Any, Any, dict[str, Any]]:
        """The descent terms, the intrusion penalty, the termination, the final altitude and the intrusion count (one launch)."""
        assert isinstance(g, vt.VerticalCRMeasurement)
        n, a = self.n, self.arrays
        reward, terminated = self.empty(n), self.empty(n, dtype=self.torch.bool)
        altitude, crash, runway, intrusion = self.empty(n), self.empty(n), self.empty(n), self.empty(n)
        self.launch(
            vt.vertical_cr_reward,
            n,
            g.envs,
            g.alt,
            g.runway_km,
            g.los,
            a["target_alt"],
            a["final_altitude"],
            a["total_intrusions"],
            reward,
            terminated,
            altitude,
            crash,
            runway,
            intrusion,
        )
        return reward, terminated, {"altitude": altitude, "crash": crash, "runway": runway, "intrusion": intrusion}

    def episode_info(self) -> dict[str, Any]:
        """:meth:`~bluesky_gym.environments.vertical_cr.task.VerticalCRTask.episode_info` on the device."""
        a = self.arrays
        return {
            "total_reward": self.stats["total_reward"].clone(),
            "total_intrusions": a["total_intrusions"].clone(),
            "final_altitude": a["final_altitude"].clone(),
        }
