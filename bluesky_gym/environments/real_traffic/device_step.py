"""RealTrafficCR's step on the device: the traffic's guidance, steering, measure, observation and reward kernels in the shared pipeline.

With ``gym.make_vec("RealTrafficCREnv-v0" or "RealTrafficCREnv-v1", device="cuda")`` (without
wind) the whole step runs on the device: the pipeline of :class:`~bluesky_gym.envs.device.DeviceStep`
(actions, physics, statistics, truncation, KPIs, autoreset) with RealTrafficCR's stages
(:class:`RealTrafficDeviceStep`). The recorded flights' arrays go to the device once; the
recorded-time clock, each slot's flight, type limit and guidance flag are per-episode arrays
kept there.

* the actions: :func:`~bluesky_gym.environments.real_traffic.task.steer_commands` (the heading
  to the recorded path ahead, the recorded profile with the offsets), one launch;
* the physics sub-steps, then the recorded traffic's departures and appearances: their times are
  known on the host from the recordings and the clock alone
  (:meth:`~bluesky_gym.realtraffic.scenario.WindowPlayer.due`, looked at only in the episodes
  whose next such time has come: :meth:`~bluesky_gym.realtraffic.scenario.WindowPlayer.next_event`),
  so in a step where some aircraft leave or enter, only those aircraft cross to the host and back
  (:meth:`~bluesky_gym.core.DeviceSimulator.edit_on_host`) with their episodes' flags; then the
  recorded profile of every guided aircraft (:func:`~bluesky_gym.realtraffic.scenario.guide_airspaces`),
  one launch;
* measure: :func:`~bluesky_gym.tasks.compiled.kwik_separation` and
  :func:`~bluesky_gym.environments.real_traffic.task.measure_rows` (route deviation, drift,
  profile errors, the ``ownship`` entry, the closest aircraft), one launch each;
* the observation: the measured tensors (:func:`~bluesky_gym.environments.real_traffic.task.observation`);
* reward and the episode sums: :func:`~bluesky_gym.environments.real_traffic.task.reward_rows`
  and :func:`~bluesky_gym.environments.real_traffic.task.episode_sums`, one launch each;
* the info's and the KPIs' mean route deviation: :func:`~bluesky_gym.tasks.compiled.sample_means`.

These are the kernels the CPU task runs (their CUDA forms): no rule of the task is written here a
second time. Under numba-cuda's simulator (``NUMBA_ENABLE_CUDASIM=1``) the outputs equal the CPU
vector environment's bit for bit (``tests/device/test_device_step_real_traffic.py``). The
multi-agent form (every recorded aircraft an agent) runs its step on the host.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from bluesky_gym.environments.real_traffic import task as rt
from bluesky_gym.envs.device import DeviceStep, TensorIO
from bluesky_gym.realtraffic.scenario import guide_airspaces
from bluesky_gym.tasks import compiled
from bluesky_gym.tasks.base import StepGeometry, Task

__all__ = ["RealTrafficDeviceStep"]

#: The player's per-slot arrays that change when aircraft enter or leave mid-episode (uploaded for those episodes).
_EVENT_ARRAYS = ("guided", "vsmax")


class RealTrafficDeviceStep(DeviceStep):
    """RealTrafficCR's step on the device (the module docstring; the arguments: :class:`~bluesky_gym.envs.device.DeviceStep`'s)."""

    task_class: ClassVar[type[Task]] = rt.RealTrafficTask
    task: rt.RealTrafficTask

    @staticmethod
    def supports(task: Task) -> bool:
        """The shared conditions (no wind, effects or extra observation terms), for the single-agent task (the recorded traffic guided)."""
        return DeviceStep.supports(task) and isinstance(task, rt.RealTrafficTask) and task.guided_traffic

    def __init__(self, task: rt.RealTrafficTask, io: TensorIO) -> None:
        super().__init__(task, io)
        self._recorded: tuple[Any, ...] | None = None
        #: (n_envs,) each episode's next time an aircraft may leave or appear (WindowPlayer.next_event), on the host.
        self._next_event = np.full(self.n, -np.inf)

    def recorded(self) -> tuple[Any, ...]:
        """The recorded flights as the kernels read them (``t0``, ``offset``, ``period``, ``lat``, ``lon``, ``alt``, ``gs``): uploaded once."""
        if self._recorded is None:
            f = self.task.flights
            t0, offset, period, lat, lon, alt, gs, _trk, _vs = f.kernel_arrays()
            up = self.io.upload
            self._recorded = (up(t0), up(offset), period, up(lat), up(lon), up(alt), up(gs))
            self._offsets = up(self.task.route_offsets)
        return self._recorded

    def host_arrays(self) -> dict[str, np.ndarray]:
        """The info's sums, and the player's clock, flights, guidance flags and type limits.

        The device advances its copy of the clock (:meth:`advance`), as the host does.
        """
        t = self.task
        p = t.player
        return {
            "route_sum": t.route_sum,
            "intrusions": t.intrusions,
            "start": p.start,
            "elapsed": p.elapsed,
            "flight": p.flight,
            "guided": p.guided,
            "vsmax": p.vsmax,
        }

    def command(self, action: Any) -> None:
        """:func:`~bluesky_gym.environments.real_traffic.task.steer_commands` of every episode's ownship (one launch)."""
        a = self.arrays
        sim_arrays = self.sim.device_arrays("lat", "lon", "alt", "ap_trk", "swlnav", "selalt", "swvnav", "selvs", "selspd", "swvnavspd")
        self.launch(
            rt.steer_commands, self.n, self.envs, self.own, action, a["start"], a["elapsed"], a["flight"], a["vsmax"], *self.recorded(), *sim_arrays
        )

    def advance(self) -> None:
        """The physics sub-steps, the clock, the aircraft leaving and entering (only they cross to the host), the recorded profiles (one launch)."""
        t = self.task
        player = t.player
        Task.advance(t)
        player.advance_clock(rt.DECISION_STEP)
        self.arrays["elapsed"] += rt.DECISION_STEP  # the host clock's addition (WindowPlayer.advance_clock), on the device's copy
        near = np.flatnonzero(player.now() >= self._next_event - 1e-6)  # the only episodes where an aircraft may leave or appear now
        if near.size:
            (ended_e, ended_s), (due_e, due_s) = player.due(near)
            if ended_e.size or due_e.size:
                envs, slots = np.concatenate([ended_e, due_e]), np.concatenate([ended_s, due_s])
                self.sim.edit_on_host(envs, slots, lambda: player.schedule(near))
                rows = np.unique(envs)
                idx = self.long(rows)
                for name in _EVENT_ARRAYS:
                    self.arrays[name][idx] = self.torch.as_tensor(np.ascontiguousarray(getattr(player, name)[rows]), device=self.io.device)
            self._next_event[near] = player.next_event(near)
        a = self.arrays
        alt, *commands = self.sim.device_arrays("alt", "selalt", "swvnav", "selvs", "selspd", "swvnavspd")
        t0, offset, period, _lat, _lon, rec_alt, rec_gs = self.recorded()
        flight, guided, start, elapsed, vsmax = (a[k] for k in ("flight", "guided", "start", "elapsed", "vsmax"))
        self.launch(guide_airspaces, self.n, t0, offset, period, rec_alt, rec_gs, flight, guided, start, elapsed, alt, vsmax, *commands)

    def start(self, rows: np.ndarray | None) -> tuple[Any, dict[str, Any]]:
        """:meth:`~bluesky_gym.envs.device.DeviceStep.start`, and the new episodes' next time an aircraft may leave or appear."""
        out = super().start(rows)
        self._next_event[slice(None) if rows is None else rows] = self.task.player.next_event(rows)
        return out

    def measure(self, envs: Any, own: Any) -> rt.RealTrafficGeometry:
        """:func:`bluesky_gym.environments.real_traffic.task.measure` of rows ``envs`` on the device (two launches)."""
        torch, p, m, a = self.torch, int(envs.shape[0]), self.m, self.arrays
        names = ("lat", "lon", "alt", "hdg", "cas", "vs", "gseast", "gsnorth", "active")
        lat, lon, alt, hdg, cas, vs, gseast, gsnorth, active = self.sim.device_arrays(*names)
        separation, los = self.empty(p, m), self.empty(p, m, dtype=torch.bool)
        self.launch(compiled.kwik_separation, p, envs, own, lat, lon, alt, active, rt.INTRUSION_NM, rt.INTRUSION_VERTICAL, separation, los)
        route, drift, cas_error, alt_error = (self.empty(p) for _ in range(4))
        ownship, intruders = self.empty(p, rt.OWNSHIP_FEATURES), self.empty(p, rt.NUM_INTRUDERS, rt.INTRUDER_FEATURES)
        recorded = self.recorded()
        self.launch(
            rt.measure_rows, p, envs, own, a["start"], a["elapsed"], a["flight"], *recorded, self._offsets,
            lat, lon, alt, hdg, cas, vs, gseast, gsnorth, separation, route, drift, cas_error, alt_error, ownship, intruders,
        )  # fmt: skip
        return rt.RealTrafficGeometry(envs, separation, los, drift, self.never[:p], own, route, cas_error, alt_error, intruders, ownship)

    def observe(self, g: StepGeometry) -> dict[str, Any]:
        """:func:`bluesky_gym.environments.real_traffic.task.observation`: the measured tensors."""
        assert isinstance(g, rt.RealTrafficGeometry)
        return rt.observation(self.task, g)

    def reward(self, g: StepGeometry) -> tuple[Any, Any, dict[str, Any]]:
        """Route and intrusion penalties and the episode sums (two launches); never terminated."""
        assert isinstance(g, rt.RealTrafficGeometry)
        n, a = self.n, self.arrays
        r, route, intrusion = self.empty(n), self.empty(n), self.empty(n)
        self.launch(rt.reward_rows, n, g.route_nm, g.los, r, route, intrusion)
        self.launch(rt.episode_sums, n, self.envs, g.route_nm, g.los, a["route_sum"], a["intrusions"])
        return r, self.torch.zeros(n, dtype=self.torch.bool, device=self.io.device), {"route": route, "intrusion": intrusion}

    def _route_mean(self, empty: float) -> Any:
        """:meth:`~bluesky_gym.environments.real_traffic.task.RealTrafficTask.mean_route_deviation` on the device (one launch)."""
        out = self.empty(self.n)
        self.launch(compiled.sample_means, self.n, self.arrays["route_sum"], self.stats["steps"], empty, out)
        return out

    def episode_info(self) -> dict[str, Any]:
        """:meth:`bluesky_gym.environments.real_traffic.task.RealTrafficTask.episode_info` on the device (one launch)."""
        return {
            "total_reward": self.stats["total_reward"].clone(),
            "total_intrusions": self.arrays["intrusions"].clone(),
            "average_route_deviation_nm": self._route_mean(rt.AVERAGE_ROUTE_EMPTY),
        }

    def kpis(self) -> dict[str, Any]:
        """The shared KPIs and the mean |route deviation| [NM] (NaN without a decision step)."""
        out = super().kpis()
        out["kpi_mean_route_deviation_nm"] = self._route_mean(np.nan)
        return out
