"""Gymnasium shells around the tasks (:mod:`bluesky_gym.envs.shell`) and the table of environments.

Each environment's classes live in its folder (``bluesky_gym.environments.<name>.env``).
"""
