"""Registration of every environment id with Gymnasium."""

from __future__ import annotations

import gymnasium as gym

# id -> (module, class, max_episode_steps)
ENVIRONMENTS: dict[str, tuple[str, str, int]] = {
    "DescentEnv-v0": ("descent_env", "DescentEnv", 300),
    "VerticalCREnv-v0": ("vertical_cr_env", "VerticalCREnv", 300),
    "PlanWaypointEnv-v0": ("plan_waypoint_env", "PlanWaypointEnv", 300),
    "HorizontalCREnv-v0": ("horizontal_cr_env", "HorizontalCREnv", 300),
    "SectorCREnv-v0": ("sector_cr_env", "SectorCREnv", 200),
    "StaticObstacleEnv-v0": ("static_obstacle_env", "StaticObstacleEnv", 100),
    "MergeEnv-v0": ("merge_env", "MergeEnv", 50),
}


def available_envs() -> list[str]:
    """Ids whose implementation module is present."""
    import importlib.util

    return [i for i, (mod, _, _) in ENVIRONMENTS.items() if importlib.util.find_spec(f"bluesky_gym.envs.{mod}") is not None]


def register_envs() -> None:
    """Register every BlueSky-Gym id with Gymnasium (idempotent).

    The seven paper environments, and the centralised multi-agent environments
    (``SectorCRCentralised-v0``, ``MergeCentralised-v0``, ``HorizontalCRCentralised-v0``).
    """
    from bluesky_gym.multiagent.registration import register_envs as register_centralised

    register_centralised()
    for env_id in available_envs():
        module, cls, steps = ENVIRONMENTS[env_id]
        if env_id in gym.registry:
            continue
        gym.register(
            id=env_id,
            entry_point=f"bluesky_gym.envs.{module}:{cls}",
            vector_entry_point=f"bluesky_gym.envs.{module}:{cls.replace('Env', 'VectorEnv')}",
            max_episode_steps=steps,
        )
