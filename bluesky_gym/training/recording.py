"""Fly episodes of an environment with a policy and film them (the ``render`` command and the demo).

The policy is ``random`` (uniform actions, seeded), ``classical`` (the benchmark's hand-written
controller), ``mvp`` (BlueSky's MVP conflict resolution, for the environments with traffic) or
the path of a Stable-Baselines3 model ``.zip`` (its algorithm is read from the file, or given).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from bluesky_gym.core.extras import missing_extra
from bluesky_gym.tasks import REFERENCE_POLICIES, RESOLUTION_REFERENCES

if TYPE_CHECKING:
    from bluesky_gym.training.policies import Policy

SB3_ALGORITHMS = {"ppo": "PPO", "sac": "SAC", "td3": "TD3", "ddpg": "DDPG", "a2c": "A2C"}


def make_actor(
    policy: str, env_id: str, action_space: Any, seed: int, algo: str | None = None, deterministic: bool = True, observation_space: Any = None
) -> Policy:
    """The policy that flies the episodes: a batched observation dict to a batch of actions.

    Bind it to the environment (:meth:`Policy.bind`) before its first reset and reset it
    (:meth:`Policy.reset`) when episodes end: ``mvp`` reads the simulator state and holds
    resolutions per episode; the others ignore both calls.

    Args:
        policy: ``random``, ``classical``, ``mvp`` or the path of a Stable-Baselines3 model ``.zip``.
        env_id: Environment id (selects the classical controller and MVP's mapping).
        action_space: Action space of one environment.
        seed: Seed of the random actions.
        algo: Algorithm of the model file (default: read from its run or the file; must agree).
        deterministic: Deterministic model actions.
        observation_space: Observation space of one environment (checked against the model's).
    """
    from bluesky_gym.training.policies import FunctionPolicy, reference_policy

    low = np.asarray(action_space.low, dtype=np.float64)
    high = np.asarray(action_space.high, dtype=np.float64)
    if policy == "random":
        rng = np.random.default_rng(seed)
        return FunctionPolicy(lambda obs: rng.uniform(low, high, size=(next(iter(obs.values())).shape[0], *low.shape)), "random")
    if policy in REFERENCE_POLICIES or policy in RESOLUTION_REFERENCES:
        return reference_policy(policy, env_id, low, high)
    path = Path(policy)
    if not path.is_file():
        names = ", ".join((*REFERENCE_POLICIES, *RESOLUTION_REFERENCES))
        raise ValueError(f"--policy must be one of {names} or an existing model .zip file, got {policy!r}")
    try:
        import stable_baselines3 as sb3
    except ImportError as exc:
        raise missing_extra("loading a model needs Stable-Baselines3", "train") from exc
    from bluesky_gym.training.evaluation import check_model_spaces, model_algorithm, model_file_damage, run_config_of

    damage = model_file_damage(path)
    if damage:
        raise ValueError(f"{damage}; it cannot be rendered")
    config = run_config_of(path)
    trained_on = config[1].get("env_id") if config is not None else None
    if trained_on and trained_on != env_id:
        raise ValueError(f"{path} was trained on {trained_on} (its {config[0] if config else ''}), not {env_id}; render it with --env {trained_on}")
    name = model_algorithm(path, algo, config[1].get("algo") if config is not None else None)
    model = getattr(sb3, name).load(path, device="cpu")
    if observation_space is not None:
        check_model_spaces(model, path, env_id, observation_space, action_space)

    def act(obs: dict[str, np.ndarray]) -> np.ndarray:
        action, _ = model.predict(obs, deterministic=deterministic)
        return np.asarray(action, dtype=np.float64).reshape(-1, *low.shape)

    return FunctionPolicy(act, name)


def record(
    env_id: str,
    policy: str = "random",
    episodes: int = 1,
    out: Path | None = None,
    seed: int = 0,
    max_steps: int | None = None,
    every: int = 1,
    max_frames: int | None = None,
    fps: float = 10.0,
    scale: float = 1.0,
    colors: int = 192,
    grid: int = 1,
    human: bool = False,
    algo: str | None = None,
    deterministic: bool = True,
    options: dict[str, Any] | None = None,
    log: Callable[[str], None] | None = None,
    scn: Path | None = None,
) -> tuple[Path | None, int]:
    """Fly ``episodes`` episodes of ``env_id`` and write their frames (or show them).

    With ``scn``, each episode is also written as a BlueSky scenario file: ``scn`` itself for one
    episode, ``<stem>-<k>.scn`` for episode ``k`` (from 1) of several (see :mod:`bluesky_gym.scenarios.export`).

    Returns:
        The file written (None with ``human``) and the number of frames.
    """
    import gymnasium as gym

    import bluesky_gym
    from bluesky_gym.render import VideoWriter

    bluesky_gym.register_envs()
    if env_id not in gym.registry:
        raise ValueError(f"unknown environment {env_id!r}; available: {', '.join(bluesky_gym.available_envs())}")
    mode = "human" if human else "rgb_array"
    kwargs: dict[str, Any] = dict(options or {})
    if max_steps is not None:
        kwargs["max_episode_steps"] = max_steps
    writer = None if human else VideoWriter(out or Path(f"{env_id}.gif"), fps=fps, scale=scale, colors=colors)
    n_frames = 0

    def emit(env: Any) -> bool:
        """Record (or, in a window, count: the environment draws itself) the current frame."""
        nonlocal n_frames
        if writer is not None:
            writer.append(env.render())
        n_frames += 1
        return max_frames is not None and n_frames >= max_frames

    if scn is not None and grid > 1:
        raise ValueError("scenario export (scn) writes single environments; use grid=1")
    if grid > 1:
        env: Any = gym.make_vec(env_id, num_envs=grid, vectorization_mode="vector_entry_point", render_mode=mode, render_grid=grid, **kwargs)
        actor = make_actor(policy, env_id, env.single_action_space, seed, algo, deterministic, env.single_observation_space)
        actor.bind(env)
        obs, _ = env.reset(seed=seed)
        actor.reset(None)
        ended = np.zeros(grid, int)
        step = 0
        stop = emit(env)
        while not stop and ended.min() < episodes:
            obs, _, te, tr, _ = env.step(actor.act(obs))
            actor.reset(np.asarray(te | tr))
            ended += np.asarray(te | tr, int)
            step += 1
            if step % every == 0 or ended.min() >= episodes:
                stop = emit(env)
    else:
        if "max_episode_steps" in kwargs:  # gym.make keeps that name for its TimeLimit wrapper
            kwargs["time_limit"] = kwargs.pop("max_episode_steps")
        env = gym.make(env_id, render_mode=mode, **kwargs)
        actor = make_actor(policy, env_id, env.action_space, seed, algo, deterministic, env.observation_space)
        actor.bind(env)
        recorder = None
        if scn is not None:
            from bluesky_gym.scenarios.export import ScenarioRecorder

            recorder = env.unwrapped.task.wrap_physics(ScenarioRecorder)
        stop = False
        for k in range(episodes):
            obs, _ = env.reset(seed=seed if k == 0 else None)
            actor.reset(None)
            stop = emit(env)
            step = 0
            done = False
            while not (done or stop):
                action = actor.act({key: v[None] for key, v in obs.items()})[0]
                obs, reward, te, tr, _ = env.step(action)
                done = te or tr
                step += 1
                if step % every == 0 or done:
                    stop = emit(env)
            if log is not None:
                log(f"episode {k + 1}: {step} steps, return {float(env.unwrapped.task.stats.total_reward[0]):+.2f}")
            if recorder is not None and scn is not None:
                target = scn if episodes == 1 else scn.with_name(f"{scn.stem}-{k + 1}{scn.suffix or '.scn'}")
                recorder.write(target, title=f"{env_id} episode {k + 1} (seed {seed}), policy {policy}")
                if log is not None:
                    log(f"wrote {target}")
            if stop:
                break
    env.close()
    path = writer.close() if writer is not None else None
    return path, n_frames
