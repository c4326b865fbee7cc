"""``bluesky-gym list`` and ``bluesky-gym info ID``: the environments, their spaces and options.

Examples::

    bluesky-gym list                    # every environment: steps, timing, observation and action
    bluesky-gym info SectorCREnv-v0     # spaces, timing and scenario options with defaults
    bluesky-gym info MergeEnv-v0 --json

The scenario options are the fields of the task's configuration dataclass; pass them to
``gym.make(ID, option=value)`` (or ``--option KEY=VALUE`` where a command accepts it).
"""

from __future__ import annotations

import argparse
import dataclasses
import inspect
import json
import re
import sys
from typing import Any

import numpy as np

from bluesky_gym.envs.registry import entry


def add_parser(subparsers: Any) -> None:
    """Register the ``list`` and ``info`` subcommands."""
    p = subparsers.add_parser("list", help="list the environments", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    p.set_defaults(func=run_list)
    q = subparsers.add_parser(
        "info",
        help="spaces, timing and scenario options of an environment",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    q.add_argument("env_id", metavar="ID", help="environment id, e.g. DescentEnv-v0")
    q.add_argument("--json", action="store_true", help="print JSON instead of text")
    q.set_defaults(func=run_info)


def env_class(env_id: str) -> type:
    """Return the single-environment class of ``env_id`` (from the environment table)."""
    return entry(env_id).env_class()


def _box(space: Any) -> dict[str, Any]:
    low, high = np.unique(space.low), np.unique(space.high)
    return {
        "shape": list(space.shape),
        "low": float(low[0]) if low.size == 1 else space.low.tolist(),
        "high": float(high[0]) if high.size == 1 else space.high.tolist(),
        "dtype": str(space.dtype),
    }


def _attribute_docs(cls: type) -> dict[str, str]:
    """Descriptions of the ``Attributes:`` section of a Google-style class docstring."""
    doc = inspect.getdoc(cls) or ""
    m = re.search(r"^Attributes:\n((?:[ \t]+.*\n?|\n)*)", doc, flags=re.MULTILINE)
    if not m:
        return {}
    out: dict[str, str] = {}
    current = None
    for line in m.group(1).splitlines():
        item = re.match(r"^\s{2,8}(\w+)(?: \([^)]*\))?:\s*(.*)$", line)
        if item:
            current = item.group(1)
            out[current] = item.group(2).strip()
        elif current and line.strip():
            out[current] += " " + line.strip()
    return out


def describe(env_id: str) -> dict[str, Any]:
    """Return everything ``info`` shows about an environment, as plain data."""
    import gymnasium as gym

    row = entry(env_id)
    cls = row.env_class()
    task_class = row.task_class()
    env = gym.make(env_id)
    try:
        obs_space = env.observation_space
        act_space = env.action_space
        config = getattr(env.unwrapped, "config")  # noqa: B009 - every BlueSky-Gym environment has one; gym.Env does not declare it
    finally:
        env.close()
    docs: dict[str, str] = {}
    for base in reversed(type(config).__mro__):  # a base class's fields (float32_spaces) are documented there
        docs.update(_attribute_docs(base))
    options = []
    for f in dataclasses.fields(config):
        default = getattr(config, f.name)
        options.append(
            {
                "name": f.name,
                "type": f.type if isinstance(f.type, str) else getattr(f.type, "__name__", str(f.type)),
                "default": default.tolist() if isinstance(default, np.ndarray) else default,
                "description": docs.get(f.name, ""),
            }
        )
    summary = (inspect.getdoc(cls) or "").split("\n", 1)[0]
    return {
        "id": env_id,
        "summary": summary,
        "class": f"{cls.__module__}.{cls.__name__}",
        "max_episode_steps": row.max_episode_steps,
        "dt_s": float(task_class.dt),
        "substeps_per_action": int(task_class.action_frequency),
        "seconds_per_step": float(task_class.dt * task_class.action_frequency),
        "has_goal": bool(task_class.has_goal),
        "reference_info_keys": list(task_class.info_keys),
        "observation": {k: _box(v) for k, v in obs_space.items()} if isinstance(obs_space, gym.spaces.Dict) else {},
        "action": _box(act_space),
        "options": options,
    }


def _fmt_bound(b: Any) -> str:
    if isinstance(b, list):
        return "[...]"
    if b in (np.inf, -np.inf):
        return "inf" if b > 0 else "-inf"
    return f"{b:g}"


def run_list(args: argparse.Namespace) -> int:
    """Print every available environment."""
    import bluesky_gym

    rows = [describe(e) for e in bluesky_gym.available_envs()]
    if args.json:
        print(json.dumps(rows, indent=2, default=str))
        return 0
    header = ("id", "steps", "s/step", "observation", "action", "options")
    table = []
    for d in rows:
        size = sum(int(np.prod(v["shape"])) for v in d["observation"].values())
        obs = f"Dict: {len(d['observation'])} keys, {size} values"
        act = f"Box{tuple(d['action']['shape'])} [{_fmt_bound(d['action']['low'])}, {_fmt_bound(d['action']['high'])}]"
        table.append((d["id"], str(d["max_episode_steps"]), f"{d['seconds_per_step']:g}", obs, act, ", ".join(o["name"] for o in d["options"])))
    widths = [max(len(r[i]) for r in [header, *table]) for i in range(len(header) - 1)]
    for r in [header, *table]:
        print("  ".join(c.ljust(w) for c, w in zip(r[:-1], widths, strict=True)) + "  " + r[-1])
    print(f"\n{len(rows)} environments; `bluesky-gym info ID` shows one in detail.")
    return 0


def run_info(args: argparse.Namespace) -> int:
    """Print one environment's spaces, timing and options."""
    try:
        d = describe(args.env_id)
    except ValueError as exc:
        print(f"bluesky-gym info: error: {exc}", file=sys.stderr)
        return 2
    if args.json:
        print(json.dumps(d, indent=2, default=str))
        return 0
    print(f"{d['id']}: {d['summary']}")
    print(f"  class: {d['class']}")
    print(
        f"  timing: {d['max_episode_steps']} steps max, {d['substeps_per_action']} x {d['dt_s']:g} s = {d['seconds_per_step']:g} s simulated per step"
    )
    print(f"  reference info keys: {', '.join(d['reference_info_keys'])}")
    print("  observation (Dict of float64 Box):")
    w = max(len(k) for k in d["observation"])
    for k, v in d["observation"].items():
        print(f"    {k.ljust(w)}  shape {tuple(v['shape'])}  bounds [{_fmt_bound(v['low'])}, {_fmt_bound(v['high'])}]")
    a = d["action"]
    print(f"  action: Box shape {tuple(a['shape'])} bounds [{_fmt_bound(a['low'])}, {_fmt_bound(a['high'])}] {a['dtype']}")
    print(f"  scenario options (gym.make('{d['id']}', name=value)):")
    if not d["options"]:
        print("    none")
    w = max((len(o["name"]) for o in d["options"]), default=0)
    for o in d["options"]:
        desc = f"  {o['description']}" if o["description"] else ""
        print(f"    {o['name'].ljust(w)}  {o['type']} = {o['default']!r}{desc}")
    return 0
