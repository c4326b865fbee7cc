"""The results page: statistics, tables and the aggregate, on synthetic sweeps with known answers."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("matplotlib")
pytest.importorskip("rliable")

from bluesky_gym.training.evaluation import EvalResult, save_result
from bluesky_gym.training.io import atomic_write_csv, atomic_write_json
from bluesky_gym.training.results import build_results, collect, reference_episode_dir, seed_episode_bootstrap


def _episodes(returns, success=None, min_sep=None):
    out = []
    for j, r in enumerate(returns):
        e = {"seed": 2**31 + j, "return": float(r), "length": 10, "kpi_success": 1.0 if success is None else success[j]}
        e["kpi_min_separation_nm"] = math.inf if min_sep is None else min_sep[j]
        e["kpi_los_count"] = 0.0
        out.append(e)
    return out


def _run(root: Path, env_id: str, algo: str, seed: int, eval_returns, steps: int = 1000) -> Path:
    d = root / env_id / algo / f"seed_{seed}"
    atomic_write_json(d / "config.json", {"env_id": env_id, "algo": algo, "seed": seed, "total_timesteps": steps, "n_envs": 1, "eval_episodes": 4})
    ts = np.arange(1, 21) * steps // 20
    atomic_write_csv(d / "episodes.csv", ["timesteps", "return", "length"], [[int(t), float(t) / steps, 10] for t in ts])
    save_result(EvalResult(env_id, algo, _episodes(eval_returns), 0.1), d, stem="eval")
    return d


def _sweep(root: Path, ppo: dict[str, list[list[float]]], sac: dict[str, list[list[float]]] | None = None) -> Path:
    for env_id, seeds in ppo.items():
        for name, value in (("random", 0), ("classical", 10)):
            save_result(EvalResult(env_id, name, _episodes([value] * 4), 0.1), reference_episode_dir(root), stem=f"{env_id}_{name}")
        for s, returns in enumerate(seeds):
            _run(root, env_id, "PPO", s, returns)
    for env_id, seeds in (sac or {}).items():
        for s, returns in enumerate(seeds):
            _run(root, env_id, "SAC", s, returns)
    return root


def test_bootstrap_point_is_the_mean_of_seed_means_and_the_interval_holds_it():
    rng = np.random.default_rng(0)
    groups = [np.array([1.0, 3.0]), np.array([10.0, 10.0, 10.0, 10.0])]
    point, lo, hi = seed_episode_bootstrap(groups, rng, n_boot=500)
    assert point == pytest.approx((2.0 + 10.0) / 2)
    assert lo < point < hi
    assert lo >= 1.0 and hi <= 10.0
    # no variation at all: the interval collapses on the value
    assert seed_episode_bootstrap([np.full(3, 4.0), np.full(5, 4.0)], rng, n_boot=50) == (4.0, 4.0, 4.0)
    # episode-level variation alone widens it even with one seed
    p, lo1, hi1 = seed_episode_bootstrap([np.array([0.0, 10.0, 0.0, 10.0])], rng, n_boot=500)
    assert p == 5.0 and lo1 < 5.0 < hi1
    assert all(math.isnan(x) for x in seed_episode_bootstrap([np.zeros(0)], rng))


def test_kpi_table_rows_and_normalised_aggregate(tmp_path, monkeypatch):
    sweep = _sweep(
        tmp_path / "sweep",
        {"AEnv-v0": [[5, 5, 5, 5], [7, 7, 7, 7], [3, 3, 3, 3]], "BEnv-v0": [[2, 2, 2, 2], [4, 4, 4, 4], [9, 9, 9, 9]]},
        {"AEnv-v0": [[1, 1, 1, 1], [1, 1, 1, 1], [1, 1, 1, 1]], "BEnv-v0": [[1, 1, 1, 1], [1, 1, 1, 1], [1, 1, 1, 1]]},
    )
    results = collect([sweep], reps=300)
    a = next(er for er in results if er.env_id == "AEnv-v0")
    assert [r.policy for r in a.rows] == ["random", "classical", "PPO", "SAC"]
    ppo = a.rows[2]
    assert ppo.runs == 3 and ppo.episodes == 12
    assert ppo.kpis["return"][0] == pytest.approx(5.0)
    assert ppo.kpis["return"][1] < 5.0 < ppo.kpis["return"][2]
    assert a.rows[0].kpis["return"] == (0.0, 0.0, 0.0)
    assert "min_sep_nm" not in ppo.kpis  # no traffic: no separation KPI

    import bluesky_gym.training.results as results_module

    drawn: dict[str, dict[str, float]] = {}
    plot = results_module.plot_learning_curves

    def spy(runs, out_dir, seed=0, references=None):
        drawn.update(references or {})
        return plot(runs, out_dir, seed=seed, references=references)

    monkeypatch.setattr(results_module, "plot_learning_curves", spy)
    page = build_results([sweep], tmp_path / "site" / "results.md", ["bluesky-gym", "results", "SWEEP", "--out", "results.md"], reps=300)
    # the learning curves carry the reference policies' held-out returns as lines
    assert drawn == {"AEnv-v0": {"random": 0.0, "classical": 10.0}, "BEnv-v0": {"random": 0.0, "classical": 10.0}}
    text = page.read_text()
    assert "bluesky-gym results SWEEP --out results.md" in text
    assert "| PPO | 3 | 12 | 5.000 [" in text
    assert "Not run for this page: TD3, DDPG." in text
    # normalised PPO scores (random 0, classical 10): A 0.5 0.7 0.3, B 0.2 0.4 0.9
    scores = np.sort([0.5, 0.7, 0.3, 0.2, 0.4, 0.9])
    from scipy.stats import trim_mean

    iqm = trim_mean(scores, 0.25)  # rliable's IQM, computed independently
    line = next(ln for ln in text.splitlines() if ln.startswith("| PPO | 3 | 2 |"))
    assert line.split("|")[4].strip().startswith(f"{iqm:.3f}")
    # SAC: every normalised score is 0.1, so PPO is better with certainty bounds well above 0.5
    poi = next(ln for ln in text.splitlines() if ln.startswith("| PPO | SAC |"))
    assert float(poi.split("|")[3].split("[")[0]) > 0.8
    for png in ["aggregate_v0.png", "AEnv-v0/learning_curves.png", "BEnv-v0/learning_curves.png"]:
        p = tmp_path / "site" / "results" / png
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", png
        assert f"results/{png}" in text


def test_page_is_reproducible_and_versions_are_aggregated_apart(tmp_path):
    sweep = _sweep(tmp_path / "sweep", {"AEnv-v0": [[5, 6, 5, 6]], "AEnv-v1": [[1, 2, 3, 4]]})
    out = tmp_path / "results.md"
    first = build_results([sweep], out, ["bluesky-gym", "results", "x"], reps=100).read_text()
    second = build_results([sweep], out, ["bluesky-gym", "results", "x"], reps=100).read_text()
    assert first == second
    assert "## Aggregate over the -v0 environments" in first and "## Aggregate over the -v1 environments" in first
    assert "Probability of improvement needs two trained algorithms" in first
    assert "Not run for this page: SAC, TD3, DDPG." in first


def test_cli_names_a_missing_directory_in_one_line(tmp_path):
    proc = subprocess.run(
        [sys.executable, "-m", "bluesky_gym", "results", str(tmp_path / "nope"), "--out", str(tmp_path / "r.md")],
        capture_output=True,
        text=True,
        cwd=tmp_path,
    )
    assert proc.returncode == 2
    assert proc.stderr.strip().count("\n") == 0
    assert "nope" in proc.stderr and "bluesky-gym results: error" in proc.stderr


def test_missing_reference_episodes_are_evaluated_once_and_kept(tmp_path):
    from bluesky_gym.training.results import complete_references

    sweep = tmp_path / "sweep"
    _run(sweep, "DescentEnv-v0", "PPO", 0, [1.0, 2.0])
    first = complete_references([sweep], episodes=2)
    assert [line.split(":")[1].split()[1] for line in first] == ["random", "classical"]
    for name in ("random", "classical"):
        assert (reference_episode_dir(sweep) / f"DescentEnv-v0_{name}_episodes.csv").exists()
    assert complete_references([sweep], episodes=2) == []
    rows = collect([sweep], reps=50)[0].rows
    assert [r.policy for r in rows] == ["random", "classical", "PPO"] and rows[0].episodes == 2


def test_references_kept_by_another_sweep_are_not_evaluated_again(tmp_path):
    from bluesky_gym.training.results import complete_references

    first, second = tmp_path / "a", tmp_path / "b"
    _run(first, "DescentEnv-v0", "PPO", 0, [1.0, 2.0])
    _run(second, "DescentEnv-v0", "SAC", 0, [1.0, 2.0])
    assert len(complete_references([first], episodes=2)) == 2
    assert complete_references([first, second], episodes=2) == []
    assert not reference_episode_dir(second).exists()
    # more episodes than the kept record: evaluated for the sweep that lacks them
    assert [line.split(" -> ")[1] for line in complete_references([first, second], episodes=3)] == [str(reference_episode_dir(first))] * 2


def _configured_run(
    root: Path, env_id: str, algo: str, seed: int, eval_returns, steps: int, trainer: str = "sb3", n_envs: int = 1, curve=None
) -> Path:
    d = _run(root, env_id, algo, seed, eval_returns, steps)
    identity = {"env_id": env_id, "algo": algo, "seed": seed, "total_timesteps": steps, "n_envs": n_envs, "hyperparams": {}}
    if trainer != "sb3":
        identity["trainer"] = trainer
    cfg = {"env_id": env_id, "algo": algo, "seed": seed, "total_timesteps": steps, "n_envs": n_envs, "eval_episodes": 4, "identity": identity}
    atomic_write_json(d / "config.json", cfg)
    if curve is not None:
        ts = np.linspace(steps / len(curve), steps, len(curve))
        atomic_write_csv(d / "episodes.csv", ["timesteps", "return", "length"], [[int(t), float(r), 10] for t, r in zip(ts, curve, strict=True)])
    return d


def _merge_sweep_with_both_trainers(tmp_path: Path) -> Path:
    """A sweep of MergeEnv-v0 with its random (0) and classical (10) references and PPO, 2 seeds, on each trainer at 1,000 steps."""
    root = _sweep(tmp_path / "sweep", {})
    for name, value in (("random", 0), ("classical", 10)):
        save_result(EvalResult("MergeEnv-v0", name, _episodes([value] * 4), 0.1), reference_episode_dir(root), stem=f"MergeEnv-v0_{name}")
    for s in range(2):
        _configured_run(root, "MergeEnv-v0", "PPO", s, [5.0, 5.0, 6.0, 6.0], 1000, trainer="fast", curve=np.linspace(0, 6, 20))
        _configured_run(root, "MergeEnv-v0", "PPO", s + 10, [5.5, 5.5, 5.5, 5.5], 1000, curve=np.linspace(0, 6, 20))  # SB3
    return root


def test_runs_of_one_algorithm_at_other_budgets_and_trainers_are_rows_of_their_own(tmp_path: Path) -> None:
    root = _merge_sweep_with_both_trainers(tmp_path)
    for s in range(2):
        _configured_run(root, "MergeEnv-v0", "PPO", s + 20, [9.0] * 4, 8000, trainer="fast", n_envs=64)
    # TD3 learns fast and then falls back; SAC does not: the observations' figures say so.
    _configured_run(root, "MergeEnv-v0", "TD3", 0, [1.0] * 4, 400, curve=[2, 6, 8, 8, 3, 1, 1, 1])
    _configured_run(root, "MergeEnv-v0", "SAC", 0, [4.0] * 4, 400, curve=[2, 4, 6, 7, 7, 7, 7, 7])
    out = tmp_path / "page.md"
    build_results([root], out, ["bluesky-gym", "results", str(root), "--out", str(out)], reps=200)
    text = out.read_text()
    labels = {r.policy for r in collect([root], reps=50)[0].rows}
    assert {
        "PPO (fast trainer, 1,000 steps, 1 env)",
        "PPO (sb3 trainer, 1,000 steps, 1 env)",
        "PPO (fast trainer, 8,000 steps, 64 envs)",
        "SAC (400 steps)",
        "TD3 (400 steps)",
    } <= labels
    trainers = text.split("## Trainers compared")[1].split("##")[0]
    assert (
        "| MergeEnv-v0 | PPO (1,000 steps, 1 env) |" in trainers and trainers.count("| yes |") == 1
    )  # 5.5 lies within the fast runs' spread and back
    scale = text.split("## Scale: the same algorithm at other budgets")[1].split("## ")[0]
    assert "0.90 (2 seeds)" in scale  # the 8e3-step runs: (9 - 0) / (10 - 0)
    observed = text.split("## The paper's observations, checked")[1].split("## Per environment")[0]
    assert "| MergeEnv-v0 | TD3 (400 steps) | 400 |" in observed
    assert "On MergeEnv-v0 the observation holds: TD3 and DDPG drop more than every other algorithm (largest drop: TD3 (400 steps)" in observed
    drops = [line for line in observed.splitlines() if line.startswith("| MergeEnv-v0 |") and line.count("|") > 6]
    header = [line for line in observed.splitlines() if line.startswith("| environment | PPO")][0]
    cells = dict(zip((c.strip() for c in header.strip("|").split("|")), (c.strip() for c in drops[-1].strip("|").split("|")), strict=True))
    assert float(cells["TD3 (400 steps)"]) > 0.5 and float(cells["SAC (400 steps)"]) == 0.0


def test_the_training_return_of_a_coarse_curve_is_the_span_that_holds_the_step() -> None:
    from bluesky_gym.training.plotting import Run
    from bluesky_gym.training.results import _training_return

    def run(t, y):
        return Run(Path("x"), "MergeEnv-v0", "PPO", 0, 2_000_000, {"timesteps": np.asarray(t, float), "return": np.asarray(y, float)}, None, {}, True)

    # a summarised 2e6-step run: spans of 1e4 steps whose points lie just after the span ends
    coarse = run([10_004, 20_008, 30_013], [-10.0, -9.0, -8.0])
    assert _training_return([coarse], 20_000, 2_000) == -9.0
    assert np.isnan(_training_return([coarse], 40_000, 2_000))  # past its curve
    fine = run(np.arange(1, 101) * 200, np.arange(1, 101, dtype=float))
    assert _training_return([fine], 20_000, 2_000) == pytest.approx(np.mean(np.arange(91, 101)))  # episodes in (18000, 20000]


def test_the_instability_verdict_says_where_the_observation_does_not_hold() -> None:
    from bluesky_gym.training.results import _instability_verdict

    assert "does not hold here" in _instability_verdict("MergeEnv-v0", {"TD3": 0.1, "DDPG": 0.2, "SAC (2e4 steps)": 0.5})
    assert "holds in part" in _instability_verdict("MergeEnv-v0", {"TD3": 0.6, "DDPG": 0.2, "SAC": 0.5})
    assert "holds: TD3 and DDPG" in _instability_verdict("MergeEnv-v0", {"TD3": 0.6, "DDPG": 0.7, "PPO": 0.5})
    assert _instability_verdict("MergeEnv-v0", {"SAC": 0.5}) == ""


def test_runs_that_differ_in_their_trainer_alone_are_compared_as_trainers_not_as_budgets(tmp_path: Path) -> None:
    root = _merge_sweep_with_both_trainers(tmp_path)
    out = tmp_path / "page.md"
    build_results([root], out, ["bluesky-gym", "results", str(root), "--out", str(out)], reps=200)
    text = out.read_text()
    assert "## Trainers compared" in text and "| MergeEnv-v0 | PPO |" in text.split("## Trainers compared")[1]
    assert "## Scale" not in text


def test_the_resolution_methods_are_reference_rows_beside_mvp_and_a_missing_one_is_named(tmp_path: Path, monkeypatch) -> None:
    """A fixture sweep of an environment with traffic: eby and swarm are scored beside mvp, ssd (no record) is named as not evaluated."""
    from bluesky_gym.training.plotting import REFERENCE_STYLES
    from bluesky_gym.training.results import PAGE_REFERENCES, kpi_table

    root = tmp_path / "sweep"
    kept = {"random": 0, "classical": 10, "mvp": 6, "eby": 7, "swarm": 3}
    for name, value in kept.items():
        result = EvalResult("SectorCREnv-v0", name, _episodes([value] * 4, min_sep=[5.0] * 4), 0.1)
        save_result(result, reference_episode_dir(root), stem=f"SectorCREnv-v0_{name}")
    for s in range(2):
        _run(root, "SectorCREnv-v0", "PPO", s, [5.0] * 4)
    (er,) = collect([root], reps=50)
    assert [r.policy for r in er.rows] == ["random", "classical", "mvp", "eby", "swarm", "PPO"]
    assert er.references == {name: float(value) for name, value in kept.items()}
    assert er.missing == ["ssd"]
    table = kpi_table(er)
    assert table[4].startswith("| mvp | – | 4 | 6.000 [6.000, 6.000] |")
    assert table[5].startswith("| eby | – | 4 | 7.000 [7.000, 7.000] |") and table[6].startswith("| swarm | – | 4 | 3.000 [3.000, 3.000] |")
    assert table[7].startswith("| PPO | 2 | 8 |")
    assert table[-1] == "Not evaluated yet (no held-out record): ssd; `bluesky-gym results` evaluates it when run again."
    assert not any(line.startswith("| ssd") for line in table)

    import bluesky_gym.training.results as results_module

    drawn: dict[str, dict[str, float]] = {}
    plot = results_module.plot_learning_curves

    def spy(runs, out_dir, seed=0, references=None):
        drawn.update(references or {})
        return plot(runs, out_dir, seed=seed, references=references)

    monkeypatch.setattr(results_module, "plot_learning_curves", spy)
    out = tmp_path / "page.md"
    text = build_results([root], out, ["bluesky-gym", "results", str(root), "--out", str(out)], reps=50).read_text()
    assert list(drawn["SectorCREnv-v0"]) == ["random", "classical", "mvp", "eby", "swarm"]  # lines in the learning curves
    assert "`eby` (Eby's method), `swarm` (Swarm) and `ssd` (Solution Space Diagram)" in text
    assert "| eby | – | 4 |" in text and "Not evaluated yet (no held-out record): ssd" in text
    # the normalised score stays 0 = random, 1 = classical: PPO's 5 is 0.5 whatever the resolution methods score
    line = next(ln for ln in text.splitlines() if ln.startswith("| PPO | 2 | 1 |"))
    assert line.split("|")[4].strip().startswith("0.500")
    # every page reference has a line style of its own colour; the resolution methods share the dash-dot line
    assert set(PAGE_REFERENCES) <= set(REFERENCE_STYLES)
    assert len({REFERENCE_STYLES[n][0] for n in PAGE_REFERENCES}) == len(PAGE_REFERENCES)
    assert {REFERENCE_STYLES[n][1] for n in ("mvp", "eby", "swarm", "ssd")} == {"-."}


def test_missing_references_are_evaluated_cheap_methods_first_and_kept_small(tmp_path: Path, monkeypatch) -> None:
    """complete_references: every page reference of an environment with mvp, policy by policy (ssd last), resumable."""
    import bluesky_gym.training.evaluation as evaluation
    from bluesky_gym.training.results import REFERENCE_RECORD_COLUMNS, complete_references

    calls: list[tuple[str, str]] = []

    def fake_evaluate(env_id, policy, episodes):
        calls.append((env_id, policy))
        episodes_ = [{**e, "reward_drift": -1.0, "total_reward": e["return"]} for e in _episodes([1.0] * episodes, min_sep=[5.0] * episodes)]
        return EvalResult(env_id, policy, episodes_, 0.1)

    monkeypatch.setattr(evaluation, "evaluate", fake_evaluate)
    monkeypatch.setattr(evaluation, "make_policy", lambda name, env_id: name)
    sweep = tmp_path / "sweep"
    for env_id in ("SectorCREnv-v0", "DescentEnv-v0", "MergeEnv-v0"):
        _run(sweep, env_id, "PPO", 0, [1.0, 2.0])
    save_result(EvalResult("MergeEnv-v0", "eby", _episodes([1.0] * 2), 0.1), reference_episode_dir(sweep), stem="MergeEnv-v0_eby")
    complete_references([sweep], episodes=2)
    order = [policy for _, policy in calls]
    assert order == ["random"] * 3 + ["classical"] * 3 + ["mvp"] * 2 + ["eby"] + ["swarm"] * 2 + ["ssd"] * 2
    assert calls[-2:] == [("MergeEnv-v0", "ssd"), ("SectorCREnv-v0", "ssd")]  # the slow one last, environment by environment
    assert ("MergeEnv-v0", "eby") not in calls  # kept already
    header = (reference_episode_dir(sweep) / "SectorCREnv-v0_ssd_episodes.csv").read_text().splitlines()[0].split(",")
    assert "seed" in header and "return" in header and set(header) <= set(REFERENCE_RECORD_COLUMNS)  # reward components dropped
    calls.clear()
    assert complete_references([sweep], episodes=2) == [] and calls == []
    (reference_episode_dir(sweep) / "SectorCREnv-v0_ssd_episodes.csv").unlink()
    assert [line.split(":")[0] for line in complete_references([sweep], episodes=2)] == ["SectorCREnv-v0"] and calls == [("SectorCREnv-v0", "ssd")]


def test_a_reference_added_to_the_page_leaves_the_other_rows_intervals_as_they_were(tmp_path: Path) -> None:
    root = tmp_path / "sweep"
    rng = np.random.default_rng(1)
    for name in ("random", "classical", "mvp", "swarm"):
        result = EvalResult("MergeEnv-v0", name, _episodes(rng.normal(size=8), min_sep=rng.uniform(1, 9, size=8)), 0.1)
        save_result(result, reference_episode_dir(root), stem=f"MergeEnv-v0_{name}")
    _run(root, "MergeEnv-v0", "PPO", 0, rng.normal(size=4))
    before = {r.policy: r.kpis for r in collect([root], reps=200)[0].rows}
    save_result(EvalResult("MergeEnv-v0", "eby", _episodes(rng.normal(size=8)), 0.1), reference_episode_dir(root), stem="MergeEnv-v0_eby")
    after = {r.policy: r.kpis for r in collect([root], reps=200)[0].rows}
    assert list(after) == ["random", "classical", "mvp", "eby", "swarm", "PPO"]
    assert before["random"]["return"][1] < before["random"]["return"][2]  # a real interval, not a collapsed one
    assert {k: v for k, v in after.items() if k != "eby"} == before
