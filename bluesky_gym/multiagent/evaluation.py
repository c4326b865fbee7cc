"""Evaluation of joint policies on held-out multi-agent scenarios, and KPI tables.

``evaluate(name, policy, episodes)`` plays the scenarios of the evaluation seeds
``2**31 .. 2**31 + episodes - 1`` (:func:`bluesky_gym.envs.seeds.eval_seeds`, never used in
training) as one batch of multi-agent episodes, each played once, and returns one record per
episode: the team return and the episode KPIs ``kpi_*`` of
:meth:`~bluesky_gym.multiagent.base.MultiAgentTask.kpis`. Every policy evaluated with the same
number of episodes sees the same scenarios.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from gymnasium.utils import seeding

from bluesky_gym.envs.seeds import eval_seeds
from bluesky_gym.multiagent import make_task
from bluesky_gym.multiagent.policies import Policy

#: (record key, column label) of the KPI table.
KPI_COLUMNS: tuple[tuple[str, str], ...] = (
    ("kpi_los_count", "LoS/ep"),
    ("kpi_los_per_agent", "LoS/agent"),
    ("kpi_los_steps", "LoS pair-steps"),
    ("kpi_min_separation_nm", "min sep [NM]"),
    ("kpi_mean_abs_drift_deg", "drift [deg]"),
    ("kpi_completion_rate", "completed"),
    ("kpi_mean_agent_return", "return/agent"),
    ("kpi_fuel_kg", "fuel [kg]"),
)


def evaluate(
    name: str,
    policy: Policy,
    episodes: int,
    *,
    seed_offset: int = 0,
    options: Mapping[str, Any] | None = None,
    max_episode_steps: int | None = None,
) -> list[dict[str, float]]:
    """Play ``episodes`` held-out multi-agent episodes with ``policy``.

    Args:
        name: Multi-agent environment name (``"sector_cr_v0"``, ...).
        policy: The joint policy (bound to the task here).
        episodes: Number of episodes (the first ``episodes`` evaluation seeds from ``seed_offset``).
        seed_offset: Index of the first evaluation seed.
        options: Scenario options.
        max_episode_steps: Time limit (default: the environment's).

    Returns:
        One record per episode: ``return`` (team return) and the ``kpi_*`` values.
    """
    task = make_task(name, episodes, max_episode_steps, **dict(options or {}))
    task.seed(task.all_envs, [seeding.np_random(s)[0] for s in eval_seeds(episodes, seed_offset)])
    policy.bind(task)
    task.reset()
    policy.reset()
    obs = task.observation()
    records: list[dict[str, float] | None] = [None] * episodes
    while not task.finished.all():
        res = task.step(policy.act(obs))
        obs = res.observation
        for e in np.flatnonzero(res.episode_done):
            rec = {"return": float(res.info["total_reward"][e])}
            rec.update({k: float(v[e]) for k, v in res.info.items() if k.startswith("kpi_")})
            records[int(e)] = rec
    return [r for r in records if r is not None]


def summarise(records: Sequence[Mapping[str, float]]) -> dict[str, tuple[float, float]]:
    """Mean and 95% confidence half-width of every key over the records (NaN values are skipped)."""
    out: dict[str, tuple[float, float]] = {}
    for key in records[0]:
        x = np.array([r[key] for r in records], dtype=np.float64)
        x = x[np.isfinite(x)]
        if x.size == 0:
            out[key] = (math.nan, math.nan)
            continue
        half = 1.96 * float(x.std(ddof=1)) / math.sqrt(x.size) if x.size > 1 else math.nan
        out[key] = (float(x.mean()), half)
    return out


def kpi_table(results: Mapping[str, Sequence[Mapping[str, float]]]) -> str:
    """A plain-text table: one row per policy, mean +- 95% half-width of each KPI column.

    Args:
        results: Policy name -> its episode records (from :func:`evaluate`).
    """
    header = ["policy", *(label for _, label in KPI_COLUMNS)]
    rows = []
    for policy, records in results.items():
        summary = summarise(records)
        cells = [policy]
        for key, _ in KPI_COLUMNS:
            mean, half = summary.get(key, (math.nan, math.nan))
            cells.append(f"{mean:.3f} +- {half:.3f}" if math.isfinite(half) else f"{mean:.3f}")
        rows.append(cells)
    widths = [max(len(r[i]) for r in [header, *rows]) for i in range(len(header))]
    lines = ["  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)).rstrip() for r in [header, *rows]]
    lines.insert(1, "  ".join("-" * w for w in widths))
    return "\n".join(lines)
