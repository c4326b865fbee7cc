"""The real-traffic PettingZoo environment step by step against its recorded outputs.

``data/parallel_digests.json`` holds, for seeded episodes of ``real_traffic_cr_v0`` and ``_v1``
(random actions, some agents left out, some names that are not agents), one SHA-256 digest per
step of everything the environment returned: observations, rewards, flags, infos and the
``agents`` list. Run this file as a script to write the recording again (only when the
environment's behaviour is meant to change).
"""

from __future__ import annotations

import hashlib
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("pettingzoo")

from bluesky_gym.environments.real_traffic.multiagent import RealTrafficParallelEnv

try:
    from .synthetic import joining_collection, save
except ImportError:  # run as a script
    from synthetic import joining_collection, save  # type: ignore[no-redef]

RECORDING = Path(__file__).with_name("data") / "parallel_digests.json"
#: (name, reset seed, max_episode_steps): whole windows, an evaluation-range seed and a time limit inside the window.
CASES = [
    ("real_traffic_cr_v0", 0, None),
    ("real_traffic_cr_v0", 3, None),
    ("real_traffic_cr_v0", 2**31 + 5, None),
    ("real_traffic_cr_v0", 1, 17),
    ("real_traffic_cr_v1", 0, None),
    ("real_traffic_cr_v1", 2, 23),
]


def _canonical(value: Any) -> Any:
    """A JSON-able form holding every bit: arrays as dtype, shape and bytes in hex; dicts with sorted keys."""
    if isinstance(value, dict):
        return {str(k): _canonical(value[k]) for k in sorted(value)}
    if isinstance(value, (list, tuple)):
        return [_canonical(v) for v in value]
    if isinstance(value, np.ndarray):
        return {"dtype": str(value.dtype), "shape": list(value.shape), "bytes": np.ascontiguousarray(value).tobytes().hex()}
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (float, np.floating)):
        return float(value).hex()
    return value if isinstance(value, (int, str)) else repr(value)


def _digest(value: Any) -> str:
    return hashlib.sha256(json.dumps(_canonical(value), sort_keys=True).encode()).hexdigest()


def rollout(options: dict[str, Any], name: str, seed: int, max_episode_steps: int | None) -> list[str]:
    """Digests of the reset and of every step of one seeded episode."""
    env = RealTrafficParallelEnv(max_episode_steps=max_episode_steps, name=name, **options)
    rng = np.random.default_rng(seed % 1000)
    obs, infos = env.reset(seed=seed)
    out = [_digest({"obs": obs, "infos": infos, "agents": list(env.agents), "state": env.state()})]
    while env.agents:
        actions: dict[str, Any] = {}
        for a in env.agents:
            if rng.random() < 0.8:  # the others fly their recording
                actions[a] = rng.uniform(-1.5, 1.5, env.action_space(a).shape)  # out of range too: clipped
        actions["not-an-agent"] = np.zeros(3)  # ignored, never validated
        step = env.step(actions)
        out.append(_digest({"step": list(step), "agents": list(env.agents), "state": env.state()}))
    return out


def record(options: dict[str, Any]) -> dict[str, list[str]]:
    """Digests of every case, keyed ``name/seed/limit``."""
    return {f"{n}/{s}/{m}": rollout(options, n, s, m) for n, s, m in CASES}


@pytest.fixture(scope="module")
def options(tmp_path_factory) -> dict:
    """Every window of this collection has aircraft appearing and leaving while it plays."""
    path = save(joining_collection(), tmp_path_factory.mktemp("rt-recorded"))
    return {"collections": (path,), "min_traffic": 1, "max_traffic": 8}


@pytest.mark.parametrize("case", CASES, ids=lambda c: f"{c[0]}-{c[1]}-{c[2]}")
def test_outputs_are_the_recorded_ones_step_by_step(options, case) -> None:
    recorded = json.loads(RECORDING.read_text())[f"{case[0]}/{case[1]}/{case[2]}"]
    now = rollout(options, *case)
    assert len(recorded) > 5, "the recorded episode is too short to mean anything"
    first = next((i for i, (a, b) in enumerate(zip(now, recorded)) if a != b), None)
    assert first is None, f"step {first} differs from the recording"
    assert len(now) == len(recorded), f"the episode has {len(now) - 1} steps, recorded {len(recorded) - 1}"


if __name__ == "__main__":
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        opts = {"collections": (save(joining_collection(), Path(tmp)),), "min_traffic": 1, "max_traffic": 8}
        RECORDING.parent.mkdir(exist_ok=True)
        RECORDING.write_text(json.dumps(record(opts), indent=1) + "\n")
    print(f"wrote {RECORDING}", file=sys.stderr)
