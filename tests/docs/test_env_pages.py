"""The generated pages of the documentation site (docs/hooks.py) and the KPI sections of the environment docstrings."""

from __future__ import annotations

import dataclasses
import importlib.util
import inspect
import re
import sys
import types
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import bluesky_gym  # noqa: F401 - registers the ids
from bluesky_gym.envs.registry import entry, env_ids

HOOKS = Path(__file__).resolve().parents[2] / "docs" / "hooks.py"


@pytest.fixture(scope="module")
def hooks() -> types.ModuleType:
    spec = importlib.util.spec_from_file_location("docs_hooks", HOOKS)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["docs_hooks"] = module
    try:
        spec.loader.exec_module(module)
        yield module
    finally:
        del sys.modules["docs_hooks"]


def kpi_rows(env_id: str) -> dict[str, str]:
    """The rows of the ``## KPIs`` table of the environment's docstring, by key."""
    doc = inspect.getdoc(entry(env_id).env_class()) or ""
    match = re.search(r"^## KPIs\n(.*?)(?=^## |\Z)", doc, flags=re.MULTILINE | re.DOTALL)
    assert match, f"{env_id}: the docstring has no '## KPIs' section"
    return {m.group(1): m.group(0) for m in re.finditer(r"^\| `(kpi_\w+)` \|.*$", match.group(1), flags=re.MULTILINE)}


def last_info(env_id: str, steps: int) -> dict[str, float]:
    """The info of the last step of a short episode (the limit ends it), random actions."""
    env = gym.make(env_id, time_limit=steps)
    env.reset(seed=0)
    env.action_space.seed(0)
    for _ in range(steps):
        _, _, terminated, truncated, info = env.step(env.action_space.sample())
        if terminated or truncated:
            break
    env.close()
    assert terminated or truncated
    return {k: float(v) for k, v in info.items() if k.startswith("kpi_")}


@pytest.mark.parametrize("env_id", env_ids())
def test_the_docstring_documents_every_kpi_the_env_emits(env_id: str) -> None:
    """Every ``kpi_*`` key of an episode's end has a row (and no row names a key that is not emitted);
    a key that is not finite in this short episode says so (``inf`` / ``NaN``) in its row."""
    rows = kpi_rows(env_id)
    kpis = last_info(env_id, 3)
    assert set(rows) == set(kpis), f"{env_id}: documented {sorted(rows)}, emitted {sorted(kpis)}"
    for key, value in kpis.items():
        if np.isnan(value):
            assert "NaN" in rows[key], f"{env_id}: {key} is NaN here; its row does not say when: {rows[key]}"
        elif np.isinf(value):
            assert "inf" in rows[key], f"{env_id}: {key} is inf here; its row does not say when: {rows[key]}"


@pytest.mark.parametrize("env_id", env_ids())
def test_the_environment_page_is_made_from_the_docstring_and_the_options(hooks: types.ModuleType, env_id: str) -> None:
    page = hooks.env_page(env_id)
    doc = inspect.getdoc(entry(env_id).env_class()) or ""
    assert page.startswith(f"# {env_id}\n\n{doc.splitlines()[0]}")
    for heading in ("Observation Space", "Action Space", "Rewards", "Episode End", "KPIs", "Version History", "Options", "Vectorised usage"):
        assert f"\n## {heading}\n" in page, f"{env_id}: no section {heading}"
    for key in kpi_rows(env_id):
        assert f"| `{key}` |" in page
    assert "Averaging KPIs" in page
    assert "Animation:" not in page
    gif = HOOKS.parent / "gifs" / f"{env_id}.gif"
    assert gif.is_file() or not env_id.endswith("-v0"), f"the paper's {env_id} has no GIF in docs/gifs"
    assert (f"](../gifs/{env_id}.gif)" in page) == gif.is_file()
    config = entry(env_id).task_class().config_class()
    for field in dataclasses.fields(config):
        assert f"| `{field.name}` |" in page, f"{env_id}: option {field.name} missing"


def test_docstring_lists_are_separated_from_their_paragraph(hooks: types.ModuleType) -> None:
    text = "In order:\n1. one;\n  more\n2. two.\n\n| a |\n|---|\n* x\n\nafter\n* y\n\n```\nx = 1\n- 1\n```"
    assert hooks.separate_lists(text) == "In order:\n\n1. one;\n  more\n2. two.\n\n| a |\n|---|\n* x\n\nafter\n\n* y\n\n```\nx = 1\n- 1\n```"


@pytest.mark.parametrize("env_id", env_ids())
def test_the_vectorised_snippet_runs(hooks: types.ModuleType, env_id: str) -> None:
    code = hooks.vector_snippet(env_id)
    assert f'"{env_id}"' in code
    namespace: dict[str, object] = {}
    exec(compile(code, f"<{env_id} page>", "exec"), namespace)  # noqa: S102 - the project's own snippet
    info = namespace["info"]
    assert isinstance(info, dict) and namespace["obs"] is not None


def test_the_cli_page_shows_every_subcommand(hooks: types.ModuleType) -> None:
    from bluesky_gym.cli import build_parser

    parsers = hooks.subcommand_parsers()
    assert {"list", "info", "train", "eval", "plot", "sweep", "render", "bench"} <= set(parsers)
    page = hooks.cli_page()
    for name, parser in parsers.items():
        assert f"\n## bluesky-gym {name}\n" in page
        usage = parser.format_usage().split("\n")[0]
        assert usage.split()[1:3] == ["bluesky-gym", name]
    assert build_parser().prog in page


def test_the_averaging_note_follows_the_kpi_table(hooks: types.ModuleType) -> None:
    body = "## Info\ntext\n\n## KPIs\n| k |\n|---|\n\n## Arguments\nargs"
    out = hooks.with_averaging_note(body)
    assert out.index("## KPIs") < out.index("Averaging KPIs") < out.index("## Arguments")
    assert hooks.with_averaging_note("## Info\ntext").endswith(hooks.AVERAGING_NOTE + "\n")


def test_sphinx_roles_become_code_spans() -> None:
    spec = importlib.util.spec_from_file_location("docs_griffe_roles", HOOKS.parent / "griffe_roles.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    text = "See :class:`~bluesky_gym.core.Simulator`, :meth:`Task.step` and :mod:`bluesky_gym.tasks.compiled`."
    assert module.plain_roles(text) == "See `Simulator`, `Task.step` and `bluesky_gym.tasks.compiled`."
