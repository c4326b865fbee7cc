"""The task's step on the device: actions, physics, measure, observation, reward and statistics as kernel launches.

With ``gym.make_vec(id, device="cuda")`` the physics always runs on the device
(:class:`~bluesky_gym.core.DeviceSimulator`). For SectorCR (``-v0`` and ``-v1``, without wind; its
registry row's ``device_step``) the rest of the step runs there too (:class:`SectorCRDeviceStep`):

* the actions (a tensor on the device) are clipped (:func:`~bluesky_gym.tasks.compiled.clip_to_bounds`)
  and given as autopilot commands (:func:`bluesky_gym.tasks.compiled.command_heading_speed`), one
  launch each;
* the physics sub-steps: one launch of the run kernel;
* measure: the task's own kernels (:func:`~bluesky_gym.tasks.compiled.sector_observe`,
  :func:`~bluesky_gym.tasks.compiled.kwik_separation`,
  :func:`~bluesky_gym.tasks.compiled.slots_in_polygons`), one launch each;
* reward and the episode sums (:func:`~bluesky_gym.tasks.compiled.sector_reward`,
  :func:`~bluesky_gym.tasks.compiled.sector_episode_reward`) and the statistics
  (:func:`~bluesky_gym.tasks.compiled.record_step`), one launch each;
* ``-v1``: the observation clipped to its declared bounds
  (:func:`~bluesky_gym.tasks.compiled.clip_to_bounds`, one launch for the own-aircraft entries and
  one for the intruders');
* the truncation (:func:`~bluesky_gym.tasks.compiled.truncation`, with the task's own
  :meth:`~bluesky_gym.environments.sector_cr.task.SectorCRTask.truncate` and
  :meth:`~bluesky_gym.tasks.base.Task.end_step` applied to the step's tensors), the info's
  ``average_drift`` (:func:`~bluesky_gym.tasks.compiled.sample_means`) and, in a step where an
  episode ends, the KPIs (:func:`~bluesky_gym.tasks.compiled.episode_kpis`), one launch each;
* the observation's layout and dtype and the copies of the info's sums: tensor views, copies
  and casts on the device.

These are the kernels the CPU task runs (their CUDA forms, :mod:`bluesky_gym.core.cuda_target`),
launched over every episode at once: no rule of the task is written here a second time, and a step
is a fixed number of launches whatever the number of episodes. One thing comes to the host per
step: which episodes ended (a boolean per episode).
Their new scenarios are drawn on the host from each episode's own generator, in the reference's
order (:meth:`~bluesky_gym.tasks.base.Task.generate`, as on the CPU), and only those episodes'
aircraft and scenario arrays are uploaded (:meth:`~bluesky_gym.core.DeviceSimulator.reset_on_host`);
then a fixed number of launches measures and observes them.

Every output is a torch tensor on the device, the info entries included. Under numba-cuda's
simulator (``NUMBA_ENABLE_CUDASIM=1``) the tensors are CPU tensors and the outputs equal the CPU
vector environment's bit for bit (``tests/device/test_device_step.py``).
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from bluesky_gym.core import DeviceSimulator, cuda_target
from bluesky_gym.environments.sector_cr import task as sc
from bluesky_gym.tasks import compiled
from bluesky_gym.tasks.base import KPI_KEYS, Task, numeric_action

__all__ = ["SectorCRDeviceStep"]


class SectorCRDeviceStep:
    """SectorCR's vector-environment step with the task on the device (see the module docstring).

    Args:
        task: The vector environment's task (its physics a :class:`~bluesky_gym.core.DeviceSimulator`).
        io: The environment's :class:`~bluesky_gym.envs.device.TensorIO`.
    """

    task_class: ClassVar[type[Task]] = sc.SectorCRTask

    @staticmethod
    def supports(task: Task) -> bool:
        """Whether ``task``'s configuration runs on the device: no wind, no effects, no extra observation terms."""
        return not task.effects and not task.observation_terms and task.config.wind is None

    def __init__(self, task: sc.SectorCRTask, io: Any) -> None:
        self.task, self.io, self.torch = task, io, io.torch
        if not isinstance(task.sim, DeviceSimulator):
            raise TypeError(f"the device step needs the task's physics on the device (DeviceSimulator), got {type(task.sim).__name__}")
        self.sim: DeviceSimulator = task.sim
        torch, dev = self.torch, io.device
        n, m = task.n_envs, task.sim.max_aircraft
        self.n, self.m = n, m
        self.envs = self._long(np.arange(n))
        self.own = self._long(np.zeros(n, np.int64))
        self.no_goal = torch.zeros(n, dtype=torch.bool, device=dev)
        self.nothing = torch.zeros(0, dtype=torch.float64, device=dev)
        spec = task.action_spec
        self.action_shape = (n, *spec.shape)
        self.action_low, self.action_high = (torch.as_tensor(b, device=dev) for b in task.action_bounds())
        self.obs_dtype = torch.float32 if task.config.float32_spaces else torch.float64
        # -v1: the declared bounds of the own-aircraft entries (the columns of the measured features)
        # and of the intruders' (the 7 x NUM_AC_STATE columns of the intruder block), for clip_to_bounds.
        bounds = task.observation_bounds()
        self.bounds = {
            block: tuple(torch.as_tensor(np.concatenate([bounds[key][i] for key in keys]), device=dev) for i in (0, 1))
            for block, keys in (("features", sc.OWN_KEYS), ("intruders", sc.INTRUDER_KEYS))
        }
        # The episode statistics (Task.stats) and SectorCR's info sums, kept on the device.
        z = dict(device=dev)
        self.stats = {
            "in_los": torch.zeros((n, m), dtype=torch.bool, **z),
            "min_sep": torch.full((n,), np.inf, dtype=torch.float64, **z),
            "los_count": torch.zeros(n, dtype=torch.int64, **z),
            "los_steps": torch.zeros(n, dtype=torch.int64, **z),
            "steps": torch.zeros(n, dtype=torch.int64, **z),
            "total_reward": torch.zeros(n, dtype=torch.float64, **z),
            "drift_sum": torch.zeros(n, dtype=torch.float64, **z),
            "drift_n": torch.zeros(n, dtype=torch.int64, **z),
            "time_to_goal": torch.full((n,), np.nan, dtype=torch.float64, **z),
            "total_intrusions": torch.zeros(n, dtype=torch.int64, **z),
            "drift_rad_sum": torch.zeros(n, dtype=torch.float64, **z),
            "drift_rad_n": torch.zeros(n, dtype=torch.int64, **z),
        }
        self.scenario: dict[str, Any] = {}

    # --- device buffers ------------------------------------------------------------------------
    def _long(self, host: np.ndarray) -> Any:
        return self.torch.as_tensor(np.ascontiguousarray(host, dtype=np.int64), device=self.io.device)

    def _k(self, tensor: Any) -> Any:
        """A tensor as a kernel argument (no copy)."""
        return self.io.kernel_array(tensor)

    def _empty(self, *shape: int, dtype: Any = None) -> Any:
        return self.torch.empty(shape, dtype=self.torch.float64 if dtype is None else dtype, device=self.io.device)

    def _upload_scenario(self, rows: np.ndarray | None) -> None:
        """The task's scenario arrays of episodes ``rows`` (all when None) to the device."""
        t = self.task
        host = {
            "wpt_lat": t.wpt_lat[:, :1],
            "wpt_lon": t.wpt_lon[:, :1],
            "poly_lat": t.poly_lat,
            "poly_lon": t.poly_lon,
            "n_vertices": t.n_vertices,
        }
        grown = "poly_lat" in self.scenario and self.scenario["poly_lat"].shape != t.poly_lat.shape
        if rows is None or grown:  # every row (a polygon with more vertices than ever before reallocates them)
            self.scenario = {k: self.torch.as_tensor(np.ascontiguousarray(v), device=self.io.device) for k, v in host.items()}
            return
        idx = self._long(rows)
        for k, v in host.items():
            self.scenario[k][idx] = self.torch.as_tensor(np.ascontiguousarray(v[rows]), device=self.io.device)

    def _clear_stats(self, idx: Any) -> None:
        """:meth:`~bluesky_gym.tasks.base.EpisodeStats.clear` and SectorCR's sums of episodes ``idx``."""
        s = self.stats
        for k in ("los_count", "los_steps", "steps", "drift_n", "total_intrusions", "drift_rad_n"):
            s[k][idx] = 0
        for k in ("total_reward", "drift_sum", "drift_rad_sum"):
            s[k][idx] = 0.0
        s["min_sep"][idx] = np.inf
        s["time_to_goal"][idx] = np.nan
        s["in_los"][idx] = False

    def sync_host(self) -> None:
        """Copy the episode statistics and SectorCR's sums into the task's host arrays (for pictures: the step never reads them)."""
        s, t = self.stats, self.task
        host = {"in_los": t.stats.in_los, "min_sep": t.stats.min_separation, "total_intrusions": t.total_intrusions}
        host.update({k: getattr(t, k) for k in ("drift_rad_sum", "drift_rad_n")})
        host.update({k: getattr(t.stats, k) for k in ("los_count", "los_steps", "steps", "total_reward", "drift_sum", "drift_n", "time_to_goal")})
        if t.stats.in_los.shape != tuple(s["in_los"].shape):
            t.stats.in_los = np.zeros(tuple(s["in_los"].shape), bool)
            host["in_los"] = t.stats.in_los
        for k, arr in host.items():
            arr[...] = s[k].cpu().numpy()

    # --- the task's kernels ---------------------------------------------------------------------
    def _measure(self, envs: Any, own: Any) -> sc.SectorGeometry:
        """:func:`bluesky_gym.environments.sector_cr.task.measure` of rows ``envs`` on the device (three launches).

        Returns:
            The task's geometry, its arrays tensors on the device.
        """
        t, k, launch = self.task, self._k, cuda_target.launch
        p, m = int(envs.shape[0]), self.m
        lat, lon, hdg, tas, alt, active = self.sim.device_arrays("lat", "lon", "hdg", "tas", "alt", "active")
        sc_ = self.scenario
        g = {
            "drift": self._empty(p),
            "features": self._empty(p, len(sc.OWN_KEYS)),
            "intruders": self._empty(p, len(sc.INTRUDER_KEYS), sc.NUM_AC_STATE),
            "n_others": self._empty(p, dtype=self.torch.int64),
            "separation": self._empty(p, m),
            "los": self._empty(p, m, dtype=self.torch.bool),
            "inside": self._empty(p, dtype=self.torch.bool),
        }
        wpt_lat, wpt_lon = sc_["wpt_lat"][envs, own].contiguous(), sc_["wpt_lon"][envs, own].contiguous()
        scales = sc.observation_scales(t.config)
        launch(
            compiled.sector_observe,
            p,
            k(envs),
            k(own),
            lat,
            lon,
            hdg,
            tas,
            active,
            k(wpt_lat),
            k(wpt_lon),
            sc._FLAT_CENTER,
            scales,
            k(g["drift"]),
            k(g["features"]),
            k(g["intruders"]),
            k(g["n_others"]),
        )
        launch(compiled.kwik_separation, p, k(envs), k(own), lat, lon, alt, active, sc.INTRUSION_DISTANCE, np.nan, k(g["separation"]), k(g["los"]))
        launch(compiled.slots_in_polygons, p, k(envs), k(own), lat, lon, k(sc_["poly_lat"]), k(sc_["poly_lon"]), k(sc_["n_vertices"]), k(g["inside"]))
        return sc.SectorGeometry(
            envs, g["separation"], g["los"], g["drift"], self.no_goal[:p], own, g["features"], g["intruders"], g["n_others"], g["inside"]
        )

    def _record(self, g: sc.SectorGeometry, reward: Any | None) -> None:
        """:meth:`~bluesky_gym.tasks.base.Task.record` of rows ``g.envs`` on the device (one launch)."""
        s, k, t = self.stats, self._k, self.task
        stepped = reward is not None
        p = int(g.envs.shape[0])
        launch_args = (
            k(g.envs),
            k(g.separation_nm),
            k(g.los),
            stepped,
            k(reward if stepped else self.nothing),
            k(g.drift_deg),
            k(g.goal_reached),
            float(t.dt),
            int(t.action_frequency),
            k(s["in_los"]),
            k(s["min_sep"]),
            k(s["los_count"]),
            k(s["los_steps"]),
            k(s["steps"]),
            k(s["total_reward"]),
            k(s["drift_sum"]),
            k(s["drift_n"]),
            k(s["time_to_goal"]),
        )
        cuda_target.launch(compiled.record_step, p, *launch_args)

    def _observation(self, g: sc.SectorGeometry) -> dict[str, Any]:
        """The task's observation (:func:`~bluesky_gym.environments.sector_cr.task.observation`) in the space's dtype.

        ``-v1``: the measured features and intruders are clipped to the declared bounds first, as
        :meth:`~bluesky_gym.tasks.base.Task.bounded` clips them on the CPU (its kernel, in place: two launches).
        """
        f, intruders = g.features, g.intruders
        if self.task.config.float32_spaces:
            k, p = self._k, int(f.shape[0])
            for block, values in (("features", f), ("intruders", intruders.reshape(p, len(sc.INTRUDER_KEYS) * sc.NUM_AC_STATE))):
                low, high = self.bounds[block]
                cuda_target.launch(compiled.clip_to_bounds, p, k(values), k(low), k(high), k(values))
        obs: dict[str, Any] = sc.observation(g)  # views of the geometry's tensors
        return {key: v.to(self.obs_dtype).contiguous() for key, v in obs.items()}

    def _episode_info(self) -> dict[str, Any]:
        """:meth:`bluesky_gym.environments.sector_cr.task.SectorCRTask.episode_info` on the device (one launch)."""
        s = self.stats
        average_drift = self._empty(self.n)
        cuda_target.launch(
            compiled.sample_means, self.n, self._k(s["drift_rad_sum"]), self._k(s["drift_rad_n"]), sc.AVERAGE_DRIFT_EMPTY, self._k(average_drift)
        )
        return {"total_reward": s["total_reward"].clone(), "total_intrusions": s["total_intrusions"].clone(), "average_drift": average_drift}

    def _kpis(self) -> dict[str, Any]:
        """:meth:`bluesky_gym.tasks.base.Task.kpis` on the device (SectorCR has no goal; one launch)."""
        s, t, k = self.stats, self.task, self._k
        distflown, fuelburn = self.sim.device_arrays("distflown", "fuelburn")
        out = {key: self._empty(self.n) for key in KPI_KEYS}
        cuda_target.launch(
            compiled.episode_kpis,
            self.n,
            k(s["steps"]),
            k(s["los_count"]),
            k(s["los_steps"]),
            k(s["min_sep"]),
            k(s["drift_sum"]),
            k(s["drift_n"]),
            distflown,
            fuelburn,
            float(t.dt),
            int(t.action_frequency),
            *(k(v) for v in out.values()),
        )
        return out

    # --- reset and step -------------------------------------------------------------------------
    def _start(self, rows: np.ndarray | None) -> tuple[Any, dict[str, Any]]:
        """New episodes in ``rows`` (all when None): drawn on the host, uploaded, measured and recorded on the device.

        Returns:
            The rows (a device tensor) and their first observation.
        """
        t = self.task
        host_rows = t.all_envs if rows is None else rows

        def reset() -> None:
            self.sim.reset_envs(host_rows)
            t.generate(host_rows)

        self.sim.reset_on_host(host_rows, reset)
        self._upload_scenario(rows)
        idx = self.envs if rows is None else self._long(rows)
        self._clear_stats(idx)
        g = self._measure(idx, self.own[: int(idx.shape[0])])
        self._record(g, None)
        return idx, self._observation(g)

    def reset(self) -> tuple[dict[str, Any], dict[str, Any]]:
        """Every episode anew (their generators seeded by the environment): the first observation and the info."""
        _, obs = self._start(None)
        return obs, self._episode_info()

    def _actions(self, actions: Any) -> Any:
        """The batch of actions as a float64 tensor on the device, validated and clipped to the action space."""
        torch = self.torch
        if isinstance(actions, torch.Tensor):
            a = actions.detach()
        elif hasattr(actions, "__cuda_array_interface__") and not cuda_target.SIMULATOR:
            a = torch.as_tensor(actions, device=self.io.device)
        elif hasattr(actions, "__dlpack__") and not isinstance(actions, np.ndarray):
            a = torch.from_dlpack(actions)
        else:
            a = torch.as_tensor(numeric_action(self.io.to_host(actions), self.action_shape))
        if a.dtype.is_complex or a.dtype == torch.bool:
            raise ValueError(f"action must be an array of real numbers with shape {self.action_shape}, got dtype {a.dtype}")
        a = a.to(device=self.io.device, dtype=torch.float64)
        if tuple(a.shape) != self.action_shape:
            raise ValueError(f"action has shape {tuple(a.shape)}, expected {self.action_shape} for {self.task.id}")
        if not bool(torch.isfinite(a).all()):
            raise ValueError("action contains NaN or infinite values")
        clipped = self._empty(*self.action_shape)  # Task.clip_action's kernel (never in place: the caller's tensor stays as it is)
        n = self.action_shape[0]
        cuda_target.launch(
            compiled.clip_to_bounds,
            n,
            self._k(a.contiguous().view(n, -1)),
            self._k(self.action_low),
            self._k(self.action_high),
            self._k(clipped.view(n, -1)),
        )
        return clipped

    def step(self, actions: Any) -> tuple[dict[str, Any], Any, Any, Any, dict[str, Any], np.ndarray]:
        """One step of every episode, ended episodes reset in the same call (SAME_STEP autoreset).

        Returns:
            Observation, reward, terminated, truncated, info (tensors on the device, Gymnasium's
            vector-environment layout), and the host's boolean mask of the episodes that ended.
        """
        t, s, k, torch, launch = self.task, self.stats, self._k, self.torch, cuda_target.launch
        c = t.config
        n = self.n
        a = self._actions(actions)
        d_speed = sc.speed_change(c)
        hdg, cas, ap_trk, selspd, swlnav, swvnavspd = self.sim.device_arrays("hdg", "cas", "ap_trk", "selspd", "swlnav", "swvnavspd")
        launch(compiled.command_heading_speed, n, k(self.envs), k(self.own), k(a), hdg, cas, sc.D_HEADING, d_speed, ap_trk, swlnav, selspd, swvnavspd)
        t.advance()
        g = self._measure(self.envs, self.own)
        obs = self._observation(g)
        reward, drift_c, intrusion_c, count = self._empty(n), self._empty(n), self._empty(n), self._empty(n, dtype=torch.int64)
        launch(
            compiled.sector_reward,
            n,
            k(g.drift_deg),
            k(g.los),
            sc.DRIFT_PENALTY,
            sc.INTRUSION_PENALTY,
            k(reward),
            k(drift_c),
            k(intrusion_c),
            k(count),
        )
        exit_c, terminated = self._empty(n), self._empty(n, dtype=torch.bool)
        lat, lon = self.sim.device_arrays("lat", "lon")
        sc_ = self.scenario
        launch(
            compiled.sector_episode_reward,
            n,
            k(self.envs),
            k(g.drift_deg),
            k(count),
            k(g.inside),
            lat,
            lon,
            k(sc_["wpt_lat"]),
            k(sc_["wpt_lon"]),
            k(s["steps"]),
            int(t.time_limit),
            bool(c.exit_ends_episode),
            sc.EXIT_MARGIN,
            sc.EARLY_EXIT_PENALTY,
            k(s["drift_rad_sum"]),
            k(s["drift_rad_n"]),
            k(s["total_intrusions"]),
            k(reward),
            k(exit_c),
            k(terminated),
        )
        self._record(g, reward)
        truncated = self._empty(n, dtype=torch.bool)
        launch(compiled.truncation, n, k(s["steps"]), int(t.time_limit), k(terminated), k(t.truncate(g)), k(truncated))
        done: Any = t.end_step(terminated, truncated)
        info: dict[str, Any] = self._episode_info()
        info.update({"reward_drift": drift_c, "reward_intrusion": intrusion_c})
        if c.exit_ends_episode:
            info["reward_exit"] = exit_c
        ended = done.cpu().numpy()  # the one transfer to the host of a step
        if ended.any():
            info.update(self._kpis())
            final_info = {key: v.clone() for key, v in info.items()}
            for key in list(info):
                if key.startswith("kpi_"):
                    info[f"_{key}"] = done.clone()
            final_obs = {key: v.clone() for key, v in obs.items()}
            rows = np.flatnonzero(ended)
            idx, new_obs = self._start(rows)
            for key, v in obs.items():
                v[idx] = new_obs[key]
            info["final_obs"] = final_obs
            info["_final_obs"] = done.clone()
            info["final_info"] = final_info
            info["_final_info"] = done.clone()
        return obs, reward, terminated, truncated, info, ended
