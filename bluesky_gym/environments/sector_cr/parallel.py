"""The PettingZoo environment of SectorCR's multi-agent form (needs the ``multiagent`` extra)."""

from __future__ import annotations

from typing import Any

from bluesky_gym.environments.sector_cr.multiagent import SectorCRMultiAgentTask
from bluesky_gym.multiagent.parallel import BlueSkyParallelEnv


class SectorCRParallelEnv(BlueSkyParallelEnv):
    """Multi-agent SectorCR: every aircraft in the sector is an agent.

    See :class:`~bluesky_gym.environments.sector_cr.multiagent.SectorCRMultiAgentTask` for the observation,
    action and reward of each agent. Scenario options are SectorCREnv-v0's (``ac_density_mode``, ...).
    """

    task_class = SectorCRMultiAgentTask
    metadata: dict[str, Any] = {**BlueSkyParallelEnv.metadata, "name": SectorCRMultiAgentTask.name}  # noqa: RUF012 - per instance: the name (_v0 or _v1) is set by __init__
