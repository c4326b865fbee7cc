"""Plain-text tables and run metadata of the benchmark results."""

from __future__ import annotations

import datetime
import os
import platform
from collections.abc import Sequence
from typing import Any

import numpy as np


def metadata() -> dict[str, Any]:
    """Collect the versions and machine facts stored with the results."""
    import gymnasium

    import bluesky_gym

    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # not available on every platform
        cores = os.cpu_count() or 0
    return {
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "bluesky_gym": bluesky_gym.__version__,
        "python": platform.python_version(),
        "numpy": np.__version__,
        "gymnasium": gymnasium.__version__,
        "platform": platform.platform(),
        "machine": platform.machine(),
        "cpu_cores": cores,
    }


def fmt_rate(x: float | None) -> str:
    """Format a rate with a k/M/G suffix (``2.74 M``)."""
    if x is None:
        return "-"
    for div, suffix in ((1e9, " G"), (1e6, " M"), (1e3, " k")):
        if abs(x) >= div:
            return f"{x / div:.3g}{suffix}"
    return f"{x:.3g}"


def fmt_time(seconds: float | None) -> str:
    """Format a duration in s, ms or µs."""
    if seconds is None:
        return "-"
    if seconds >= 1.0:
        return f"{seconds:.2f} s"
    if seconds >= 1e-3:
        return f"{seconds * 1e3:.3g} ms"
    return f"{seconds * 1e6:.3g} µs"


def fmt_ratio(r: float | None, target: float | None = None) -> str:
    """``123x``, with `` ok`` / `` LOW`` when a target is given."""
    if r is None:
        return "-"
    text = f"{r:.0f}x" if r >= 10 else f"{r:.2g}x"
    if target is not None:
        text += " ok" if r >= target else " LOW"
    return text


def table(header: Sequence[str], rows: Sequence[Sequence[str]], right: Sequence[bool] | None = None) -> str:
    """Lay out aligned columns; ``right`` says which columns are right-aligned (numbers)."""
    widths = [max(len(str(c)) for c in col) for col in zip(header, *rows, strict=False)]
    right = right if right is not None else [i > 0 for i in range(len(header))]

    def line(cells: Sequence[str]) -> str:
        return "  ".join(str(c).rjust(w) if r else str(c).ljust(w) for c, w, r in zip(cells, widths, right, strict=True)).rstrip()

    rule = "  ".join("-" * w for w in widths).rstrip()
    return "\n".join([line(header), rule, *(line(r) for r in rows)])


def _how(settings: dict[str, Any], spread: bool = False) -> str:
    """Describe how the figures were obtained."""
    text = f"median of timed blocks (~{settings['seconds']:g} s per cell)"
    repeats = settings.get("repeats", 1)
    if repeats > 1:
        text = f"median over {repeats} runs of the {text}; ratios: median of same-run ratios"
    return text + ("; spread = slowest-fastest block" if spread else "")


def _cell(result: dict[str, Any] | None) -> str:
    if result is None:
        return "-"
    if "error" in result:
        return "error"
    return fmt_rate(result["rate"])


def _spread(result: dict[str, Any]) -> str:
    return f"{fmt_rate(result['rate_low'])}-{fmt_rate(result['rate_high'])}"


def format_core(core: dict[str, Any]) -> str:
    """Format the core benchmark as text."""
    target = core["target"]
    settings = core["settings"]
    out = [
        "Simulation core: aircraft-sub-steps per second (one aircraft advanced by one time step)",
        f"DT {settings['dt']:g} s; A320s (or a mixed fleet) at 1000-11000 m, 1 in {settings['turn_every']} turning; {_how(settings, spread=True)}",
        "",
    ]
    rows = []
    for r in [*core["native"], *core.get("mixed", [])]:
        note = ""
        if (r["envs"], r["aircraft"]) == (target["envs"], target["aircraft"]) and r.get("fleet", "A320") == "A320":
            met = r["rate"] >= target["rate"]
            note = f"target >= {fmt_rate(target['rate'])} (~{target['vs_bluesky']:.0f}x BlueSky): {'met' if met else 'NOT MET'}"
        rows.append(
            [
                r["kernel"],
                r.get("fleet", "A320"),
                str(r["envs"]),
                str(r["aircraft"]),
                fmt_rate(r["rate"]),
                _spread(r),
                fmt_time(r["call_s"]),
                fmt_ratio(r.get("vs_bluesky")),
                note,
            ]
        )
    out.append(
        table(
            ["kernel", "fleet", "airspaces", "aircraft", "ac-sub-steps/s", "spread", "step time", "vs BlueSky", ""],
            rows,
            [False, False, True, True, True, True, True, True, False],
        )
    )
    bs = core.get("bluesky")
    out.append("vs BlueSky: this rate / BlueSky's rate for one airspace with the same number of aircraft")
    out.append("")
    if bs is None:
        out.append("BlueSky: not measured (give --bluesky-python PATH, an interpreter with bluesky-simulator installed)")
    elif "error" in bs:
        out.append(f"BlueSky ({bs.get('python')}): failed: {bs['error']}")
    else:
        v = bs.get("versions", {})
        versions = f"python {v.get('python', '?')}, numpy {v.get('numpy', '?')}"
        out.append(f"BlueSky {v.get('bluesky-simulator', '?')} (one airspace per process; {versions}):")
        rows = [[str(r["aircraft"]), fmt_rate(r["rate"]), _spread(r), fmt_time(r["call_s"])] for r in bs["results"]]
        out.append(table(["aircraft", "ac-sub-steps/s", "spread", "step time"], rows))
        if bs.get("failed_runs"):
            out.append(f"({bs['failed_runs']} BlueSky run(s) failed and were left out)")
    return "\n".join(out)


