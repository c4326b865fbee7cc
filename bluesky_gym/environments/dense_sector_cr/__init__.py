"""DenseSectorCREnv: its task, environment, scene and multi-agent form (see :mod:`bluesky_gym.environments`)."""
