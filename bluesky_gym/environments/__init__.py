"""The environments, one folder each: everything that is one environment's lives in its folder.

A folder holds one file per role, each ranked with the generic layer it extends (the layering
test, ``tests/test_layering.py``, checks that a file only imports from its own rank and below):

* ``task.py``: the batched task (the MDP), on :mod:`bluesky_gym.tasks.base` (tasks layer);
* ``scene.py``: the render scene builder, on :mod:`bluesky_gym.render` (render layer);
* ``env.py``: the Gymnasium environment classes, on :mod:`bluesky_gym.envs.shell` (envs layer);
* ``multiagent.py``: the multi-agent task, its centralised environment and its picture, on
  :mod:`bluesky_gym.multiagent.base` (multiagent layer);
* ``parallel.py``: the PettingZoo environment, on :mod:`bluesky_gym.multiagent.parallel`
  (multiagent layer);
* ``controller.py``: the classical controller and the MVP mapping (the reference policies), on
  :mod:`bluesky_gym.training.policies` (training layer).

The environment table (:mod:`bluesky_gym.envs.registry`) names these modules, one row per
environment; adding an environment is adding a folder and a row.
"""
