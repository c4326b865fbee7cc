"""Running the benchmark worker in another Python interpreter.

Each measurement that needs the real BlueSky or the reference package runs
:mod:`bluesky_gym.benchmarks.worker` as a script in a fresh process of the given interpreter. The
script and its :mod:`~bluesky_gym.benchmarks.timing` module are copied into a private temporary
folder, which is also the working directory, so nothing of this project (or anything else that
happens to sit next to it) is importable there unless asked for: the ``backend-env`` mode gets a
folder with only this project's ``bluesky_gym`` package in it.
"""

from __future__ import annotations

import importlib.util
import json
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

_HERE = Path(__file__).resolve().parent
_PACKAGE_DIR = _HERE.parent  # this project's bluesky_gym package


def bluesky_python(explicit: str | None = None, disabled: bool = False) -> str | None:
    """Choose the interpreter to measure BlueSky with, or None when BlueSky is not available.

    Args:
        explicit: An interpreter given on the command line (used as is).
        disabled: Skip BlueSky altogether.

    Returns:
        ``explicit`` if given; else this interpreter when ``bluesky`` is importable here; else None.

    """
    if disabled:
        return None
    if explicit:
        return explicit
    if importlib.util.find_spec("bluesky") is not None:
        return sys.executable
    return None


def _clean_environment() -> dict[str, str]:
    """Copy this process's environment without the PYTHONPATH entries that hold a ``bluesky_gym`` package.

    Such an entry (a checkout of this project) would shadow the reference package, or put this
    interpreter's packages in front of the other interpreter's own.
    """
    env = dict(os.environ)
    path = env.pop("PYTHONPATH", "")
    keep = [p for p in path.split(os.pathsep) if p and not (Path(p) / "bluesky_gym" / "__init__.py").is_file()]
    if keep:
        env["PYTHONPATH"] = os.pathsep.join(keep)
    env.pop("PYTHONHOME", None)
    return env


def run_worker(python: str, mode: str, config: dict[str, Any], timeout: float) -> dict[str, Any]:
    """Run one worker measurement in ``python`` and return its result.

    Args:
        python: Path of the interpreter (relative to the current directory), or its name on ``PATH``.
        mode: ``"bluesky-core"``, ``"backend-env"`` or ``"reference-env"``.
        config: The mode's configuration (see :mod:`bluesky_gym.benchmarks.worker`).
        timeout: Seconds after which the process is killed.

    Returns:
        The worker's JSON result, or ``{"error": message}`` when it failed, timed out or could not
        be started.

    """
    found = shutil.which(python)  # a relative path names a file from here, not from the worker's directory
    python = str(Path(found).absolute()) if found else python
    with tempfile.TemporaryDirectory(prefix="bluesky-gym-bench-") as tmp_name:
        tmp = Path(tmp_name)
        for name in ("worker.py", "timing.py"):
            shutil.copyfile(_HERE / name, tmp / name)
        config = dict(config)
        if mode == "backend-env":
            root = tmp / "package"
            root.mkdir()
            try:
                (root / "bluesky_gym").symlink_to(_PACKAGE_DIR, target_is_directory=True)
            except OSError:  # no symlinks on this file system
                shutil.copytree(_PACKAGE_DIR, root / "bluesky_gym", ignore=shutil.ignore_patterns("__pycache__"))
            config["package_root"] = str(root)
        out = tmp / "result.json"
        cmd = [python, str(tmp / "worker.py"), mode, json.dumps(config), str(out)]
        try:
            proc = subprocess.run(cmd, cwd=tmp, env=_clean_environment(), capture_output=True, text=True, timeout=timeout)
        except FileNotFoundError:
            return {"error": f"interpreter not found: {python}"}
        except subprocess.TimeoutExpired:
            return {"error": f"timed out after {timeout:.0f} s"}
        if out.is_file():
            try:
                return json.loads(out.read_text(encoding="utf-8"))
            except json.JSONDecodeError as exc:
                return {"error": f"unreadable worker result: {exc}"}
        tail = (proc.stderr or proc.stdout or "").strip().splitlines()
        return {"error": f"worker exited with code {proc.returncode}: {tail[-1] if tail else 'no output'}"}
