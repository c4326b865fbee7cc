"""SectorCR's step on the device: its measure, observation and reward kernels in the shared device pipeline.

With ``gym.make_vec(id, device="cuda")`` the physics always runs on the device
(:class:`~bluesky_gym.core.DeviceSimulator`). For SectorCR (``-v0`` and ``-v1``, without wind; its
registry row's ``device_step``) the rest of the step runs there too: the pipeline of
:class:`~bluesky_gym.envs.device.DeviceStep` (actions, physics, statistics, truncation, KPIs,
autoreset) with SectorCR's stages (:class:`SectorCRDeviceStep`):

* measure: :func:`~bluesky_gym.tasks.compiled.sector_observe`,
  :func:`~bluesky_gym.tasks.compiled.kwik_separation` and
  :func:`~bluesky_gym.tasks.compiled.slots_in_polygons`, one launch each;
* the observation: views of the measured tensors (:func:`~bluesky_gym.environments.sector_cr.task.observation`);
* reward and the episode sums: :func:`~bluesky_gym.tasks.compiled.sector_reward` and
  :func:`~bluesky_gym.tasks.compiled.sector_episode_reward` (``-v1``: the sector exit), one launch each;
* the truncation where the agent left the sector (``-v0``: the task's own
  :meth:`~bluesky_gym.environments.sector_cr.task.SectorCRTask.truncate` applied to the tensors)
  and the info's ``average_drift`` (:func:`~bluesky_gym.tasks.compiled.sample_means`, one launch).

These are the kernels the CPU task runs (their CUDA forms): no rule of the task is written here a
second time. Under numba-cuda's simulator (``NUMBA_ENABLE_CUDASIM=1``) the outputs equal the CPU
vector environment's bit for bit (``tests/device/test_device_step.py``).
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from bluesky_gym.environments.sector_cr import task as sc
from bluesky_gym.envs.device import DeviceStep, TensorIO
from bluesky_gym.tasks import compiled
from bluesky_gym.tasks.base import StepGeometry, Task

__all__ = ["SectorCRDeviceStep"]


class SectorCRDeviceStep(DeviceStep):
    """SectorCR's step on the device (the module docstring; the arguments: :class:`~bluesky_gym.envs.device.DeviceStep`'s)."""

    task_class: ClassVar[type[Task]] = sc.SectorCRTask
    task: sc.SectorCRTask

    def __init__(self, task: sc.SectorCRTask, io: TensorIO) -> None:
        super().__init__(task, io)
        self.heading_step, self.speed_step = sc.D_HEADING, sc.speed_change(task.config)
        self.no_goal = self.never

    def host_arrays(self) -> dict[str, np.ndarray]:
        """The agents' waypoints (slot 0's column), the sector polygons and the info's sums."""
        t = self.task
        arrays = {"wpt_lat": t.wpt_lat[:, :1], "wpt_lon": t.wpt_lon[:, :1], "poly_lat": t.poly_lat, "poly_lon": t.poly_lon}
        arrays.update({k: getattr(t, k) for k in ("n_vertices", "total_intrusions", "drift_rad_sum", "drift_rad_n")})
        return arrays

    def measure(self, envs: Any, own: Any) -> sc.SectorGeometry:
        """:func:`bluesky_gym.environments.sector_cr.task.measure` of rows ``envs`` on the device (three launches)."""
        p, m = int(envs.shape[0]), self.m
        lat, lon, hdg, tas, alt, active = self.sim.device_arrays("lat", "lon", "hdg", "tas", "alt", "active")
        a = self.arrays
        drift, features = self.empty(p), self.empty(p, len(sc.OWN_KEYS))
        intruders, n_others = self.empty(p, len(sc.INTRUDER_KEYS), sc.NUM_AC_STATE), self.empty(p, dtype=self.torch.int64)
        separation, los, inside = self.empty(p, m), self.empty(p, m, dtype=self.torch.bool), self.empty(p, dtype=self.torch.bool)
        wpt_lat, wpt_lon = a["wpt_lat"][envs, own].contiguous(), a["wpt_lon"][envs, own].contiguous()
        scales = sc.observation_scales(self.task.config)
        self.launch(
            compiled.sector_observe,
            p,
            envs,
            own,
            lat,
            lon,
            hdg,
            tas,
            active,
            wpt_lat,
            wpt_lon,
            sc.FLAT_CENTER,
            scales,
            drift,
            features,
            intruders,
            n_others,
        )
        self.launch(compiled.kwik_separation, p, envs, own, lat, lon, alt, active, sc.INTRUSION_DISTANCE, np.nan, separation, los)
        self.launch(compiled.slots_in_polygons, p, envs, own, lat, lon, a["poly_lat"], a["poly_lon"], a["n_vertices"], inside)
        return sc.SectorGeometry(envs, separation, los, drift, self.no_goal[:p], own, features, intruders, n_others, inside)

    def observe(self, g: StepGeometry) -> dict[str, Any]:
        """:func:`bluesky_gym.environments.sector_cr.task.observation`: views of the measured tensors."""
        assert isinstance(g, sc.SectorGeometry)
        return sc.observation(g)

    def reward(self, g: StepGeometry) -> tuple[Any, Any, dict[str, Any]]:
        """Drift and intrusion penalties and the episode sums; ``-v1``: the sector exit (two launches)."""
        assert isinstance(g, sc.SectorGeometry)
        t, n, a = self.task, self.n, self.arrays
        c = t.config
        reward, drift_c, intrusion_c, count = self.empty(n), self.empty(n), self.empty(n), self.empty(n, dtype=self.torch.int64)
        self.launch(compiled.sector_reward, n, g.drift_deg, g.los, sc.DRIFT_PENALTY, sc.INTRUSION_PENALTY, reward, drift_c, intrusion_c, count)
        exit_c, terminated = self.empty(n), self.empty(n, dtype=self.torch.bool)
        lat, lon = self.sim.device_arrays("lat", "lon")
        self.launch(
            compiled.sector_episode_reward,
            n,
            self.envs,
            g.drift_deg,
            count,
            g.inside,
            lat,
            lon,
            a["wpt_lat"],
            a["wpt_lon"],
            self.stats["steps"],
            int(t.time_limit),
            bool(c.exit_ends_episode),
            sc.EXIT_MARGIN,
            sc.EARLY_EXIT_PENALTY,
            a["drift_rad_sum"],
            a["drift_rad_n"],
            a["total_intrusions"],
            reward,
            exit_c,
            terminated,
        )
        components = {"drift": drift_c, "intrusion": intrusion_c}
        if c.exit_ends_episode:
            components["exit"] = exit_c
        return reward, terminated, components

    def cut(self, g: StepGeometry) -> Any:
        """The task's own :meth:`~bluesky_gym.environments.sector_cr.task.SectorCRTask.truncate` (the sector left), on the tensors."""
        return self.task.truncate(g)

    def episode_info(self) -> dict[str, Any]:
        """:meth:`bluesky_gym.environments.sector_cr.task.SectorCRTask.episode_info` on the device (one launch)."""
        a = self.arrays
        average_drift = self.sample_mean("drift_rad_sum", "drift_rad_n", sc.AVERAGE_DRIFT_EMPTY)
        return {"total_reward": self.stats["total_reward"].clone(), "total_intrusions": a["total_intrusions"].clone(), "average_drift": average_drift}
