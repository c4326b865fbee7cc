"""The split between training and evaluation scenario seeds.

Every scenario of BlueSky-Gym is drawn from a generator seeded through ``reset(seed=...)``
(episode ``i`` of a vector environment reset with a list of seeds uses the ``i``-th). The
benchmark keeps two disjoint ranges:

* **training**: every seed given to a training environment is in ``[0, 2**31)``. The run seed
  ``S`` and the environment index ``i`` are mixed through :class:`numpy.random.SeedSequence`, so
  runs with neighbouring seeds do not share scenario streams; a resumed run gets fresh streams
  derived from the timesteps already done. Later episodes of a training environment continue its
  generator (they are not reseeded).
* **evaluation**: held-out episode ``j`` is the scenario of ``reset(seed=EVAL_SEED_BASE + j)``,
  ``EVAL_SEED_BASE = 2**31``, each from a fresh generator, never used in training. Evaluating
  ``N`` episodes always uses the same first ``N`` evaluation seeds, so every policy (trained,
  ``random``, ``classical``) is scored on the same scenarios.
"""

from __future__ import annotations

import numpy as np

TRAIN_SEED_LIMIT = 2**31
EVAL_SEED_BASE = 2**31
EVAL_SEED_LIMIT = 2**32
_TRAIN_TAG = 0x5EED_7A1


def train_env_seeds(seed: int, n_envs: int, stream: int = 0) -> list[int]:
    """Scenario seeds of the ``n_envs`` training environments of run seed ``seed``.

    Args:
        seed: The run's seed (any non-negative integer).
        n_envs: Number of environments.
        stream: Distinguishes restarts of the same run (e.g. the timesteps done at a resume).

    Returns:
        ``n_envs`` distinct seeds in ``[0, 2**31)``.

    """
    if seed < 0 or stream < 0:
        raise ValueError(f"seed and stream must be non-negative, got {seed}, {stream}")
    state = np.random.SeedSequence([_TRAIN_TAG, int(seed), int(stream)]).generate_state(n_envs, dtype=np.uint64)
    seeds = [int(s % TRAIN_SEED_LIMIT) for s in state]
    # Collisions are astronomically unlikely; make the environments distinct regardless.
    seen: set[int] = set()
    for i, s in enumerate(seeds):
        while s in seen:
            s = (s + 1) % TRAIN_SEED_LIMIT
        seen.add(s)
        seeds[i] = s
    return seeds


def eval_seeds(episodes: int, offset: int = 0) -> list[int]:
    """Return the held-out evaluation seeds of episodes ``offset .. offset + episodes - 1``."""
    if episodes < 1 or offset < 0:
        raise ValueError(f"episodes must be >= 1 and offset >= 0, got {episodes}, {offset}")
    if EVAL_SEED_BASE + offset + episodes > EVAL_SEED_LIMIT:
        raise ValueError("evaluation seeds beyond 2**32 are not available")
    return [EVAL_SEED_BASE + offset + j for j in range(episodes)]


def is_eval_seed(seed: int) -> bool:
    """Whether ``seed`` belongs to the held-out evaluation range."""
    return EVAL_SEED_BASE <= seed < EVAL_SEED_LIMIT
