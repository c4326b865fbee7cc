"""skrl (torch): its Gymnasium wrapper takes the native VectorEnv as is (dict observations are tensorised and
flattened by skrl itself, keys in sorted order). PPO/SAC agents with skrl's RandomMemory and SequentialTrainer.
A pass-through Gymnasium VectorWrapper only counts step calls for the timing.
"""

import tempfile
import time

import common
import gymnasium as gym
import torch
from skrl.agents.torch.ppo import PPO, PPO_CFG
from skrl.agents.torch.sac import SAC, SAC_CFG
from skrl.envs.wrappers.torch import wrap_env
from skrl.memories.torch import RandomMemory
from skrl.models.torch import DeterministicMixin, GaussianMixin, Model
from skrl.trainers.torch import SequentialTrainer
from torch import nn


class Counting(gym.vector.VectorWrapper):
    def __init__(self, env, clock):
        super().__init__(env)
        self.clock = clock

    def step(self, actions):
        self.clock.tick()
        return self.env.step(actions)


def mlp(i, hidden, o, act):
    layers, d = [], i
    for h in hidden:
        layers += [nn.Linear(d, h), act()]
        d = h
    return nn.Sequential(*layers, nn.Linear(d, o))


class Policy(GaussianMixin, Model):
    def __init__(self, observation_space, action_space, device, hidden, act):
        Model.__init__(self, observation_space=observation_space, action_space=action_space, device=device)
        GaussianMixin.__init__(self, clip_actions=False, clip_log_std=True, min_log_std=-20, max_log_std=2, reduction="sum")
        self.net = mlp(self.num_observations, hidden, self.num_actions, act)
        self.log_std_parameter = nn.Parameter(torch.zeros(self.num_actions))

    def compute(self, inputs, role):
        return self.net(inputs["observations"]), {"log_std": self.log_std_parameter}


class Value(DeterministicMixin, Model):
    def __init__(self, observation_space, action_space, device, hidden, act, with_action=False):
        Model.__init__(self, observation_space=observation_space, action_space=action_space, device=device)
        DeterministicMixin.__init__(self, clip_actions=False)
        self.with_action = with_action
        self.net = mlp(self.num_observations + (self.num_actions if with_action else 0), hidden, 1, act)

    def compute(self, inputs, role):
        x = inputs["observations"]
        if self.with_action:
            x = torch.cat([x, inputs["taken_actions"]], dim=-1)
        return self.net(x), {}


def run(s):
    n = s["num_envs"]
    if s["algo"] == "PPO":
        clock = common.StepClock(s["warmup_rollouts"] * s["n_steps"], n)
        timesteps = (s["warmup_rollouts"] + s["timed_rollouts"]) * s["n_steps"]
    else:
        clock = common.StepClock(s["warmup_steps"], 1)
        timesteps = s["warmup_steps"] + s["timed_steps"]
    env = wrap_env(Counting(common.make_vec(n), clock), wrapper="gymnasium")
    dev = env.device
    exp = dict(directory=tempfile.mkdtemp(prefix="skrl_"), write_interval=0, checkpoint_interval=0)
    if s["algo"] == "PPO":
        models = {
            "policy": Policy(env.observation_space, env.action_space, dev, common.PPO_HIDDEN, nn.Tanh),
            "value": Value(env.observation_space, env.action_space, dev, common.PPO_HIDDEN, nn.Tanh),
        }
        memory = RandomMemory(memory_size=s["n_steps"], num_envs=n, device=dev)
        cfg = PPO_CFG(
            rollouts=s["n_steps"],
            learning_epochs=s["epochs"],
            mini_batches=n * s["n_steps"] // s["minibatch"],
            discount_factor=common.GAMMA,
            gae_lambda=common.GAE_LAMBDA,
            learning_rate=common.LR,
            grad_norm_clip=common.MAX_GRAD_NORM,
            ratio_clip=common.CLIP,
            value_clip=0.0,
            entropy_loss_scale=common.ENT_COEF,
            value_loss_scale=common.VF_COEF,
            kl_threshold=0.0,
            time_limit_bootstrap=True,
            experiment=exp,
        )
        agent = PPO(models=models, memory=memory, observation_space=env.observation_space, action_space=env.action_space, device=dev, cfg=cfg)
    else:
        models = {"policy": Policy(env.observation_space, env.action_space, dev, common.SAC_HIDDEN, nn.ReLU)}
        for k in ("critic_1", "critic_2", "target_critic_1", "target_critic_2"):
            models[k] = Value(env.observation_space, env.action_space, dev, common.SAC_HIDDEN, nn.ReLU, with_action=True)
        memory = RandomMemory(memory_size=s["buffer_size"], num_envs=1, device=dev)
        cfg = SAC_CFG(
            gradient_steps=1,
            batch_size=s["batch_size"],
            discount_factor=common.GAMMA,
            polyak=0.005,
            learning_rate=common.LR,
            learning_starts=s["learning_starts"],
            random_timesteps=0,
            learn_entropy=True,
            initial_entropy_value=1.0,
            experiment=exp,
        )
        agent = SAC(models=models, memory=memory, observation_space=env.observation_space, action_space=env.action_space, device=dev, cfg=cfg)
    trainer = SequentialTrainer(
        cfg=dict(timesteps=timesteps, headless=True, disable_progressbar=True, close_environment_at_exit=False), env=env, agents=agent
    )
    trainer.train()
    t1, c1 = time.perf_counter(), time.process_time()
    assert clock.timed_steps() == common.expected_steps(s), (clock.timed_steps(), common.expected_steps(s))
    return dict(env_steps=clock.timed_steps(), seconds=t1 - clock.t0, cpu_seconds=c1 - clock.c0, device=str(dev))


if __name__ == "__main__":
    common.run_main("skrl", run)
