"""Where a batched environment step's time goes: the physics core against everything else.

A batched step of an environment is the physics (the core's sub-steps, and the aircraft it
creates when episodes reset) plus the task layer (action mapping, observation, reward,
termination, statistics, scenario generation on autoreset) and the Gymnasium shell. This profile
runs the native vector environment under cProfile and splits the step time into the time spent
inside :mod:`bluesky_gym.core` (summed over the calls that enter it from outside) and the rest.

cProfile charges its own overhead to every Python call it sees, and the task layer makes many
more Python calls than the compiled physics, so the task-layer share it reports is an upper
bound of the share without the profiler.
"""

from __future__ import annotations

import cProfile
import pstats
import time
from typing import Any

import gymnasium as gym
import numpy as np

import bluesky_gym
from bluesky_gym.benchmarks.profiling import short_path

_CORE = "bluesky_gym/core/"


def _in_core(filename: str) -> bool:
    return _CORE in filename.replace("\\", "/")


def profile_env(env_id: str, num_envs: int = 1024, steps: int = 40, top: int = 12, seed: int = 0) -> dict[str, Any]:
    """Profile ``steps`` batched steps of ``env_id`` with random actions.

    Args:
        env_id: Environment id.
        num_envs: Episodes in the batch.
        steps: Number of profiled steps (resets of ending episodes included).
        top: Number of task-layer functions listed (by own time).
        seed: Seed of the episodes and of the actions.

    Returns:
        ``env_id``, ``num_envs``, ``steps``, ``step_s`` (seconds per step without the profiler),
        ``profiled_step_s``, ``physics_s`` and ``task_s`` (per profiled step), ``task_share``
        (fraction of the profiled step outside the core) and ``functions``: the ``top`` functions
        outside the core by own time, with ``function``, ``calls``, ``own_s`` (per step) and
        ``own_pct``.
    """
    bluesky_gym.register_envs()
    env = gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point")
    try:
        env.reset(seed=seed)
        env.action_space.seed(seed)
        actions = [env.action_space.sample() for _ in range(steps)]
        for a in actions[:5]:  # warm-up: compilation, caches
            env.step(a)
        t0 = time.perf_counter()
        for a in actions:
            env.step(a)
        step_s = (time.perf_counter() - t0) / steps
        prof = cProfile.Profile()
        prof.enable()
        for a in actions:
            env.step(a)
        prof.disable()
    finally:
        env.close()
    raw: dict[Any, Any] = pstats.Stats(prof).stats  # type: ignore[attr-defined]
    total = sum(own for (_cc, _nc, own, _cum, _callers) in raw.values())
    physics = 0.0
    for (filename, _line, _name), (_cc, _nc, _own, _cum, callers) in raw.items():
        if _in_core(filename):
            physics += sum(ct for (cfile, _cl, _cn), (_c1, _c2, _tt, ct) in callers.items() if not _in_core(cfile))
    functions = [
        {
            "function": f"{short_path(filename)}:{line}({name})" if line else name,
            "calls": nc / steps,
            "own_s": own / steps,
            "own_pct": 100.0 * own / total,
        }
        for (filename, line, name), (_cc, nc, own, _cum, _callers) in raw.items()
        if not _in_core(filename)
    ]
    functions.sort(key=lambda f: f["own_s"], reverse=True)
    return {
        "env_id": env_id,
        "num_envs": num_envs,
        "steps": steps,
        "step_s": step_s,
        "profiled_step_s": total / steps,
        "physics_s": physics / steps,
        "task_s": (total - physics) / steps,
        "task_share": float(np.clip((total - physics) / total, 0.0, 1.0)) if total > 0 else float("nan"),
        "functions": functions[:top],
    }
