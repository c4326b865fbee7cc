"""The PettingZoo environment of DenseSectorCR's multi-agent form (needs the ``multiagent`` extra)."""

from __future__ import annotations

from typing import Any

from bluesky_gym.environments.dense_sector_cr.multiagent import DenseSectorCRMultiAgentTask
from bluesky_gym.multiagent.parallel import BlueSkyParallelEnv


class DenseSectorCRParallelEnv(BlueSkyParallelEnv):
    """Multi-agent DenseSectorCR: every aircraft in the sector is an agent, and agents keep entering.

    See :class:`~bluesky_gym.environments.dense_sector_cr.multiagent.DenseSectorCRMultiAgentTask`.
    An aircraft that enters during a step appears in that step's dicts with its first observation
    (reward 0, neither terminated nor truncated, an empty info) and is in ``agents`` from then on.
    Scenario options are DenseSectorCREnv-v0's (``spawn_rate_start``, ...).
    """

    task_class = DenseSectorCRMultiAgentTask
    metadata: dict[str, Any] = {**BlueSkyParallelEnv.metadata, "name": DenseSectorCRMultiAgentTask.name}  # noqa: RUF012 - per instance: the name (_v0 or _v1) is set by __init__
