"""The fast trainer's updates are SB3's: same data in, same parameters out (to float rounding)."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("stable_baselines3", reason="needs Stable-Baselines3 (the 'train' extra)")

import torch
from stable_baselines3.common.logger import configure

from bluesky_gym.envs.seeds import train_env_seeds
from bluesky_gym.training.fast import trainer_class
from bluesky_gym.training.fast.base import NoHooks
from bluesky_gym.training.fast.offpolicy import ReplayStorage
from bluesky_gym.training.hyperparams import PAPER, merge
from bluesky_gym.training.runner import make_run_spec, new_model
from bluesky_gym.training.sb3_vec_env import SB3VecEnv

ENV = "HorizontalCREnv-v0"


def _model(algo: str, n_envs: int, hp: dict, compile: bool = False) -> tuple:
    spec = make_run_spec(merge(PAPER, {"algos": {algo: hp}}), ENV, algo, 7, n_envs=n_envs, total_timesteps=1, trainer="fast", compile=compile)
    venv = SB3VecEnv(ENV, num_envs=n_envs)
    model = new_model(spec, venv)
    model.set_logger(configure(None, []))
    return model, venv


def _state(module: torch.nn.Module) -> dict[str, torch.Tensor]:
    return {k: v.detach().clone() for k, v in module.state_dict().items()}


def _dict_obs(trainer, flat: torch.Tensor) -> dict[str, np.ndarray]:
    parts = torch.split(flat, trainer.batch_obs.sizes, dim=-1)
    return {k: p.numpy().astype(np.float64) for k, p in zip(trainer.batch_obs.keys, parts, strict=True)}


@pytest.mark.parametrize("compile", [False, True], ids=["eager", "compiled"])
def test_ppo_rollout_update_equals_sb3_train(compile: bool) -> None:
    n_envs, n_steps = 4, 16
    hp = {"n_steps": n_steps, "batch_size": n_envs * n_steps, "n_epochs": 3}  # one minibatch: the order SB3 draws does not matter
    fast_model, venv = _model("PPO", n_envs, hp, compile)
    sb3_model, _ = _model("PPO", n_envs, hp)
    before = _state(sb3_model.policy)
    assert all(torch.equal(before[k], v) for k, v in _state(fast_model.policy).items())  # same seed, same initial networks

    trainer = trainer_class("PPO")(fast_model, venv.venv, seed=0, compile=compile)
    trainer.start(train_env_seeds(0, n_envs))
    last_values, last_dones = trainer.collect(NoHooks())

    buffer = sb3_model.rollout_buffer
    buffer.reset()
    for t in range(n_steps):
        buffer.add(
            _dict_obs(trainer, trainer.obs[t]),
            trainer.actions[t].numpy(),
            trainer.rewards[t].numpy(),
            trainer.starts[t].numpy(),
            trainer.values[t].clone(),
            trainer.log_probs[t].clone(),
        )
    buffer.compute_returns_and_advantage(last_values=last_values.clone(), dones=last_dones.numpy())
    sb3_model.train()
    trainer.update(last_values, last_dones)

    trained, reference = _state(fast_model.policy), _state(sb3_model.policy)
    moved = max(float((reference[k] - before[k]).abs().max()) for k in reference)
    assert moved > 1e-4  # the update did something
    for k in reference:
        assert torch.allclose(trained[k], reference[k], rtol=1e-4, atol=2e-6), k
    # The Adam moments go into the model file's optimiser: the same as SB3's after its own steps.
    trainer.adam.store_into(fast_model.policy.optimizer)
    ours, theirs = fast_model.policy.optimizer.state_dict()["state"], sb3_model.policy.optimizer.state_dict()["state"]
    assert ours.keys() == theirs.keys()
    for i in theirs:
        assert float(ours[i]["step"]) == float(theirs[i]["step"]) == 3
        assert torch.allclose(ours[i]["exp_avg"], theirs[i]["exp_avg"], rtol=1e-4, atol=1e-7)


def test_gae_equals_sb3() -> None:
    rng = np.random.default_rng(1)
    n_steps, n_envs = 9, 5
    rewards, values = rng.normal(size=(n_steps, n_envs)).astype(np.float32), rng.normal(size=(n_steps, n_envs)).astype(np.float32)
    starts = (rng.random((n_steps, n_envs)) < 0.3).astype(np.float32)
    last_values, last_dones = rng.normal(size=n_envs).astype(np.float32), rng.random(n_envs) < 0.5
    import gymnasium as gym
    from stable_baselines3.common.buffers import RolloutBuffer

    from bluesky_gym.training.fast.ppo import generalised_advantages

    buffer = RolloutBuffer(n_steps, gym.spaces.Box(-1, 1, (1,)), gym.spaces.Box(-1, 1, (1,)), n_envs=n_envs, gamma=0.97, gae_lambda=0.9)
    buffer.rewards[:], buffer.values[:], buffer.episode_starts[:] = rewards, values, starts
    buffer.compute_returns_and_advantage(torch.as_tensor(last_values), last_dones)
    ours = generalised_advantages(*(torch.as_tensor(x) for x in (rewards, values, starts, last_values, last_dones.astype(np.float32))), 0.97, 0.9)
    assert starts.any() and last_dones.any() and not last_dones.all()
    assert np.allclose(ours.numpy(), buffer.advantages, rtol=1e-5, atol=1e-6)


@pytest.mark.parametrize("algo", ["TD3", "DDPG"])
def test_td3_ddpg_gradient_step_equals_sb3_train(algo: str) -> None:
    hp = {"buffer_size": 1000, "batch_size": 32, "learning_starts": 0}
    if algo == "TD3":
        hp.update(target_policy_noise=0.0, policy_delay=1)  # deterministic, so that both see the same targets
    fast_model, venv = _model(algo, 2, hp)
    sb3_model, _ = _model(algo, 2, hp)
    trainer = trainer_class(algo)(fast_model, venv.venv, seed=0)
    trainer.start(train_env_seeds(0, 2))
    trainer.collect(NoHooks())
    batch = trainer.buffer.sample(32, trainer.generator)
    obs, actions, rewards, next_obs, dones = batch

    class Sample:  # SB3's ReplayBufferSamples, holding our batch
        observations = _dict_obs(trainer, obs)
        next_observations = _dict_obs(trainer, next_obs)

    Sample.observations = {k: torch.as_tensor(v, dtype=torch.float32) for k, v in Sample.observations.items()}
    Sample.next_observations = {k: torch.as_tensor(v, dtype=torch.float32) for k, v in Sample.next_observations.items()}
    Sample.actions, Sample.rewards, Sample.dones, Sample.discounts = actions, rewards, dones, None
    sb3_model.replay_buffer.sample = lambda *args, **kwargs: Sample  # the same batch for SB3
    before = _state(sb3_model.critic)
    sb3_model.train(gradient_steps=1, batch_size=32)
    trainer.train_step(batch)
    for part in ("actor", "critic", "actor_target", "critic_target"):
        ours, theirs = _state(getattr(fast_model, part)), _state(getattr(sb3_model, part))
        for k in theirs:
            assert torch.allclose(ours[k], theirs[k], rtol=1e-5, atol=1e-7), (part, k)
    assert max(float((_state(sb3_model.critic)[k] - before[k]).abs().max()) for k in before) > 1e-5  # the step did something


def test_sac_log_probabilities_equal_sb3() -> None:
    model, venv = _model("SAC", 1, {"buffer_size": 100})
    trainer = trainer_class("SAC")(model, venv.venv, seed=0)
    obs = torch.randn(50, trainer.batch_obs.dim)
    actions, log_prob = trainer.sample_actions(obs)
    latent = model.actor.latent_pi(obs)
    mean, log_std = model.actor.mu(latent), torch.clamp(model.actor.log_std(latent), -20, 2)
    dist = model.actor.action_dist.proba_distribution(mean, log_std)
    gaussian = torch.atanh(torch.clamp(actions, -1 + 1e-6, 1 - 1e-6))
    assert torch.allclose(log_prob, dist.log_prob(actions, gaussian), rtol=1e-4, atol=1e-4)


def test_replay_storage_keeps_the_newest_transitions_in_order() -> None:
    buffer = ReplayStorage(6, 2, obs_dim=1, action_dim=1, device="cpu")
    for step in range(5):
        value = torch.tensor([[2.0 * step], [2.0 * step + 1]])
        buffer.add(value, value + 100, value, value[:, 0], torch.zeros(2))
    assert buffer.size == 6
    state = buffer.state()
    assert state["obs"][:, 0].tolist() == [4.0, 5.0, 6.0, 7.0, 8.0, 9.0]
    smaller = ReplayStorage(4, 2, 1, 1, "cpu")
    smaller.load(state)
    assert smaller.size == 4 and smaller.state()["next_obs"][:, 0].tolist() == [106.0, 107.0, 108.0, 109.0]
