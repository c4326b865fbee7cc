"""The environment table is the one list of environments: registration, rendering and the multi-agent package read it."""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import pytest

import bluesky_gym
from bluesky_gym.envs import registry
from bluesky_gym.envs.shell import BlueSkyEnv, BlueSkyVectorEnv
from bluesky_gym.tasks.base import Task

from .expected_spaces import MAX_EPISODE_STEPS


def test_rows_resolve_to_consistent_classes() -> None:
    ids = [e.id for e in registry.ENVIRONMENTS]
    assert len(ids) == len(set(ids)) and set(ids) == set(MAX_EPISODE_STEPS)
    assert bluesky_gym.ENVIRONMENTS is registry.ENVIRONMENTS
    for e in registry.ENVIRONMENTS:
        task, env, venv = e.task_class(), e.env_class(), e.vector_env_class()
        assert issubclass(task, Task) and task.env_id == e.id.replace("-v1", "-v0")  # a -v1 row is its -v0 task, configured
        assert issubclass(env, BlueSkyEnv) and env.task_class is task
        assert issubclass(venv, BlueSkyVectorEnv) and venv.task_class is task
        assert callable(e.scene_builder())
        assert e.max_episode_steps == MAX_EPISODE_STEPS[e.id]
        with pytest.raises(dataclasses.FrozenInstanceError):
            e.id = "x"  # type: ignore[misc]


def test_gymnasium_registration_is_the_table() -> None:
    for e in registry.ENVIRONMENTS:
        spec = gym.spec(e.id)
        assert (spec.entry_point, spec.vector_entry_point, spec.max_episode_steps) == (e.env, e.vector_env, None)
    for m in registry.multiagent_entries():
        if m.centralised_id is None:  # the _v1 names have no centralised id
            assert m.name.endswith("_v1")
            continue
        spec = gym.spec(m.centralised_id)
        assert (spec.entry_point, spec.max_episode_steps) == (m.centralised_env, None)


def test_multiagent_forms() -> None:
    import bluesky_gym.multiagent as ma

    assert sorted(ma.names()) == [
        "dense_sector_cr_v0",
        "dense_sector_cr_v1",
        "horizontal_cr_v0",
        "horizontal_cr_v1",
        "merge_v0",
        "merge_v1",
        "sector_cr_v0",
        "sector_cr_v1",
    ]
    for m in registry.multiagent_entries():
        task = m.task_class()
        assert task.name == m.name.replace("_v1", "_v0") and ma.task_class(m.name) is task
        assert ma.make_task(m.name).name == m.name
        if m.centralised_id is not None:
            assert registry.multiagent_entry(m.centralised_id) is m
        assert registry.single_agent_entry(m.name).multiagent is m
        assert registry.single_agent_entry(m.name).id.endswith(m.name[-2:])
        assert registry.resolve(m.parallel_env).task_class is task
        assert registry.resolve(m.centralised_env).task_class is task
        assert callable(m.scene_builder())
    with pytest.raises(ValueError, match="unknown multi-agent environment"):
        registry.multiagent_entry("nope_v0")


def test_unknown_ids() -> None:
    with pytest.raises(ValueError, match="unknown environment 'Nope-v0'; available: DescentEnv-v0"):
        registry.entry("Nope-v0")
    assert registry.scene_builder("Nope-v0") is registry.resolve(registry.GENERIC_SCENE)
    with pytest.raises(ValueError, match="module:attribute"):
        registry.resolve("bluesky_gym.envs.registry")


def test_making_a_paper_v0_id_gives_no_out_of_date_warning() -> None:
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)
        bluesky_gym.register_envs()  # installs the filter for the paper's -v0 ids after the "error" one
        gym.make("DescentEnv-v0").close()


def test_rows_name_their_reference_policies_and_kpi_panels() -> None:
    from bluesky_gym.multiagent.policies import MVPMapping, Policy
    from bluesky_gym.tasks import REFERENCE_POLICIES
    from bluesky_gym.training.plotting import CURVE_METRICS

    for e in registry.ENVIRONMENTS:
        assert e.reference_policies[0] == "random" and set(e.reference_policies) <= set(REFERENCE_POLICIES)
        assert ("classical" in e.reference_policies) == (e.classical is not None)
        assert ("mvp" in e.reference_policies) == (e.mvp is not None)
        if e.classical is not None:
            assert isinstance(registry.resolve(e.classical)(), Policy)
        if e.mvp is not None:
            assert isinstance(registry.resolve(e.mvp), MVPMapping)
        known = {m for m, _ in CURVE_METRICS} | {registry.ALTITUDE_ERROR, "final_altitude", "waypoints_completed", "kpi_track_distance_km"}
        known |= {"kpi_extra_track_km", "crashed", "faf_reach", "kpi_los_per_flight_hour", "kpi_time_to_first_los_s", "kpi_fuel_kg"}
        assert all(metric in known and label for metric, label in e.kpis), e.id
    for row in registry.PAPER_ENVIRONMENTS:  # a -v1 row: its -v0 row with the -v1 configuration
        if row.v1 is not None:
            v1 = registry.entry(row.id.replace("-v0", "-v1"))
            assert (v1.classical, v1.mvp, v1.kpis, v1.scene) == (row.classical, row.mvp, row.kpis, row.scene)
            assert v1.options == (("float32_spaces", True), *row.v1)


def _string_keyed_tables(tree: object, keys: set[str]) -> list[int]:
    """Line numbers of dict literals with a key in ``keys``, and of comparisons and subscripts with such a string."""
    import ast

    assert isinstance(tree, ast.AST)
    lines = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Dict) and any(isinstance(k, ast.Constant) and k.value in keys for k in node.keys):
            lines.append(node.lineno)
        elif isinstance(node, ast.Subscript) and isinstance(node.slice, ast.Constant) and node.slice.value in keys:
            lines.append(node.lineno)
    return lines


def test_no_table_keyed_by_environment_outside_the_registry() -> None:
    """Every per-environment table is a field of the environment's row: no other module keys a dict by an id or multi-agent name."""
    import ast
    from pathlib import Path

    keys = {e.id for e in registry.ENVIRONMENTS} | {m.name for m in registry.multiagent_entries()}
    package = Path(registry.__file__).resolve().parents[1]
    # The run configuration addresses environments by id, as the config files users write do
    # (hyperparams.PAPER is configs/paper.toml): an experiment's setting, not the environment's.
    exempt = {package / "envs" / "registry.py", package / "training" / "hyperparams.py"}
    found = {}
    for path in sorted(package.rglob("*.py")):
        if path in exempt:
            continue
        lines = _string_keyed_tables(ast.parse(path.read_text(encoding="utf-8")), keys)
        if lines:
            found[str(path.relative_to(package))] = lines
    assert not found, f"tables keyed by environment outside the registry: {found}"


def test_the_table_check_finds_a_table() -> None:
    import ast

    tree = ast.parse('A = {"MergeEnv-v0": 1}\nB = c["sector_cr_v0"]\nC = {"other": 2}\n')
    assert _string_keyed_tables(tree, {"MergeEnv-v0", "sector_cr_v0"}) == [1, 2]
