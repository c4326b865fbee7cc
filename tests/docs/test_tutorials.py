"""The tutorials of the documentation site run: each page's python code blocks, in order, as one script.

Budgets are shrunk with the variable the tutorials document, ``BLUESKY_GYM_TUTORIAL_SCALE``.
"""

from __future__ import annotations

import re
import shlex
import sys
import types
from pathlib import Path

import gymnasium as gym
import pytest

DOCS = Path(__file__).resolve().parents[2] / "docs"
TUTORIALS = DOCS / "tutorials"
SCALE = "0.02"


def run_page(name: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> types.ModuleType:
    """Execute the page's python blocks as one module in a temporary directory; returns the module."""
    page = DOCS / name if (DOCS / name).is_file() else TUTORIALS / name
    blocks = re.findall(r"```python\n(.*?)```", page.read_text(encoding="utf-8"), flags=re.DOTALL)
    assert blocks, f"{page} has no python code"
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("BLUESKY_GYM_TUTORIAL_SCALE", SCALE)
    module = types.ModuleType(f"tutorial_{page.stem.replace('-', '_')}")
    module.__file__ = str(page)
    sys.modules[module.__name__] = module  # dataclasses resolve their annotations through sys.modules
    try:
        exec(compile("\n\n".join(blocks), str(page), "exec"), module.__dict__)  # noqa: S102 - the project's own document
    finally:
        del sys.modules[module.__name__]
    return module


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore:rich is experimental")
def test_train_ppo(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    pytest.importorskip("stable_baselines3", reason="the tutorial needs the 'train' extra")
    page = run_page("train-ppo.md", tmp_path, monkeypatch)
    assert (tmp_path / "ppo_descent.zip").is_file()
    assert page.model.num_timesteps >= page.total_timesteps
    assert len(page.trained.episodes) == len(page.random.episodes) == page.eval_episodes
    assert page.trained.policy == "PPO" and "PPO" in page.format_table([page.trained, page.random])


@pytest.mark.slow
def test_training_fast(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("stable_baselines3", reason="the page needs the 'train' extra")
    (tmp_path / "configs").symlink_to(DOCS.parent / "configs")  # the page runs from the repository's root
    page = run_page("training-fast.md", tmp_path, monkeypatch)
    assert page.result["trainer"] == "fast" and page.spec.n_envs == 16 and page.spec.hyperparams["n_steps"] == 128
    assert (tmp_path / "runs" / "descent-fast" / "model.zip").is_file()
    out = capsys.readouterr().out.split()
    assert out[0] == "fast" and int(out[1]) == page.result["timesteps"]
    assert int(out[-1]) == page.trainer.num_timesteps >= 2048


def test_own_environment(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    try:
        page = run_page("own-environment.md", tmp_path, monkeypatch)
        env = gym.make("SmoothHorizontalCR-v0")
        assert isinstance(env.unwrapped.task, page.SmoothHorizontalCRTask)
        env.reset(seed=0)
        info = env.step([1.0])[4]
        assert info["reward_turn"] == -0.05
        env = gym.make("ComfortDescent-v0")
        env.reset(seed=0)
        for _ in range(3):
            info = env.step([-1.0])[4]
        assert info["reward_comfort"] == -0.02 * (abs(env.unwrapped.task.sim.vs[0, 0]) - 5.0) < 0.0
    finally:
        gym.registry.pop("SmoothHorizontalCR-v0", None)
        gym.registry.pop("ComfortDescent-v0", None)


def test_evaluate(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    page = run_page("evaluate.md", tmp_path, monkeypatch)
    assert [len(r.episodes) for r in (page.random, page.classical, page.mine)] == [page.episodes] * 3
    assert page.classical.mean_return > page.random.mean_return
    assert page.mine.summary["los"]["n"] == page.episodes
    finite = page.finite
    assert finite.size == page.random.summary["time_to_goal_s"]["n"]


@pytest.mark.parametrize("name", ["index.md", "core.md"])
def test_the_snippets_of_a_page_run(name: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    page = run_page(name, tmp_path, monkeypatch)
    if name == "index.md":
        success, final_altitude = map(float, capsys.readouterr().out.split())  # the single episode ran to its end
        assert success in (0.0, 1.0) and final_altitude != 0.0
        assert page.reward.shape == (page.venv.num_envs,)
    else:
        assert page.sim.active[:, 0].all()


def test_the_commands_of_the_training_page_parse() -> None:
    from bluesky_gym.cli import build_parser

    page = (DOCS / "training-fast.md").read_text(encoding="utf-8")
    commands = [
        line for block in re.findall(r"```bash\n(.*?)```", page, flags=re.DOTALL) for line in block.splitlines() if line.startswith("bluesky-gym ")
    ]
    assert len(commands) >= 4
    for line in commands:
        args = build_parser().parse_args(shlex.split(line)[1:])
        assert args.func is not None


def test_the_throughput_table_is_the_committed_measurement() -> None:
    import json

    from bluesky_gym.benchmarks.train_bench import format_table

    measured = json.loads((DOCS.parent / "results" / "bench" / "train-cpu.json").read_text(encoding="utf-8"))
    page = (DOCS / "training-fast.md").read_text(encoding="utf-8")
    assert "bluesky-gym bench train --repeat 3 --json results/bench/train-cpu.json" in page
    assert format_table(measured["train"]) in page


def test_the_library_table_is_the_committed_measurement() -> None:
    import json

    rows = json.loads((DOCS.parent / "benchmarks" / "libraries" / "measured" / "results.json").read_text())["rows"]
    measured = {(r["candidate"], r["setting"]): r for r in rows}
    page = (DOCS / "training-fast.md").read_text(encoding="utf-8")
    names = {
        "sb3": "SB3 2.9.2",
        "torchrl": "TorchRL",
        "skrl": "skrl",
        "rl_games": "rl_games",
        "pufferlib": "PufferLib",
        "sbx": "SBX",
        "bluesky-gym fast": "**the fast trainer**",
    }
    for candidate, label in names.items():
        row = next(line for line in page.splitlines() if line.startswith(f"| {label}"))
        cells = [c.strip() for c in row.strip("|").split("|")]
        for k, setting in enumerate("ABC", start=1):
            r = measured.get((candidate, setting))
            expected = f"{r['sps']:,.0f}" if r and r.get("sps") else "–"
            assert cells[k] == expected, (candidate, setting, cells[k], expected)
        ratios = [measured.get((candidate, s), {}).get("cpu_ratio_to_sb3") for s in "ABC"]
        assert cells[4] == " / ".join("1" if candidate == "sb3" else "–" if x is None else f"{x:.2f}" for x in ratios), (candidate, cells[4])


def test_the_parity_claim_is_what_the_generated_parity_page_shows() -> None:
    page = (DOCS / "training-fast.md").read_text(encoding="utf-8")
    claim = "On all three environments the fast trainer's mean held-out return lies\nwithin the 95% interval of SB3's"
    assert claim in page and "(results-parity.md)" in page
    results = (DOCS / "results-parity.md").read_text(encoding="utf-8")
    assert "bluesky-gym results results/parity/fast results/parity/sb3 --out docs/results-parity.md" in results
    table = results.split("## Trainers compared")[1].split("\n## ")[0]
    rows = [line for line in table.splitlines() if line.startswith("| ") and "-v" in line]
    assert {row.split(" | ")[0].lstrip("| ") for row in rows} == {"DescentEnv-v0", "HorizontalCREnv-v0", "SectorCREnv-v0"}
    assert all(row.rstrip().endswith("| yes |") for row in rows), rows
