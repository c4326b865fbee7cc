"""DenseSectorCR's step on the device: SectorCR's stages, and the traffic flow with its draws on the host.

For DenseSectorCR (``-v0`` and ``-v1``, without wind; its registry row's ``device_step``) the step
is SectorCR's on the device (:class:`~bluesky_gym.environments.sector_cr.device_step.SectorCRDeviceStep`:
measure, observation, reward, statistics, truncation, KPIs, autoreset) with the traffic flow
after the physics sub-steps (:class:`DenseSectorCRDeviceStep`):

* the aircraft that left the sector: :func:`~bluesky_gym.environments.dense_sector_cr.task.outside_sector`
  and :meth:`~bluesky_gym.core.DeviceSimulator.delete_flagged`, one launch each, nothing to the host;
* the aircraft that enter: drawn on the host from each episode's own generator, in the CPU task's
  order (:meth:`~bluesky_gym.environments.dense_sector_cr.task.DenseSectorCRTask.spawn`: it reads
  only the task's per-episode arrays), and created on the device with only the new aircraft
  crossing (:meth:`~bluesky_gym.core.DeviceSimulator.edit_on_host`), in a step where any enter;
* the first-loss clock (:func:`~bluesky_gym.environments.dense_sector_cr.task.first_loss`) and
  the losses per flight-hour (:func:`~bluesky_gym.environments.dense_sector_cr.task.per_flight_hour`),
  one launch each; the flow's counts (``spawned``, ``spawns_dropped``) go to the device with the info.

The draws keep each row equal to the CPU vector environment's, bit for bit under numba-cuda's
simulator (``tests/device/test_device_step_dense_sector_cr.py``); their cost is host time that
grows with the number of episodes (a Poisson draw per episode and step, as on the CPU).
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from bluesky_gym.environments.dense_sector_cr import task as dsc
from bluesky_gym.environments.sector_cr.device_step import SectorCRDeviceStep
from bluesky_gym.envs.device import TensorIO
from bluesky_gym.tasks.base import StepGeometry, Task

__all__ = ["DenseSectorCRDeviceStep"]


class DenseSectorCRDeviceStep(SectorCRDeviceStep):
    """DenseSectorCR's step on the device (the module docstring; the arguments: :class:`~bluesky_gym.envs.device.DeviceStep`'s)."""

    task_class: ClassVar[type[Task]] = dsc.DenseSectorCRTask
    task: dsc.DenseSectorCRTask

    def __init__(self, task: dsc.DenseSectorCRTask, io: TensorIO) -> None:
        super().__init__(task, io)
        self.outside = self.empty(self.n, self.m, dtype=self.torch.bool)

    def host_arrays(self) -> dict[str, np.ndarray]:
        """SectorCR's, and the first-loss clock."""
        t = self.task
        return {**super().host_arrays(), "first_los_s": t.first_los_s, "los_at_start": t.los_at_start}

    def advance(self) -> None:
        """The physics sub-steps, then the traffic flow: the aircraft outside the sector deleted, the new ones created."""
        t, a = self.task, self.arrays
        super(dsc.DenseSectorCRTask, t).advance()  # the physics sub-steps (SectorCR's advance; the task's own adds the flow on the host)
        lat, lon, active = self.sim.device_arrays("lat", "lon", "active")
        self.launch(dsc.outside_sector, self.n, lat, lon, active, a["poly_lat"], a["poly_lon"], a["n_vertices"], self.outside)
        self.sim.delete_flagged(self.kernel_array(self.outside))
        t.spawn(t.all_envs)

    def record(self, g: StepGeometry, reward: Any | None) -> None:
        """The common statistics, then the first-loss clock of rows ``g.envs`` (one launch)."""
        super().record(g, reward)
        s, a, t = self.stats, self.arrays, self.task
        self.launch(
            dsc.first_loss, int(g.envs.shape[0]), g.envs, reward is not None, s["los_count"], s["steps"], float(t.dt), int(t.action_frequency),
            a["los_at_start"], a["first_los_s"],
        )  # fmt: skip

    def episode_info(self) -> dict[str, Any]:
        """SectorCR's entries, the other aircraft in the sector now and the flow's counts."""
        t = self.task
        (active,) = self.sim.device_arrays("active")
        traffic = self.io.tensor(active)[:, 1:].sum(dim=1)
        return {**super().episode_info(), "traffic": traffic, "spawned": self.long(t.spawned), "spawns_dropped": self.long(t.spawns_dropped)}

    def kpis(self) -> dict[str, Any]:
        """The common KPIs, losses per flight-hour (one launch), the time to the first loss and the aircraft that entered."""
        s, t = self.stats, self.task
        out = super().kpis()
        per_hour = self.empty(self.n)
        self.launch(dsc.per_flight_hour, self.n, s["los_count"], s["steps"], float(t.dt), int(t.action_frequency), per_hour)
        out["kpi_los_per_flight_hour"] = per_hour
        out["kpi_time_to_first_los_s"] = self.arrays["first_los_s"].clone()
        out["kpi_aircraft_spawned"] = self.long(t.spawned).to(self.torch.float64)
        return out
