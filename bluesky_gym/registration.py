"""Registration of every environment id with Gymnasium, from the table in :mod:`bluesky_gym.envs.registry`."""

from __future__ import annotations

import warnings

import gymnasium as gym

from bluesky_gym.envs.registry import ENVIRONMENTS, env_ids


def available_envs() -> list[str]:
    """Ids of the single-agent environments whose implementation modules are present.

    An environment built from data that are prepared at first use (``RealTrafficCREnv-v0``) is
    listed whether its data are in place or not: making it needs none, its first reset prepares
    them (``EnvEntry.data_status`` says what is missing).
    """
    return env_ids()


def register_envs() -> None:
    """Register every BlueSky-Gym id with Gymnasium (idempotent).

    Every row of the environment table (with its native vector environment as vector entry
    point), and the centralised id of every multi-agent form that has one.

    The ids are registered without Gymnasium's time limit: each environment's task owns its limit
    (``gym.make(id, time_limit=N)`` and ``gym.make_vec(..., max_episode_steps=N)`` set it,
    ``env.spec.max_episode_steps`` reports it).
    """
    from bluesky_gym.multiagent.registration import register_envs as register_centralised

    # A -v0 id is the paper's MDP, kept in every release next to its -v1: Gymnasium's "is out of
    # date, consider upgrading" DeprecationWarning does not apply to it. Only that message, only
    # for these ids, is silenced.
    paper = "|".join(e.id[: -len("-v0")] for e in ENVIRONMENTS if e.id.endswith("-v0"))
    warnings.filterwarnings("ignore", message=rf".*The environment ({paper})-v0 is out of date", category=DeprecationWarning)
    for entry in ENVIRONMENTS:
        if entry.id not in gym.registry and entry.is_available():
            # An id that configures its task (a -v1) passes itself, so that its errors name it.
            kwargs = {"env_id": entry.id, **dict(entry.options)} if entry.options else {}
            gym.register(id=entry.id, entry_point=entry.env, vector_entry_point=entry.vector_env, max_episode_steps=None, kwargs=kwargs)
    register_centralised()
