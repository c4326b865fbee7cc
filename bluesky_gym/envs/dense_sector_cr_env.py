"""DenseSectorCREnv-v0."""

from __future__ import annotations

from bluesky_gym.envs.shell import BlueSkyEnv, BlueSkyVectorEnv
from bluesky_gym.tasks.dense_sector_cr import DenseSectorCRTask


class DenseSectorCREnv(BlueSkyEnv):
    """Dense-traffic stress test: cross a sector while traffic keeps entering it at a rising rate.

    TODO docstring
    """

    task_class = DenseSectorCRTask


class DenseSectorCRVectorEnv(BlueSkyVectorEnv):
    """Natively batched :class:`DenseSectorCREnv`."""

    task_class = DenseSectorCRTask
