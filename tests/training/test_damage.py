"""Damaged run directories are detected and named; the run resumes from the last intact checkpoint or starts over, never a mixture."""

from __future__ import annotations

import json
import shutil
from collections.abc import Callable
from pathlib import Path

import pytest

pytest.importorskip("stable_baselines3", reason="needs Stable-Baselines3 (the 'train' extra)")

from stable_baselines3.common.callbacks import BaseCallback

from bluesky_gym.cli import main
from bluesky_gym.training.evaluation import reference_returns, reference_scores
from bluesky_gym.training.hyperparams import PAPER, merge
from bluesky_gym.training.io import file_damage, latest_checkpoint, read_json
from bluesky_gym.training.runner import RunDamaged, inspect_run, make_run_spec, run_training

from .conftest import csv_rows

ENV = "DescentEnv-v0"
# One gradient step per 8 vector steps: what is tested is the bookkeeping, not the learning.
CONFIG = {
    "run": {"n_envs": 2, "total_timesteps": 300, "checkpoint_freq": 100, "eval_episodes": 0},
    "algos": {"SAC": {"buffer_size": 1000, "learning_starts": 32, "batch_size": 16, "train_freq": 8, "gradient_steps": 1}},
}
SPEC = make_run_spec(merge(PAPER, CONFIG), ENV, "SAC", 0)


class StopAfter(BaseCallback):
    """Stands for a crash: raise once ``steps`` are done."""

    def __init__(self, steps: int) -> None:
        super().__init__()
        self.steps = steps

    def _on_step(self) -> bool:
        if self.model.num_timesteps >= self.steps:
            raise KeyboardInterrupt
        return True


@pytest.fixture(scope="module")
def killed_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A SAC run killed at 250 of 300 steps, with checkpoints at about 100 and 200 steps and episodes logged after them."""
    d = tmp_path_factory.mktemp("killed") / "run"
    with pytest.raises(KeyboardInterrupt):
        run_training(SPEC, d, verbose=0, tensorboard=False, callbacks=[StopAfter(250)])
    record, _ = latest_checkpoint(d)
    assert record["previous"] is not None and record["episodes_logged"] > record["previous"]["episodes_logged"] > 0
    assert not inspect_run(d).problems
    return d


def _train(run_dir: Path, tiny_config: Path, *flags: str) -> int:
    """``bluesky-gym train`` of the run in ``run_dir`` (``<out>/<env>/SAC/seed_0``)."""
    out = run_dir.parents[2]
    return main(
        ["train", "--env", ENV, "--algo", "SAC", "--out", str(out), "--config", str(tiny_config), "--no-progress", "--no-tensorboard", *flags]
    )


@pytest.fixture
def tiny_config(tmp_path: Path) -> Path:
    path = tmp_path / "tiny.json"
    path.write_text(json.dumps(CONFIG))
    return path


def _latest(d: Path) -> Path:
    return d / read_json(d / "checkpoint.json")["dir"]


def _truncate(path: Path) -> None:
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])


def _edit_json(path: Path, **changes: object) -> None:
    path.write_text(json.dumps({**read_json(path), **changes}))


def _bump_timesteps(d: Path) -> None:
    """Edit the latest checkpoint's step count in ``checkpoint.json`` (its files untouched)."""
    _edit_json(d / "checkpoint.json", timesteps=read_json(d / "checkpoint.json")["timesteps"] + 1000)


