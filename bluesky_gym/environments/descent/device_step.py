"""Descent's step on the device: its action, measure and reward kernels in the shared device pipeline.

With ``gym.make_vec(id, device="cuda")`` the physics always runs on the device
(:class:`~bluesky_gym.core.DeviceSimulator`). For Descent (``-v0`` and ``-v1``, without wind; its
registry row's ``device_step``) the rest of the step runs there too: the pipeline of
:class:`~bluesky_gym.envs.device.DeviceStep` (actions, physics, statistics, truncation, KPIs,
autoreset) with Descent's stages (:class:`DescentDeviceStep`):

* the action: :func:`~bluesky_gym.environments.descent.task.command_vertical_speed` (one launch);
* measure: :func:`~bluesky_gym.environments.descent.task.descent_measure` (one launch);
* the observation: scalings of the measured tensors (:func:`~bluesky_gym.environments.descent.task.observation`);
* reward, termination and the final altitude: :func:`~bluesky_gym.environments.descent.task.descent_reward` (one launch);
* the extra track of the KPIs: the shared one (the runway leg as the nominal route).

These are the kernels the CPU task runs (their CUDA forms): no rule of the task is written here a
second time. Under numba-cuda's simulator (``NUMBA_ENABLE_CUDASIM=1``) the outputs equal the CPU
vector environment's bit for bit (``tests/device/test_device_step_descent.py``).
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from bluesky_gym.environments.descent import task as dt
from bluesky_gym.envs.device import DeviceStep, TensorIO
from bluesky_gym.tasks.base import StepGeometry, Task

__all__ = ["DescentDeviceStep"]


class DescentDeviceStep(DeviceStep):
    """Descent's step on the device (the module docstring; the arguments: :class:`~bluesky_gym.envs.device.DeviceStep`'s)."""

    task_class: ClassVar[type[Task]] = dt.DescentTask
    task: dt.DescentTask

    def __init__(self, task: dt.DescentTask, io: TensorIO) -> None:
        super().__init__(task, io)

    def host_arrays(self) -> dict[str, np.ndarray]:
        """The target and final altitudes."""
        t = self.task
        return {"target_alt": t.target_alt, "final_altitude": t.final_altitude}

    def command(self, action: Any) -> None:
        """:meth:`~bluesky_gym.environments.descent.task.DescentTask.apply_action`: the vertical speed written into the autopilot (one launch)."""
        alt, selalt, selvs = self.sim.device_arrays("alt", "selalt", "selvs")
        self.launch(dt.command_vertical_speed, self.n, self.envs, self.own, action, alt, bool(self.task.config.hold_altitude_at_zero), selalt, selvs)

    def measure(self, envs: Any, own: Any) -> dt.DescentMeasurement:
        """:meth:`~bluesky_gym.environments.descent.task.DescentTask.measure` of rows ``envs`` on the device (one launch)."""
        p = int(envs.shape[0])
        lat, lon, alt, vs = self.sim.device_arrays("lat", "lon", "alt", "vs")
        alt_r, vs_r, runway_km, goal = self.empty(p), self.empty(p), self.empty(p), self.empty(p, dtype=self.torch.bool)
        self.launch(dt.descent_measure, p, envs, own, lat, lon, alt, vs, float(self.task.config.runway_distance_km), alt_r, vs_r, runway_km, goal)
        return dt.DescentMeasurement(envs, *self.no_traffic(p), None, goal, alt_r, vs_r, runway_km)

    def observe(self, g: StepGeometry) -> dict[str, Any]:
        """:func:`~bluesky_gym.environments.descent.task.observation`: scalings of the measured tensors."""
        assert isinstance(g, dt.DescentMeasurement)
        return dt.observation(g, self.arrays["target_alt"])

    def reward(self, g: StepGeometry) -> tuple[Any, Any, dict[str, Any]]:
        """The altitude, crash and runway terms, the termination and the final altitude (one launch)."""
        assert isinstance(g, dt.DescentMeasurement)
        n, a = self.n, self.arrays
        reward, terminated = self.empty(n), self.empty(n, dtype=self.torch.bool)
        altitude, crash, runway = self.empty(n), self.empty(n), self.empty(n)
        self.launch(
            dt.descent_reward, n, g.envs, g.alt, g.runway_km, a["target_alt"], a["final_altitude"], reward, terminated, altitude, crash, runway
        )
        return reward, terminated, {"altitude": altitude, "crash": crash, "runway": runway}

    def episode_info(self) -> dict[str, Any]:
        """:meth:`~bluesky_gym.environments.descent.task.DescentTask.episode_info` on the device."""
        return {"total_reward": self.stats["total_reward"].clone(), "final_altitude": self.arrays["final_altitude"].clone()}
