"""The PettingZoo environment of HorizontalCR's multi-agent form (needs the ``multiagent`` extra)."""

from __future__ import annotations

from typing import Any

from bluesky_gym.environments.horizontal_cr.multiagent import HorizontalCRMultiAgentTask
from bluesky_gym.multiagent.parallel import BlueSkyParallelEnv


class HorizontalCRParallelEnv(BlueSkyParallelEnv):
    """Multi-agent HorizontalCR: the ownship and its intruders are all agents.

    See :class:`~bluesky_gym.environments.horizontal_cr.multiagent.HorizontalCRMultiAgentTask`. Scenario
    options are HorizontalCREnv-v0's (``num_intruders``, ...).
    """

    task_class = HorizontalCRMultiAgentTask
    metadata: dict[str, Any] = {**BlueSkyParallelEnv.metadata, "name": HorizontalCRMultiAgentTask.name}  # noqa: RUF012 - per instance: the name (_v0 or _v1) is set by __init__
