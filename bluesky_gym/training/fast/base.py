"""What every fast trainer shares: observations as one tensor, episode bookkeeping, checkpoint files.

A fast trainer trains the networks of a Stable-Baselines3 model (``model.policy``, its
optimisers) on a native vector environment (``gym.make_vec(..., vectorization_mode=
"vector_entry_point")``). It steps the environment with one array per step and keeps
everything per environment as arrays; the run directory's bookkeeping (episode log,
checkpoints) is done by the caller through :class:`Hooks`.
"""

from __future__ import annotations

import re
import time
from collections import deque
from collections.abc import Callable
from pathlib import Path
from typing import Any, ClassVar, Protocol

import numpy as np
import torch

#: Episodes over which the logged mean return and length are taken (as SB3's ``stats_window_size``).
STATS_WINDOW = 100


class Hooks(Protocol):
    """What a fast trainer tells its caller during :meth:`FastTrainer.learn`."""

    def on_rollout_start(self, trainer: FastTrainer) -> None:
        """Called where the model is trained on every transition counted so far (a checkpoint may be taken)."""

    def on_episodes(self, trainer: FastTrainer, records: list[dict[str, Any]]) -> None:
        """Called after a step in which episodes ended, with one record per ended episode."""


class NoHooks:
    """Hooks that do nothing."""

    def on_rollout_start(self, trainer: FastTrainer) -> None:
        """Do nothing."""

    def on_episodes(self, trainer: FastTrainer, records: list[dict[str, Any]]) -> None:
        """Do nothing."""


class ObservationBatcher:
    """Dict observations of a vector environment as one ``(rows, features)`` float32 tensor.

    The keys are concatenated in the order of the observation space, each flattened: exactly
    the features SB3's ``CombinedExtractor`` computes from them, so the SB3 networks can be fed
    the tensor directly.

    Args:
        space: The single-environment observation space (a ``Dict`` of ``Box``).
        device: The learner's torch device.

    """

    def __init__(self, space: Any, device: torch.device) -> None:
        self.keys = list(space.spaces)
        self.sizes = [int(np.prod(space.spaces[k].shape)) for k in self.keys]
        self.dim = int(sum(self.sizes))
        self.device = device

    def __call__(self, obs: dict[str, Any], rows: Any = None) -> torch.Tensor:
        """Return the observations (of ``rows`` only, if given) as one float32 tensor on the device.

        ``obs`` holds numpy arrays, or tensors (an environment made with ``device="cuda"``): those
        are concatenated where they are, without a copy to the host.
        """
        first = obs[self.keys[0]]
        if isinstance(first, torch.Tensor):
            idx = None if rows is None else torch.as_tensor(rows, device=first.device)
            tensors = [obs[k] if idx is None else obs[k][idx] for k in self.keys]
            n = tensors[0].shape[0]
            return torch.cat([t.reshape(n, -1).to(torch.float32) for t in tensors], dim=1).to(self.device)
        parts = [np.asarray(obs[k] if rows is None else obs[k][rows]) for k in self.keys]
        n = parts[0].shape[0]
        flat = np.concatenate([p.reshape(n, -1) for p in parts], axis=1, dtype=np.float32)
        return torch.from_numpy(flat).to(self.device)


def _per_env(value: Any, n: int) -> bool:
    return isinstance(value, np.ndarray) and value.ndim == 1 and value.shape[0] == n


