"""``bluesky-gym list`` and ``bluesky-gym info --env ID``: the environments, their spaces and options.

Examples::

    bluesky-gym list                          # every environment: steps, timing, spaces
    bluesky-gym info --env SectorCREnv-v0     # spaces, timing and scenario options with defaults
    bluesky-gym info --env MergeEnv-v0 --json
    bluesky-gym info --env SectorCRCentralised-v0

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
import warnings
from typing import Any

import numpy as np

from bluesky_gym.cli.arguments import add_env_option
from bluesky_gym.envs.registry import ENVIRONMENTS
from bluesky_gym.multiagent.registration import centralised_ids


def add_parser(subparsers: Any) -> None:
    """Register the ``list`` and ``info`` subcommands."""
    p = subparsers.add_parser("list", help="list the environments", description=__doc__)
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    p.set_defaults(func=run_list)
    q = subparsers.add_parser(
        "info",
        help="spaces, timing and scenario options of an environment",
        description=__doc__,
    )
    add_env_option(q)
    q.add_argument("--json", action="store_true", help="print JSON instead of text")
    q.set_defaults(func=run_info)


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


def known_env(env_id: str) -> str:
    """Return ``env_id`` if it is a single-agent or centralised id, else raise ``ValueError`` listing both kinds."""
    import bluesky_gym

    if env_id in bluesky_gym.available_envs() or env_id in centralised_ids():
        return env_id
    raise ValueError(
        f"unknown environment {env_id!r}; available: {', '.join(bluesky_gym.available_envs())}; centralised: {', '.join(centralised_ids())}"
    )


def describe(env_id: str) -> dict[str, Any]:
    """Return everything ``info`` shows about an environment (single-agent or centralised), as plain data."""
    import gymnasium as gym

    import bluesky_gym

    bluesky_gym.register_envs()
    known_env(env_id)
    with warnings.catch_warnings():
        # Describing a -v0 id is not using an outdated version: no "out of date" notice from Gymnasium.
        warnings.filterwarnings("ignore", message=".*is out of date", category=DeprecationWarning)
        env = gym.make(env_id)
    try:
        obs_space = env.observation_space
        act_space = env.action_space
        cls = type(env.unwrapped)
        task = getattr(env.unwrapped, "task")  # noqa: B009 - every BlueSky-Gym environment has one; gym.Env does not declare it
        config = task.config
        max_steps = env.spec.max_episode_steps if env.spec is not None and env.spec.max_episode_steps else task.max_episode_steps
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
    row = next((e for e in ENVIRONMENTS if e.id == env_id), None)
    summary = (inspect.getdoc(cls) or "").split("\n", 1)[0]
    summary = summary.removeprefix(f"{env_id}: ")
    return {
        "id": env_id,
        "summary": summary,
        "kind": "centralised multi-agent" if env_id in centralised_ids() else "single-agent",
        "class": f"{cls.__module__}.{cls.__name__}",
        "max_episode_steps": int(max_steps),
        "dt_s": float(task.dt),
        "substeps_per_action": int(task.action_frequency),
        "seconds_per_step": float(task.dt * task.action_frequency),
        "has_goal": bool(getattr(task, "has_goal", True)),
        "reference_info_keys": list(task.info_keys),
        "observation": {k: _box(v) for k, v in obs_space.items()} if isinstance(obs_space, gym.spaces.Dict) else {},
        "action": _box(act_space),
        "options": options,
        "data": None if row is None else row.data_status(),
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

    single = [describe(e) for e in bluesky_gym.available_envs()]
    centralised = [describe(e) for e in centralised_ids()]
    if args.json:
        print(json.dumps(single + centralised, indent=2, default=str))
        return 0
    _print_table(single)
    notes: dict[str, list[str]] = {}
    for d in single:
        if d["data"]:
            notes.setdefault(d["data"], []).append(d["id"])
    for note, ids in notes.items():
        print(f"\n{', '.join(ids)}: data {note}")
    print(f"\n{len(single)} environments; `bluesky-gym info --env ID` shows one in detail.")
    print("\nCentralised multi-agent environments (one agent steers every aircraft; `train` and `eval`")
    print("take them too; `bluesky-gym train-ma` trains a policy shared by the aircraft instead):\n")
    _print_table(centralised)
    return 0


def _print_table(rows: list[dict[str, Any]]) -> None:
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


def run_info(args: argparse.Namespace) -> int:
    """Print one environment's spaces, timing and options."""
    try:
        d = describe(args.env)
    except ValueError as exc:
        print(f"bluesky-gym info: error: {exc}", file=sys.stderr)
        return 2
    if args.json:
        print(json.dumps(d, indent=2, default=str))
        return 0
    print(f"{d['id']}: {d['summary']}")
    print(f"  kind: {d['kind']}")
    print(f"  class: {d['class']}")
    print(
        f"  timing: {d['max_episode_steps']} steps max, {d['substeps_per_action']} x {d['dt_s']:g} s = {d['seconds_per_step']:g} s simulated per step"
    )
    print(f"  reference info keys: {', '.join(d['reference_info_keys'])}")
    if d["data"]:
        print(f"  data: {d['data']}")
    dtypes = sorted({v["dtype"] for v in d["observation"].values()})
    print(f"  observation (Dict of {'/'.join(dtypes)} Box):")
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
