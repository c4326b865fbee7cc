"""Throughput of the Gymnasium environments: environment steps per second with random actions.

For every id: the single environment (``gym.make``), the native vector environment at each batch
size (``gym.make_vec(..., vectorization_mode="vector_entry_point")``, counting every episode's
step), this project's BlueSky backend (``gym.make(id, backend="bluesky")``, in the interpreter
that has BlueSky) and the reference implementation bluesky-gym 0.2.0 (in the interpreter given
for it). Each cell is a short time-bounded measurement (see
:func:`~bluesky_gym.benchmarks.timing.env_step_rate`); the resets that ending episodes need are
part of the measured time.
"""

from __future__ import annotations

import statistics
from collections.abc import Sequence
from typing import Any

import gymnasium as gym

import bluesky_gym
from bluesky_gym.benchmarks.core_bench import kernel_of
from bluesky_gym.benchmarks.external import run_worker
from bluesky_gym.benchmarks.timing import combine, env_step_rate
from bluesky_gym.registration import available_envs

BATCH_SIZES: tuple[int, ...] = (64, 1024)
#: The issue's targets: single environment vs the reference, and the largest batch vs the reference.
TARGET_SINGLE_VS_REFERENCE = 30.0
TARGET_BATCHED_VS_REFERENCE = 1000.0
TARGET_BATCH = 1024
SEED = 0
DEFAULT_SECONDS = 1.5  # time budget per cell [s]


def _sim_kernel(env: Any) -> str:
    task = getattr(getattr(env, "unwrapped", env), "task", None)
    return kernel_of(getattr(task, "sim", None)) if task is not None else "?"


def native_single_rate(env_id: str, seconds: float) -> dict[str, Any]:
    """Measure steps per second of ``gym.make(env_id)`` (with Gymnasium's default wrappers)."""
    bluesky_gym.register_envs()
    env = gym.make(env_id)
    try:
        result: dict[str, Any] = env_step_rate(env, seconds, seed=SEED)
        result["kernel"] = _sim_kernel(env)
    finally:
        env.close()
    return result


def native_vector_rate(env_id: str, num_envs: int, seconds: float) -> dict[str, Any]:
    """Measure episode steps per second of the native vector environment with ``num_envs`` episodes."""
    bluesky_gym.register_envs()
    env = gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point")
    try:
        result: dict[str, Any] = env_step_rate(env, seconds, seed=SEED, num_envs=num_envs)
        result["kernel"] = _sim_kernel(env)
    finally:
        env.close()
    return result


def _cell(fn: Any, *args: Any) -> dict[str, Any]:
    """Run one in-process measurement; an exception becomes ``{"error": ...}``."""
    try:
        return fn(*args)
    except Exception as exc:  # noqa: BLE001 - one broken environment must not end the whole table
        return {"error": f"{type(exc).__name__}: {exc}"}


def _worker_cell(python: str, mode: str, env_id: str, seconds: float) -> dict[str, Any]:
    out = run_worker(python, mode, {"env_id": env_id, "seconds": seconds, "seed": SEED}, timeout=120.0 + 10.0 * seconds)
    if "result" in out:
        return {**out["result"], "versions": out.get("versions", {})}
    return {"error": out.get("error", "no result")}


def _ratio(a: dict[str, Any] | None, b: dict[str, Any] | None) -> float | None:
    if not a or not b or "rate" not in a or "rate" not in b:
        return None
    return a["rate"] / b["rate"]


