"""Vector environments on a CUDA GPU: ``gym.make_vec(id, num_envs=N, device="cuda")``.

With ``device="cuda"`` a native vector environment runs its physics on the device
(:class:`~bluesky_gym.core.DeviceSimulator`, the ``"cuda"`` backend) and speaks torch tensors:
observations, rewards, ``terminated`` and ``truncated`` (and the final observations of the
episodes that ended) are tensors on the GPU, and actions may be given as tensors on the GPU
(or as anything array-like).

How the batches travel (:class:`TensorIO`):

* **Out**: each output array goes to the device once per step, into a numba-cuda device array
  (:func:`bluesky_gym.core.cuda_target.to_device`), which torch then wraps without a copy through
  the CUDA Array Interface (``__cuda_array_interface__``): the tensor owns the device array's
  memory. The same zero-copy wrap gives the simulator's own device state as tensors
  (:meth:`TensorIO.tensor`, used by ``state_tensors`` of the vector environment).
* **In**: actions on the device (a torch tensor, or any object with ``__cuda_array_interface__``
  or ``__dlpack__``) are copied to the host once per step: the actions become autopilot
  commands, which the task gives on the host.

Where the task's whole step runs on the device (:class:`DeviceStep`, a subclass per task in its
folder's ``device_step.py``, named by its registry row: every single-agent task),
neither copy happens: the actions stay on the device, the kernels write into
tensors (:meth:`TensorIO.kernel_array`), and only which episodes ended comes to the host.

Under numba-cuda's simulator (``NUMBA_ENABLE_CUDASIM=1``) the device arrays are numpy arrays in
disguise and torch has no GPU to put tensors on: the tensors are then CPU tensors, made by the
same code path, so that the environment's logic is tested without a GPU.
"""

from __future__ import annotations

from typing import Any, ClassVar, cast

import numpy as np

from bluesky_gym.core import DeviceSimulator, cuda_target
from bluesky_gym.core.extras import missing_extra
from bluesky_gym.tasks import compiled
from bluesky_gym.tasks.base import KPI_KEYS, StepGeometry, Task, numeric_action

#: The values of the vector environments' ``device`` argument.
DEVICES = ("cpu", "cuda")


def check_device(device: Any) -> str:
    """Validate a vector environment's ``device`` argument.

    Raises:
        ValueError: ``device`` is not one of :data:`DEVICES`.
    """
    if not isinstance(device, str) or device not in DEVICES:
        raise ValueError(f"device must be one of {DEVICES}, got {device!r}")
    return device


def _torch() -> Any:
    try:
        import torch
    except ImportError as exc:
        raise missing_extra("device='cuda' gives torch tensors and needs PyTorch", "train") from exc
    return torch


class TensorIO:
    """Moves a vector environment's batches between numpy on the host and torch tensors on the device.

    Raises:
        MissingDependencyError: Without numba-cuda (the ``gpu`` extra) or PyTorch (the ``train`` extra).
        RuntimeError: Neither a CUDA GPU nor numba-cuda's simulator is there to run on.
    """

    def __init__(self) -> None:
        cuda_target.require()
        self.torch = _torch()
        if cuda_target.SIMULATOR:
            self.device = self.torch.device("cpu")
        elif cuda_target.device_present() and self.torch.cuda.is_available():
            self.device = self.torch.device("cuda", self.torch.cuda.current_device())
        else:
            raise RuntimeError(
                "device='cuda' needs a CUDA GPU seen by both numba-cuda and PyTorch (none found); "
                "numba-cuda's simulator (NUMBA_ENABLE_CUDASIM=1) runs the same code on the CPU"
            )

    def tensor(self, device_array: Any) -> Any:
        """A torch tensor sharing the memory of a numba-cuda device array (no copy; a CPU copy under the simulator)."""
        if cuda_target.SIMULATOR:
            return self.torch.from_numpy(device_array.copy_to_host())
        return self.torch.as_tensor(device_array, device=self.device)

    def kernel_array(self, tensor: Any) -> Any:
        """A contiguous tensor as a kernel argument sharing its memory (numba-cuda's view of it; its numpy view under the simulator)."""
        if cuda_target.SIMULATOR:
            return tensor.numpy()
        return cuda_target.cuda.as_cuda_array(tensor)

    def upload(self, host: np.ndarray) -> Any:
        """A host array as a tensor on the device: one copy into a numba-cuda device array, wrapped by :meth:`tensor`."""
        return self.tensor(cuda_target.to_device(np.ascontiguousarray(host)))

    def upload_all(self, arrays: dict[str, np.ndarray]) -> dict[str, Any]:
        """:meth:`upload` of every array of a dict."""
        return {k: self.upload(v) for k, v in arrays.items()}

    def to_host(self, value: Any) -> Any:
        """Actions as the task takes them: a tensor or device array copied to the host; anything else as it is.

        Accepts torch tensors on any device, objects with ``__cuda_array_interface__`` (CuPy,
        numba-cuda, ...) or ``__dlpack__`` (JAX, ...), and array-likes (numpy, lists).
        """
        torch = self.torch
        if isinstance(value, torch.Tensor):
            return value.detach().cpu().numpy()
        if hasattr(value, "copy_to_host"):  # numba-cuda's device arrays (and the simulator's)
            return value.copy_to_host()
        if hasattr(value, "__cuda_array_interface__"):
            return cuda_target.cuda.as_cuda_array(value).copy_to_host()
        if hasattr(value, "__dlpack__") and not isinstance(value, np.ndarray):
            return torch.from_dlpack(value).cpu().numpy()
        return value


