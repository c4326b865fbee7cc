"""Evaluation on held-out scenarios and the KPI table."""

from __future__ import annotations

import json
import math
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

from bluesky_gym.environments.descent.controller import DescentController
from bluesky_gym.envs.seeds import EVAL_SEED_BASE
from bluesky_gym.training.evaluation import (
    evaluate,
    format_table,
    load_result,
    make_policy,
    normalised_score,
    reference_scores,
    save_result,
    summarise,
)

from .conftest import needs_sb3

ENV = "DescentEnv-v0"


def test_batched_evaluation_equals_single_episodes() -> None:
    res = evaluate(ENV, DescentController(), 5, batch=2)  # chunks of 2, 2 and 1 episodes
    assert [e["seed"] for e in res.episodes] == list(range(EVAL_SEED_BASE, EVAL_SEED_BASE + 5))
    env = gym.make(ENV)
    ctrl = DescentController()
    for rec in res.episodes:
        obs, _ = env.reset(seed=rec["seed"])
        ret, n, done = 0.0, 0, False
        while not done:
            a = ctrl.act({k: v[None] for k, v in obs.items()})[0]
            obs, r, te, tr, info = env.step(a)
            ret += r
            n += 1
            done = te or tr
        assert rec["return"] == pytest.approx(ret, rel=1e-12)
        assert rec["length"] == n
        assert rec["kpi_success"] == info["kpi_success"] and rec["terminated"] is True
        assert rec["final_altitude"] == pytest.approx(info["final_altitude"])


def test_evaluation_is_deterministic_and_offsets_seeds() -> None:
    a = evaluate(ENV, make_policy("random", ENV), 6)
    b = evaluate(ENV, make_policy("random", ENV), 6)
    assert [e["return"] for e in a.episodes] == [e["return"] for e in b.episodes]
    c = evaluate(ENV, make_policy("classical", ENV), 3, seed_offset=3)
    d = evaluate(ENV, make_policy("classical", ENV), 6)
    assert [e["return"] for e in c.episodes] == [e["return"] for e in d.episodes[3:]]


def test_summary_table_and_files(tmp_path: Path) -> None:
    rand = evaluate(ENV, make_policy("random", ENV), 8)
    clas = evaluate(ENV, make_policy("classical", ENV), 8)
    s = clas.summary
    assert s["return"]["n"] == 8 and s["success"]["mean"] == 1.0
    assert s["los"]["n"] == 0 and s["min_sep_nm"]["n"] == 0  # no traffic in Descent
    assert s["time_to_goal_s"]["mean"] > 0
    table = format_table([rand, clas], {"random": rand.mean_return, "classical": clas.mean_return})
    assert "normalised" in table and "LoS" not in table and "time to goal" in table
    lines = table.splitlines()
    assert lines[2].startswith("random") and lines[2].rstrip().endswith("0.000")
    assert lines[3].startswith("classical") and lines[3].rstrip().endswith("1.000")
    save_result(clas, tmp_path, "eval_classical")
    again = load_result(tmp_path, "eval_classical")
    assert again.summary == clas.summary and len(again.episodes) == 8


def test_the_table_shows_an_environments_own_kpis_where_it_has_them() -> None:
    """DenseSectorCR's losses per flight-hour and time to the first loss are columns of its table, and of no other."""
    dense = "DenseSectorCREnv-v0"
    res = evaluate(dense, make_policy("random", dense), 4)
    assert res.summary["los_per_hour"]["n"] == 4 and res.summary["los_per_hour"]["mean"] >= 0.0
    first = [e["kpi_time_to_first_los_s"] for e in res.episodes]
    assert res.summary["first_los_s"]["n"] == sum(math.isfinite(x) for x in first) > 0  # episodes without a loss are left out
    table = format_table([res])
    assert "LoS/flight-h" in table and "first LoS [s]" in table
    assert "LoS/flight-h" not in format_table([evaluate(ENV, make_policy("random", ENV), 2)])


def test_summarise_ignores_missing_values() -> None:
    eps = [
        {"return": 1.0, "length": 10, "kpi_time_to_goal_s": 100.0, "kpi_min_separation_nm": 3.0, "kpi_los_count": 1.0},
        {"return": 3.0, "length": 20, "kpi_time_to_goal_s": math.nan, "kpi_min_separation_nm": math.inf, "kpi_los_count": 0.0},
    ]
    s = summarise(eps)
    assert s["return"]["mean"] == 2.0 and s["return"]["n"] == 2
    assert s["time_to_goal_s"] == {"mean": 100.0, "std": 0.0, "ci95": 0.0, "n": 1}
    assert s["los"]["n"] == 1 and s["min_sep_nm"]["n"] == 1
    assert math.isnan(s["drift_deg"]["mean"])


def test_normalised_score() -> None:
    assert normalised_score(-50.0, -100.0, 0.0) == 0.5
    assert normalised_score(-100.0, -100.0, 0.0) == 0.0
    assert normalised_score(10.0, -100.0, 0.0) == pytest.approx(1.1)
    assert math.isnan(normalised_score(1.0, 2.0, 2.0))


