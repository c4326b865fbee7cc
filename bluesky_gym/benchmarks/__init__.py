"""Throughput benchmarks behind ``bluesky-gym bench``.

* :mod:`~bluesky_gym.benchmarks.core_bench`: aircraft-sub-steps per second of the native core
  (per batch size and kernel) and of the real BlueSky;
* :mod:`~bluesky_gym.benchmarks.env_bench`: environment steps per second, single and batched, of
  the BlueSky backend and of the reference bluesky-gym 0.2.0;
* :mod:`~bluesky_gym.benchmarks.profiling`: where the core's step time goes;
* :mod:`~bluesky_gym.benchmarks.timing` and :mod:`~bluesky_gym.benchmarks.worker`: the
  measurement loop and the script that measures in another interpreter
  (:mod:`~bluesky_gym.benchmarks.external` runs it).

Nothing here asserts a speed: targets are printed next to the figures.
"""

from bluesky_gym.benchmarks.core_bench import run_core
from bluesky_gym.benchmarks.env_bench import run_envs
from bluesky_gym.benchmarks.profiling import profile_core

__all__ = ["profile_core", "run_core", "run_envs"]
