"""SAC, TD3 and DDPG on the native vector environment: SB3's networks and updates, a tensor replay buffer.

The schedule is SB3's ``OffPolicyAlgorithm.learn``: collect ``train_freq`` steps (or episodes) of
every environment, then, once more than ``learning_starts`` steps are done, make
``gradient_steps`` gradient steps (``-1``: one per transition collected). Before
``learning_starts`` the actions are uniform in the action space. The replay buffer stores the
final observation of an ended episode as its next observation and treats a truncated episode as
not done, as SB3's buffer with ``handle_timeout_termination``. The updates are SB3's ``SAC.train``
(automatic or fixed entropy coefficient) and ``TD3.train`` (DDPG is TD3 with one critic, no
policy delay and no target smoothing, as in SB3), on SB3's networks and optimisers; what differs
is that transitions and samples are tensors on the learner's device, drawn with the trainer's own
generator.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import torch
import torch.nn.functional as F

from bluesky_gym.training.fast.base import FastTrainer, Hooks, NoHooks, ended_rows, progress

#: The replay buffer of a checkpoint (the transitions stored so far, in insertion order).
REPLAY_FILE = "replay_buffer.pt"


class ReplayStorage:
    """A circular buffer of transitions as tensors: observation, action, reward, next observation, terminated.

    Args:
        capacity: Transitions kept (rounded down to a multiple of ``n_envs``, at least ``n_envs``).
        n_envs: Transitions added per step.
        obs_dim: Features of a flat observation.
        action_dim: Action dimensions.
        device: Torch device.

    """

    def __init__(self, capacity: int, n_envs: int, obs_dim: int, action_dim: int, device: Any) -> None:

        self.n_envs = n_envs
        self.capacity = max(capacity // n_envs, 1) * n_envs
        self.obs = torch.zeros((self.capacity, obs_dim), device=device)
        self.next_obs = torch.zeros((self.capacity, obs_dim), device=device)
        self.actions = torch.zeros((self.capacity, action_dim), device=device)
        self.rewards = torch.zeros((self.capacity, 1), device=device)
        self.dones = torch.zeros((self.capacity, 1), device=device)
        self.pos = 0
        self.size = 0

    def add(self, obs: Any, next_obs: Any, actions: Any, rewards: Any, dones: Any) -> None:
        """Store one transition per environment."""
        rows = slice(self.pos, self.pos + self.n_envs)
        self.obs[rows] = obs
        self.next_obs[rows] = next_obs
        self.actions[rows] = actions
        self.rewards[rows, 0] = rewards
        self.dones[rows, 0] = dones
        self.pos = (self.pos + self.n_envs) % self.capacity
        self.size = min(self.size + self.n_envs, self.capacity)

    def sample(self, batch_size: int, generator: Any) -> tuple[Any, Any, Any, Any, Any]:
        """``batch_size`` transitions drawn uniformly with replacement."""
        rows = torch.randint(0, self.size, (batch_size,), generator=generator, device=self.obs.device)
        return self.obs[rows], self.actions[rows], self.rewards[rows], self.next_obs[rows], self.dones[rows]

    def state(self) -> dict[str, Any]:
        """The stored transitions, oldest first."""
        order = torch.arange(self.size) if self.size < self.capacity else (torch.arange(self.capacity) + self.pos) % self.capacity
        order = order.to(self.obs.device)
        names = ("obs", "next_obs", "actions", "rewards", "dones")
        return {"size": self.size, **{name: getattr(self, name)[order].cpu() for name in names}}

    def load(self, state: dict[str, Any]) -> None:
        """Refill the buffer from :meth:`state` (the newest transitions if it holds more than the capacity)."""
        size = int(state["size"])
        keep = min(size, self.capacity)
        for name in ("obs", "next_obs", "actions", "rewards", "dones"):
            getattr(self, name)[:keep] = state[name][size - keep : size].to(self.obs.device)
        self.size = keep
        self.pos = keep % self.capacity


class FastOffPolicy(FastTrainer):
    """The collection schedule and replay buffer of SAC, TD3 and DDPG (subclasses: the actor and the update)."""

    def __init__(self, model: Any, venv: Any, *, seed: int, tensorboard_log: str | None = None, compile: bool = False) -> None:
        super().__init__(model, venv, seed=seed, tensorboard_log=tensorboard_log, compile=compile)
        from stable_baselines3.common.type_aliases import TrainFrequencyUnit

        if int(model.n_envs) != self.n_envs:
            raise ValueError(f"the model was made for {model.n_envs} environments, the environment has {self.n_envs}")
        if model.action_noise is not None:
            raise ValueError("action_noise is not supported by the fast trainer")
        self.learning_starts = int(model.learning_starts)
        self.batch_size = int(model.batch_size)
        self.tau = float(model.tau)
        self.gamma = float(model.gamma)
        self.train_every = int(model.train_freq.frequency)
        self.train_per_episode = model.train_freq.unit == TrainFrequencyUnit.EPISODE
        if self.train_per_episode and self.n_envs > 1:
            raise ValueError("train_freq in episodes needs a single environment; give train_freq in steps")
        self.gradient_steps = int(model.gradient_steps)
        self.buffer = ReplayStorage(int(model.buffer_size), self.n_envs, self.batch_obs.dim, self.action_dim, self.device)

    # --- acting -----------------------------------------------------------------------------------------
    def policy_actions(self, obs: Any) -> Any:
        """The exploration actions of the policy, scaled to [-1, 1]."""
        raise NotImplementedError

    def collect(self, hooks: Hooks) -> int:
        """Collect ``train_freq`` steps (or episodes); return the number of transitions collected."""
        steps = episodes = 0
        while (episodes if self.train_per_episode else steps) < self.train_every:
            obs = self.current_obs
            if self.num_timesteps < self.learning_starts:
                scaled = torch.rand((self.n_envs, self.action_dim), generator=self.generator, device=self.device) * 2 - 1
            else:
                with torch.no_grad():
                    scaled = self.policy_actions(obs)
            actions = self.action_low + 0.5 * (scaled + 1.0) * (self.action_high - self.action_low)
            next_obs, reward, terminated, truncated, info = self.step_env(actions, hooks)
            done = terminated | truncated
            following = self.batch_obs(next_obs)
            stored_next = following
            if done.any():  # the next observation of an ended episode is its final one
                rows = ended_rows(done)
                stored_next = following.clone()
                stored_next[torch.as_tensor(rows, device=self.device)] = self.batch_obs(info["final_obs"], rows)
            rewards = torch.as_tensor(reward, dtype=torch.float32, device=self.device)
            self.buffer.add(obs, stored_next, scaled, rewards, torch.as_tensor(terminated, dtype=torch.float32, device=self.device))
            self._obs = following
            steps += 1
            episodes += int(done.sum())
        return steps * self.n_envs

    def learn(self, total_timesteps: int, hooks: Hooks | None = None, progress_bar: bool = False) -> None:
        """Alternate collection and training until ``total_timesteps`` steps are done."""
        hooks = hooks or NoHooks()
        bar = progress(total_timesteps, self.num_timesteps) if progress_bar else None
        last_record = self.num_timesteps
        try:
            while self.num_timesteps < total_timesteps:
                hooks.on_rollout_start(self)
                collected = self.collect(hooks)
                if self.num_timesteps > 0 and self.num_timesteps > self.learning_starts:
                    steps = self.gradient_steps if self.gradient_steps >= 0 else collected
                    if steps > 0:
                        stats = self.train(steps)
                        if self.num_timesteps - last_record >= 1000 or self.num_timesteps >= total_timesteps:
                            self.record(stats)
                            last_record = self.num_timesteps
                if bar is not None:
                    bar.update(self.num_timesteps - bar.n)
        finally:
            if bar is not None:
                bar.close()

    # --- training ---------------------------------------------------------------------------------------
    def train_step(self, batch: tuple[Any, ...]) -> Any:
        """One gradient step on a sampled batch; return its statistics as a tensor."""
        raise NotImplementedError

    def train(self, gradient_steps: int) -> dict[str, float]:
        """Make ``gradient_steps`` gradient steps on batches drawn from the replay buffer."""
        totals: Any = None
        for _ in range(gradient_steps):
            stats = self.train_step(self.buffer.sample(self.batch_size, self.generator))
            totals = stats if totals is None else totals + stats
        means = (totals / gradient_steps).tolist()
        return {**dict(zip(self.stat_names, means, strict=True)), "train/n_updates": float(self.n_updates)}

    #: Names of the statistics :meth:`train_step` returns, in order.
    stat_names: tuple[str, ...] = ()

    def _polyak(self, source: Any, target: Any) -> None:
        from stable_baselines3.common.utils import polyak_update

        polyak_update(source.parameters(), target.parameters(), self.tau)

    # --- checkpoints ------------------------------------------------------------------------------------
    def checkpoint_writers(self) -> dict[str, Any]:
        """The model, the trainer's state and the replay buffer."""
        return {**super().checkpoint_writers(), REPLAY_FILE: self.save_replay_buffer}

    def save_replay_buffer(self, path: str | Path) -> None:
        """Write the stored transitions to ``path``."""
        with open(path, "wb") as f:
            torch.save(self.buffer.state(), f)

    def restore(self, checkpoint_dir: str | Path) -> None:
        """Restore the trainer's state and the replay buffer of a checkpoint."""
        super().restore(checkpoint_dir)
        self.buffer.load(torch.load(Path(checkpoint_dir) / REPLAY_FILE, map_location="cpu", weights_only=True))