class EpisodeTracker:
    """Returns, lengths and reward-component sums of the episodes in flight, as arrays.

    :meth:`step` returns one record per episode that ended in the step: ``env_index``,
    ``return``, ``length``, ``terminated``, the episode's sum of every reward component
    (``reward_*``) and the final step's scalar info values (reference info keys, ``kpi_*``):
    the columns of a run's episode log.

    Args:
        n_envs: Number of batched environments.

    """

    def __init__(self, n_envs: int) -> None:
        self.n_envs = n_envs
        self.returns = np.zeros(n_envs)
        self.lengths = np.zeros(n_envs, dtype=np.int64)
        self.components: dict[str, np.ndarray] = {}

    def reset(self) -> None:
        """Forget the episodes in flight (after the environment was reset)."""
        self.returns[:] = 0.0
        self.lengths[:] = 0
        self.components.clear()

    def step(self, reward: np.ndarray, terminated: np.ndarray, truncated: np.ndarray, info: dict[str, Any]) -> list[dict[str, Any]]:
        """Account for one step of every environment; return the records of the episodes that ended."""
        n = self.n_envs
        self.returns += reward
        self.lengths += 1
        for k, v in info.items():
            if k.startswith("reward_") and _per_env(v, n):
                if k not in self.components:
                    self.components[k] = np.zeros(n)
                self.components[k] += v
        done = np.logical_or(terminated, truncated)
        if not done.any():
            return []
        final = info.get("final_info", info)
        scalars = {k: v for k, v in final.items() if _per_env(v, n) and not k.startswith("reward_") and v.dtype.kind in "biuf"}
        records = []
        for i in np.flatnonzero(done).tolist():
            record: dict[str, Any] = {
                "env_index": i,
                "return": float(self.returns[i]),
                "length": int(self.lengths[i]),
                "terminated": bool(terminated[i]),
            }
            record.update({k: float(v[i]) for k, v in self.components.items()})
            record.update({k: v[i].item() for k, v in scalars.items()})
            records.append(record)
        self.returns[done] = 0.0
        self.lengths[done] = 0
        for v in self.components.values():
            v[done] = 0.0
        return records


def ended_rows(mask: Any) -> Any:
    """The indices of the True entries of a step's mask: numpy for numpy masks, a tensor (on its device) for tensors."""
    if isinstance(mask, torch.Tensor):
        return torch.nonzero(mask).flatten()
    return np.flatnonzero(mask)


def _per_env_tensor(value: Any, n: int) -> bool:
    return isinstance(value, torch.Tensor) and value.ndim == 1 and value.shape[0] == n


class TensorEpisodeTracker(EpisodeTracker):
    """:class:`EpisodeTracker` of an environment whose outputs are tensors on a device (``device="cuda"``).

    Returns, lengths and component sums stay tensors on that device; only the rows of the
    episodes that ended come to the host, for their records (one check per step whether any did).

    Args:
        n_envs: Number of batched environments.
        device: The environment's device.
    """

    def __init__(self, n_envs: int, device: torch.device) -> None:
        self.n_envs = n_envs
        self.returns = torch.zeros(n_envs, dtype=torch.float64, device=device)  # type: ignore[assignment]
        self.lengths = torch.zeros(n_envs, dtype=torch.int64, device=device)  # type: ignore[assignment]
        self.components = {}

    def reset(self) -> None:
        """Forget the episodes in flight (after the environment was reset)."""
        self.returns.zero_()  # type: ignore[attr-defined]
        self.lengths.zero_()  # type: ignore[attr-defined]
        self.components.clear()

    def step(self, reward: Any, terminated: Any, truncated: Any, info: dict[str, Any]) -> list[dict[str, Any]]:
        """Account for one step of every environment; return the records of the episodes that ended."""
        n = self.n_envs
        self.returns += reward
        self.lengths += 1
        for k, v in info.items():
            if k.startswith("reward_") and _per_env_tensor(v, n):
                if k not in self.components:
                    self.components[k] = torch.zeros(n, dtype=torch.float64, device=v.device)  # type: ignore[assignment]
                self.components[k] += v
        done = terminated | truncated
        rows = ended_rows(done)
        if rows.numel() == 0:
            return []
        final = info.get("final_info", info)
        picked = {k: v[rows].cpu().numpy() for k, v in final.items() if _per_env_tensor(v, n) and not k.startswith("reward_")}
        scalars = {k: v for k, v in picked.items() if v.dtype.kind in "biuf"}
        returns, lengths, ended = self.returns[rows].cpu().numpy(), self.lengths[rows].cpu().numpy(), terminated[rows].cpu().numpy()
        components = {k: v[rows].cpu().numpy() for k, v in self.components.items()}
        records = []
        for j, i in enumerate(rows.cpu().tolist()):
            record: dict[str, Any] = {"env_index": i, "return": float(returns[j]), "length": int(lengths[j]), "terminated": bool(ended[j])}
            record.update({k: float(v[j]) for k, v in components.items()})
            record.update({k: v[j].item() for k, v in scalars.items()})
            records.append(record)
        self.returns[rows] = 0.0
        self.lengths[rows] = 0
        for v in self.components.values():
            v[rows] = 0.0
        return records


