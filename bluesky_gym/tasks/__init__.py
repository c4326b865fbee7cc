"""The MDPs as batched tasks: one task per module, the step pipeline in :mod:`bluesky_gym.tasks.base`."""
