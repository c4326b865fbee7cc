"""Every Python snippet of the README runs as written, in order, with small training budgets.

The snippets build on each other (the first makes ``env``, later ones use it), so they run in
one namespace, in the README's order, in a temporary directory. A snippet that trains writes its
budget on one line, ``budget = N``; this test replaces N by :data:`SMALL_BUDGET` and changes
nothing else, so what runs is what the README shows. A training snippet without such a line
fails the test.
"""

from __future__ import annotations

import re
import tempfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SMALL_BUDGET = 150
BUDGET_LINE = re.compile(r"^budget = [\d_]+", flags=re.MULTILINE)


def python_snippets(markdown: str) -> list[str]:
    """The fenced ``python`` blocks of a Markdown text, in order."""
    return re.findall(r"^```python\n(.*?)^```", markdown, flags=re.MULTILINE | re.DOTALL)


@pytest.mark.filterwarnings("ignore:rich is experimental")  # SB3's progress bar uses tqdm.rich
def test_readme_python_snippets_run_as_written(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    for module, extra in (("stable_baselines3", "train"), ("pettingzoo", "multiagent"), ("pygame", "render"), ("moviepy", "render")):
        pytest.importorskip(module, reason=f"the README snippets use the '{extra}' extra")
    import torch

    threads = torch.get_num_threads()
    monkeypatch.chdir(tmp_path)
    temp = tmp_path / "temp"  # the temporary directory the snippets see: they leave nothing there
    temp.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(temp))
    monkeypatch.delenv("SB3_LOGDIR", raising=False)
    snippets = python_snippets((ROOT / "README.md").read_text(encoding="utf-8"))
    assert len(snippets) >= 6
    namespace: dict[str, object] = {"__name__": "readme"}
    trained = 0
    try:
        for k, code in enumerate(snippets):
            if ".learn(" in code:
                assert BUDGET_LINE.search(code), f"README snippet {k + 1} trains without a `budget = N` line:\n{code}"
                assert "progress_bar=True" in code, f"README snippet {k + 1} trains silently"
                code = BUDGET_LINE.sub(f"budget = {SMALL_BUDGET}", code)
                trained += 1
            exec(compile(code, f"README.md python snippet {k + 1}", "exec"), namespace)  # noqa: S102 - runs the README's snippets
    finally:
        torch.set_num_threads(threads)
    assert trained >= 2
    assert namespace["model"].num_timesteps >= SMALL_BUDGET  # type: ignore[attr-defined]
    assert list((tmp_path / "videos").glob("*.mp4"))
    assert not list(temp.glob("SB3-*")), "a README snippet leaves Stable-Baselines3's log folder in the temporary directory"


def test_the_batched_ppo_snippet_updates_after_a_short_rollout() -> None:
    snippet = next(s for s in python_snippets((ROOT / "README.md").read_text(encoding="utf-8")) if "PPO(" in s)
    envs = int(re.search(r"num_envs=(\d+)", snippet).group(1))  # type: ignore[union-attr]
    n_steps = int(re.search(r"n_steps=(\d+)", snippet).group(1))  # type: ignore[union-attr]
    assert envs * n_steps <= 16_384  # steps collected before the first update
