"""The project's fast trainer (SB3's networks and updates on batched rollouts), PPO compiled, on the same settings."""

import time

import common
import torch.nn as nn
from stable_baselines3 import PPO, SAC

from bluesky_gym.envs.seeds import train_env_seeds
from bluesky_gym.training.fast.offpolicy import FastSAC
from bluesky_gym.training.fast.ppo import FastPPO
from bluesky_gym.training.sb3_vec_env import SB3VecEnv


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
            policy_kwargs=dict(net_arch=dict(pi=common.PPO_HIDDEN, vf=common.PPO_HIDDEN), activation_fn=nn.Tanh),
            device="cpu",
            seed=0,
            verbose=0,
        )
        trainer = FastPPO(model, venv.venv, seed=0, compile=True)
        rollout = s["num_envs"] * s["n_steps"]
        warm, total = s["warmup_rollouts"] * rollout, (s["warmup_rollouts"] + s["timed_rollouts"]) * rollout
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
        trainer = FastSAC(model, venv.venv, seed=0)
        warm, total = s["warmup_steps"], s["warmup_steps"] + s["timed_steps"]
    trainer.start(train_env_seeds(0, s["num_envs"]))
    trainer.learn(warm)
    t0, c0, steps0 = time.perf_counter(), time.process_time(), trainer.num_timesteps
    trainer.learn(total)
    t1, c1 = time.perf_counter(), time.process_time()
    steps = trainer.num_timesteps - steps0
    assert steps == common.expected_steps(s), (steps, common.expected_steps(s))
    return dict(env_steps=steps, seconds=t1 - t0, cpu_seconds=c1 - c0)


if __name__ == "__main__":
    common.run_main("bluesky-gym fast", run)
