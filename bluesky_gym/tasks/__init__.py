"""The batched tasks' shared code: the step pipeline (:mod:`bluesky_gym.tasks.base`), geometry and kernels.

Each task lives in its environment's folder (``bluesky_gym.environments.<name>.task``).
"""

#: The reference policies a task is scored against, in table order: uniform random actions, the
#: task's hand-written classical controller, and BlueSky's MVP conflict resolution where the task
#: has traffic. Each environment's registry row (:class:`bluesky_gym.envs.registry.EnvEntry`)
#: names its own controller and MVP mapping; this tuple is the one spelling of the names.
REFERENCE_POLICIES: tuple[str, ...] = ("random", "classical", "mvp")
#: Reference policies that can be selected (``eval``, ``sweep --references``) but are not scored
#: by default: the ``mvp`` policy's mapping flying another of BlueSky's resolution methods, by its
#: ``RESO`` name, where the task has ``mvp``. The results pages score them beside ``mvp``.
RESOLUTION_REFERENCES: dict[str, str] = {"eby": "EBY", "swarm": "SWARM", "ssd": "SSD"}