#: name -> (how to damage, words the message must hold, the checkpoint the run resumes from: "latest", "previous" or None).
DAMAGE: dict[str, tuple[Callable[[Path], None], str, str | None]] = {
    "checkpoint.json names a missing directory": (
        lambda d: _edit_json(d / "checkpoint.json", dir="checkpoints/step_000000099999"),
        "which is missing",
        "previous",
    ),
    "checkpoint model.zip deleted": (lambda d: (_latest(d) / "model.zip").unlink(), "model.zip is missing", "previous"),
    "checkpoint model.zip truncated": (lambda d: _truncate(_latest(d) / "model.zip"), "model.zip has", "previous"),
    "replay buffer truncated": (lambda d: _truncate(_latest(d) / "replay_buffer.pkl"), "replay_buffer.pkl has", "previous"),
    "episodes.csv deleted": (lambda d: (d / "episodes.csv").unlink(), "episodes.csv is missing", None),
    "episodes.csv truncated": (lambda d: _truncate(d / "episodes.csv"), "episodes.csv has", "previous"),
    "checkpoint.json timesteps edited": (_bump_timesteps, "model.zip holds", "previous"),
    # Without checkpoint.json the checkpoints on disk are checked by their own files.
    "checkpoint.json bad JSON": (lambda d: _truncate(d / "checkpoint.json"), "checkpoint.json is not valid JSON", "latest"),
    "checkpoint.json deleted": (lambda d: (d / "checkpoint.json").unlink(), "checkpoint.json is missing", "latest"),
    "checkpoint.json bad JSON, latest model.zip truncated": (
        lambda d: (_truncate(_latest(d) / "model.zip"), _truncate(d / "checkpoint.json")),
        "checkpoint.json is not valid JSON",
        "previous",
    ),
    "checkpoint.json bad JSON, latest replay buffer truncated": (
        lambda d: (_truncate(_latest(d) / "replay_buffer.pkl"), _truncate(d / "checkpoint.json")),
        "checkpoint.json is not valid JSON",
        "previous",
    ),
    "checkpoint.json bad JSON, episodes.csv truncated": (
        lambda d: (_truncate(d / "checkpoint.json"), (d / "episodes.csv").write_text(_head(d / "episodes.csv", 1))),
        "checkpoint.json is not valid JSON",
        None,
    ),
}


def _head(path: Path, rows: int) -> str:
    """The header and the first ``rows`` rows of a CSV file."""
    return "".join(path.read_text().splitlines(keepends=True)[: rows + 1])


