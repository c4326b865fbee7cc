"""Shared pieces of the library harnesses: settings, the flat-observation vector env, timing, results.

Each harness trains PPO (settings A, B) or SAC (setting C) on SectorCREnv-v0 through the native
batched vector env and writes one JSON line per setting with the env-steps/s measured over the timed
part of training (after a warm-up).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
import traceback

import numpy as np

ENV_ID = "SectorCREnv-v0"

# Setting -> number of envs, rollout length per env, minibatch, epochs, warm-up and timed rollouts.
SETTINGS = {
    "A": dict(algo="PPO", num_envs=1024, n_steps=16, minibatch=4096, epochs=10, warmup_rollouts=1, timed_rollouts=5),
    "B": dict(algo="PPO", num_envs=16, n_steps=128, minibatch=64, epochs=10, warmup_rollouts=1, timed_rollouts=10),
    "C": dict(algo="SAC", num_envs=1, batch_size=256, learning_starts=100, warmup_steps=300, timed_steps=1500, buffer_size=100_000),
}

# The common hyper-parameters.
LR = 3e-4
GAMMA = 0.99
GAE_LAMBDA = 0.95
CLIP = 0.2
VF_COEF = 0.5
ENT_COEF = 0.0
MAX_GRAD_NORM = 0.5
PPO_HIDDEN = [64, 64]  # tanh, separate actor and critic
SAC_HIDDEN = [256, 256]  # ReLU, actor and two critics


def set_threads() -> None:
    """One thread for torch (the harness is imported after the env vars for XLA are set by run_all.sh)."""
    try:
        import torch

        torch.set_num_threads(1)
        torch.set_num_interop_threads(1)
    except ImportError:
        pass
    except RuntimeError:
        pass


def make_vec(num_envs: int):
    """The native batched environment (SAME_STEP autoreset, dict observations of float64)."""
    import gymnasium as gym

    import bluesky_gym

    bluesky_gym.register_envs()
    return gym.make_vec(ENV_ID, num_envs=num_envs, vectorization_mode="vector_entry_point")


def flatten(obs: dict) -> np.ndarray:
    """Concatenate the dict observation's keys in sorted order into (N, 31) float32."""
    return np.concatenate([obs[k] for k in sorted(obs)], axis=-1).astype(np.float32)


def flat_dim(single_space) -> int:
    return int(sum(int(np.prod(single_space[k].shape)) for k in single_space.spaces))


def make_flat_vec(num_envs: int):
    """Gymnasium VectorEnv over the native env with flat float32 observations (info["final_obs"] flattened too)."""
    import gymnasium as gym

    venv = make_vec(num_envs)

    class _Flat(gym.vector.VectorEnv):
        def __init__(self, venv):
            self.venv = venv
            self.num_envs = venv.num_envs
            self.metadata = venv.metadata
            self.spec = venv.spec
            self.render_mode = None
            d = flat_dim(venv.single_observation_space)
            self.single_observation_space = gym.spaces.Box(-np.inf, np.inf, (d,), np.float32)
            self.observation_space = gym.spaces.Box(-np.inf, np.inf, (self.num_envs, d), np.float32)
            self.single_action_space = venv.single_action_space
            self.action_space = venv.action_space
            self.closed = False

        def reset(self, *, seed=None, options=None):
            obs, info = self.venv.reset(seed=seed, options=options)
            return flatten(obs), info

        def step(self, actions):
            obs, r, te, tr, info = self.venv.step(actions)
            if "final_obs" in info:
                info = dict(info)
                info["final_obs"] = flatten(info["final_obs"])
            return flatten(obs), r, te, tr, info

        def close(self, **kwargs):
            self.venv.close()

        @property
        def unwrapped(self):
            return self

    return _Flat(venv)


class StepClock:
    """Counts vector-env step calls and stamps the wall time at the first step after the warm-up."""

    def __init__(self, warmup_calls: int, steps_per_call: int):
        self.warmup_calls = warmup_calls
        self.steps_per_call = steps_per_call
        self.calls = 0
        self.t0 = None

    def tick(self) -> None:
        if self.calls == self.warmup_calls:
            self.t0, self.c0 = time.perf_counter(), time.process_time()
        self.calls += 1

    def timed_steps(self) -> int:
        return (self.calls - self.warmup_calls) * self.steps_per_call


def args_parser(name: str) -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(description=f"{name} throughput harness on {ENV_ID}")
    p.add_argument("--setting", required=True, choices=list(SETTINGS))
    p.add_argument("--out", required=True, help="JSON-lines file to append the result to")
    p.add_argument("--quick", action="store_true", help="shorter run while developing (fewer timed rollouts/steps)")
    return p


def setting(name: str, quick: bool) -> dict:
    s = dict(SETTINGS[name])
    if quick:
        if "timed_rollouts" in s:
            s["timed_rollouts"] = 1
        else:
            s["timed_steps"] = 100
    return s


def expected_steps(s: dict) -> int:
    if s["algo"] == "PPO":
        return s["timed_rollouts"] * s["num_envs"] * s["n_steps"]
    return s["timed_steps"]


def write_result(out: str, candidate: str, setting_name: str, **fields) -> None:
    rec = dict(candidate=candidate, setting=setting_name, pid=os.getpid(), **fields)
    if rec.get("seconds"):
        rec["sps"] = rec["env_steps"] / rec["seconds"]
        if rec.get("cpu_seconds") is not None:
            # CPU time of this process (all its threads) over the timed part / wall time: < 1 means it waited for a core.
            rec["cpu_share"] = rec["cpu_seconds"] / rec["seconds"]
    rec["loadavg_end"] = open("/proc/loadavg").read().split()[:3]
    with open(out, "a") as f:
        f.write(json.dumps(rec) + "\n")
    print(json.dumps(rec), flush=True)


def run_main(candidate: str, fn) -> None:
    """Parse args, run ``fn(setting_dict) -> dict(env_steps=..., seconds=..., **extra)`` and record it."""
    args = args_parser(candidate).parse_args()
    set_threads()
    s = setting(args.setting, args.quick)
    t_start = time.perf_counter()
    try:
        res = fn(s)
        res.setdefault("status", "ok")
    except NotImplementedError as e:
        res = dict(status="n/a", error=str(e))
    except Exception as e:  # noqa: BLE001
        traceback.print_exc()
        res = dict(status="error", error=f"{type(e).__name__}: {e}"[:2000])
    res["total_wall_s"] = time.perf_counter() - t_start
    res["quick"] = args.quick
    write_result(args.out, candidate, args.setting, **res)
    sys.stdout.flush()
