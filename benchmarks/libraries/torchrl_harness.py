"""TorchRL: GymWrapper over the native Gymnasium VectorEnv (SAME_STEP autoreset is supported as is),
dict observation keys concatenated (sorted) by TorchRL's own CatTensors transform, float64->float32 by
DoubleToFloat. PPO: Collector + GAE + ClipPPOLoss + ReplayBuffer(SamplerWithoutReplacement), the loop of
TorchRL's PPO tutorial. SAC: Collector (1 frame per batch) + SACLoss + SoftUpdate + ReplayBuffer.
"""

import time
import warnings

import common
import torch
from torch import nn

warnings.filterwarnings("ignore", category=DeprecationWarning)

from tensordict.nn import TensorDictModule  # noqa: E402
from torchrl.collectors import Collector  # noqa: E402
from torchrl.data import LazyTensorStorage, ReplayBuffer  # noqa: E402
from torchrl.data.replay_buffers.samplers import SamplerWithoutReplacement  # noqa: E402
from torchrl.envs import CatTensors, Compose, DoubleToFloat, GymWrapper, TransformedEnv  # noqa: E402
from torchrl.modules import (  # noqa: E402
    MLP,
    IndependentNormal,
    NormalParamExtractor,
    ProbabilisticActor,
    TanhNormal,
    ValueOperator,
)
from torchrl.objectives import ClipPPOLoss, SACLoss, SoftUpdate  # noqa: E402
from torchrl.objectives.value import GAE  # noqa: E402


class StateIndependentScale(nn.Module):
    """loc from the MLP, scale = exp(log_std), a parameter (SB3's Gaussian policy)."""

    def __init__(self, act_dim):
        super().__init__()
        self.log_std = nn.Parameter(torch.zeros(act_dim))

    def forward(self, loc):
        return loc, self.log_std.exp().expand_as(loc)


def make_env(n):
    import gymnasium as gym
    import numpy as np

    venv = gym.vector.VectorWrapper(common.make_vec(n))
    keys = sorted(venv.single_observation_space.spaces)
    # TorchRL reads env.autoreset_mode (the attribute of Gymnasium's own SyncVectorEnv/AsyncVectorEnv);
    # the native env declares it only in metadata["autoreset_mode"] (Gymnasium's documented place).
    venv.autoreset_mode = venv.metadata["autoreset_mode"]

    # TorchRL's GymWrapper runs check_env_specs on a short rollout; it fails because the env's "airspeed"
    # observation leaves its declared Box(-1, 1) (values up to ~1.22 seen). Declare every key unbounded.
    def unbounded(space):
        return gym.spaces.Dict({k: gym.spaces.Box(-np.inf, np.inf, b.shape, b.dtype) for k, b in space.spaces.items()})

    venv.single_observation_space = unbounded(venv.single_observation_space)
    venv.observation_space = unbounded(venv.observation_space)
    env = GymWrapper(venv, device="cpu")  # TransformedEnv(GymWrapper, VecGymEnvTransform) for a vector env
    return TransformedEnv(env, Compose(CatTensors(in_keys=keys, out_key="observation", del_keys=True), DoubleToFloat()))


