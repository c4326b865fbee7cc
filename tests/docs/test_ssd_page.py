"""docs/baselines.md's SSD example (section 5) runs as written and shows what it says."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("pyclipper")

PAGE = Path(__file__).resolve().parents[2] / "docs" / "baselines.md"


def test_ssd_example_runs(capsys: Any) -> None:
    blocks = [b for b in re.findall(r"```python\n(.*?)```", PAGE.read_text(encoding="utf-8"), flags=re.DOTALL) if "bluesky_gym.core.ssd" in b]
    assert len(blocks) == 1
    scope: dict[str, Any] = {}
    exec(compile(blocks[0], str(PAGE), "exec"), scope)  # noqa: S102 - the project's own document
    res, sim = scope["res"], scope["sim"]
    turn = (res.trk[0] - sim.trk[0] + 180.0) % 360.0 - 180.0
    assert np.all(turn > 1.0)  # both turn right
    assert capsys.readouterr().out.count("[") == 2
