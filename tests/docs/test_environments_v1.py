"""The code of docs/environments-v1.md runs, and its table names every -v1 configuration field the registry sets."""

from __future__ import annotations

import re
from pathlib import Path

from bluesky_gym.envs.registry import PAPER_ENVIRONMENTS

PAGE = Path(__file__).resolve().parents[2] / "docs" / "environments-v1.md"


def test_code_blocks_run() -> None:
    text = PAGE.read_text(encoding="utf-8")
    blocks = re.findall(r"```python\n(.*?)```", text, flags=re.DOTALL)
    assert blocks
    exec(compile("\n\n".join(blocks), str(PAGE), "exec"), {})  # noqa: S102 - the project's own document


def test_every_field_is_documented() -> None:
    text = PAGE.read_text(encoding="utf-8")
    fields = {"float32_spaces"} | {name for row in PAPER_ENVIRONMENTS for name, _ in row.v1 or ()}
    assert all(f"`{name}`" in text for name in fields)
