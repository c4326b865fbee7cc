"""MkDocs hook: the pages generated from the code.

* one page per environment of :data:`bluesky_gym.envs.registry.ENVIRONMENTS`, made from the
  environment class's docstring (observation table, actions, rewards, episode end, KPIs, options,
  version history), its GIF, the scenario options with their defaults and a vectorised-usage
  snippet, and an overview table of them all; the navigation lists every row of the table;
* the command-line reference, the ``--help`` of every ``bluesky-gym`` subcommand, formatted by
  the argument parsers themselves.

Nothing here is copied by hand: a docstring or an option changes, the page changes.
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import importlib
import inspect
import os
import re
import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))  # document this checkout

ENV_DIR = "environments"
GIF_DIR = Path(__file__).resolve().parent / "gifs"
NAV_SECTION = "Environments"
HELP_WIDTH = "100"  # columns of the generated --help texts

AVERAGING_NOTE = """\
!!! note "Averaging KPIs"
    Some KPIs are not finite by design (the table above says which and when): the minimum
    separation of an episode without other aircraft is `inf`, the time to goal of an episode that
    did not reach its goal is `NaN`, and so is the mean drift of a task without a heading goal. A
    plain `np.mean` over episodes then gives `inf` or `NaN`. Average the finite values
    (`np.mean(x[np.isfinite(x)])`, or `np.nanmean` where only NaN occurs) and report how many
    episodes they came from. `bluesky-gym eval` and the KPI tables do exactly that: every column's
    mean, 95% half-width and count are over the finite values, so the time to goal is the mean
    over successful episodes, and the loss-of-separation count is left out for episodes without
    traffic.
"""


def env_ids() -> list[str]:
    """Ids of the environment table, in its order."""
    from bluesky_gym.envs.registry import env_ids as table_ids

    return list(table_ids())


def vector_snippet(env_id: str) -> str:
    """Python code that runs ``env_id`` as a natively batched environment."""
    return f"""\
import gymnasium as gym
import bluesky_gym  # registers the ids

venv = gym.make_vec("{env_id}", num_envs=64, vectorization_mode="vector_entry_point")
obs, info = venv.reset(seed=0)  # episode i is seeded with 0 + i
for _ in range(10):
    obs, reward, terminated, truncated, info = venv.step(venv.action_space.sample())