def ppo(s):
    n, T = s["num_envs"], s["n_steps"]
    env = make_env(n)
    obs_dim = env.observation_spec["observation"].shape[-1]
    act_dim = env.action_spec.shape[-1]
    actor_net = nn.Sequential(
        MLP(in_features=obs_dim, out_features=act_dim, num_cells=common.PPO_HIDDEN, activation_class=nn.Tanh), StateIndependentScale(act_dim)
    )
    actor = ProbabilisticActor(
        TensorDictModule(actor_net, in_keys=["observation"], out_keys=["loc", "scale"]),
        in_keys=["loc", "scale"],
        spec=env.action_spec,
        distribution_class=IndependentNormal,
        return_log_prob=True,
    )
    critic = ValueOperator(MLP(in_features=obs_dim, out_features=1, num_cells=common.PPO_HIDDEN, activation_class=nn.Tanh), in_keys=["observation"])
    frames = n * T
    rollouts = s["warmup_rollouts"] + s["timed_rollouts"]
    collector = Collector(env, actor, frames_per_batch=frames, total_frames=frames * rollouts, device="cpu")
    gae = GAE(gamma=common.GAMMA, lmbda=common.GAE_LAMBDA, value_network=critic, average_gae=False)
    loss = ClipPPOLoss(
        actor,
        critic,
        clip_epsilon=common.CLIP,
        entropy_bonus=False,
        entropy_coeff=common.ENT_COEF,
        critic_coeff=common.VF_COEF,
        loss_critic_type="l2",
        normalize_advantage=True,
    )
    opt = torch.optim.Adam(loss.parameters(), lr=common.LR)
    rb = ReplayBuffer(storage=LazyTensorStorage(frames), sampler=SamplerWithoutReplacement(), batch_size=s["minibatch"])
    t0 = None
    done_rollouts = 0
    for data in collector:
        with torch.no_grad():
            gae(data)
        rb.empty()
        rb.extend(data.reshape(-1))
        for _ in range(s["epochs"]):
            for _ in range(frames // s["minibatch"]):
                mb = rb.sample()
                out = loss(mb)
                total = out["loss_objective"] + out["loss_critic"]
                opt.zero_grad()
                total.backward()
                nn.utils.clip_grad_norm_(loss.parameters(), common.MAX_GRAD_NORM)
                opt.step()
        collector.update_policy_weights_()
        done_rollouts += 1
        if done_rollouts == s["warmup_rollouts"]:
            t0, c0 = time.perf_counter(), time.process_time()
    t1, c1 = time.perf_counter(), time.process_time()
    collector.shutdown()
    assert done_rollouts == rollouts
    return dict(env_steps=s["timed_rollouts"] * frames, seconds=t1 - t0, cpu_seconds=c1 - c0)


def sac(s):
    env = make_env(1)
    obs_dim = env.observation_spec["observation"].shape[-1]
    act_dim = env.action_spec.shape[-1]
    actor_net = nn.Sequential(
        MLP(in_features=obs_dim, out_features=2 * act_dim, num_cells=common.SAC_HIDDEN, activation_class=nn.ReLU), NormalParamExtractor()
    )
    actor = ProbabilisticActor(
        TensorDictModule(actor_net, in_keys=["observation"], out_keys=["loc", "scale"]),
        in_keys=["loc", "scale"],
        spec=env.action_spec,
        distribution_class=TanhNormal,
        return_log_prob=False,
    )
    q_net = MLP(in_features=obs_dim + act_dim, out_features=1, num_cells=common.SAC_HIDDEN, activation_class=nn.ReLU)
    qvalue = ValueOperator(q_net, in_keys=["observation", "action"])
    loss = SACLoss(actor, qvalue, num_qvalue_nets=2, alpha_init=1.0, fixed_alpha=False)  # target entropy 'auto' = -act_dim
    loss.make_value_estimator(gamma=common.GAMMA)
    target = SoftUpdate(loss, tau=0.005)
    opt = torch.optim.Adam(loss.parameters(), lr=common.LR)
    total_steps = s["warmup_steps"] + s["timed_steps"]
    collector = Collector(env, actor, frames_per_batch=1, total_frames=total_steps, init_random_frames=s["learning_starts"], device="cpu")
    rb = ReplayBuffer(storage=LazyTensorStorage(s["buffer_size"]), batch_size=s["batch_size"])
    t0 = None
    steps = 0
    for data in collector:
        rb.extend(data.reshape(-1))
        steps += data.numel()
        if steps > s["learning_starts"]:
            out = loss(rb.sample())
            total = out["loss_actor"] + out["loss_qvalue"] + out["loss_alpha"]
            opt.zero_grad()
            total.backward()
            opt.step()
            target.step()
            collector.update_policy_weights_()
        if steps == s["warmup_steps"]:
            t0, c0 = time.perf_counter(), time.process_time()
    t1, c1 = time.perf_counter(), time.process_time()
    collector.shutdown()
    assert steps == total_steps
    return dict(env_steps=steps - s["warmup_steps"], seconds=t1 - t0, cpu_seconds=c1 - c0)


def run(s):
    return ppo(s) if s["algo"] == "PPO" else sac(s)


if __name__ == "__main__":
    common.run_main("torchrl", run)
