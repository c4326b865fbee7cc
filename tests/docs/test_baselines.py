"""docs/baselines.md runs as written: its python blocks, executed in order, resolve and evaluate."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np

PAGE = Path(__file__).resolve().parents[2] / "docs" / "baselines.md"


def test_baselines_page_code_runs(capsys: Any) -> None:
    blocks = re.findall(r"```python\n(.*?)```", PAGE.read_text(encoding="utf-8"), flags=re.DOTALL)
    assert len(blocks) == 3  # MVP, the mvp policy, SSD (tests/docs/test_ssd_page.py)
    scope: dict[str, Any] = {}
    exec(compile(blocks[0], str(PAGE), "exec"), scope)  # noqa: S102 - the project's own document
    res = scope["res"]
    turn = (res.trk[0] - scope["sim"].trk[0] + 180.0) % 360.0 - 180.0
    assert np.all(np.abs(turn) > 1.0) and np.sign(turn[0]) == np.sign(turn[1])
    assert capsys.readouterr().out.count("[") == 2
    exec(compile(blocks[1], str(PAGE), "exec"), scope)  # noqa: S102
    assert scope["policy"].name == "mvp" and scope["obs"]["x_r"].shape[0] == 8
