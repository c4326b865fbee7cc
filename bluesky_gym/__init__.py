"""BlueSky-Gym: reinforcement-learning environments for air traffic applications.

``import bluesky_gym`` registers every environment id with Gymnasium; ``register_envs()`` does the
same and may be called again (it is idempotent), so the paper's code runs unchanged::

    import gymnasium as gym
    import bluesky_gym
    bluesky_gym.register_envs()
    env = gym.make("DescentEnv-v0")
"""

from bluesky_gym.envs.registry import ENVIRONMENTS
from bluesky_gym.registration import available_envs, register_envs

#: The package version, written only here (pyproject.toml reads it; see CHANGELOG.md).
__version__ = "1.1.0"
__all__ = ["ENVIRONMENTS", "available_envs", "register_envs", "__version__"]

register_envs()