def format_envs(envs: dict[str, Any]) -> str:
    """Format the environment benchmark as text."""
    t = envs["targets"]
    sizes = envs["batch_sizes"]
    largest = max(sizes) if sizes else None
    kernels = sorted({r["single"].get("kernel", "?") for r in envs["rows"] if "error" not in r["single"]})
    out = [
        "Environment steps per second, random actions (batched: steps of all episodes together)",
        f"native kernel: {', '.join(kernels) or '-'}; {_how(envs['settings'])}",
        "",
    ]
    header = ["env", "single", *[f"x{n}" for n in sizes], "BlueSky", "reference", f"single/ref (>={t['single_vs_reference']:.0f}x)"]
    if largest is not None:
        target = f" (>={t['batched_vs_reference']:.0f}x)" if largest == t["batch"] else ""
        header.append(f"x{largest}/ref{target}")
    header.append("single/BlueSky")
    rows = []
    errors = []
    for r in envs["rows"]:
        cells = [r["id"], _cell(r["single"]), *[_cell(r["batched"][str(n)]) for n in sizes], _cell(r["bluesky"]), _cell(r["reference"])]
        cells.append(fmt_ratio(r["single_vs_reference"], t["single_vs_reference"]))
        if largest is not None:
            cells.append(fmt_ratio(r["batched_vs_reference"], t["batched_vs_reference"] if largest == t["batch"] else None))
        cells.append(fmt_ratio(r["single_vs_bluesky"]))
        rows.append(cells)
        named = [("single", r["single"]), *[(f"x{n}", r["batched"][str(n)]) for n in sizes]]
        named += [("BlueSky", r["bluesky"]), ("reference", r["reference"])]
        errors += [f"  {r['id']} {name}: {res['error']}" for name, res in named if res and "error" in res]
    out.append(table(header, rows))
    out.append("")
    settings = envs["settings"]
    bs_note = settings.get("bluesky_python") or "not measured (give --bluesky-python PATH)"
    ref_note = settings.get("reference_python") or "not measured (give --reference-python PATH, with bluesky-gym==0.2.0)"
    out.append(f"BlueSky = this project's backend='bluesky' (single env) in: {bs_note}")
    out.append(f"reference = bluesky-gym 0.2.0 (single env) in: {ref_note}")
    if errors:
        out.append("errors:")
        out += errors
    return "\n".join(out)


def format_profile(prof: dict[str, Any]) -> str:
    """Format a profile of the core step as text."""
    head = (
        f"Profile of Simulator.step, {prof['kernel']} kernel, {prof['envs']} airspaces x {prof['aircraft']} aircraft, "
        f"{prof['steps']} steps: {fmt_time(prof['step_s'])} per step "
        f"({fmt_rate(prof['envs'] * prof['aircraft'] / prof['step_s'])} ac-sub-steps/s), "
        f"{fmt_time(prof['profiled_step_s'])} under the profiler"
    )
    rows = [
        [f["function"], f"{f['calls']:.3g}", fmt_time(f["own_s"]), f"{f['own_pct']:.1f}%", fmt_time(f["cum_s"]), f"{f['cum_pct']:.1f}%"]
        for f in prof["functions"]
    ]
    return head + "\n\n" + table(["function", "calls/step", "own/step", "own %", "cum/step", "cum %"], rows)


def format_env_profile(prof: dict[str, Any]) -> str:
    """Format a profile of a batched environment step (physics against task layer) as text."""
    head = (
        f"Profile of {prof['env_id']} x {prof['num_envs']}, {prof['steps']} batched steps: {fmt_time(prof['step_s'])} per step; "
        f"under the profiler {fmt_time(prof['profiled_step_s'])}: physics {fmt_time(prof['physics_s'])}, "
        f"task layer and shell {fmt_time(prof['task_s'])} ({100.0 * prof['task_share']:.1f}% of the step, an upper bound)"
    )
    rows = [[f["function"], f"{f['calls']:.3g}", fmt_time(f["own_s"]), f"{f['own_pct']:.1f}%"] for f in prof["functions"]]
    return head + "\n\n" + table(["function outside the core", "calls/step", "own/step", "own %"], rows)
