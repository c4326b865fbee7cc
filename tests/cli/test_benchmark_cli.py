"""Every benchmark subcommand on tiny budgets: list, info, train, eval, plot, sweep, demo."""

from __future__ import annotations

import dataclasses
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import gymnasium as gym
import pytest

from bluesky_gym.cli import main
from bluesky_gym.core.extras import install_hint
from bluesky_gym.registration import available_envs
from bluesky_gym.training.io import read_json

from .conftest import ROOT, needs_sb3

ENV = "DescentEnv-v0"


def test_list_and_info(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    assert all(env_id in out for env_id in available_envs())
    assert main(["info", ENV]) == 0
    out = capsys.readouterr().out
    config = gym.make(ENV).unwrapped.config
    for f in dataclasses.fields(config):
        assert f"{f.name}" in out and repr(getattr(config, f.name)) in out
    assert "altitude" in out and "30 s simulated per step" in out
    assert main(["info", ENV, "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["max_episode_steps"] == 300 and info["action"]["shape"] == [1]
    assert {o["name"]: o["default"] for o in info["options"]}["alt_min"] == 2000
    assert main(["list", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert [d["id"] for d in rows if d["kind"] == "single-agent"] == available_envs()
    assert main(["info", "NoSuchEnv-v0"]) == 2


@pytest.mark.parametrize(("env_id", "dtype"), [("MergeEnv-v1", "float32"), ("MergeEnv-v0", "float64"), ("MergeCentralised-v0", "float64")])
def test_info_prints_the_dtype_of_the_spaces(env_id: str, dtype: str, capsys: pytest.CaptureFixture[str]) -> None:
    """A -v1 id has float32 spaces: ``info`` says so for the observation and the action."""
    assert main(["info", "--env", env_id]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert f"  observation (Dict of {dtype} Box):" in lines
    assert next(line for line in lines if line.startswith("  action:")).endswith(f" {dtype}")


@needs_sb3
def test_train_eval_plot(tmp_path: Path, tiny_config: Path, capsys: pytest.CaptureFixture[str]) -> None:
    args = [
        "train",
        ENV,
        "--algo",
        "sac",
        "--steps",
        "200",
        "--seed",
        "2",
        "--n-envs",
        "2",
        "--config",
        str(tiny_config),
        "--out",
        str(tmp_path / "runs"),
        "--no-progress",
    ]
    assert main(args) == 0
    run_dir = tmp_path / "runs" / ENV / "SAC" / "seed_2"
    out = capsys.readouterr().out
    assert str(run_dir) in out and "return" in out
    cfg = read_json(run_dir / "config.json")
    assert cfg["hyperparams"]["buffer_size"] == 5000 and cfg["hyperparams"]["learning_rate"] == 3e-4  # file over paper
    assert cfg["hyperparams"]["gradient_steps"] == -1 and cfg["notes"]  # adapted to 2 environments
    assert read_json(run_dir / "result.json")["timesteps"] == 200
    assert main(args) == 0
    assert "already finished" in capsys.readouterr().out

    ev = tmp_path / "ev"
    assert main(["eval", ENV, "--model", str(run_dir), "--model", "random", "--model", "classical", "--episodes", "6", "--out", str(ev)]) == 0
    table = capsys.readouterr().out
    assert "normalised" in table and "SAC" in table and "classical" in table
    assert sorted(p.name for p in ev.glob("*.json")) == ["eval_SAC_seed_2.json", "eval_classical.json", "eval_random.json"]
    assert read_json(ev / "eval_random.json")["episodes"] == 6

    plots = tmp_path / "plots"
    assert main(["plot", str(tmp_path / "runs"), "--out", str(plots), "--reference-episodes", "4"]) == 0
    assert {p.name for p in plots.glob("*.png")} == {"learning_curves.png", f"kpis_{ENV}.png", "aggregate.png"}
    agg = read_json(plots / "aggregate.json")
    assert agg["final"]["SAC"]["runs"] == 1 and set(agg["references"]) == {ENV}
    assert main(["eval", ENV, "--model", str(tmp_path / "missing.zip")]) == 2


@needs_sb3
def test_sweep_local_is_resumable(tmp_path: Path, tiny_config: Path, capsys: pytest.CaptureFixture[str]) -> None:
    envs = [ENV] + [e for e in available_envs() if e == "MergeEnv-v0"]
    out = tmp_path / "sweep"
    args = [
        "sweep",
        "--envs",
        *envs,
        "--algos",
        "PPO",
        "--seeds",
        "0",
        "1",
        "--steps",
        "128",
        "--n-envs",
        "2",
        "--config",
        str(tiny_config),
        "--out",
        str(out),
        "--local",
    ]
    assert main(args) == 0
    summary = read_json(out / "sweep.json")
    assert len(summary["runs"]) == 2 * len(envs)
    assert all(r["status"] == "finished" and not r["skipped"] and r["timesteps"] == 128 for r in summary["runs"])
    assert all(r["normalised_score"] is not None for r in summary["runs"])
    assert set(summary["references"]) == set(envs)
    assert "reference DescentEnv-v0" in capsys.readouterr().out
    assert main(args) == 0
    assert all(r["skipped"] for r in read_json(out / "sweep.json")["runs"])


@needs_sb3
def test_sweep_killed_mid_run_resumes_with_nothing_lost_or_repeated(tmp_path: Path, tiny_config: Path) -> None:
    out = tmp_path / "sweep"
    cmd = [
        sys.executable,
        "-m",
        "bluesky_gym",
        "sweep",
        "--envs",
        ENV,
        "--algos",
        "SAC",
        "--seeds",
        "0",
        "--steps",
        "1000",
        "--n-envs",
        "2",
        "--config",
        str(tiny_config),
        "--out",
        str(out),
        "--local",
    ]
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    run_dir = out / ENV / "SAC" / "seed_0"
    proc = subprocess.Popen(cmd, cwd=tmp_path, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, preexec_fn=os.setsid)
    try:
        deadline = time.time() + 300
        while time.time() < deadline:
            ck = run_dir / "checkpoint.json"
            if ck.exists() and read_json(ck)["timesteps"] >= 200:
                break
            assert proc.poll() is None, proc.stderr.read().decode()
            time.sleep(0.2)
        else:
            pytest.fail("no checkpoint within 300 s")
        time.sleep(1.0)  # let it run past the checkpoint
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    assert proc.returncode == -signal.SIGKILL
    ckpt = read_json(run_dir / "checkpoint.json")
    assert not (run_dir / "result.json").exists() and ckpt["timesteps"] < 1000
    before = (run_dir / "episodes.csv").read_text().splitlines()

    res = subprocess.run(cmd, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr
    result = read_json(run_dir / "result.json")
    assert result["resumed_from"] == ckpt["timesteps"] and result["timesteps"] == 1000
    after = (run_dir / "episodes.csv").read_text().splitlines()
    kept = ckpt["episodes_logged"] + 1
    assert after[:kept] == before[:kept]
    rows = [line.split(",") for line in after[1:]]
    assert [int(r[0]) for r in rows] == list(range(len(rows)))  # no episode lost or logged twice
    steps = [int(r[1]) for r in rows]
    assert steps == sorted(steps) and all(s > ckpt["timesteps"] for s in steps[kept - 1 :])
    procs = read_json(run_dir / "run.json")["processes"]
    assert [s["start_timesteps"] for s in procs] == [0, ckpt["timesteps"]]
    import pickle

    final = read_json(run_dir / "checkpoint.json")
    with open(run_dir / final["dir"] / "replay_buffer.pkl", "rb") as f:
        assert pickle.load(f).size() * 2 == 1000  # every transition exactly once in the replay buffer
    assert read_json(out / "sweep.json")["runs"][0]["resumed_from"] == ckpt["timesteps"]
    assert not list(run_dir.rglob("*.tmp")) and not (run_dir / ".lock").exists()  # leftovers of the kill are cleaned


@pytest.mark.slow
@needs_sb3
def test_sweep_on_ray(tmp_path: Path, tiny_config: Path) -> None:
    pytest.importorskip("ray")
    out = tmp_path / "sweep"
    cmd = [
        sys.executable,
        "-m",
        "bluesky_gym",
        "sweep",
        "--envs",
        ENV,
        "--algos",
        "PPO",
        "DDPG",
        "--seeds",
        "0",
        "--steps",
        "128",
        "--n-envs",
        "2",
        "--config",
        str(tiny_config),
        "--out",
        str(out),
        "--cpus-per-run",
        "1",
    ]
    home = tmp_path / "home"  # Ray writes nothing to the home directory (settings in tests/conftest.py)
    home.mkdir()
    env = dict(os.environ, HOME=str(home), PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    res = subprocess.run(cmd, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=900)
    assert res.returncode == 0, res.stdout + res.stderr
    assert sorted(p.relative_to(home) for p in home.rglob("*")) == []
    runs = read_json(out / "sweep.json")["runs"]
    assert {(r["algo"], r["status"]) for r in runs} == {("PPO", "finished"), ("DDPG", "finished")}
    assert read_json(out / ENV / "DDPG" / "seed_0" / "config.json")["hyperparams"]["train_freq"] == 1


@needs_sb3
def test_demo(tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    import bluesky_gym.training.plotting as plotting

    drawn: dict[str, dict[str, float]] = {}
    plot = plotting.plot_learning_curves

    def spy(runs, out_dir, seed=0, references=None):  # type: ignore[no-untyped-def]
        drawn.update(references or {})
        return plot(runs, out_dir, seed=seed, references=references)

    monkeypatch.setattr(plotting, "plot_learning_curves", spy)
    out = tmp_path / "demo"
    assert main(["demo", "--steps", "2048", "--n-envs", "8", "--episodes", "6", "--out", str(out), "--no-progress"]) == 0
    text = capsys.readouterr().out
    assert "PPO (trained)" in text and "normalised" in text and "wall-clock" in text
    demo = read_json(out / "demo.json")
    assert demo["timesteps"] == 2048 and demo["timings_s"]["total_s"] > 0
    assert set(demo["kpis"]) == {"PPO", "random", "classical"}
    # the learning curve shows the reference policies' held-out returns as lines
    assert set(drawn) == {demo["env_id"]} and set(drawn[demo["env_id"]]) == {"random", "classical"}
    assert drawn[demo["env_id"]]["classical"] == pytest.approx(demo["kpis"]["classical"]["return"]["mean"])
    assert {Path(p).name for p in demo["plots"]} >= {"learning_curves.png", "aggregate.png"}
    try:
        import pygame  # noqa: F401

        import bluesky_gym.render  # noqa: F401
    except ImportError:
        assert demo["gif"] is None
    else:
        assert demo["gif"] and Path(demo["gif"]).stat().st_size > 1000


def test_missing_optional_dependencies_are_named(monkeypatch: pytest.MonkeyPatch, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setitem(sys.modules, "stable_baselines3", None)
    assert main(["train", ENV, "--steps", "10", "--out", str(tmp_path)]) == 2
    assert install_hint("train") in capsys.readouterr().err
    # The reference policies, their evaluation and the catalog need no SB3.
    assert main(["eval", ENV, "--model", "classical", "--episodes", "2", "--out", str(tmp_path / "ev")]) == 0
    assert "classical" in capsys.readouterr().out
    (tmp_path / "model.zip").write_bytes(b"")
    assert main(["eval", ENV, "--model", str(tmp_path / "model.zip"), "--algo", "PPO", "--episodes", "2"]) == 2
    assert install_hint("train") in capsys.readouterr().err


@needs_sb3
def test_missing_ray_is_named(monkeypatch: pytest.MonkeyPatch, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setitem(sys.modules, "ray", None)
    assert main(["sweep", "--envs", ENV, "--algos", "PPO", "--steps", "10", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert install_hint("distributed") in err and "--local" in err
