"""The real-traffic tables of README.md and docs/realtraffic.md are what `bluesky-gym realtraffic report` makes from results/realtraffic."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from bluesky_gym.realtraffic.report import blocks_in, fill, render_blocks

ROOT = Path(__file__).resolve().parents[2]
RESULTS = ROOT / "results" / "realtraffic"
PAGES = {"README.md": {"fidelity"}, "docs/realtraffic.md": {"fidelity", "fidelity.vertical", "fidelity-a320", "stats"}}


@pytest.mark.parametrize("page", sorted(PAGES))
def test_page_tables_are_generated_from_the_committed_measurements(page: str) -> None:
    text = (ROOT / page).read_text(encoding="utf-8")
    assert PAGES[page] <= set(blocks_in(text)), f"{page} lacks blocks {PAGES[page] - set(blocks_in(text))}"
    regenerated = fill(text, render_blocks(RESULTS), page)
    assert regenerated == text, f"{page}: a realtraffic table differs from `bluesky-gym realtraffic report results/realtraffic` (edited by hand?)"


def test_a_hand_edited_number_is_caught() -> None:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    row = re.search(r"^\| switzerland \| 5 min \| .*$", text, flags=re.MULTILINE)
    assert row is not None
    edited = text.replace(row.group(0), row.group(0).replace(" | 0 | ", " | 7 | ", 1))
    assert edited != text
    assert fill(edited, render_blocks(RESULTS), "README.md") == text


def test_measurements_name_the_command_that_made_them() -> None:
    files = sorted(RESULTS.glob("*.json"))
    assert {f.name for f in files} >= {"fidelity.json", "fidelity-a320.json", "stats.json"}
    for f in files:
        doc = json.loads(f.read_text(encoding="utf-8"))
        words = doc["command"].split()
        assert words[:2] == ["bluesky-gym", "realtraffic"], f.name
        assert words[words.index("--json") + 1] == f"results/realtraffic/{f.name}", f.name
        assert not any(w.startswith(("/", "~")) for w in words), doc["command"]
        assert doc["version"] and doc["inputs"]["collections"]
