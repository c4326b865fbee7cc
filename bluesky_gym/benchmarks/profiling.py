"""Where the native core's step time goes: cProfile of :meth:`Simulator.step`.

numpy's ufuncs are not separate entries in cProfile; their time is the ``own`` time of the Python
function that calls them. So the per-function own time says which part of the step (performance
update, autopilot, ISA, speed/heading/altitude update, ...) costs what.
"""

from __future__ import annotations

import cProfile
import pstats
import time
from typing import Any

from bluesky_gym.benchmarks.core_bench import core_scenario, kernel_of, make_simulator, populate, recommand_turns


def profile_core(n_envs: int = 4096, n_aircraft: int = 20, kernel: str | None = None, steps: int = 30, top: int = 15) -> dict[str, Any]:
    """Profile ``steps`` simulator steps of the core benchmark traffic.

    Args:
        n_envs: Airspaces.
        n_aircraft: Aircraft per airspace.
        kernel: Step kernel (None: the simulator's default).
        steps: Number of profiled steps.
        top: Number of functions listed (by own time).

    Returns:
        ``kernel``, ``envs``, ``aircraft``, ``steps``, ``step_s`` (seconds per step without the
        profiler), ``profiled_step_s`` (with it) and ``functions``: a list of dicts with
        ``function``, ``calls`` (per step), ``own_s`` and ``cum_s`` (per step) and ``own_pct``,
        ``cum_pct`` (percent of the profiled step time).

    """
    sim = make_simulator(n_envs, n_aircraft, kernel)
    turns = populate(sim, core_scenario(n_envs, n_aircraft))
    for _ in range(3):  # warm-up (compilation, caches)
        sim.step()
    t0 = time.perf_counter()
    for _ in range(steps):
        sim.step()
    step_s = (time.perf_counter() - t0) / steps
    recommand_turns(sim, *turns)

    prof = cProfile.Profile()
    prof.enable()
    for _ in range(steps):
        sim.step()
    prof.disable()
    stats = pstats.Stats(prof)
    raw: dict[Any, Any] = stats.stats  # type: ignore[attr-defined]
    step_total = sum(v[3] for k, v in raw.items() if k[2] == "step" and k[0].endswith("simulator.py"))
    total = step_total or stats.total_tt  # type: ignore[attr-defined]
    functions = []
    for (filename, line, name), (_cc, ncalls, own, cum, _callers) in raw.items():
        label = f"{short_path(filename)}:{line}({name})" if line else name
        functions.append(
            {
                "function": label,
                "calls": ncalls / steps,
                "own_s": own / steps,
                "cum_s": cum / steps,
                "own_pct": 100.0 * own / total,
                "cum_pct": 100.0 * cum / total,
            }
        )
    functions.sort(key=lambda f: f["own_s"], reverse=True)
    return {
        "kernel": kernel_of(sim),
        "envs": n_envs,
        "aircraft": n_aircraft,
        "steps": steps,
        "step_s": step_s,
        "profiled_step_s": total / steps,
        "functions": functions[:top],
    }


def short_path(filename: str) -> str:
    """``bluesky_gym/core/simulator.py`` instead of an absolute path; the base name otherwise."""
    parts = filename.replace("\\", "/").split("/")
    if "bluesky_gym" in parts:
        return "/".join(parts[parts.index("bluesky_gym") :])
    return parts[-1]
