"""The benchmark: train, evaluate, compare and plot Stable-Baselines3 agents on BlueSky-Gym.

Stable-Baselines3 and PyTorch are optional (the ``train`` extra). Modules of this package that
need them import them lazily through :func:`bluesky_gym.core.extras.require_sb3`, so ``import bluesky_gym.training`` and
the reference policies, evaluation and plotting of stored runs work without them.

Modules:
    sb3_vec_env: :class:`~bluesky_gym.training.sb3_vec_env.SB3VecEnv`, SB3's VecEnv over the
        native batched environment.
    hyperparams: the paper's hyperparameters and config files.
    policies: the reference policies (``random`` and a classical controller per environment).
    evaluation: deterministic evaluation on held-out scenarios and KPI tables.
    fast: the fast trainer (SB3's networks and updates, batched rollouts on the native environment).
    runner: one resumable training run in a run directory.
    sweep: the grid of runs, sequential or on Ray.
    plotting: learning curves and the aggregate across environments.
"""

from __future__ import annotations

from typing import Any

from bluesky_gym.core.extras import require_sb3

ALGORITHMS = ("PPO", "SAC", "TD3", "DDPG")
OFF_POLICY = ("SAC", "TD3", "DDPG")
#: The trainers of ``bluesky-gym train --trainer``: Stable-Baselines3's own loops, or the batched :mod:`~bluesky_gym.training.fast` trainer.
TRAINERS = ("sb3", "fast")


def make_vector_env(env_id: str, num_envs: int, **kwargs: Any) -> Any:
    """Make the native batched environment of ``env_id`` (``gym.make_vec``, vector entry point).

    An id without a batched form (the centralised multi-agent environments) gets Gymnasium's
    ``SyncVectorEnv`` with the same ``SAME_STEP`` autoreset instead.

    Args:
        env_id: Environment id.
        num_envs: Number of episodes simulated together.
        **kwargs: Scenario options, ``max_episode_steps``, ``render_mode``.

    """
    import gymnasium as gym

    import bluesky_gym

    bluesky_gym.register_envs()
    if env_id not in gym.registry:
        raise ValueError(f"unknown environment {env_id!r}; available: {', '.join(bluesky_gym.available_envs())}")
    if gym.spec(env_id).vector_entry_point is None:
        # A centralised multi-agent id has no batched form: Gymnasium steps its single environments in a loop.
        return gym.make_vec(
            env_id, num_envs=num_envs, vectorization_mode="sync", vector_kwargs={"autoreset_mode": gym.vector.AutoresetMode.SAME_STEP}, **kwargs
        )
    return gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point", **kwargs)


def algorithm_class(name: str) -> Any:
    """Return the Stable-Baselines3 class of an algorithm name (``PPO``, ``SAC``, ``TD3``, ``DDPG``)."""
    key = name.upper()
    if key not in ALGORITHMS:
        raise ValueError(f"unknown algorithm {name!r}; choose one of {', '.join(ALGORITHMS)}")
    return getattr(require_sb3(), key)