class DeviceStep:
    """A task's vector-environment step on the device: the task's kernels launched over every episode.

    The pipeline is the CPU task's (:meth:`bluesky_gym.tasks.base.Task.step`), stage by stage, each
    stage the CUDA form of the kernel the CPU task runs (:mod:`bluesky_gym.core.cuda_target`):

    * the actions (a tensor on the device) are validated, clipped
      (:func:`~bluesky_gym.tasks.compiled.clip_to_bounds`) and given as autopilot commands
      (:meth:`command`);
    * the physics sub-steps (:meth:`~bluesky_gym.tasks.base.Task.advance`);
    * :meth:`measure`, :meth:`observe` (``-v1``: each entry clipped to its declared bounds, as
      :meth:`~bluesky_gym.tasks.base.Task.bounded` does), :meth:`reward`;
    * the episode statistics (:func:`~bluesky_gym.tasks.compiled.record_step`), the truncation
      (:func:`~bluesky_gym.tasks.compiled.truncation`, with :meth:`cut`), the info
      (:meth:`episode_info`) and, in a step where an episode ends, the KPIs
      (:func:`~bluesky_gym.tasks.compiled.episode_kpis`, and
      :func:`~bluesky_gym.tasks.compiled.goal_kpis` with :meth:`extra_track_km` for a task with a
      goal).

    A step is a fixed number of launches, whatever the number of episodes; one thing comes to the
    host per step: which episodes ended (a boolean per episode). Their new scenarios are drawn on
    the host from each episode's own generator, in the reference's order
    (:meth:`~bluesky_gym.tasks.base.Task.generate`, as on the CPU), and only those episodes'
    aircraft and per-episode arrays are uploaded
    (:meth:`~bluesky_gym.core.DeviceSimulator.reset_on_host`, :meth:`host_arrays`); then a fixed
    number of launches measures and observes them.

    A task's subclass (its folder's ``device_step.py``, named by its registry row) supplies the
    stages that differ: :meth:`measure`, :meth:`observe`, :meth:`reward`, :meth:`episode_info`,
    and where they apply :meth:`command`, :meth:`advance`, :meth:`cut` and :meth:`extra_track_km`. Every output
    is a torch tensor on the device, the info entries included.

    Args:
        task: The vector environment's task (its physics a :class:`~bluesky_gym.core.DeviceSimulator`).
        io: The environment's :class:`TensorIO`.

    Raises:
        TypeError: The task's physics is not on the device.
    """

    #: The task class the step belongs to.
    task_class: ClassVar[type[Task]]
    #: Heading change per unit of the heading action [deg] (:meth:`command`'s default).
    heading_step: float = 0.0
    #: CAS change per unit of the speed action [m/s] (:meth:`command`'s default).
    speed_step: float = 0.0

    @staticmethod
    def supports(task: Task) -> bool:
        """Whether ``task``'s configuration runs on the device: no wind, no effects, no extra observation terms."""
        return not task.effects and not task.observation_terms and task.config.wind is None

    def __init__(self, task: Task, io: TensorIO) -> None:
        if not isinstance(task.sim, DeviceSimulator):
            raise TypeError(f"the device step needs the task's physics on the device (DeviceSimulator), got {type(task.sim).__name__}")
        self.task, self.io, self.torch = task, io, io.torch
        self.sim: Any = task.sim
        torch, dev = self.torch, io.device
        n, m = task.n_envs, task.sim.max_aircraft
        self.n, self.m = n, m
        self.envs = self.long(np.arange(n))
        self.own = self.long(np.zeros(n, np.int64))
        self.action_shape = (n, *task.action_spec.shape)
        self.action_low, self.action_high = (torch.as_tensor(b, device=dev) for b in task.action_bounds())
        self.obs_dtype = torch.float32 if task.config.float32_spaces else torch.float64
        self.bounds = {k: tuple(torch.as_tensor(b, device=dev) for b in lh) for k, lh in task.observation_bounds().items()}
        self.nothing = torch.zeros(0, dtype=torch.float64, device=dev)
        self.never = torch.zeros(n, dtype=torch.bool, device=dev)
        # The episode statistics (Task.stats), kept on the device.
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
        }
        #: The task's per-episode arrays on the device (:meth:`host_arrays`), uploaded at each reset.
        self.arrays: dict[str, Any] = {}
        self._no_traffic: tuple[Any, Any] | None = None

    # --- what a task supplies ------------------------------------------------------------------
    def host_arrays(self) -> dict[str, np.ndarray]:
        """The task's per-episode host arrays the step reads or updates on the device (first axis: the episode).

        Uploaded for the reset episodes after :meth:`~bluesky_gym.tasks.base.Task.generate`
        (which gives them their new values), copied back by :meth:`sync_host`. They may be views
        (e.g. a task's first column only); an array whose shape changed (grown) is uploaded whole.
        """
        return {}

    def command(self, action: Any) -> None:
        """Give the clipped actions (float64, (n_envs, 2)) as heading and speed commands to slot 0.

        The kernel :func:`~bluesky_gym.tasks.compiled.command_heading_speed`, with
        :attr:`heading_step` and :attr:`speed_step`.
        """
        hdg, cas, ap_trk, selspd, swlnav, swvnavspd = self.sim.device_arrays("hdg", "cas", "ap_trk", "selspd", "swlnav", "swvnavspd")
        k = self.kernel_array
        cuda_target.launch(
            compiled.command_heading_speed,
            self.n,
            k(self.envs),
            k(self.own),
            k(action),
            hdg,
            cas,
            float(self.heading_step),
            float(self.speed_step),
            ap_trk,
            swlnav,
            selspd,
            swvnavspd,
        )

    def measure(self, envs: Any, own: Any) -> StepGeometry:
        """The task's geometry of rows (``envs``, ``own``) (device tensors), its arrays tensors on the device."""
        raise NotImplementedError

    def observe(self, g: StepGeometry) -> dict[str, Any]:
        """The task's own observation entries (float64 tensors) from the geometry."""
        raise NotImplementedError

    def reward(self, g: StepGeometry) -> tuple[Any, Any, dict[str, Any]]:
        """Reward (n_envs,), termination (n_envs,) and named reward components, tensors on the device."""
        raise NotImplementedError

    def cut(self, g: StepGeometry) -> Any:
        """(n_envs,) the task's own truncation (:meth:`~bluesky_gym.tasks.base.Task.truncate`): none by default."""
        return self.never

    def episode_info(self) -> dict[str, Any]:
        """The task's info entries (:meth:`~bluesky_gym.tasks.base.Task.episode_info`), tensors on the device."""
        return {"total_reward": self.stats["total_reward"].clone()}

    def advance(self) -> None:
        """The physics sub-steps of a decision step: the task's :meth:`~bluesky_gym.tasks.base.Task.advance` by default."""
        self.task.advance()

    def extra_track_km(self) -> Any:
        """(n_envs,) a task with a goal: the distance flown beyond the nominal route [km] (:meth:`~bluesky_gym.tasks.base.Task.extra_track_km`).

        The kernel :func:`~bluesky_gym.tasks.compiled.extra_track` with the task's route array
        (:attr:`~bluesky_gym.tasks.base.Task.route_km_array`, kept on the device); NaN without one.
        """
        name = self.task.route_km_array
        if name is None:
            return self.empty(self.n).fill_(np.nan)
        (distflown,) = self.sim.device_arrays("distflown")
        out = self.empty(self.n)
        self.launch(compiled.extra_track, self.n, distflown, self.arrays[name], out)
        return out

    def _host_arrays(self) -> dict[str, np.ndarray]:
        """:meth:`host_arrays` and the task's nominal routes (:attr:`~bluesky_gym.tasks.base.Task.route_km_array`)."""
        arrays = self.host_arrays()
        name = self.task.route_km_array
        if name is not None:
            arrays[name] = getattr(self.task, name)
        return arrays

    # --- tensors and kernels --------------------------------------------------------------------
    def no_traffic(self, rows: int) -> tuple[Any, Any]:
        """Separations [NM] (inf) and loss-of-separation flags (False) of ``rows`` rows, for a task without traffic.

        What its CPU measure gives the statistics: no separation to anyone, never a loss of it.
        Made once, (n_envs, max_aircraft), and sliced.
        """
        if self._no_traffic is None:
            torch, shape = self.torch, (self.n, self.m)
            self._no_traffic = (
                torch.full(shape, np.inf, dtype=torch.float64, device=self.io.device),
                torch.zeros(shape, dtype=torch.bool, device=self.io.device),
            )
        separation, los = self._no_traffic
        return separation[:rows], los[:rows]

    def sample_mean(self, total: str, count: str, empty: float) -> Any:
        """(n_envs,) the mean of the samples summed in the task's arrays ``total`` and ``count``; ``empty`` without one.

        The kernel :func:`~bluesky_gym.tasks.compiled.sample_means`, one launch.
        """
        out = self.empty(self.n)
        self.launch(compiled.sample_means, self.n, self.arrays[total], self.arrays[count], empty, out)
        return out

    def long(self, host: np.ndarray) -> Any:
        """A host array of integers as an int64 tensor on the device (a copy: later changes of ``host`` do not show)."""
        return self.torch.tensor(np.ascontiguousarray(host, dtype=np.int64), device=self.io.device)

    def kernel_array(self, tensor: Any) -> Any:
        """A tensor as a kernel argument (no copy)."""
        return self.io.kernel_array(tensor)

    def empty(self, *shape: int, dtype: Any = None) -> Any:
        """An uninitialised tensor on the device (float64 unless ``dtype``)."""
        return self.torch.empty(shape, dtype=self.torch.float64 if dtype is None else dtype, device=self.io.device)

    def launch(self, kernel: Any, rows: int, *args: Any) -> None:
        """Launch ``kernel`` over ``rows`` rows, tensors among ``args`` passed without a copy (they must be contiguous)."""
        torch = self.torch
        cuda_target.launch(kernel, rows, *(self.kernel_array(a) if isinstance(a, torch.Tensor) else a for a in args))

    # --- the shared stages ---------------------------------------------------------------------
    def _upload_arrays(self, rows: np.ndarray | None, idx: Any) -> None:
        """The task's per-episode arrays of episodes ``rows`` (all when None; ``idx``: the same on the device) to the device."""
        dev = self.io.device
        for name, host in self._host_arrays().items():
            held = self.arrays.get(name)
            if rows is None or held is None or tuple(held.shape) != host.shape:
                self.arrays[name] = self.torch.tensor(np.ascontiguousarray(host), device=dev)  # a copy (never the host's memory)
            else:
                held[idx] = self.torch.as_tensor(np.ascontiguousarray(host[rows]), device=dev)

    def _clear_stats(self, idx: Any) -> None:
        """:meth:`~bluesky_gym.tasks.base.EpisodeStats.clear` of episodes ``idx`` on the device."""
        s = self.stats
        for key in ("los_count", "los_steps", "steps", "drift_n"):
            s[key][idx] = 0
        for key in ("total_reward", "drift_sum"):
            s[key][idx] = 0.0
        s["min_sep"][idx] = np.inf
        s["time_to_goal"][idx] = np.nan
        s["in_los"][idx] = False

    def sync_host(self) -> None:
        """Copy the episode statistics and the task's per-episode arrays to the host (for pictures: the step never reads them)."""
        s, t = self.stats, self.task
        names = {"in_los": "in_los", "min_sep": "min_separation"}
        for key, value in s.items():
            name = names.get(key, key)
            if key == "in_los" and t.stats.in_los.shape != tuple(value.shape):
                t.stats.in_los = np.zeros(tuple(value.shape), bool)
            getattr(t.stats, name)[...] = value.cpu().numpy()
        for name, host in self._host_arrays().items():
            host[...] = self.arrays[name].cpu().numpy()

    def record(self, g: StepGeometry, reward: Any | None) -> None:
        """:meth:`~bluesky_gym.tasks.base.Task.record` of rows ``g.envs`` on the device (one launch)."""
        s, t = self.stats, self.task
        stepped = reward is not None
        self.launch(
            compiled.record_step,
            int(g.envs.shape[0]),
            g.envs,
            g.separation_nm,
            g.los,
            stepped,
            reward if stepped else self.nothing,
            self.nothing if g.drift_deg is None else cast(Any, g.drift_deg).contiguous(),  # (a view of a geometry's column, for some tasks)
            g.goal_reached,
            float(t.dt),
            int(t.action_frequency),
            *(s[key] for key in ("in_los", "min_sep", "los_count", "los_steps", "steps", "total_reward", "drift_sum", "drift_n", "time_to_goal")),
        )

    def observation(self, g: StepGeometry) -> dict[str, Any]:
        """:meth:`observe` in the space's dtype; ``-v1``: each entry clipped to its declared bounds first (one launch each)."""
        obs = self.observe(g)
        out = {}
        for key, value in obs.items():
            if self.task.config.float32_spaces:  # clipped in a copy: the geometry's tensors stay as measured
                v = value.to(dtype=self.torch.float64, copy=True).contiguous()
                rows = int(v.shape[0])
                flat = v.view(rows, -1)
                low, high = self.bounds[key]
                self.launch(compiled.clip_to_bounds, rows, flat, low, high, flat)
            else:
                v = value
            out[key] = v.to(self.obs_dtype).contiguous()
        return out

    def kpis(self) -> dict[str, Any]:
        """:meth:`~bluesky_gym.tasks.base.Task.kpis` on the device."""
        s, t = self.stats, self.task
        distflown, fuelburn = self.sim.device_arrays("distflown", "fuelburn")
        out = {key: self.empty(self.n) for key in KPI_KEYS}
        self.launch(
            compiled.episode_kpis,
            self.n,
            *(s[key] for key in ("steps", "los_count", "los_steps", "min_sep", "drift_sum", "drift_n")),
            distflown,
            fuelburn,
            float(t.dt),
            int(t.action_frequency),
            *out.values(),
        )
        if t.has_goal:
            success, time_to_goal = self.empty(self.n), self.empty(self.n)
            self.launch(compiled.goal_kpis, self.n, s["time_to_goal"], success, time_to_goal)
            out.update({"kpi_success": success, "kpi_time_to_goal_s": time_to_goal, "kpi_extra_track_km": self.extra_track_km()})
        return out

    def actions(self, actions: Any) -> Any:
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
        clipped = self.empty(*self.action_shape)  # Task.clip_action's kernel (never in place: the caller's tensor stays as it is)
        n = self.action_shape[0]
        self.launch(compiled.clip_to_bounds, n, a.contiguous().view(n, -1), self.action_low, self.action_high, clipped.view(n, -1))
        return clipped

    # --- reset and step -------------------------------------------------------------------------
    def start(self, rows: np.ndarray | None) -> tuple[Any, dict[str, Any]]:
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
        idx = self.envs if rows is None else self.long(rows)
        self._upload_arrays(rows, idx)
        self._clear_stats(idx)
        g = self.measure(idx, self.own[: int(idx.shape[0])])
        self.record(g, None)
        return idx, self.observation(g)

    def reset(self) -> tuple[dict[str, Any], dict[str, Any]]:
        """Every episode anew (their generators seeded by the environment): the first observation and the info."""
        _, obs = self.start(None)
        return obs, self.episode_info()

    def step(self, actions: Any) -> tuple[dict[str, Any], Any, Any, Any, dict[str, Any], np.ndarray]:
        """One step of every episode, ended episodes reset in the same call (SAME_STEP autoreset).

        Returns:
            Observation, reward, terminated, truncated, info (tensors on the device, Gymnasium's
            vector-environment layout), and the host's boolean mask of the episodes that ended.
        """
        t, n = self.task, self.n
        self.command(self.actions(actions))
        self.advance()
        g = self.measure(self.envs, self.own)
        obs = self.observation(g)
        reward, terminated, components = self.reward(g)
        self.record(g, reward)
        truncated = self.empty(n, dtype=self.torch.bool)
        self.launch(compiled.truncation, n, self.stats["steps"], int(t.time_limit), terminated, self.cut(g), truncated)
        done: Any = t.end_step(terminated, truncated)
        info: dict[str, Any] = self.episode_info()
        info.update({f"reward_{k}": v for k, v in components.items()})
        ended = done.cpu().numpy()  # the one transfer to the host of a step
        if ended.any():
            info.update(self.kpis())
            final_info = {key: v.clone() for key, v in info.items()}
            for key in list(info):
                if key.startswith("kpi_"):
                    info[f"_{key}"] = done.clone()
            final_obs = {key: v.clone() for key, v in obs.items()}
            idx, new_obs = self.start(np.flatnonzero(ended))
            for key, v in obs.items():
                v[idx] = new_obs[key]
            info["final_obs"] = final_obs
            info["_final_obs"] = done.clone()
            info["final_info"] = final_info
            info["_final_info"] = done.clone()
        return obs, reward, terminated, truncated, info, ended
