"""Batched simulation core reproducing BlueSky 1.1.1 (no Gymnasium, PettingZoo or pygame)."""

from bluesky_gym.core.physics import Physics
from bluesky_gym.core.simulator import Simulator
from bluesky_gym.core.wind import WindField

__all__ = ["Physics", "Simulator", "WindField"]
