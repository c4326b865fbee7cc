"""rl_games: its agents talk to an IVecEnv (step -> obs, rewards, dones, infos; 4-tuple, numpy or torch).
A small IVecEnv over the native VectorEnv concatenates the dict observation (sorted keys, numpy) because
rl_games' MLP builders take one flat tensor, and passes truncations as infos["time_outs"] (rl_games'
bootstrap convention). PPO = a2c_continuous (separate actor/critic, fixed sigma = state-independent
log-std); SAC = rl_games' sac agent.
"""

import tempfile
import time

import common
import numpy as np
from rl_games.common import env_configurations, vecenv
from rl_games.common.algo_observer import DefaultAlgoObserver
from rl_games.common.ivecenv import IVecEnv
from rl_games.torch_runner import Runner

CLOCK = None


class BlueSkyIVecEnv(IVecEnv):
    def __init__(self, config_name, num_actors, **kwargs):
        self.env = common.make_flat_vec(num_actors)

    def step(self, actions):
        CLOCK.tick()
        obs, r, te, tr, info = self.env.step(actions)
        return obs, r.astype(np.float32), te | tr, {"time_outs": (tr & ~te).astype(np.float32)}

    def reset(self):
        obs, _ = self.env.reset(seed=0)
        return obs

    def get_number_of_agents(self):
        return 1

    def get_env_info(self):
        return {"action_space": self.env.single_action_space, "observation_space": self.env.single_observation_space, "agents": 1, "value_size": 1}


def network(hidden, act):
    return {
        "name": "actor_critic",
        "separate": True,
        "space": {
            "continuous": {
                "mu_activation": "None",
                "sigma_activation": "None",
                "mu_init": {"name": "default"},
                "sigma_init": {"name": "const_initializer", "val": 0},
                "fixed_sigma": True,
            }
        },
        "mlp": {"units": hidden, "activation": act, "initializer": {"name": "default"}, "regularizer": {"name": "None"}},
    }


def run(s):
    global CLOCK
    n = s["num_envs"]
    vecenv.register("BLUESKY", lambda config_name, num_actors, **kw: BlueSkyIVecEnv(config_name, num_actors, **kw))
    env_configurations.register("bluesky", {"vecenv_type": "BLUESKY", "env_creator": lambda **kw: None})
    train_dir = tempfile.mkdtemp(prefix="rlgames_")
    common_cfg = dict(
        env_name="bluesky",
        name="bluesky",
        device="cpu",
        device_name="cpu",
        num_actors=n,
        train_dir=train_dir,
        reward_shaper={"scale_value": 1.0},
        normalize_input=False,
        print_stats=False,
        save_frequency=0,
        gamma=common.GAMMA,
        score_to_win=1e9,
        env_config={},
    )
    if s["algo"] == "PPO":
        CLOCK = common.StepClock(s["warmup_rollouts"] * s["n_steps"], n)
        params = {
            "seed": 0,
            "torch_threads": 1,
            "algo": {"name": "a2c_continuous"},
            "model": {"name": "continuous_a2c_logstd"},
            "network": network(common.PPO_HIDDEN, "tanh"),
            "config": dict(
                common_cfg,
                ppo=True,
                normalize_advantage=True,
                normalize_value=False,
                tau=common.GAE_LAMBDA,
                learning_rate=common.LR,
                lr_schedule="None",
                kl_threshold=0.008,
                grad_norm=common.MAX_GRAD_NORM,
                entropy_coef=common.ENT_COEF,
                truncate_grads=True,
                e_clip=common.CLIP,
                clip_value=False,
                horizon_length=s["n_steps"],
                minibatch_size=s["minibatch"],
                mini_epochs=s["epochs"],
                critic_coef=2 * common.VF_COEF,  # rl_games: loss = a + 0.5 * critic_coef * c
                bounds_loss_coef=0.0,
                max_epochs=s["warmup_rollouts"] + s["timed_rollouts"],
                value_bootstrap=True,
            ),
        }
    else:
        CLOCK = common.StepClock(s["warmup_steps"], 1)
        params = {
            "seed": 0,
            "torch_threads": 1,
            "algo": {"name": "sac"},
            "model": {"name": "soft_actor_critic"},
            "network": {
                "name": "soft_actor_critic",
                "separate": True,
                "space": {"continuous": {}},
                "mlp": {"units": common.SAC_HIDDEN, "activation": "relu", "initializer": {"name": "default"}},
                "log_std_bounds": [-5, 2],
            },
            "config": dict(
                common_cfg,
                num_steps_per_episode=1,
                num_updates_per_step=1,
                num_warmup_steps=s["learning_starts"],
                batch_size=s["batch_size"],
                init_alpha=1.0,
                learnable_temperature=True,
                replay_buffer_size=s["buffer_size"],
                actor_lr=common.LR,
                critic_lr=common.LR,
                alpha_lr=common.LR,
                critic_tau=0.005,
                policy_frequency=1,
                max_epochs=s["warmup_steps"] + s["timed_steps"],
                value_bootstrap=True,
            ),
        }
    runner = Runner(algo_observer=DefaultAlgoObserver())
    runner.load({"params": params})
    runner.run({"train": True, "play": False})
    t1, c1 = time.perf_counter(), time.process_time()
    assert CLOCK.timed_steps() == common.expected_steps(s), (CLOCK.timed_steps(), common.expected_steps(s))
    return dict(env_steps=CLOCK.timed_steps(), seconds=t1 - CLOCK.t0, cpu_seconds=c1 - CLOCK.c0)


if __name__ == "__main__":
    common.run_main("rl_games", run)
