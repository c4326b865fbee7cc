"""Wrappers for single and natively batched BlueSky-Gym environments."""

from bluesky_gym.wrappers.noise import NoisyObservationWrapper, VectorNoisyObservationWrapper
from bluesky_gym.wrappers.wind import MAX_WIND, VectorWindFieldWrapper, Wind, WindFieldWrapper

__all__ = ["MAX_WIND", "NoisyObservationWrapper", "VectorNoisyObservationWrapper", "VectorWindFieldWrapper", "Wind", "WindFieldWrapper"]
