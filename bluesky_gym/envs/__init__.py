"""Gymnasium environments (thin shells around :mod:`bluesky_gym.tasks`)."""
