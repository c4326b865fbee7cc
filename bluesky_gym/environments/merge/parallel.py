"""The PettingZoo environment of Merge's multi-agent form (needs the ``multiagent`` extra)."""

from __future__ import annotations

from typing import Any

from bluesky_gym.environments.merge.multiagent import MergeMultiAgentTask
from bluesky_gym.multiagent.parallel import BlueSkyParallelEnv


class MergeParallelEnv(BlueSkyParallelEnv):
    """Multi-agent Merge: every arrival is an agent.

    See :class:`~bluesky_gym.environments.merge.multiagent.MergeMultiAgentTask`. Scenario options are
    MergeEnv-v0's (``num_aircraft``, ...).
    """

    task_class = MergeMultiAgentTask
    metadata: dict[str, Any] = {**BlueSkyParallelEnv.metadata, "name": MergeMultiAgentTask.name}  # noqa: RUF012 - per instance: the name (_v0 or _v1) is set by __init__
