"""The state of run directories at a glance (``bluesky-gym runs``).

:func:`describe_run` reads a run directory without changing it and reports its environment,
algorithm, seed, steps done out of the total, status and latest score. The status is one of

* ``running``: a live process holds the run's lock;
* ``finished``: ``result.json`` is written and the run is intact;
* ``damaged``: :func:`~bluesky_gym.training.runner.inspect_run` found damage (sizes only, not
  checksums, so that listing stays fast); ``bluesky-gym train`` names it and offers the way on;
* ``failed``: the last training process ended with an error (recorded in ``run.json``);
* ``interrupted``: training started and stopped (killed or interrupted); rerunning resumes it;
* ``new``: only the configuration is written.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from bluesky_gym.training.io import DamagedFileError, latest_checkpoint, read_csv_rows, read_json
from bluesky_gym.training.runner import EPISODE_LOG, RunLock, inspect_run

#: Episodes averaged for the latest training score of an unfinished run.
RECENT_EPISODES = 20
STATUSES = ("running", "finished", "damaged", "failed", "interrupted", "new")


def _read(path: Path) -> Any:
    try:
        return read_json(path) if path.exists() else None
    except DamagedFileError:
        return None


def describe_run(run_dir: str | Path) -> dict[str, Any]:
    """Describe one run directory.

    Returns:
        ``{"path", "env_id", "algo", "seed", "steps_done", "steps_total", "status", "score",
        "score_kind", "problems"}``; ``score`` is the mean held-out return of a finished run
        (``score_kind`` ``"held-out"``), else the mean return of the last logged training
        episodes (``"training"``), or None.

    """
    d = Path(run_dir)
    config = _read(d / "config.json") or {}
    result = _read(d / "result.json")
    health = inspect_run(d, deep=False)
    header, rows = read_csv_rows(d / EPISODE_LOG) if (d / EPISODE_LOG).exists() else ([], [])
    returns = [float(r[header.index("return")]) for r in rows if "return" in header and r[header.index("return")] != ""]
    logged_steps = max((int(r[header.index("timesteps")]) for r in rows), default=0) if "timesteps" in header else 0
    try:
        ckpt = latest_checkpoint(d)
    except DamagedFileError:
        ckpt = None
    processes = (_read(d / "run.json") or {}).get("processes", [])
    last_error = processes[-1].get("error", "") if processes else ""

    if RunLock(d).is_held():
        status, steps = "running", max(logged_steps, ckpt[0]["timesteps"] if ckpt else 0)
    elif health.problems:
        status, steps = "damaged", (ckpt[0]["timesteps"] if ckpt else 0)
    elif result is not None:
        status, steps = "finished", int(result.get("timesteps", 0))
    elif last_error and not last_error.startswith("KeyboardInterrupt"):
        status, steps = "failed", (ckpt[0]["timesteps"] if ckpt else 0)
    elif processes or rows:
        status, steps = "interrupted", (ckpt[0]["timesteps"] if ckpt else 0)
    else:
        status, steps = "new", 0

    score, kind = None, None
    if status == "finished" and result and result.get("eval"):
        score, kind = float(result["eval"]["return"]["mean"]), "held-out"
    elif returns:
        score, kind = float(np.mean(returns[-RECENT_EPISODES:])), "training"
    return {
        "path": str(d),
        "env_id": config.get("env_id", "?"),
        "algo": config.get("algo", "?"),
        "seed": config.get("seed", "?"),
        "steps_done": int(steps),
        "steps_total": config.get("total_timesteps"),
        "status": status,
        "score": score,
        "score_kind": kind,
        "problems": health.problems,
        "error": last_error or None,
    }


def find_run_dirs(paths: Sequence[str | Path]) -> list[Path]:
    """Return every run directory (holding ``config.json`` or ``run.json``) at or below ``paths``."""
    found: list[Path] = []
    for p in map(Path, paths):
        if not p.exists():
            raise FileNotFoundError(f"{p} does not exist")
        if (p / "config.json").exists() or (p / "run.json").exists():
            found.append(p)
        elif p.is_dir():
            found.extend(sorted({c.parent for name in ("config.json", "run.json") for c in p.rglob(name) if c.parent.name != "references"}))
    return list(dict.fromkeys(found))


def format_runs(rows: Sequence[dict[str, Any]], root: str | Path | None = None) -> str:
    """Format :func:`describe_run` results as a text table (paths relative to ``root``)."""
    head = ["run", "env", "algo", "seed", "steps", "status", "score"]
    table = []
    for r in rows:
        path = Path(r["path"])
        if root is not None:
            try:
                path = path.relative_to(root)
            except ValueError:
                pass
        total = r["steps_total"]
        pct = f" ({100 * r['steps_done'] / total:.0f}%)" if total else ""
        score = "-" if r["score"] is None else f"{r['score']:.2f} ({r['score_kind']})"
        table.append([str(path), str(r["env_id"]), str(r["algo"]), str(r["seed"]), f"{r['steps_done']}/{total or '?'}{pct}", r["status"], score])
    widths = [max(len(x) for x in col) for col in zip(head, *table)]
    lines = ["  ".join(h.ljust(w) for h, w in zip(head, widths)), "  ".join("-" * w for w in widths)]
    lines += ["  ".join(c.ljust(w) for c, w in zip(row, widths)).rstrip() for row in table]
    for r in rows:
        for problem in r["problems"]:
            lines.append(f"damaged {r['path']}: {problem}")
        if r["status"] == "failed":
            lines.append(f"failed {r['path']}: {r['error']}")
    return "\n".join(lines)
