"""Stable-Baselines3 baseline through the project's adapter SB3VecEnv (dict observations, MultiInputPolicy)."""

import time

import common
import torch.nn as nn
from stable_baselines3 import PPO, SAC
from stable_baselines3.common.callbacks import BaseCallback

from bluesky_gym.training.sb3_vec_env import SB3VecEnv


class Clock(BaseCallback):
    """PPO: stamp the start of rollout number warmup+1. SAC: stamp at env step warmup_steps."""

    def __init__(self, warmup_rollouts=None, warmup_steps=None):
        super().__init__()
        self.warmup_rollouts, self.warmup_steps = warmup_rollouts, warmup_steps
        self.rollouts = 0
        self.t0 = None
        self.steps0 = None

    def _on_rollout_start(self) -> None:
        if self.warmup_rollouts is not None:
            if self.rollouts == self.warmup_rollouts:
                self.t0, self.c0, self.steps0 = time.perf_counter(), time.process_time(), self.num_timesteps
            self.rollouts += 1

    def _on_step(self) -> bool:
        if self.warmup_steps is not None and self.t0 is None and self.num_timesteps >= self.warmup_steps:
            self.t0, self.c0, self.steps0 = time.perf_counter(), time.process_time(), self.num_timesteps
        return True


def run(s):
    venv = SB3VecEnv(common.ENV_ID, num_envs=s["num_envs"])
    if s["algo"] == "PPO":
        model = PPO(
            "MultiInputPolicy",
            venv,
            n_steps=s["n_steps"],
            batch_size=s["minibatch"],
            n_epochs=s["epochs"],
            learning_rate=common.LR,
            gamma=common.GAMMA,
            gae_lambda=common.GAE_LAMBDA,
            clip_range=common.CLIP,
            vf_coef=common.VF_COEF,
            ent_coef=common.ENT_COEF,
            max_grad_norm=common.MAX_GRAD_NORM,
            normalize_advantage=True,
            policy_kwargs=dict(net_arch=dict(pi=common.PPO_HIDDEN, vf=common.PPO_HIDDEN), activation_fn=nn.Tanh, share_features_extractor=False),
            device="cpu",
            seed=0,
            verbose=0,
        )
        clock = Clock(warmup_rollouts=s["warmup_rollouts"])
        total = (s["warmup_rollouts"] + s["timed_rollouts"]) * s["num_envs"] * s["n_steps"]
    else:
        model = SAC(
            "MultiInputPolicy",
            venv,
            learning_rate=common.LR,
            buffer_size=s["buffer_size"],
            batch_size=s["batch_size"],
            learning_starts=s["learning_starts"],
            train_freq=1,
            gradient_steps=1,
            ent_coef="auto",
            gamma=common.GAMMA,
            policy_kwargs=dict(net_arch=common.SAC_HIDDEN, activation_fn=nn.ReLU, n_critics=2),
            device="cpu",
            seed=0,
            verbose=0,
        )
        clock = Clock(warmup_steps=s["warmup_steps"])
        total = s["warmup_steps"] + s["timed_steps"]
    model.learn(total_timesteps=total, callback=clock)
    t1, c1 = time.perf_counter(), time.process_time()
    steps = model.num_timesteps - clock.steps0
    assert steps == common.expected_steps(s), (steps, common.expected_steps(s))
    return dict(env_steps=steps, seconds=t1 - clock.t0, cpu_seconds=c1 - clock.c0)


if __name__ == "__main__":
    common.run_main("sb3", run)
