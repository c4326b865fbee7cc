"""Run summaries: a finished run reduced to what its results need, for committing.

A finished run directory holds megabytes that only training needs: checkpoints, the TensorBoard
log, an episode log with a row per training episode (thousands at 2e6 steps) and the model.
:func:`summarise_run` keeps what the results page and ``bluesky-gym runs`` read: the
configuration, the process record, the held-out evaluation (``eval.json``,
``eval_episodes.csv``), ``result.json``, and the learning curve as ``curve.csv``: the episode
log in ``bins`` equal spans of timesteps, each row the number of episodes that ended in the span
and the mean of every numeric column over them (non-finite values left out; six significant
digits). It removes the
rest, and records what it removed in ``result.json`` (``"summarised"``), so that
:func:`~bluesky_gym.training.runner.inspect_run` does not take their absence for damage.
"""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any

import numpy as np

from bluesky_gym.training.io import atomic_write_csv, atomic_write_json, read_csv_rows, read_json
from bluesky_gym.training.runner import EPISODE_LOG, TENSORBOARD_DIR, inspect_run

#: The learning curve of a summarised run.
CURVE = "curve.csv"
#: Spans of timesteps of the curve.
DEFAULT_BINS = 200
#: Significant digits of the curve's means (a plot's resolution, a quarter of the file of full precision).
CURVE_DIGITS = 6
#: What a summary removes from a run (the final model last: ``keep_model`` keeps it); ``bluesky-gym results pack`` packs them.
SUMMARY_DROPS = ("checkpoints", "checkpoint.json", TENSORBOARD_DIR, EPISODE_LOG, "model.zip")
#: Episode-log columns the curve does not average (the span's end and its episode count replace them).
_NOT_AVERAGED = ("episode", "timesteps", "wall_time_s", "env_index")


def curve_rows(header: list[str], rows: list[list[str]], total_timesteps: int, bins: int) -> tuple[list[str], list[list[Any]]]:
    """The learning curve of an episode log: per span of timesteps, the episodes and the mean of each column.

    Args:
        header: The episode log's columns.
        rows: Its rows (as read from the CSV).
        total_timesteps: The run's timesteps (the end of the last span).
        bins: Number of equal spans.

    Returns:
        The curve's header (``timesteps``, ``episodes``, ``wall_time_s``, then the averaged
        columns) and its rows, spans without an episode left out.

    """
    data = np.array([[float(x) if x != "" else np.nan for x in r] for r in rows], dtype=np.float64).reshape(len(rows), len(header))
    steps = data[:, header.index("timesteps")]
    edges = np.linspace(0, total_timesteps, bins + 1)
    which = np.clip(np.searchsorted(edges, steps, side="left") - 1, 0, bins - 1)
    averaged = [c for c in header if c not in _NOT_AVERAGED]
    out = []
    for b in range(bins):
        mask = which == b
        if not mask.any():
            continue
        row: list[Any] = [int(edges[b + 1]), int(mask.sum()), float(np.nanmax(data[mask, header.index("wall_time_s")]))]
        for c in averaged:
            values = data[mask, header.index(c)]
            finite = values[np.isfinite(values)]
            row.append(float(f"{finite.mean():.{CURVE_DIGITS}g}") if finite.size else float("nan"))
        out.append(row)
    return ["timesteps", "episodes", "wall_time_s", *averaged], out


def summarise_run(run_dir: str | Path, bins: int = DEFAULT_BINS, keep_model: bool = False) -> dict[str, Any]:
    """Reduce a finished, intact run to its summary (see the module); return what was removed.

    Running it again on a summarised run does nothing.

    Raises:
        ValueError: The run is not finished, or is damaged (the message names the damage).

    """
    d = Path(run_dir)
    if not (d / "result.json").exists():
        raise ValueError(f"{d} is not a finished run (no result.json)")
    result = read_json(d / "result.json")
    if result.get("summarised"):
        return dict(result["summarised"])
    health = inspect_run(d)
    if health.problems:
        raise ValueError(f"{d} is damaged: {'; '.join(health.problems)}")
    log = d / EPISODE_LOG
    if log.exists():
        header, rows = read_csv_rows(log)
        curve_header, curve = curve_rows(header, rows, int(result["timesteps"]), bins)
        atomic_write_csv(d / CURVE, curve_header, curve)
    removed = [name for name in SUMMARY_DROPS if (d / name).exists() and not (keep_model and name == "model.zip")]
    record = {"removed": removed, "curve": CURVE if log.exists() else None, "bins": bins}
    files = {k: v for k, v in result.get("files", {}).items() if k not in removed}
    atomic_write_json(d / "result.json", {**result, "files": files, "summarised": record})
    for name in removed:  # after result.json says so: a run killed in between is still a summary
        path = d / name
        if path.is_dir():
            shutil.rmtree(path)
        else:
            path.unlink()
    return record