# Episodes that end restart within the same step; their last observation and info (with the
# kpi_* keys) are in info["final_obs"] and info["final_info"].
venv.close()
"""


def _cell(value: Any, code: bool = False) -> str:
    """``value`` as the text of a table cell (in a code span if ``code``)."""
    text = str(value).replace("|", "\\|").replace("\n", " ")
    if code:
        return f"`{text}`"
    return text.replace("[", "\\[") if text else " "


_LIST_ITEM = re.compile(r"^\s*(?:\d+\.|[*-]) ")


def separate_lists(text: str) -> str:
    """Put a blank line before every list that directly follows a paragraph line.

    Docstrings and the pages written for GitHub start lists on the line after their introduction,
    which Python-Markdown would read as one paragraph. Fenced code is left alone.
    """
    out: list[str] = []
    in_list = in_fence = False
    for line in text.split("\n"):
        if line.lstrip().startswith("```"):
            in_fence = not in_fence
        elif in_fence:
            pass
        elif _LIST_ITEM.match(line):
            if not in_list and out and out[-1].strip() and not out[-1].lstrip().startswith("|"):
                out.append("")
            in_list = True
        elif not line.strip():
            in_list = False
        out.append(line)
    return "\n".join(out)


def with_averaging_note(body: str) -> str:
    """The docstring body with :data:`AVERAGING_NOTE` at the end of its KPIs section (or at the end)."""
    match = re.search(r"^## KPIs\n.*?(?=^## |\Z)", body, flags=re.MULTILINE | re.DOTALL)
    end = match.end() if match else len(body)
    return f"{body[:end].rstrip()}\n\n{AVERAGING_NOTE}\n{body[end:]}"


def env_page(env_id: str) -> str:
    """The Markdown page of one environment."""
    from bluesky_gym.cli.catalog import describe
    from bluesky_gym.envs.registry import entry

    row = entry(env_id)
    cls = row.env_class()
    doc = inspect.getdoc(cls) or ""
    summary, _, body = doc.partition("\n")
    body = re.sub(r"^Animation:.*?(?:\n\n|\Z)", "", body.strip(), flags=re.DOTALL | re.MULTILINE)
    facts = describe(env_id)
    out = [f"# {env_id}", "", summary.strip(), ""]
    if (GIF_DIR / f"{env_id}.gif").is_file():
        out += [f"![{env_id}, flown by the classical controller](../gifs/{env_id}.gif)", ""]
    obs = ", ".join(f"`{k}` {tuple(v['shape'])}" for k, v in facts["observation"].items())
    out += [
        "| property | value |",
        "|---|---|",
        f"| class | `{facts['class']}` |",
        f"| decision step | {facts['seconds_per_step']:g} s ({facts['substeps_per_action']} physics steps of {facts['dt_s']:g} s) |",
        f"| episode limit | {facts['max_episode_steps']} steps |",
        f"| observation | {obs} |",
        f"| action | `Box` {tuple(facts['action']['shape'])}, low {facts['action']['low']}, high {facts['action']['high']} |",
        "",
        with_averaging_note(body),
        "",
        "## Options",
        "",
        f'Keyword arguments of `gym.make("{env_id}", ...)` and `gym.make_vec`; a bad value is refused with an error naming the option.',
        "",
        "| option | type | default | meaning |",
        "|---|---|---|---|",
    ]
    for o in facts["options"]:
        out.append(f"| `{o['name']}` | {_cell(o['type'], code=True)} | {_cell(o['default'], code=True)} | {_cell(o['description'])} |")
    out += [
        "",
        "## Vectorised usage",
        "",
        "All episodes of a batch are stepped together with array operations in one process:",
        "",
        "```python",
        vector_snippet(env_id).rstrip(),
        "```",
        "",
    ]
    return "\n".join(out)


def overview_page() -> str:
    """The table of every environment."""
    from bluesky_gym.envs.registry import entry

    out = [
        "# Environments",
        "",
        "Every environment is a Gymnasium environment (`gym.make(id)`) and a natively batched one",
        '(`gym.make_vec(id, num_envs=N, vectorization_mode="vector_entry_point")`). Each page below is',
        "generated from the environment's docstring and its options.",
        "",
        "| id | task | decision step | episode limit |",
        "|---|---|---|---|",
    ]
    for env_id in env_ids():
        row = entry(env_id)
        task = row.task_class()
        summary = (inspect.getdoc(row.env_class()) or "").split("\n", 1)[0]
        out.append(f"| [{env_id}]({env_id}.md) | {_cell(summary)} | {task.dt * task.action_frequency:g} s | {row.max_episode_steps} steps |")
    out += ["", "The `-v0` ids are the paper's MDPs; [the -v0 contract](../environments-v0.md) specifies them.", ""]
    out += ["The `-v1` ids are the same tasks without the paper's MDP defects; [the -v1 changes](../environments-v1.md) lists them.", ""]
    return "\n".join(out)


@contextlib.contextmanager
def _columns(width: str) -> Iterator[None]:
    old = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = width
    try:
        yield
    finally:
        if old is None:
            del os.environ["COLUMNS"]
        else:
            os.environ["COLUMNS"] = old


def subcommand_parsers() -> dict[str, argparse.ArgumentParser]:
    """Every ``bluesky-gym`` subcommand's parser, by name, in the order of ``--help``."""
    from bluesky_gym.cli import SUBCOMMAND_MODULES
    from bluesky_gym.cli.arguments import Parser

    sub = Parser(prog="bluesky-gym").add_subparsers()
    for name in SUBCOMMAND_MODULES:
        importlib.import_module(f"bluesky_gym.cli.{name}").add_parser(sub)
    return dict(sub.choices)


def cli_page() -> str:
    """The command-line reference: every subcommand's ``--help``."""
    from bluesky_gym.cli import build_parser

    with _columns(HELP_WIDTH):
        top = build_parser().format_help()
        helps = {name: parser.format_help() for name, parser in subcommand_parsers().items()}
    out = [
        "# The bluesky-gym command",
        "",
        "Training, evaluation, sweeps, plots, videos and throughput benchmarks. Installed with the",
        "package; training and evaluation need the `train` extra, `sweep --address` the `distributed`",
        "extra. `python -m bluesky_gym` is the same command. This page is the `--help` of every",
        "subcommand, as the installed version prints it.",
        "",
        "```text",
        top.rstrip(),
        "```",
        "",
    ]
    for name, text in helps.items():
        out += [f"## bluesky-gym {name}", "", "```text", text.rstrip(), "```", ""]
    return "\n".join(out)


def on_config(config: Any) -> Any:
    """List every environment of the table in the navigation, after the section's first page."""
    for item in config["nav"]:
        if isinstance(item, dict) and NAV_SECTION in item:
            section = item[NAV_SECTION]
            section[1:1] = [{env_id: f"{ENV_DIR}/{env_id}.md"} for env_id in env_ids()]
    return config


def on_page_markdown(markdown: str, page: Any, config: Any, files: Any) -> str:
    """Every page: lists that follow a paragraph line directly are lists (:func:`separate_lists`)."""
    return separate_lists(markdown)


def generated_pages() -> dict[str, Callable[[], str]]:
    """The pages made from the code: path below ``docs/`` -> function returning its Markdown."""
    pages: dict[str, Callable[[], str]] = {f"{ENV_DIR}/index.md": overview_page}
    for env_id in env_ids():
        pages[f"{ENV_DIR}/{env_id}.md"] = functools.partial(env_page, env_id)
    pages["cli.md"] = cli_page
    return pages


def on_files(files: Any, config: Any) -> Any:
    """Add the generated pages."""
    from mkdocs.structure.files import File

    for path, make in generated_pages().items():
        files.append(File.generated(config, path, content=make()))
    return files
