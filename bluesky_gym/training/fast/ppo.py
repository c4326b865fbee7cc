"""PPO on the native vector environment: SB3's networks and update, batched rollouts and advantages.

The update is SB3's ``PPO.train`` (clipped surrogate, value loss, entropy bonus, advantage
normalisation per minibatch, gradient clipping, optional ``target_kl`` early stop and
``clip_range_vf``), and so are the rollouts (Gaussian actions clipped to the action space, a
truncated episode's reward bootstrapped with ``gamma`` times the value of its final observation,
GAE(lambda)). What differs is the mechanics: the rollout lives in tensors of shape
``(n_steps, n_envs, ...)``, the whole batch of environments is stepped with one array, the
advantages of all environments are computed together, and the losses of the minibatches are
summed on the device and read once per rollout.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import torch
import torch.nn.functional as F

from bluesky_gym.training.fast.base import Adam, FastTrainer, Hooks, NoHooks, ended_rows, progress

_LOG_SQRT_2PI = 0.5 * math.log(2.0 * math.pi)


def gaussian_log_prob(actions: Any, mean: Any, log_std: Any) -> Any:
    """Log-density of ``actions`` under independent Gaussians, summed over the action dimensions."""
    return (-((actions - mean) ** 2) * 0.5 * (-2.0 * log_std).exp() - log_std - _LOG_SQRT_2PI).sum(-1)


def gaussian_entropy(log_std: Any, rows: int) -> Any:
    """Entropy of independent Gaussians with ``log_std``, summed over the action dimensions, once per row."""
    return (0.5 + _LOG_SQRT_2PI + log_std).sum().expand(rows)


def generalised_advantages(rewards: Any, values: Any, starts: Any, last_values: Any, last_dones: Any, gamma: float, lam: float) -> Any:
    """GAE(lambda) advantages of a rollout, all environments at once (SB3's ``compute_returns_and_advantage``).

    Args:
        rewards: ``(n_steps, n_envs)`` rewards (truncations already bootstrapped).
        values: ``(n_steps, n_envs)`` value estimates of the observations.
        starts: ``(n_steps, n_envs)`` 1 where the observation is the first of an episode.
        last_values: ``(n_envs,)`` values of the observations after the last step.
        last_dones: ``(n_envs,)`` 1 where the last step ended an episode.
        gamma: Discount factor.
        lam: GAE lambda.

    """
    advantages = torch.empty_like(rewards)
    running = torch.zeros_like(last_values)
    next_values, next_nonterminal = last_values, 1.0 - last_dones
    for t in range(rewards.shape[0] - 1, -1, -1):
        delta = rewards[t] + gamma * next_values * next_nonterminal - values[t]
        running = delta + gamma * lam * next_nonterminal * running
        advantages[t] = running
        next_values, next_nonterminal = values[t], 1.0 - starts[t]
    return advantages


def run_layers(layers: torch.nn.Module, x: torch.Tensor) -> torch.Tensor:
    """Apply a layer or an ``nn.Sequential`` of layers to ``x``, with ``Tanh`` computed as ``2 sigmoid(2x) - 1``.

    The same function as the layers' own ``forward`` (to float rounding, about 1e-7), but PyTorch's
    ``tanh`` kernel runs about five times slower on the CPU than its ``sigmoid``, which makes it
    the largest single cost of a PPO update with large minibatches.
    """
    for layer in layers if isinstance(layers, torch.nn.Sequential) else (layers,):
        x = torch.sigmoid(2.0 * x) * 2.0 - 1.0 if isinstance(layer, torch.nn.Tanh) else layer(x)
    return x


class MeanAndValue(torch.nn.Module):
    """The mean actions and the values of an SB3 ``ActorCriticPolicy`` for flat observations (its parameters, its layers)."""

    def __init__(self, policy: Any) -> None:
        super().__init__()
        self.policy = policy

    def forward(self, obs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Return ``(mean actions, values)``."""
        extractor = self.policy.mlp_extractor
        mean = run_layers(self.policy.action_net, run_layers(extractor.policy_net, obs))
        values = run_layers(self.policy.value_net, run_layers(extractor.value_net, obs)).squeeze(-1)
        return mean, values

    def values(self, obs: torch.Tensor) -> torch.Tensor:
        """Return the values alone."""
        return run_layers(self.policy.value_net, run_layers(self.policy.mlp_extractor.value_net, obs)).squeeze(-1)


class FastPPO(FastTrainer):
    """PPO with SB3's ``MultiInputPolicy`` networks and update rule on the native vector environment.

    The minibatch update (loss, gradients, clipping, Adam) is one function of the parameters; with
    ``compile`` it is compiled as a whole by ``torch.compile`` (gradients by ``torch.func``), which
    takes seconds once but removes most of the per-minibatch overhead of small minibatches.

    Args:
        model: An SB3 ``PPO`` model (``MultiInputPolicy``, diagonal Gaussian actions, no gSDE).
        venv: The native vector environment (as many environments as the model was made for).
        seed: Seed of the action noise and the minibatch order.
        tensorboard_log: TensorBoard directory, or None.
        compile: Compile the minibatch update with ``torch.compile``.

    """

    algo = "PPO"

    def __init__(self, model: Any, venv: Any, *, seed: int, tensorboard_log: str | None = None, compile: bool = False) -> None:
        super().__init__(model, venv, seed=seed, tensorboard_log=tensorboard_log, compile=compile)
        from stable_baselines3.common.distributions import DiagGaussianDistribution

        policy = model.policy
        if not isinstance(policy.action_dist, DiagGaussianDistribution) or model.use_sde:
            raise ValueError("the fast PPO trainer needs a Box action space with diagonal Gaussian actions (no use_sde)")
        if int(model.n_envs) != self.n_envs:
            raise ValueError(f"the model was made for {model.n_envs} environments, the environment has {self.n_envs}")
        self.policy = policy
        self.n_steps = int(model.n_steps)
        self.batch_size = int(model.batch_size)
        self.n_epochs = int(model.n_epochs)
        self.gamma = float(model.gamma)
        self.gae_lambda = float(model.gae_lambda)
        self.clip_range = float(model.clip_range(1.0))
        self.clip_range_vf = None if model.clip_range_vf is None else float(model.clip_range_vf(1.0))
        self.normalize_advantage = bool(model.normalize_advantage)
        self.ent_coef = float(model.ent_coef)
        self.vf_coef = float(model.vf_coef)
        self.max_grad_norm = float(model.max_grad_norm)
        self.target_kl = None if model.target_kl is None else float(model.target_kl)
        self.net = MeanAndValue(policy)
        # The tensors the update changes in place: the policy's own parameters (shared storage).
        self.params = {k: p.detach().requires_grad_(not self.compile) for k, p in self.net.named_parameters()}
        self.adam = Adam(self.params, policy.optimizer)
        shape = (self.n_steps, self.n_envs)
        dev = self.device
        self.obs = torch.zeros((*shape, self.batch_obs.dim), device=dev)
        self.actions = torch.zeros((*shape, self.action_dim), device=dev)
        self.rewards = torch.zeros(shape, device=dev)
        self.starts = torch.zeros(shape, device=dev)
        self.values = torch.zeros(shape, device=dev)
        self.log_probs = torch.zeros(shape, device=dev)
        self._starts = torch.ones(self.n_envs, device=dev)
        self._update = torch.compile(self.update_minibatch) if self.compile else self.update_minibatch

    # --- rollouts ---------------------------------------------------------------------------------------
    def start(self, env_seeds: list[int]) -> None:
        """Reset the environments; the first observations count as episode starts."""
        super().start(env_seeds)
        self._starts.fill_(1.0)

    def collect(self, hooks: Hooks) -> tuple[torch.Tensor, torch.Tensor]:
        """Fill the rollout tensors with ``n_steps`` steps of every environment; return the last values and dones."""
        log_std = self.policy.log_std
        for t in range(self.n_steps):
            obs = self.current_obs
            with torch.no_grad():
                mean, values = self.net(obs)
                noise = torch.randn(mean.shape, generator=self.generator, device=self.device)
                actions = mean + noise * log_std.exp()
                log_probs = gaussian_log_prob(actions, mean, log_std)
            next_obs, reward, terminated, truncated, info = self.step_env(torch.clamp(actions, self.action_low, self.action_high), hooks)
            rewards = torch.as_tensor(reward, dtype=torch.float32, device=self.device)
            timeouts = ended_rows(truncated & ~terminated)
            if len(timeouts):  # bootstrap a truncated episode with the value of its final observation
                with torch.no_grad():
                    final_values = self.net.values(self.batch_obs(info["final_obs"], timeouts))
                rows = torch.as_tensor(timeouts, device=self.device)
                rewards[rows] += self.gamma * final_values
            self.obs[t] = obs
            self.actions[t] = actions
            self.rewards[t] = rewards
            self.starts[t] = self._starts
            self.values[t] = values
            self.log_probs[t] = log_probs
            self._starts = torch.as_tensor(terminated | truncated, dtype=torch.float32, device=self.device)
            self._obs = self.batch_obs(next_obs)
        with torch.no_grad():
            last_values = self.net.values(self.current_obs)
        return last_values, self._starts

    # --- the update -------------------------------------------------------------------------------------
    def loss(self, params: dict[str, torch.Tensor], batch: tuple[torch.Tensor, ...]) -> tuple[torch.Tensor, torch.Tensor]:
        """SB3's PPO loss of one minibatch and its statistics (policy loss, value loss, entropy loss, approx. KL, clip fraction).

        Args:
            params: The parameters of :attr:`net`, by name.
            batch: Observations, actions, old log-probabilities, advantages, returns, old values.

        """
        obs, actions, old_log_probs, advantages, returns, old_values = batch
        mean, values = torch.func.functional_call(self.net, params, (obs,))
        log_std = params["policy.log_std"]
        log_probs = gaussian_log_prob(actions, mean, log_std)
        entropy = gaussian_entropy(log_std, obs.shape[0])
        if self.normalize_advantage and advantages.shape[0] > 1:
            advantages = (advantages - advantages.mean()) / (advantages.std() + 1e-8)
        log_ratio = log_probs - old_log_probs
        ratio = log_ratio.exp()
        policy_loss = -torch.min(advantages * ratio, advantages * torch.clamp(ratio, 1 - self.clip_range, 1 + self.clip_range)).mean()
        if self.clip_range_vf is not None:
            values = old_values + torch.clamp(values - old_values, -self.clip_range_vf, self.clip_range_vf)
        value_loss = F.mse_loss(returns, values)
        entropy_loss = -entropy.mean()
        loss = policy_loss + self.ent_coef * entropy_loss + self.vf_coef * value_loss
        with torch.no_grad():
            approx_kl = ((ratio - 1) - log_ratio).mean()
            clip_fraction = ((ratio - 1).abs() > self.clip_range).float().mean()
        return loss, torch.stack([policy_loss.detach(), value_loss.detach(), entropy_loss.detach(), approx_kl.detach(), clip_fraction])

    def update_minibatch(self, rows: torch.Tensor, *columns: torch.Tensor) -> torch.Tensor:
        """One gradient step on the minibatch ``rows`` of the rollout ``columns`` (loss, gradients, clipping, Adam); return its statistics.

        The minibatch is gathered here, so that a compiled update reads the rows in place.
        """
        batch = tuple(x[rows] for x in columns)
        if self.compile:  # gradients as a function, so that torch.compile sees the whole step
            grads, stats = torch.func.grad(self.loss, has_aux=True)(self.params, batch)
        else:
            loss, stats = self.loss(self.params, batch)
            grads = dict(zip(self.params, torch.autograd.grad(loss, list(self.params.values())), strict=True))
        self.adam.apply(grads, self.max_grad_norm)
        return stats

    def update(self, last_values: torch.Tensor, last_dones: torch.Tensor) -> dict[str, float]:
        """``n_epochs`` passes of minibatch updates over the rollout; return the mean statistics."""
        advantages = generalised_advantages(self.rewards, self.values, self.starts, last_values, last_dones, self.gamma, self.gae_lambda)
        returns = advantages + self.values
        size = self.n_steps * self.n_envs
        columns = (
            self.obs.reshape(size, -1),
            self.actions.reshape(size, -1),
            *(x.reshape(size) for x in (self.log_probs, advantages, returns, self.values)),
        )
        totals = torch.zeros(5, device=self.device)
        count = 0
        stop = False
        for _ in range(self.n_epochs):
            order = torch.randperm(size, generator=self.generator, device=self.device)
            for start in range(0, size, self.batch_size):
                rows = order[start : start + self.batch_size]
                if self.target_kl is not None:  # SB3 stops before the step of the minibatch that is too far
                    with torch.no_grad():
                        approx_kl = float(self.loss(self.params, tuple(x[rows] for x in columns))[1][3])
                    if approx_kl > 1.5 * self.target_kl:
                        stop = True
                        break
                totals += self._update(rows, *columns)
                count += 1
            self.n_updates += 1
            if stop:
                break
        mean = (totals / max(count, 1)).tolist()
        var = returns.var()
        explained = float("nan") if float(var) == 0 else float(1 - (returns - self.values).var() / var)
        return {
            "train/policy_gradient_loss": mean[0],
            "train/value_loss": mean[1],
            "train/entropy_loss": mean[2],
            "train/approx_kl": mean[3],
            "train/clip_fraction": mean[4],
            "train/explained_variance": explained,
            "train/std": float(self.policy.log_std.detach().exp().mean()),
        }

    def save(self, path: str | Path) -> None:
        """Write the model file, its optimiser holding the trainer's Adam moments."""
        self.adam.store_into(self.policy.optimizer)
        super().save(path)

    def learn(self, total_timesteps: int, hooks: Hooks | None = None, progress_bar: bool = False) -> None:
        """Collect rollouts and update until ``total_timesteps`` steps are done (the last rollout is completed)."""
        hooks = hooks or NoHooks()
        bar = progress(total_timesteps, self.num_timesteps) if progress_bar else None
        try:
            while self.num_timesteps < total_timesteps:
                hooks.on_rollout_start(self)
                last_values, last_dones = self.collect(hooks)
                stats = self.update(last_values, last_dones)
                self.record(stats)
                if bar is not None:
                    bar.update(self.num_timesteps - bar.n)
        finally:
            if bar is not None:
                bar.close()
