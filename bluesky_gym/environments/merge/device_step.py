"""Merge's step on the device: its measure, observation and reward kernels in the shared device pipeline.

With ``gym.make_vec("MergeEnv-v0" or "MergeEnv-v1", device="cuda")`` (without wind) the whole
step runs on the device: the pipeline of :class:`~bluesky_gym.envs.device.DeviceStep` (actions,
physics, statistics, truncation, KPIs, autoreset) with Merge's stages (:class:`MergeDeviceStep`):

* measure: the current targets (:func:`~bluesky_gym.tasks.compiled.merge_targets`), the
  observation geometry (:func:`~bluesky_gym.tasks.compiled.merge_observe`), the separation
  (:func:`~bluesky_gym.tasks.compiled.kwik_separation`) and the runway goal
  (:func:`~bluesky_gym.tasks.compiled.merge_goal`); ``-v1`` also the FAF reached in the step
  (:func:`~bluesky_gym.tasks.compiled.merge_faf_now`) and the targets and geometry again, for
  every row (a row whose target did not change gets the same values again);
* the observation: the task's own :meth:`~bluesky_gym.environments.merge.task.MergeTask.observe`
  applied to the measured tensors (views and arithmetic);
* reward and the episode sums: :func:`~bluesky_gym.tasks.compiled.merge_reward` and
  :func:`~bluesky_gym.tasks.compiled.merge_episode_sums`;
* the info's ``average_drift`` (:func:`~bluesky_gym.tasks.compiled.sample_means`); the extra
  track of the KPIs is the shared one (the episodes' nominal routes, drawn with their scenarios).

These are the kernels the CPU task runs (their CUDA forms): no rule of the task is written here a
second time. Under numba-cuda's simulator (``NUMBA_ENABLE_CUDASIM=1``) the outputs equal the CPU
vector environment's bit for bit (``tests/device/test_device_step_merge.py``).
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from bluesky_gym.environments.merge import task as mg
from bluesky_gym.envs.device import DeviceStep, TensorIO
from bluesky_gym.tasks import compiled
from bluesky_gym.tasks.base import StepGeometry, Task

__all__ = ["MergeDeviceStep"]


class MergeDeviceStep(DeviceStep):
    """Merge's step on the device (the module docstring; the arguments: :class:`~bluesky_gym.envs.device.DeviceStep`'s)."""

    task_class: ClassVar[type[Task]] = mg.MergeTask
    task: mg.MergeTask

    def __init__(self, task: mg.MergeTask, io: TensorIO) -> None:
        super().__init__(task, io)
        self.heading_step, self.speed_step = mg.D_HEADING, mg.D_SPEED
        self.no_rows = self.torch.zeros(0, dtype=self.torch.bool, device=io.device)

    def host_arrays(self) -> dict[str, np.ndarray]:
        """The FAF flags and the info's sums."""
        t = self.task
        names = ("wpt_reach", "faf_reached", "total_intrusions", "drift_rad_sum", "drift_rad_n")
        return {k: getattr(t, k) for k in names}

    def _targets(self, after: Any) -> tuple[Any, Any]:
        p, space = int(after.shape[0]), self.task.airspace
        lat, lon = self.empty(p), self.empty(p)
        self.launch(compiled.merge_targets, p, after, space.faf_lat, space.faf_lon, mg.RWY_LAT, mg.RWY_LON, lat, lon)
        return lat, lon

    def measure(self, envs: Any, own: Any) -> mg.MergeGeometry:
        """:func:`bluesky_gym.environments.merge.task.measure` of rows ``envs`` on the device (four launches; ``-v1``: seven)."""
        torch, p, m, space = self.torch, int(envs.shape[0]), self.m, self.task.airspace
        lat, lon, hdg, tas, alt, active = self.sim.device_arrays("lat", "lon", "hdg", "tas", "alt", "active")
        after = self.arrays["wpt_reach"][envs] != 0  # as MergeTask.measure reads it
        features, intruders, n_others = self.empty(p, 4), self.empty(p, 7, mg.NUM_AC_STATE), self.empty(p, dtype=torch.int64)

        def observe(after: Any) -> None:
            tlat, tlon = self._targets(after)
            self.launch(compiled.merge_observe, p, envs, own, lat, lon, hdg, tas, active, tlat, tlon, mg.OBS_SCALES, features, intruders, n_others)

        observe(after)
        faf_now = None
        if self.task.config.faf_same_step:
            faf_now, after_now = self.empty(p, dtype=torch.bool), self.empty(p, dtype=torch.bool)
            self.launch(compiled.merge_faf_now, p, after, features, space.faf_margin_nm, faf_now, after_now)
            after = after_now
            observe(after)
        separation, los = self.empty(p, m), self.empty(p, m, dtype=torch.bool)
        self.launch(compiled.kwik_separation, p, envs, own, lat, lon, alt, active, mg.INTRUSION_DISTANCE, np.nan, separation, los)
        reached = self.empty(p, dtype=torch.bool)
        self.launch(compiled.merge_goal, p, after, features, self.no_rows if faf_now is None else faf_now, space.goal_margin_nm, reached)
        airspeed = self.io.tensor(tas)[envs, own]
        return mg.MergeGeometry(
            envs, separation, los, features[:, 0], reached, own, after, features[:, 1], features, airspeed, intruders, n_others, faf_now
        )

    def observe(self, g: StepGeometry) -> dict[str, Any]:
        """The task's own :meth:`~bluesky_gym.environments.merge.task.MergeTask.observe` of the measured tensors."""
        return self.task.observe(g)

    def reward(self, g: StepGeometry) -> tuple[Any, Any, dict[str, Any]]:
        """FAF reach reward, runway goal, drift and intrusion penalties and the episode sums (two launches)."""
        assert isinstance(g, mg.MergeGeometry)
        torch, n, a, space = self.torch, self.n, self.arrays, self.task.airspace
        r, reach, drift, intrusion = self.empty(n), self.empty(n), self.empty(n), self.empty(n)
        reach_faf, near_runway, count = self.empty(n, dtype=torch.bool), self.empty(n, dtype=torch.bool), self.empty(n, dtype=torch.int64)
        faf_now = self.no_rows if g.faf_now is None else g.faf_now
        self.launch(
            compiled.merge_reward,
            n,
            g.features,
            g.after_faf,
            faf_now,
            g.goal_reached,
            g.los,
            space.faf_margin_nm,
            mg.REACH_REWARD,
            mg.DRIFT_PENALTY,
            mg.INTRUSION_PENALTY,
            r,
            reach,
            drift,
            intrusion,
            reach_faf,
            near_runway,
            count,
        )
        sums = (a[k] for k in ("wpt_reach", "faf_reached", "drift_rad_sum", "drift_rad_n", "total_intrusions"))
        self.launch(compiled.merge_episode_sums, n, self.envs, g.features, reach_faf, near_runway, count, *sums)
        return r, near_runway, {"reach": reach, "drift": drift, "intrusion": intrusion}

    def episode_info(self) -> dict[str, Any]:
        """:meth:`bluesky_gym.environments.merge.task.MergeTask.episode_info` on the device (one launch)."""
        a = self.arrays
        average_drift = self.sample_mean("drift_rad_sum", "drift_rad_n", mg.AVERAGE_DRIFT_EMPTY)
        return {
            "total_reward": self.stats["total_reward"].clone(),
            "faf_reach": a["faf_reached"].clone(),
            "average_drift": average_drift,
            "total_intrusions": a["total_intrusions"].clone(),
        }
