"""Reference: the native vector env alone, random actions, same N and step count as each setting."""

import time

import numpy as np
from common import make_vec, run_main


def run(s):
    n = s["num_envs"]
    if s["algo"] == "PPO":
        warm, timed = s["warmup_rollouts"] * s["n_steps"], s["timed_rollouts"] * s["n_steps"]
    else:
        warm, timed = s["warmup_steps"], s["timed_steps"]
    env = make_vec(n)
    rng = np.random.default_rng(0)
    env.reset(seed=0)
    for _ in range(warm):
        env.step(rng.uniform(-1, 1, (n, 2)))
    t0, c0 = time.perf_counter(), time.process_time()
    for _ in range(timed):
        env.step(rng.uniform(-1, 1, (n, 2)))
    dt, dc = time.perf_counter() - t0, time.process_time() - c0
    return dict(env_steps=timed * n, seconds=dt, cpu_seconds=dc)


if __name__ == "__main__":
    run_main("env-only", run)
