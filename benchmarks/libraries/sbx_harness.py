"""SBX (Stable-Baselines-Jax) through the project's SB3VecEnv. SBX's PPO takes no dict observations
("Dict observation space is not supported yet."), so for PPO a small SB3 VecEnvWrapper concatenates the
keys (sorted) into one float32 vector; SBX's SAC takes the dict as is (MultiInputPolicy, which flattens).
"""

import os
import time

import common
import gymnasium as gym
import numpy as np
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.vec_env import VecEnvWrapper

from bluesky_gym.training.sb3_vec_env import SB3VecEnv

assert "xla_cpu_multi_thread_eigen=false" in os.environ.get("XLA_FLAGS", ""), "run with XLA_FLAGS set (see run_all.sh)"

import flax.linen as nn  # noqa: E402
import jax  # noqa: E402
from sbx import PPO, SAC  # noqa: E402


class FlattenDict(VecEnvWrapper):
    def __init__(self, venv):
        d = common.flat_dim(venv.observation_space)
        super().__init__(venv, observation_space=gym.spaces.Box(-np.inf, np.inf, (d,), np.float32))

    def reset(self):
        return common.flatten(self.venv.reset())

    def step_wait(self):
        obs, rew, done, infos = self.venv.step_wait()
        for i in np.flatnonzero(done):
            t = infos[i].get("terminal_observation")
            if t is not None:
                infos[i]["terminal_observation"] = common.flatten(t)
        return common.flatten(obs), rew, done, infos


class Clock(BaseCallback):
    def __init__(self, warmup_rollouts=None, warmup_steps=None):
        super().__init__()
        self.warmup_rollouts, self.warmup_steps = warmup_rollouts, warmup_steps
        self.rollouts, self.t0, self.steps0 = 0, None, None

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
        venv = FlattenDict(venv)
        model = PPO(
            "MlpPolicy",
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
            policy_kwargs=dict(net_arch=dict(pi=common.PPO_HIDDEN, vf=common.PPO_HIDDEN), activation_fn=nn.tanh),
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
            policy_kwargs=dict(net_arch=common.SAC_HIDDEN, activation_fn=nn.relu, n_critics=2),
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
    return dict(env_steps=steps, seconds=t1 - clock.t0, cpu_seconds=c1 - clock.c0, jax=jax.__version__, jax_devices=str(jax.devices()))


if __name__ == "__main__":
    common.run_main("sbx", run)
