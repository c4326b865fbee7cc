"""Registration of the centralised multi-agent environments with Gymnasium.

Only Gymnasium is imported here, so ``bluesky_gym`` can call :func:`register_envs` at import time
without the optional multi-agent dependencies.
"""

from __future__ import annotations

import gymnasium as gym

# id -> (class in bluesky_gym.multiagent.centralised, max_episode_steps)
CENTRALISED_ENVIRONMENTS: dict[str, tuple[str, int]] = {
    "SectorCRCentralised-v0": ("SectorCRCentralisedEnv", 200),
    "MergeCentralised-v0": ("MergeCentralisedEnv", 50),
    "HorizontalCRCentralised-v0": ("HorizontalCRCentralisedEnv", 300),
}


def register_envs() -> None:
    """Register the centralised ids with Gymnasium (idempotent)."""
    for env_id, (cls, steps) in CENTRALISED_ENVIRONMENTS.items():
        if env_id in gym.registry:
            continue
        gym.register(id=env_id, entry_point=f"bluesky_gym.multiagent.centralised:{cls}", max_episode_steps=steps)
