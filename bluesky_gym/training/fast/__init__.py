"""The fast trainer: PPO, SAC, TD3 and DDPG on the native batched environment, one array per step.

Stable-Baselines3 steps a ``VecEnv`` through per-environment Python: one info dict per
environment and step, a loop over environments for every timeout and episode, a callback that
reads those dicts. With 1024 batched environments that costs more than the simulator itself. The
fast trainer keeps what SB3 does well and replaces its loops:

* **Kept from SB3**: the policy and value networks (``MultiInputPolicy``: the same layers, the same
  initialisation from the run seed), their optimisers, the losses and update rules of SB3's PPO,
  SAC, TD3 and DDPG, and the model file. A fast run's ``model.zip`` *is* an SB3 model
  (``PPO.load("model.zip")`` works), so evaluation, rendering, ``sweep``, ``results`` and
  ``demo`` read it unchanged.
* **Replaced**: rollout collection reads the native vector environment's arrays (one
  ``(num_envs, features)`` tensor per step, no per-environment Python), rollouts and the replay
  buffer are tensors on the learner's device, advantages are computed for all environments at
  once, episode statistics are kept as arrays (Python runs once per *finished episode*, for its
  log row), and losses are reduced without a host synchronisation per minibatch.

The hyperparameter names are those of SB3 (and of ``configs/paper.toml``); a name the fast
trainer does not implement is refused (:data:`HYPERPARAMETERS`). ``docs/training-fast.md``
explains when to use which trainer, with measured throughput.

Modules:
    base: what every fast trainer shares (observations as one tensor, episode bookkeeping,
        checkpoint files, TensorBoard).
    ppo: :class:`~bluesky_gym.training.fast.ppo.FastPPO`.
    offpolicy: :class:`~bluesky_gym.training.fast.offpolicy.FastSAC` and
        :class:`~bluesky_gym.training.fast.offpolicy.FastTD3` and
        :class:`~bluesky_gym.training.fast.offpolicy.FastDDPG`.
"""

from __future__ import annotations

from typing import Any

_OFF_POLICY = frozenset({"learning_rate", "buffer_size", "learning_starts", "batch_size", "tau", "gamma", "train_freq", "gradient_steps"})
#: Hyperparameters (SB3 constructor arguments) the fast trainer implements, per algorithm.
HYPERPARAMETERS: dict[str, frozenset[str]] = {
    "PPO": frozenset(
        {
            "learning_rate",
            "n_steps",
            "batch_size",
            "n_epochs",
            "gamma",
            "gae_lambda",
            "clip_range",
            "clip_range_vf",
            "normalize_advantage",
            "ent_coef",
            "vf_coef",
            "max_grad_norm",
            "target_kl",
        }
    ),
    "SAC": _OFF_POLICY | {"ent_coef", "target_update_interval", "target_entropy"},
    "TD3": _OFF_POLICY | {"policy_delay", "target_policy_noise", "target_noise_clip"},
    "DDPG": _OFF_POLICY,
}


def trainer_class(algo: str) -> Any:
    """Return the fast trainer class of an algorithm (``PPO``, ``SAC``, ``TD3``, ``DDPG``)."""
    key = algo.upper()
    if key == "PPO":
        from bluesky_gym.training.fast.ppo import FastPPO

        return FastPPO
    if key == "SAC":
        from bluesky_gym.training.fast.offpolicy import FastSAC

        return FastSAC
    if key == "TD3":
        from bluesky_gym.training.fast.offpolicy import FastTD3

        return FastTD3
    if key == "DDPG":
        from bluesky_gym.training.fast.offpolicy import FastDDPG

        return FastDDPG
    raise ValueError(f"unknown algorithm {algo!r}; choose one of {', '.join(HYPERPARAMETERS)}")
