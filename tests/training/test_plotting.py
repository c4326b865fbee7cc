"""Learning curves and the aggregate across environments."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from bluesky_gym.training.io import atomic_write_csv, atomic_write_json
from bluesky_gym.training.plotting import (
    aggregate,
    bootstrap_mean_ci,
    find_runs,
    iqm,
    load_run,
    plot_aggregate,
    plot_learning_curves,
    smoothed,
    stratified_bootstrap_iqm,
)

pytest.importorskip("matplotlib")


def test_smoothed_window_mean() -> None:
    x = np.array([1.0, 2.0, 3.0, 10.0])
    y = np.array([1.0, 3.0, 5.0, 7.0])
    out = smoothed(x, y, np.array([0.5, 2.0, 3.0, 9.0, 10.0]), window=2.0)
    np.testing.assert_allclose(out[[1, 2, 4]], [2.0, 4.0, 7.0])
    assert np.isnan(out[0]) and np.isnan(out[3])


def test_iqm_and_bootstrap() -> None:
    assert iqm(np.array([0.0, 1.0, 2.0, 3.0, 100.0, -100.0, 1.5, 2.5])) == pytest.approx(np.mean([1.0, 1.5, 2.0, 2.5]))
    assert iqm(np.array([4.0])) == 4.0
    rng = np.random.default_rng(0)
    point, lo, hi = stratified_bootstrap_iqm({"a": np.array([0.0, 0.1, 0.2]), "b": np.array([1.0, 1.1, 0.9])}, rng)
    assert lo <= point <= hi and 0.0 < point < 1.1
    mean, lo, hi = bootstrap_mean_ci(np.array([[1.0, 2.0], [3.0, 4.0]]), rng)
    np.testing.assert_allclose(mean, [2.0, 3.0])
    assert np.all(lo <= mean) and np.all(mean <= hi)


def _fake_run(root: Path, env_id: str, algo: str, seed: int, level: float, final: float | None) -> Path:
    d = root / env_id / algo / f"seed_{seed}"
    atomic_write_json(d / "config.json", {"env_id": env_id, "algo": algo, "seed": seed, "total_timesteps": 1000, "eval_episodes": 5})
    rng = np.random.default_rng(seed)
    steps = np.arange(10, 1001, 10)
    ret = level * steps / 1000 + rng.normal(0, 0.01, steps.size)
    rows = [[k, s, 0.0, 0, r, 10, 1, float(k % 2), np.inf, 0.0] for k, (s, r) in enumerate(zip(steps, ret, strict=True))]
    header = [
        "episode",
        "timesteps",
        "wall_time_s",
        "env_index",
        "return",
        "length",
        "terminated",
        "kpi_success",
        "kpi_min_separation_nm",
        "kpi_los_count",
    ]
    atomic_write_csv(d / "episodes.csv", header, rows)
    if final is not None:
        atomic_write_json(d / "eval.json", {"summary": {"return": {"mean": final}}})
    return d


def test_plots_and_aggregate_from_run_dirs(tmp_path: Path) -> None:
    for seed in range(3):
        _fake_run(tmp_path, "DescentEnv-v0", "PPO", seed, level=1.0, final=0.5 + 0.1 * seed)
        _fake_run(tmp_path, "DescentEnv-v0", "SAC", seed, level=0.5, final=None)
        _fake_run(tmp_path, "MergeEnv-v0", "PPO", seed, level=2.0, final=2.0)
    dirs = find_runs([tmp_path])
    assert len(dirs) == 9
    runs = [load_run(d) for d in dirs]
    written = plot_learning_curves(runs, tmp_path / "plots")
    assert {p.name for p in written} == {"learning_curves.png", "kpis_DescentEnv-v0.png", "kpis_MergeEnv-v0.png"}
    assert all(p.stat().st_size > 5000 for p in written)
    refs = {"DescentEnv-v0": {"random": 0.0, "classical": 1.0}, "MergeEnv-v0": {"random": 0.0, "classical": 4.0}}
    agg = aggregate(runs, refs)
    # PPO: Descent finals 0.5, 0.6, 0.7 and Merge 0.5 x 3 -> IQM of the middle of the six.
    assert agg["final"]["PPO"]["iqm"] == pytest.approx(iqm(np.array([0.5, 0.6, 0.7, 0.5, 0.5, 0.5])))
    assert agg["final"]["PPO"]["runs"] == 6 and agg["final"]["PPO"]["envs"] == ["DescentEnv-v0", "MergeEnv-v0"]
    # SAC has no held-out evaluation: its score is the mean training return of the last 10%.
    assert agg["final"]["SAC"]["iqm"] == pytest.approx(0.5 * 0.955, abs=0.02)
    # Training curves end (5% window) near 0.975 x level / classical: 0.975 on Descent, 0.4875 on
    # Merge; the IQM keeps two of each.
    curve = np.array(agg["curve"]["PPO"]["iqm"])
    assert curve[-1] == pytest.approx((0.975 + 0.4875) / 2, abs=0.02) and curve[0] < 0.05
    files = plot_aggregate(agg, tmp_path / "plots")
    assert json.loads(files[1].read_text())["final"]["PPO"]["runs"] == 6
    assert files[0].stat().st_size > 5000
