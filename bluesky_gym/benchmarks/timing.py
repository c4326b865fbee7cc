"""Time-bounded throughput measurement (standard library only).

This module must not import anything outside the standard library: the benchmark worker loads it
in other interpreters (with the real BlueSky or the reference package), where this project's
dependencies may be missing or a different ``bluesky_gym`` package may be installed.

A measurement runs a callable in blocks of calls. The block length is calibrated so that a block
lasts about a tenth of the time budget; blocks are repeated until the budget is spent (and at
least ``min_blocks`` have run). The reported rate is the median of the per-block rates, which is
robust against the occasional slow block on a busy machine; the lowest and highest block rates
are kept to show the spread.
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable
from typing import Any

BLOCKS_PER_BUDGET = 10


def measure(
    call: Callable[[], Any],
    units_per_call: float,
    seconds: float,
    *,
    between: Callable[[], Any] | None = None,
    warmup_calls: int = 2,
    min_blocks: int = 3,
    max_blocks: int = 1000,
) -> dict[str, float]:
    """Measure how many units per second ``call`` processes.

    Args:
        call: The operation to time (one environment step, one simulator step, ...).
        units_per_call: Units of work done by one call (e.g. aircraft times sub-steps).
        seconds: Time budget for the timed blocks [s] (calibration and warm-up come on top).
        between: Untimed work done before every block (e.g. re-issuing turn commands).
        warmup_calls: Untimed calls before calibration (JIT compilation, caches, first reset).
        min_blocks: Minimum number of timed blocks, even when the budget is exceeded.
        max_blocks: Maximum number of timed blocks.

    Returns:
        A dict with ``rate`` (median units/s over the blocks), ``rate_low`` and ``rate_high``
        (slowest and fastest block), ``call_s`` (median seconds per call), ``calls`` (timed
        calls in total), ``blocks`` and ``seconds`` (timed seconds in total).

    """
    if units_per_call <= 0 or seconds <= 0:
        raise ValueError(f"units_per_call and seconds must be > 0, got {units_per_call} and {seconds}")
    clock = time.perf_counter
    for _ in range(warmup_calls):
        call()
    # Calibrate: repeat single calls for ~2% of the budget to estimate the time of one call.
    t0 = clock()
    n_cal = 0
    while True:
        call()
        n_cal += 1
        elapsed = clock() - t0
        if elapsed >= 0.02 * seconds or n_cal >= 1000:
            break
    per_call = elapsed / n_cal
    block_calls = max(1, int(seconds / BLOCKS_PER_BUDGET / max(per_call, 1e-9)))

    rates: list[float] = []
    timed = 0.0
    calls = 0
    while len(rates) < max_blocks and (timed < seconds or len(rates) < min_blocks):
        if between is not None:
            between()
        t0 = clock()
        for _ in range(block_calls):
            call()
        dt = clock() - t0
        timed += dt
        calls += block_calls
        rates.append(block_calls * units_per_call / max(dt, 1e-12))
    rate = statistics.median(rates)
    return {
        "rate": rate,
        "rate_low": min(rates),
        "rate_high": max(rates),
        "call_s": units_per_call / rate,
        "calls": float(calls),
        "blocks": float(len(rates)),
        "seconds": timed,
    }


def env_step_rate(env: Any, seconds: float, seed: int = 0, num_envs: int = 1, pool_size: int = 64) -> dict[str, float]:
    """Environment steps per second of a Gymnasium environment driven by random actions.

    The random actions are drawn from ``env.action_space`` before the timing starts and then
    cycled, so the figure is the cost of ``step`` (and of the resets it triggers), not of
    sampling. A single environment is reset when its episode ends (the reset is timed, as in a
    training loop); a vector environment resets its episodes itself.

    Args:
        env: A ``gymnasium.Env`` or ``gymnasium.vector.VectorEnv`` (already constructed).
        seconds: Time budget of the timed blocks [s].
        seed: Seed of the first reset and of the action sampler.
        num_envs: Episodes stepped by one ``step`` call (1 for a single environment).
        pool_size: Number of pre-drawn actions.

    Returns:
        The :func:`measure` result, in environment steps (transitions) per second, plus
        ``episodes`` (episode ends seen during the whole measurement).

    """
    env.action_space.seed(seed)
    pool = [env.action_space.sample() for _ in range(pool_size)]
    env.reset(seed=seed)
    state = {"i": 0, "episodes": 0}

    if num_envs == 1:

        def call() -> None:
            i = state["i"]
            state["i"] = i + 1
            _, _, terminated, truncated, _ = env.step(pool[i % pool_size])
            if terminated or truncated:
                state["episodes"] += 1
                env.reset()

    else:

        def call() -> None:
            i = state["i"]
            state["i"] = i + 1
            _, _, terminated, truncated, _ = env.step(pool[i % pool_size])
            state["episodes"] += int((terminated | truncated).sum())

    result = measure(call, float(num_envs), seconds)
    result["episodes"] = float(state["episodes"])
    return result


def combine(results: list[dict[str, Any]]) -> dict[str, Any]:
    """Combine repeated measurements of the same cell.

    Args:
        results: :func:`measure` results of repeated runs (error results are skipped).

    Returns:
        The first result's other keys, with ``rate`` and ``call_s`` the medians over the runs,
        ``rate_low``/``rate_high`` the extremes over all blocks, ``calls``, ``blocks`` and
        ``seconds`` summed, and ``runs`` the list of per-run rates; the first error result if no
        run succeeded.

    """
    good = [r for r in results if "error" not in r]
    if not good:
        return results[0]
    out = dict(good[0])
    out["rate"] = statistics.median(r["rate"] for r in good)
    out["call_s"] = statistics.median(r["call_s"] for r in good)
    out["rate_low"] = min(r["rate_low"] for r in good)
    out["rate_high"] = max(r["rate_high"] for r in good)
    for key in ("calls", "blocks", "seconds", "episodes"):
        if key in out:
            out[key] = sum(r[key] for r in good)
    out["runs"] = [r["rate"] for r in good]
    return out
