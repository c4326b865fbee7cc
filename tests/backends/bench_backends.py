"""Decision steps per second of every environment on the native and the BlueSky backend.

Run from the repository root, in an environment with the ``bluesky`` extra (for the BlueSky
column; without it only the native columns are measured)::

    python tests/backends/bench_backends.py --repeat 5 --seconds 3

Each cell is the median over ``--repeat`` timing blocks of ``--seconds`` each, after a warm-up, of
single-environment decision steps per second with uniformly random actions (the env is reset when
an episode ends; resets are included). The last column is the native vector environment
(``gym.make_vec(..., vectorization_mode="vector_entry_point")``) in environment steps per second.
The output is a Markdown table.
"""

from __future__ import annotations

import argparse
import importlib.util
import statistics
import time
from collections.abc import Callable

import gymnasium as gym
import numpy as np

import bluesky_gym  # noqa: F401  (registers the environments)
from bluesky_gym.registration import available_envs


def _blocks(step: Callable[[], int], seconds: float, repeat: int, warmup: float) -> float:
    """Median rate (units per second) over ``repeat`` blocks of about ``seconds`` each."""
    end = time.perf_counter() + warmup
    while time.perf_counter() < end:
        step()
    rates = []
    for _ in range(repeat):
        n = 0
        t0 = time.perf_counter()
        while (elapsed := time.perf_counter() - t0) < seconds:
            n += step()
        rates.append(n / elapsed)
    return statistics.median(rates)


def single_env_rate(env_id: str, backend: str, seconds: float, repeat: int, warmup: float) -> float:
    """Median decision steps per second of one environment."""
    env = gym.make(env_id, backend=backend)
    rng = np.random.default_rng(0)
    env.reset(seed=0)
    space = env.action_space

    def step() -> int:
        _, _, term, trunc, _ = env.step(rng.uniform(space.low, space.high))
        if term or trunc:
            env.reset()
        return 1

    try:
        return _blocks(step, seconds, repeat, warmup)
    finally:
        env.close()


def vector_env_rate(env_id: str, num_envs: int, seconds: float, repeat: int, warmup: float) -> float:
    """Median environment steps per second of the native vector environment."""
    env = gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point")
    rng = np.random.default_rng(0)
    env.reset(seed=0)
    space = env.action_space

    def step() -> int:
        env.step(rng.uniform(space.low, space.high))
        return num_envs

    try:
        return _blocks(step, seconds, repeat, warmup)
    finally:
        env.close()


def main(argv: list[str] | None = None) -> None:
    """Measure and print the Markdown table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--envs", nargs="*", default=None, help="environment ids (default: all available)")
    parser.add_argument("--seconds", type=float, default=3.0, help="length of one timing block [s]")
    parser.add_argument("--repeat", type=int, default=5, help="timing blocks per cell (the median is reported)")
    parser.add_argument("--warmup", type=float, default=1.0, help="warm-up before timing [s]")
    parser.add_argument("--num-envs", type=int, default=64, help="episodes of the native vector environment")
    args = parser.parse_args(argv)
    has_bluesky = importlib.util.find_spec("bluesky") is not None
    ids = args.envs or available_envs()
    print(f"| environment | native (steps/s) | bluesky (steps/s) | native / bluesky | native vector, {args.num_envs} envs (env-steps/s) |")
    print("|---|---:|---:|---:|---:|")
    for env_id in ids:
        native = single_env_rate(env_id, "native", args.seconds, args.repeat, args.warmup)
        bluesky = single_env_rate(env_id, "bluesky", args.seconds, args.repeat, args.warmup) if has_bluesky else float("nan")
        vector = vector_env_rate(env_id, args.num_envs, args.seconds, args.repeat, args.warmup)
        ratio = native / bluesky if has_bluesky else float("nan")
        print(f"| {env_id} | {native:,.0f} | {bluesky:,.1f} | {ratio:,.0f}x | {vector:,.0f} |", flush=True)


if __name__ == "__main__":
    main()
