"""Registration of the centralised multi-agent environments with Gymnasium.

The ids come from the environment table (:mod:`bluesky_gym.envs.registry`); only Gymnasium is
imported here, so ``bluesky_gym`` can call :func:`register_envs` at import time without the
optional multi-agent dependencies.
"""

from __future__ import annotations

import gymnasium as gym

from bluesky_gym.envs.registry import multiagent_entries


def centralised_ids() -> list[str]:
    """Gymnasium ids of the centralised multi-agent environments, in table order."""
    return [m.centralised_id for m in multiagent_entries() if m.centralised_id is not None]


def register_envs() -> None:
    """Register the centralised ids with Gymnasium (idempotent), without a Gymnasium time limit (the task owns it)."""
    for m in multiagent_entries():
        if m.centralised_id is not None and m.centralised_id not in gym.registry:
            gym.register(id=m.centralised_id, entry_point=m.centralised_env, max_episode_steps=None)