def test_reference_scores_are_cached(tmp_path: Path) -> None:
    first = reference_scores(ENV, 4, tmp_path)
    assert (tmp_path / f"{ENV}.json").exists()
    assert first["classical"]["summary"]["return"]["mean"] > first["random"]["summary"]["return"]["mean"]
    cache = json.loads((tmp_path / f"{ENV}.json").read_text())
    cache["random"]["summary"]["return"]["mean"] = -1234.5
    (tmp_path / f"{ENV}.json").write_text(json.dumps(cache))
    assert reference_scores(ENV, 4, tmp_path)["random"]["summary"]["return"]["mean"] == -1234.5  # read, not recomputed
    assert reference_scores(ENV, 5, tmp_path)["random"]["episodes"] == 5  # other size: recomputed


@needs_sb3
def test_trained_model_is_found_in_a_run_directory(tmp_path: Path) -> None:
    from stable_baselines3 import DDPG, PPO, SAC, TD3

    from bluesky_gym.training.evaluation import algorithm_of_zip, find_model, load_policy
    from bluesky_gym.training.sb3_vec_env import SB3VecEnv

    model = PPO("MultiInputPolicy", SB3VecEnv(ENV, 1), n_steps=16, batch_size=16, device="cpu")
    model.save(tmp_path / "model.zip")
    assert algorithm_of_zip(tmp_path / "model.zip") == "PPO"
    for cls in (SAC, TD3, DDPG):
        cls("MultiInputPolicy", SB3VecEnv(ENV, 1), buffer_size=10, device="cpu").save(tmp_path / "other.zip")
        assert algorithm_of_zip(tmp_path / "other.zip") == cls.__name__
    (tmp_path / "other.zip").unlink()
    assert find_model(tmp_path) == (tmp_path / "model.zip", None)
    policy = load_policy(tmp_path)
    res = evaluate(ENV, policy, 2)
    assert np.isfinite(res.mean_return)
    with pytest.raises(FileNotFoundError):
        find_model(tmp_path / "nothing")


@needs_sb3
def test_a_damaged_model_is_named_in_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from stable_baselines3 import PPO

    from bluesky_gym.cli import main
    from bluesky_gym.training.io import atomic_write_json, file_record
    from bluesky_gym.training.runner import save_checkpoint
    from bluesky_gym.training.sb3_vec_env import SB3VecEnv
    from bluesky_gym.training.status import describe_run

    model = PPO("MultiInputPolicy", SB3VecEnv(ENV, 1), n_steps=16, batch_size=16, device="cpu")
    config = {"env_id": ENV, "algo": "PPO", "seed": 0, "total_timesteps": 16}
    # a finished run whose final model is cut off, and a run whose only checkpoint is
    finished, checkpointed = tmp_path / "finished", tmp_path / "checkpointed"
    for d in (finished, checkpointed):
        atomic_write_json(d / "config.json", config)
    model.save(finished / "model.zip")
    record = {"model.zip": file_record(finished / "model.zip")}
    atomic_write_json(finished / "result.json", {"status": "finished", "timesteps": 0, "episodes": 0, "files": record})
    save_checkpoint(model, checkpointed, 0, 0.0)
    bare = tmp_path / "bare.zip"
    model.save(bare)
    cut = {finished: finished / "model.zip", checkpointed: next(checkpointed.glob("checkpoints/step_*/model.zip")), bare: bare}
    for path in cut.values():
        path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    assert describe_run(finished)["status"] == describe_run(checkpointed)["status"] == "damaged"

    for target, path in cut.items():
        for algo in ([], ["--algo", "PPO"]):
            assert main(["eval", "--env", ENV, "--model", str(target), *algo, "--episodes", "1", "--out", str(tmp_path / "ev")]) == 2
            captured = capsys.readouterr()
            assert captured.err.count("\n") == 1 and str(path) in captured.err, captured.err
            assert "cannot tell the algorithm" not in captured.err and "Traceback" not in captured.err
    assert not (tmp_path / "ev").exists()
    for algo in ([], ["--algo", "ppo"]):
        assert main(["render", "--env", ENV, "--policy", str(bare), *algo, "--out", str(tmp_path / "x.gif")]) == 2
        captured = capsys.readouterr()
        assert captured.err.count("\n") == 1 and str(bare) in captured.err and "cannot tell the algorithm" not in captured.err


def test_eval_writes_its_default_output_where_git_ignores_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    import shutil
    import subprocess

    from bluesky_gym.cli import main

    git = shutil.which("git")
    if git is None:
        pytest.skip("needs git")
    checkout = tmp_path / "checkout"  # a checkout with the project's .gitignore
    checkout.mkdir()
    shutil.copy(Path(__file__).resolve().parents[2] / ".gitignore", checkout / ".gitignore")
    subprocess.run([git, "init", "-q"], cwd=checkout, check=True)
    monkeypatch.chdir(checkout)
    assert main(["eval", "--env", ENV, "--model", "random", "--episodes", "1"]) == 0
    written = [p for p in checkout.rglob("*.json") if ".git" not in p.parts]
    assert len(written) == 1 and str(written[0].relative_to(checkout)) in capsys.readouterr().err
    status = subprocess.run([git, "status", "--porcelain", "--untracked-files=all"], cwd=checkout, capture_output=True, text=True, check=True)
    assert status.stdout.splitlines() == ["?? .gitignore"]