class Adam:
    """Adam over a dict of tensors, updated in place: ``torch.optim.Adam``'s rule, written out so that it can be compiled with the loss.

    It takes its settings from, and gives its moments back to, the SB3 optimiser it stands in for
    (:meth:`load_from`, :meth:`store_into`), so the model file holds the optimiser's true state.

    Args:
        params: The tensors it updates (sharing storage with the networks' parameters).
        optimizer: The ``torch.optim.Adam`` of those parameters (settings and, if it has one, state).

    """

    def __init__(self, params: dict[str, torch.Tensor], optimizer: torch.optim.Optimizer) -> None:
        if not isinstance(optimizer, torch.optim.Adam) or len(optimizer.param_groups) != 1:
            raise ValueError(f"the fast trainer needs the model's optimizer to be one torch.optim.Adam group, got {type(optimizer).__name__}")
        group = optimizer.param_groups[0]
        if group["weight_decay"] or group["amsgrad"] or group["maximize"]:
            raise ValueError("the fast trainer implements Adam without weight decay, amsgrad or maximize")
        self.lr = float(group["lr"])
        self.beta1, self.beta2 = (float(b) for b in group["betas"])
        self.eps = float(group["eps"])
        self.params = params
        self.exp_avg = {k: torch.zeros_like(v) for k, v in params.items()}
        self.exp_avg_sq = {k: torch.zeros_like(v) for k, v in params.items()}
        self.step = torch.zeros((), device=next(iter(params.values())).device)
        self.load_from(optimizer)

    def apply(self, grads: dict[str, torch.Tensor], max_grad_norm: float | None = None) -> None:
        """One Adam step with ``grads``, clipped first to a global norm of ``max_grad_norm`` (as ``clip_grad_norm_``)."""
        if max_grad_norm is not None:
            norm = torch.linalg.vector_norm(torch.stack([torch.linalg.vector_norm(g) for g in grads.values()]))
            coef = torch.clamp(max_grad_norm / (norm + 1e-6), max=1.0)
            grads = {k: g * coef for k, g in grads.items()}
        with torch.no_grad():
            self.step.add_(1)
            bias1 = 1 - self.beta1**self.step
            bias2_sqrt = (1 - self.beta2**self.step).sqrt()
            for k, p in self.params.items():
                g = grads[k]
                self.exp_avg[k].lerp_(g, 1 - self.beta1)
                self.exp_avg_sq[k].mul_(self.beta2).addcmul_(g, g, value=1 - self.beta2)
                p.sub_(self.lr / bias1 * self.exp_avg[k] / (self.exp_avg_sq[k].sqrt() / bias2_sqrt + self.eps))

    def _ordered(self, optimizer: torch.optim.Optimizer) -> list[tuple[str, torch.Tensor]]:
        """The optimiser's parameters with the names of :attr:`params` (matched by storage)."""
        by_storage = {v.data_ptr(): k for k, v in self.params.items()}
        out = []
        for p in optimizer.param_groups[0]["params"]:
            if p.data_ptr() not in by_storage:
                raise ValueError("the optimizer holds a parameter the fast trainer does not update")
            out.append((by_storage[p.data_ptr()], p))
        return out

    def load_from(self, optimizer: torch.optim.Optimizer) -> None:
        """Take the moments and step count of ``optimizer`` (a loaded model's), if it has stepped."""
        for name, p in self._ordered(optimizer):
            state = optimizer.state.get(p)
            if state:
                self.exp_avg[name].copy_(state["exp_avg"])
                self.exp_avg_sq[name].copy_(state["exp_avg_sq"])
                self.step.fill_(float(state["step"]))

    def store_into(self, optimizer: torch.optim.Optimizer) -> None:
        """Give ``optimizer`` these moments and step count (before the model is saved)."""
        if float(self.step) == 0:
            return
        for name, p in self._ordered(optimizer):
            optimizer.state[p] = {
                "step": self.step.detach().clone().cpu(),
                "exp_avg": self.exp_avg[name].detach().clone(),
                "exp_avg_sq": self.exp_avg_sq[name].detach().clone(),
            }