def _q_values(critic: Any, obs: Any, actions: Any) -> list[Any]:
    """The Q-values of every critic network of an SB3 ``ContinuousCritic`` on flat observations."""
    inputs = torch.cat([obs, actions], dim=1)
    return [q(inputs) for q in critic.q_networks]


class FastSAC(FastOffPolicy):
    """SAC with SB3's ``MultiInputPolicy`` actor, twin critics and (automatic) entropy coefficient.

    Args:
        model: An SB3 ``SAC`` model (no gSDE).
        venv: The native vector environment.
        seed: Seed of the exploration noise, warm-up actions and replay samples.
        tensorboard_log: TensorBoard directory, or None.
        compile: Compile the gradient step with ``torch.compile``.

    """

    algo = "SAC"
    stat_names = ("train/ent_coef", "train/actor_loss", "train/critic_loss", "train/ent_coef_loss")

    def __init__(self, model: Any, venv: Any, *, seed: int, tensorboard_log: str | None = None, compile: bool = False) -> None:
        super().__init__(model, venv, seed=seed, tensorboard_log=tensorboard_log, compile=compile)
        if model.use_sde:
            raise ValueError("use_sde is not supported by the fast trainer")
        self.actor, self.critic, self.critic_target = model.actor, model.critic, model.critic_target
        self.target_update_interval = int(model.target_update_interval)
        self.target_entropy = float(model.target_entropy)
        self.log_ent_coef = model.log_ent_coef
        self.ent_coef_optimizer = model.ent_coef_optimizer
        self.fixed_ent_coef: torch.Tensor = model.ent_coef_tensor if self.ent_coef_optimizer is None else torch.ones((), device=self.device)

    def sample_actions(self, obs: Any) -> tuple[Any, Any]:
        """Squashed Gaussian actions in [-1, 1] and their log-probabilities (SB3's ``action_log_prob``)."""
        latent = self.actor.latent_pi(obs)
        mean = self.actor.mu(latent)
        log_std = torch.clamp(self.actor.log_std(latent), -20.0, 2.0)
        std = log_std.exp()
        gaussian = mean + std * torch.randn(mean.shape, generator=self.generator, device=self.device)
        actions = torch.tanh(gaussian)
        log_prob = (-((gaussian - mean) ** 2) / (2 * std**2) - log_std - 0.5 * np.log(2 * np.pi)).sum(-1)
        log_prob = log_prob - torch.log(1 - actions**2 + 1e-6).sum(-1)
        return actions, log_prob

    def policy_actions(self, obs: Any) -> Any:
        """Sampled (not greedy) actions, as SB3's SAC explores."""
        return self.sample_actions(obs)[0]

    def train_step(self, batch: tuple[Any, ...]) -> Any:
        """One step of SB3's ``SAC.train``: entropy coefficient, critics, actor, then the target critics."""
        obs, actions, rewards, next_obs, dones = batch
        actions_pi, log_prob = self.sample_actions(obs)
        log_prob = log_prob.reshape(-1, 1)
        ent_coef_loss = torch.zeros((), device=self.device)
        if self.ent_coef_optimizer is not None:
            ent_coef = torch.exp(self.log_ent_coef.detach())
            ent_coef_loss = -(self.log_ent_coef * (log_prob + self.target_entropy).detach()).mean()
            self.ent_coef_optimizer.zero_grad()
            ent_coef_loss.backward()
            self.ent_coef_optimizer.step()
        else:
            ent_coef = self.fixed_ent_coef
        with torch.no_grad():
            next_actions, next_log_prob = self.sample_actions(next_obs)
            next_q = torch.min(torch.cat(_q_values(self.critic_target, next_obs, next_actions), dim=1), dim=1, keepdim=True)[0]
            next_q = next_q - ent_coef * next_log_prob.reshape(-1, 1)
            target_q = rewards + (1 - dones) * self.gamma * next_q
        current_q = _q_values(self.critic, obs, actions)
        critic_loss = 0.5 * sum(F.mse_loss(q, target_q) for q in current_q)
        self.critic.optimizer.zero_grad()
        critic_loss.backward()  # type: ignore[union-attr]
        self.critic.optimizer.step()
        min_q_pi = torch.min(torch.cat(_q_values(self.critic, obs, actions_pi), dim=1), dim=1, keepdim=True)[0]
        actor_loss = (ent_coef * log_prob - min_q_pi).mean()
        self.actor.optimizer.zero_grad()
        actor_loss.backward()
        self.actor.optimizer.step()
        self.n_updates += 1
        if self.n_updates % self.target_update_interval == 0:
            self._polyak(self.critic, self.critic_target)
        return torch.stack([ent_coef.reshape(()), actor_loss.detach(), critic_loss.detach(), ent_coef_loss.detach()])  # type: ignore[union-attr]


