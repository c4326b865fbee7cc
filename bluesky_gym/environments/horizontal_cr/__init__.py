"""HorizontalCREnv: its task, environment, scene and reference policies (see :mod:`bluesky_gym.environments`)."""