def _measure_row(
    env_id: str, batch_sizes: Sequence[int], seconds: float, bluesky_python: str | None, reference_python: str | None, say: Any
) -> dict[str, Any]:
    """Measure every cell of one environment's row (one run)."""
    say(f"{env_id} single")
    row: dict[str, Any] = {"id": env_id, "single": _cell(native_single_rate, env_id, seconds), "batched": {}}
    for n in batch_sizes:
        say(f"{env_id} x {n}")
        row["batched"][str(n)] = _cell(native_vector_rate, env_id, n, seconds)
    row["bluesky"] = None
    if bluesky_python:
        say(f"{env_id} BlueSky backend")
        row["bluesky"] = _worker_cell(bluesky_python, "backend-env", env_id, seconds)
    row["reference"] = None
    if reference_python and env_id.endswith("-v0"):  # the reference package has the paper's ids only
        say(f"{env_id} reference")
        row["reference"] = _worker_cell(reference_python, "reference-env", env_id, seconds)
    largest = row["batched"].get(str(max(batch_sizes))) if batch_sizes else None
    row["single_vs_reference"] = _ratio(row["single"], row["reference"])
    row["batched_vs_reference"] = _ratio(largest, row["reference"])
    row["single_vs_bluesky"] = _ratio(row["single"], row["bluesky"])
    return row


RATIOS = ("single_vs_reference", "batched_vs_reference", "single_vs_bluesky")


def _combine_rows(runs: list[dict[str, Any]]) -> dict[str, Any]:
    """One row from the same row of several runs: median figures, median same-run ratios."""

    def cell(cells: list[dict[str, Any] | None]) -> dict[str, Any] | None:
        return None if cells[0] is None else combine([c for c in cells if c is not None])

    row: dict[str, Any] = {"id": runs[0]["id"], "single": cell([r["single"] for r in runs])}
    row["batched"] = {n: cell([r["batched"][n] for r in runs]) for n in runs[0]["batched"]}
    row["bluesky"] = cell([r["bluesky"] for r in runs])
    row["reference"] = cell([r["reference"] for r in runs])
    for key in RATIOS:
        values = [r[key] for r in runs if r[key] is not None]
        row[key] = statistics.median(values) if values else None
        row[f"{key}_runs"] = values
    return row


def run_envs(
    ids: Sequence[str] | None = None,
    batch_sizes: Sequence[int] = BATCH_SIZES,
    seconds: float = DEFAULT_SECONDS,
    bluesky_python: str | None = None,
    reference_python: str | None = None,
    progress: Any = None,
    repeats: int = 1,
) -> dict[str, Any]:
    """Run the whole environment benchmark.

    With ``repeats`` > 1 the whole table is measured that many times; each figure is the median
    over the runs and each ratio the median of the ratios measured within the same run.

    Args:
        ids: Environment ids (default: every available one).
        batch_sizes: Numbers of episodes of the native vector environment.
        seconds: Time budget per measurement [s].
        bluesky_python: Interpreter with the real BlueSky (for the BlueSky backend), or None.
        reference_python: Interpreter with bluesky-gym 0.2.0 installed, or None.
        progress: Optional callable taking a one-line status message.
        repeats: Number of runs.

    Returns:
        ``{"rows": [...], "batch_sizes": [...], "targets": {...}, "settings": {...}}``; each row
        has ``id``, ``single``, ``batched`` (batch size -> result), ``bluesky``, ``reference``
        (a result, ``{"error": ...}`` or None when not measured) and the ratios.

    """
    say = progress or (lambda _msg: None)
    ids = list(ids) if ids else available_envs()
    unknown = [i for i in ids if i not in available_envs()]
    if unknown:
        raise ValueError(f"unknown or unavailable environment id(s) {unknown}; available: {available_envs()}")
    runs = []
    for rep in range(repeats):
        tag = f"envs: run {rep + 1}/{repeats}: " if repeats > 1 else "envs: "

        def tell(msg: str, tag: str = tag) -> None:
            say(tag + msg)

        runs.append([_measure_row(env_id, batch_sizes, seconds, bluesky_python, reference_python, tell) for env_id in ids])
    rows = [_combine_rows([run[i] for run in runs]) for i in range(len(ids))]
    return {
        "rows": rows,
        "batch_sizes": list(batch_sizes),
        "targets": {
            "single_vs_reference": TARGET_SINGLE_VS_REFERENCE,
            "batched_vs_reference": TARGET_BATCHED_VS_REFERENCE,
            "batch": TARGET_BATCH,
        },
        "settings": {
            "seconds": seconds,
            "repeats": repeats,
            "seed": SEED,
            "bluesky_python": bluesky_python,
            "reference_python": reference_python,
        },
    }
