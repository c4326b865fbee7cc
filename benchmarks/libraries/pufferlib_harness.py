"""PufferLib 3.0: its trainer PuffeRL drives a PufferLib vector env (async_reset/recv/send, flat observations).
A small adapter gives the native Gymnasium VectorEnv that interface (dict -> flat float32 with numpy).
The PPO is PufferLib's own: per-minibatch recomputed 'puff' advantage (GAE generalised with V-trace clipping,
equal to GAE at rho=c=1 on-policy), prioritised segment sampling (switched off here: prio_alpha=0, beta0=1),
value clipping (switched off: vf_clip_coef=1e9), reward clamping to [-1, 1] (always on). No SAC in PufferLib.
"""

import tempfile
import time

import common
import gymnasium as gym
import numpy as np
import pufferlib.pufferl as pufferl
import torch
from torch import nn


class PufferVec:
    """Just enough of pufferlib.vector's interface for PuffeRL: one batch of all N envs per recv."""

    def __init__(self, n, clock):
        self.env = common.make_flat_vec(n)
        self.clock = clock
        self.num_agents = self.agents_per_batch = self.num_envs = n
        self.single_observation_space = self.env.single_observation_space
        # float32 actions: PuffeRL allocates its action buffer with the space's dtype, and a float64 buffer
        # makes float64 log-probs that it cannot write into its float32 buffers.
        self.single_action_space = gym.spaces.Box(-1.0, 1.0, self.env.single_action_space.shape, np.float32)
        self.observation_space = self.env.observation_space
        self.action_space = gym.spaces.Box(-1.0, 1.0, self.env.action_space.shape, np.float32)
        self.env_id = np.arange(n)
        self.mask = np.ones(n, dtype=bool)

    def async_reset(self, seed=None):
        obs, _ = self.env.reset(seed=seed)
        z = np.zeros(self.num_agents, dtype=np.float32)
        self._last = (obs, z, z.astype(bool), z.astype(bool))

    def send(self, actions):
        self.clock.tick()
        obs, r, te, tr, _ = self.env.step(actions)
        self._last = (obs, r.astype(np.float32), te, tr)

    def recv(self):
        o, r, d, t = self._last
        return o, r, d, t, [], self.env_id, self.mask

    def close(self):
        self.env.close()


def mlp(i, o):
    h = common.PPO_HIDDEN
    return nn.Sequential(nn.Linear(i, h[0]), nn.Tanh(), nn.Linear(h[0], h[1]), nn.Tanh(), nn.Linear(h[1], o))


class Policy(nn.Module):
    """Separate actor/critic MLPs, Gaussian with state-independent log-std; PufferLib's policy API
    (forward/forward_eval -> (torch.distributions.Normal, value)).
    """

    def __init__(self, obs_dim, act_dim):
        super().__init__()
        self.actor = mlp(obs_dim, act_dim)
        self.critic = mlp(obs_dim, 1)
        self.log_std = nn.Parameter(torch.zeros(act_dim))

    def forward_eval(self, obs, state=None):
        mean = self.actor(obs)
        return torch.distributions.Normal(mean, self.log_std.exp().expand_as(mean)), self.critic(obs)

    forward = forward_eval


def run(s):
    if s["algo"] != "PPO":
        raise NotImplementedError("PufferLib 3.0 implements PPO only (no SAC/TD3/DDPG)")
    n, T = s["num_envs"], s["n_steps"]
    # PuffeRL samples minibatches as whole segments of bptt_horizon steps: minibatch 64 < 128 steps needs
    # bptt_horizon 64 (a 128-step rollout per env is then 2 segments per env).
    horizon = min(T, s["minibatch"])
    clock = common.StepClock(s["warmup_rollouts"] * T, n)
    vec = PufferVec(n, clock)
    policy = Policy(vec.single_observation_space.shape[0], vec.single_action_space.shape[0])
    rollouts = s["warmup_rollouts"] + s["timed_rollouts"]
    config = dict(
        seed=0,
        torch_deterministic=True,
        cpu_offload=False,
        device="cpu",
        optimizer="adam",
        anneal_lr=False,
        precision="float32",
        total_timesteps=rollouts * n * T,
        learning_rate=common.LR,
        gamma=common.GAMMA,
        gae_lambda=common.GAE_LAMBDA,
        update_epochs=s["epochs"],
        clip_coef=common.CLIP,
        vf_coef=common.VF_COEF,
        vf_clip_coef=1e9,
        max_grad_norm=common.MAX_GRAD_NORM,
        ent_coef=common.ENT_COEF,
        adam_beta1=0.9,
        adam_beta2=0.999,
        adam_eps=1e-8,
        data_dir=tempfile.mkdtemp(prefix="puffer_"),
        checkpoint_interval=10**9,
        batch_size=n * T,
        minibatch_size=s["minibatch"],
        max_minibatch_size=s["minibatch"],
        bptt_horizon=horizon,
        compile=False,
        compile_mode="default",
        compile_fullgraph=False,
        use_rnn=False,
        vtrace_rho_clip=1.0,
        vtrace_c_clip=1.0,
        prio_alpha=0.0,
        prio_beta0=1.0,
        env="SectorCREnv-v0",
    )
    trainer = pufferl.PuffeRL(config, vec, policy)
    try:
        for _ in range(rollouts):
            trainer.evaluate()
            trainer.train()
        t1, c1 = time.perf_counter(), time.process_time()
    finally:
        trainer.utilization.stop()  # its monitoring thread is not a daemon
    assert clock.timed_steps() == common.expected_steps(s), (clock.timed_steps(), common.expected_steps(s))
    return dict(
        env_steps=clock.timed_steps(),
        seconds=t1 - clock.t0,
        cpu_seconds=c1 - clock.c0,
        bptt_horizon=horizon,
        minibatches_per_rollout=trainer.total_minibatches,
    )


if __name__ == "__main__":
    common.run_main("pufferlib", run)