class FastTrainer:
    """Base of the fast trainers: the SB3 model trained, the environment stepped, the files of a checkpoint.

    Args:
        model: The Stable-Baselines3 model whose networks and optimisers are trained (made or
            loaded on an environment with the same spaces and number of environments).
        venv: The native vector environment to train on (``SAME_STEP`` autoreset).
        seed: Seed of the trainer's own random generator (actions, minibatches, replay samples).
        tensorboard_log: Directory of the TensorBoard logs (``<dir>/<ALGO>_<k>``, as SB3), or None.
        compile: Compile the update with ``torch.compile``.

    """

    algo: ClassVar[str]
    #: The trainer's own state in a checkpoint: step count, update count, random generator.
    STATE_FILE: ClassVar[str] = "trainer.pt"

    def __init__(self, model: Any, venv: Any, *, seed: int, tensorboard_log: str | None = None, compile: bool = False) -> None:

        self.model = model
        self.venv = venv
        self.n_envs = int(venv.num_envs)
        self.device = torch.device(model.device)
        self.generator = torch.Generator(device=self.device)
        self.generator.manual_seed(int(seed))
        self.num_timesteps = int(model.num_timesteps)
        self.n_updates = 0
        self.compile = bool(compile)
        self.batch_obs = ObservationBatcher(venv.single_observation_space, self.device)
        #: The environment speaks tensors on its device (``gym.make_vec(..., device="cuda")``): the
        #: trainer hands it the action tensor and reads its outputs where they are, without host copies.
        self.env_on_device = getattr(venv, "device", "cpu") == "cuda"
        self.episodes = TensorEpisodeTracker(self.n_envs, self.device) if self.env_on_device else EpisodeTracker(self.n_envs)
        self.recent_returns: deque[float] = deque(maxlen=STATS_WINDOW)
        self.recent_lengths: deque[int] = deque(maxlen=STATS_WINDOW)
        space = venv.single_action_space
        self.action_low = torch.as_tensor(np.asarray(space.low, dtype=np.float32), device=self.device)
        self.action_high = torch.as_tensor(np.asarray(space.high, dtype=np.float32), device=self.device)
        self.action_dim = int(np.prod(space.shape))
        self.tensorboard_log = tensorboard_log
        self._writer: Any = None
        self._obs: torch.Tensor | None = None
        self._t0 = time.perf_counter()
        self._t0_steps = self.num_timesteps

    # --- environment ---------------------------------------------------------------------------------
    def start(self, env_seeds: list[int]) -> None:
        """Reset every environment with its scenario seed; the episodes in flight are forgotten."""
        obs, _ = self.venv.reset(seed=env_seeds)
        self._obs = self.batch_obs(obs)
        self.episodes.reset()
        self._t0, self._t0_steps = time.perf_counter(), self.num_timesteps

    @property
    def current_obs(self) -> torch.Tensor:
        """The flat observations of the environments now (after :meth:`start`)."""
        if self._obs is None:
            raise RuntimeError("the trainer's environments are not started; call start() first")
        return self._obs

    def step_env(self, actions: torch.Tensor, hooks: Hooks) -> tuple[dict[str, Any], Any, Any, Any, dict[str, Any]]:
        """Step every environment with ``actions`` (already in the action space); log ended episodes through ``hooks``.

        Returns numpy arrays, or tensors on the learner's device for an environment on the device
        (:attr:`env_on_device`).
        """
        if self.env_on_device:
            obs, reward, terminated, truncated, info = self.venv.step(actions)
            reward, terminated, truncated = (x.to(self.device) for x in (reward, terminated, truncated))
        else:
            obs, reward, terminated, truncated, info = self.venv.step(actions.cpu().numpy())
            reward = np.asarray(reward, dtype=np.float64)
            terminated = np.asarray(terminated, dtype=bool)
            truncated = np.asarray(truncated, dtype=bool)
        self.num_timesteps += self.n_envs
        records = self.episodes.step(reward, terminated, truncated, info)
        if records:
            self.recent_returns.extend(r["return"] for r in records)
            self.recent_lengths.extend(r["length"] for r in records)
            hooks.on_episodes(self, records)
        return obs, reward, terminated, truncated, info

    def learn(self, total_timesteps: int, hooks: Hooks | None = None, progress_bar: bool = False) -> None:
        """Train until ``total_timesteps`` environment steps are done (PPO: until the rollout that reaches it ends)."""
        raise NotImplementedError

    # --- logging -----------------------------------------------------------------------------------------
    def steps_per_second(self) -> float:
        """Environment steps per second since :meth:`start`."""
        return (self.num_timesteps - self._t0_steps) / max(time.perf_counter() - self._t0, 1e-9)

    def record(self, values: dict[str, float]) -> None:
        """Write scalars to TensorBoard at the current step (nothing without a TensorBoard directory)."""
        if self.tensorboard_log is None:
            return
        if self._writer is None:
            from torch.utils.tensorboard import SummaryWriter

            self._writer = SummaryWriter(log_dir=str(_tensorboard_run_dir(Path(self.tensorboard_log), self.algo, self.num_timesteps > 0)))
        if self.recent_returns:
            episodes = {"rollout/ep_rew_mean": float(np.mean(self.recent_returns)), "rollout/ep_len_mean": float(np.mean(self.recent_lengths))}
            values = {**episodes, **values}
        values = {**values, "time/fps": self.steps_per_second()}
        for name, value in values.items():
            self._writer.add_scalar(name, value, self.num_timesteps)

    def close(self) -> None:
        """Flush and close the TensorBoard log."""
        if self._writer is not None:
            self._writer.close()
            self._writer = None

    # --- checkpoints -----------------------------------------------------------------------------------
    def checkpoint_writers(self) -> dict[str, Callable[[Path], None]]:
        """The files of a checkpoint, each with the function that writes it to a given path."""
        return {"model.zip": self.save, self.STATE_FILE: self.save_state}

    def save(self, path: str | Path) -> None:
        """Write the model as a Stable-Baselines3 model file (``<ALGO>.load(path)`` reads it)."""
        self.model.num_timesteps = self.num_timesteps
        self.model.save(path)

    def state(self) -> dict[str, Any]:
        """The trainer's own state (what the SB3 model file does not hold)."""
        return {"num_timesteps": self.num_timesteps, "n_updates": self.n_updates, "generator": self.generator.get_state()}

    def save_state(self, path: str | Path) -> None:
        """Write :meth:`state` to ``path``."""
        with open(path, "wb") as f:
            torch.save(self.state(), f)

    def restore(self, checkpoint_dir: str | Path) -> None:
        """Restore the trainer's own state from a checkpoint directory (the model is loaded by the caller).

        Raises:
            ValueError: The state does not belong to the model (another step count).

        """
        path = Path(checkpoint_dir) / self.STATE_FILE
        state = torch.load(path, map_location="cpu", weights_only=True)
        if int(state["num_timesteps"]) != self.num_timesteps:
            raise ValueError(f"{path} is at {state['num_timesteps']} steps but the model beside it at {self.num_timesteps}")
        self.n_updates = int(state["n_updates"])
        self.generator.set_state(state["generator"])


def progress(total: int, done: int) -> Any:
    """A progress bar over environment steps (tqdm, from the ``train`` extra)."""
    from tqdm import tqdm

    return tqdm(total=total, initial=done, unit="step", unit_scale=True, dynamic_ncols=True)


def _tensorboard_run_dir(root: Path, algo: str, resume: bool) -> Path:
    """``<root>/<ALGO>_<k>`` as SB3 names it: a new ``k`` for a new run, the latest one for a resumed run."""
    ids = [int(m.group(1)) for p in root.glob(f"{algo}_*") if (m := re.fullmatch(rf"{re.escape(algo)}_(\d+)", p.name))]
    latest = max(ids, default=0)
    return root / f"{algo}_{latest if resume and latest else latest + 1}"