@pytest.mark.parametrize("damage", sorted(DAMAGE))
def test_damage_is_named_and_the_run_resumes_from_the_last_intact_checkpoint_or_restarts(
    damage: str, killed_run: Path, tmp_path: Path, tiny_config: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    harm, words, resumes_from = DAMAGE[damage]
    original = csv_rows(killed_run / "episodes.csv")[1:]
    latest = read_json(killed_run / "checkpoint.json")
    intact = {"latest": latest, "previous": latest["previous"], None: None}[resumes_from]
    run_dir = tmp_path / "out" / ENV / "SAC" / "seed_0"
    shutil.copytree(killed_run, run_dir)
    harm(run_dir)
    if damage == "episodes.csv truncated":
        # cut below the previous checkpoint's rows too: nothing is left to resume from
        _truncate(run_dir / "episodes.csv")
        if len(csv_rows(run_dir / "episodes.csv")[1:]) < latest["previous"]["episodes_logged"]:
            intact = None
    resumable = intact is not None
    before = {p: p.stat().st_mtime_ns for p in run_dir.rglob("*") if p.is_file()}

    # Named, refused, nothing changed.
    assert _train(run_dir, tiny_config) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and words in err and "damaged" in err and "--restart" in err
    assert {p: p.stat().st_mtime_ns for p in run_dir.rglob("*") if p.is_file()} == before

    flag = "--resume-from-last-intact" if resumable else "--restart"
    if not resumable:
        assert _train(run_dir, tiny_config, "--resume-from-last-intact") == 2
        assert "no intact checkpoint" in capsys.readouterr().err
    assert _train(run_dir, tiny_config, flag) == 0
    out = capsys.readouterr().out
    assert "damaged" in out and str(run_dir) in out
    result = read_json(run_dir / "result.json")
    rows = csv_rows(run_dir / "episodes.csv")[1:]
    assert [int(r[0]) for r in rows] == list(range(len(rows))) == list(range(result["episodes"]))  # none lost, none twice
    assert [int(r[1]) for r in rows] == sorted(int(r[1]) for r in rows) and result["timesteps"] >= SPEC.total_timesteps
    repair = read_json(run_dir / "run.json")["processes"][-1]["repair"]
    assert any(words in p for p in repair["damage"])
    if intact is not None:
        assert f"at {intact['timesteps']} steps" in err
        assert result["resumed_from"] == intact["timesteps"]
        kept = intact["episodes_logged"]
        assert rows[:kept] == original[:kept]  # the intact part of the log, untouched
        assert all(int(r[1]) > intact["timesteps"] for r in rows[kept:])
    else:
        assert result["resumed_from"] is None and repair["action"] == "started over"
    assert not inspect_run(run_dir).problems


def test_damaged_final_files_are_detected(killed_run: Path, tmp_path: Path) -> None:
    d = tmp_path / "run"
    shutil.copytree(killed_run, d)
    done = run_training(SPEC, d, verbose=0, tensorboard=False)["timesteps"]
    assert done >= SPEC.total_timesteps
    assert file_damage(d / "model.zip", read_json(d / "result.json")["files"]["model.zip"]) is None
    _truncate(d / "model.zip")
    with pytest.raises(RunDamaged, match="final model: .*model.zip has"):
        run_training(SPEC, d, verbose=0, tensorboard=False)
    (d / "result.json").write_text('{"status": "finished",\n  "timesteps": 4')
    with pytest.raises(RunDamaged, match=r"result.json is not valid JSON \(.* line 2 column"):
        run_training(SPEC, d, verbose=0, tensorboard=False)
    result = run_training(SPEC, d, verbose=0, tensorboard=False, on_damage="resume")  # the final checkpoint is intact
    assert result["timesteps"] == done and result["resumed_from"] == done and not inspect_run(d).problems
    # Without checkpoint.json the final checkpoint is found on disk: result.json counts the episodes it includes.
    _truncate(d / "checkpoint.json")
    assert [c["timesteps"] for c in inspect_run(d).intact] == [done]
    result = run_training(SPEC, d, verbose=0, tensorboard=False, on_damage="resume")
    assert result["timesteps"] == done and result["resumed_from"] == done and not inspect_run(d).problems


def test_a_truncated_reference_cache_is_named_and_computed_again(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    first = reference_scores(ENV, 2, tmp_path)
    cache = tmp_path / f"{ENV}.json"
    _truncate(cache)
    again = reference_scores(ENV, 2, tmp_path)
    assert str(cache) in capsys.readouterr().err
    assert reference_returns(again) == reference_returns(first) and read_json(cache)["episodes"] == 2


def test_a_sweep_names_a_damaged_run_and_takes_the_same_choice(
    killed_run: Path, tmp_path: Path, tiny_config: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "sweep"
    run_dir = out / ENV / "SAC" / "seed_0"
    shutil.copytree(killed_run, run_dir)
    (_latest(run_dir) / "model.zip").unlink()
    sweep = ["sweep", "--env", ENV, "--algos", "SAC", "--out", str(out), "--config", str(tiny_config), "--local", "--quiet"]
    assert main(sweep) == 1  # a run failed
    summary = read_json(out / "sweep.json")["runs"]
    assert summary[0]["status"] == "failed" and "model.zip is missing" in summary[0]["error"]
    assert not (run_dir / "result.json").exists()
    assert main([*sweep, "--resume-from-last-intact"]) == 0
    capsys.readouterr()
    assert read_json(run_dir / "result.json")["resumed_from"] == read_json(killed_run / "checkpoint.json")["previous"]["timesteps"]


def test_without_checkpoint_json_a_fast_run_resumes_from_its_checkpoints_on_disk(tmp_path: Path) -> None:
    from bluesky_gym.training.fast.offpolicy import REPLAY_FILE

    spec = make_run_spec(merge(PAPER, {**CONFIG, "run": {**CONFIG["run"], "trainer": "fast"}}), ENV, "SAC", 0)
    d = tmp_path / "run"

    class Crash:
        """Fast-trainer hooks that stand for a crash at 250 steps."""

        def on_rollout_start(self, trainer: object) -> None:
            pass

        def on_episodes(self, trainer: object, records: list[dict[str, object]]) -> None:
            if trainer.num_timesteps >= 250:  # type: ignore[attr-defined]
                raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_training(spec, d, verbose=0, tensorboard=False, callbacks=[Crash()])
    latest = read_json(d / "checkpoint.json")
    previous = latest["previous"]
    assert set(latest["files"]) == {"model.zip", "trainer.pt", REPLAY_FILE}
    _truncate(d / "checkpoint.json")
    found = inspect_run(d).intact
    assert [c["timesteps"] for c in found][:1] == [latest["timesteps"]] and found[0]["episodes_logged"] == latest["episodes_logged"]
    assert found[0]["files"] == latest["files"]  # the very files checkpoint.json recorded
    (d / latest["dir"] / "trainer.pt").unlink()  # the latest is incomplete: the one before is resumed
    assert [c["timesteps"] for c in inspect_run(d).intact] == [previous["timesteps"]]
    result = run_training(spec, d, verbose=0, tensorboard=False, on_damage="resume")
    assert result["resumed_from"] == previous["timesteps"] and result["timesteps"] >= spec.total_timesteps
    assert not inspect_run(d).problems