class FastTD3(FastOffPolicy):
    """TD3 (and DDPG) with SB3's ``MultiInputPolicy`` actor and critics.

    Args:
        model: An SB3 ``TD3`` or ``DDPG`` model.
        venv: The native vector environment.
        seed: Seed of the warm-up actions, target smoothing noise and replay samples.
        tensorboard_log: TensorBoard directory, or None.
        compile: Compile the gradient step with ``torch.compile``.

    """

    algo = "TD3"
    stat_names = ("train/actor_loss", "train/critic_loss")

    def __init__(self, model: Any, venv: Any, *, seed: int, tensorboard_log: str | None = None, compile: bool = False) -> None:
        super().__init__(model, venv, seed=seed, tensorboard_log=tensorboard_log, compile=compile)
        self.actor, self.actor_target = model.actor, model.actor_target
        self.critic, self.critic_target = model.critic, model.critic_target
        self.policy_delay = int(model.policy_delay)
        self.target_policy_noise = float(model.target_policy_noise)
        self.target_noise_clip = float(model.target_noise_clip)
        self._actor_loss: Any = None

    def policy_actions(self, obs: Any) -> Any:
        """The actor's actions: SB3's TD3 and DDPG explore only with ``action_noise``, which the paper leaves out."""
        return self.actor.mu(obs)

    def train_step(self, batch: tuple[Any, ...]) -> Any:
        """One step of SB3's ``TD3.train``: the critics, and every ``policy_delay`` steps the actor and the targets."""
        obs, actions, rewards, next_obs, dones = batch
        self.n_updates += 1
        with torch.no_grad():
            noise = torch.randn(actions.shape, generator=self.generator, device=self.device) * self.target_policy_noise
            noise = noise.clamp(-self.target_noise_clip, self.target_noise_clip)
            next_actions = (self.actor_target.mu(next_obs) + noise).clamp(-1, 1)
            next_q = torch.min(torch.cat(_q_values(self.critic_target, next_obs, next_actions), dim=1), dim=1, keepdim=True)[0]
            target_q = rewards + (1 - dones) * self.gamma * next_q
        current_q = _q_values(self.critic, obs, actions)
        critic_loss = sum(F.mse_loss(q, target_q) for q in current_q)
        self.critic.optimizer.zero_grad()
        critic_loss.backward()  # type: ignore[union-attr]
        self.critic.optimizer.step()
        if self.n_updates % self.policy_delay == 0:
            actor_loss = -self.critic.q_networks[0](torch.cat([obs, self.actor.mu(obs)], dim=1)).mean()
            self.actor.optimizer.zero_grad()
            actor_loss.backward()
            self.actor.optimizer.step()
            self._polyak(self.critic, self.critic_target)
            self._polyak(self.actor, self.actor_target)
            self._actor_loss = actor_loss.detach()
        actor_loss_value = self._actor_loss if self._actor_loss is not None else torch.zeros((), device=self.device)
        return torch.stack([actor_loss_value, critic_loss.detach()])  # type: ignore[union-attr]


class FastDDPG(FastTD3):
    """DDPG: SB3's ``DDPG`` is TD3 with one critic, no policy delay and no target policy smoothing (its model says so)."""

    algo = "DDPG"
