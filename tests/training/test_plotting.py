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


def _descent_run(root: Path, name: str, seed: int, n_steps: int, finished: bool = True) -> Path:
    """A Descent run whose episodes fly 10 steps 300 m off the target, then land at 30 m."""
    from bluesky_gym.environments.descent.task import ALT_DIF_REWARD_SCALE

    d = root / name / f"seed_{seed}"
    # as the runner writes it: the digest covers the whole identity, seed included
    identity = {"env_id": "DescentEnv-v0", "algo": "PPO", "seed": seed, "hyperparams": {"n_steps": n_steps, "learning_rate": 3e-4}}
    config = {"env_id": "DescentEnv-v0", "algo": "PPO", "seed": seed, "total_timesteps": 1000, "identity": identity, "digest": f"d{n_steps}s{seed}"}
    atomic_write_json(d / "config.json", config)
    header = [
        "episode",
        "timesteps",
        "wall_time_s",
        "env_index",
        "return",
        "length",
        "terminated",
        "final_altitude",
        "reward_altitude",
        "kpi_los_count",
        "kpi_success",
    ]
    rows = [[k, 100 * (k + 1), 0.0, 0, -5.0 - k, 11, 1, 30.0 + k, 10 * 300.0 * ALT_DIF_REWARD_SCALE, 0.0, 1.0] for k in range(10)]
    atomic_write_csv(d / "episodes.csv", header, rows)
    if finished:
        atomic_write_json(d / "result.json", {"status": "finished"})
    return d


def test_reference_lines_kpis_per_environment_and_seeds_per_configuration(tmp_path: Path) -> None:
    from bluesky_gym.training.plotting import aggregate_figure, kpi_panels, learning_curve_figures

    runs = [
        load_run(_descent_run(tmp_path, "a", 0, 128)),
        load_run(_descent_run(tmp_path, "a", 1, 128, finished=False)),
        load_run(_descent_run(tmp_path, "b", 0, 2048)),
    ]
    # Descent's KPI panels: altitude error and final altitude, not the constant LoS count or success.
    panels = [m for m, _ in kpi_panels("DescentEnv-v0", runs)]
    assert panels == ["return", "altitude_error_m", "final_altitude", "length"]
    np.testing.assert_allclose(runs[0].metric("altitude_error_m"), 300.0)
    refs = {"DescentEnv-v0": {"random": -60.0, "classical": -20.0, "mvp": -12.0}}
    figures = learning_curve_figures(runs, references=refs)
    assert set(figures) == {"learning_curves", "kpis_DescentEnv-v0"}
    ax = figures["learning_curves"].axes[0]
    labels = ax.get_legend_handles_labels()[1]
    # Two configurations with seed 0: two lines, labelled by what differs, seeds counted per configuration.
    assert labels[:2] == ["PPO n_steps=128 (2 seeds, 1 unfinished)", "PPO n_steps=2048 (1 seed)"]
    assert labels[2:] == ["random", "classical", "mvp"]
    levels = {line.get_label(): line.get_ydata()[0] for line in ax.get_lines() if line.get_label() in refs["DescentEnv-v0"]}
    assert levels == refs["DescentEnv-v0"]
    kpi_axes = figures["kpis_DescentEnv-v0"].axes
    assert [a.get_ylabel() for a in kpi_axes[:3]] == ["episode return", "mean altitude error [m]", "final altitude [m] (-100: crashed)"]
    drawn = [line.get_ydata() for line in kpi_axes[1].get_lines() if line.get_label().startswith("PPO n_steps=128")]
    assert len(drawn) == 1 and np.nanmax(np.abs(np.asarray(drawn[0]) - 300.0)) < 1e-9  # the derived altitude error is plotted
    assert "random" in kpi_axes[0].get_legend_handles_labels()[1] and "random" not in kpi_axes[1].get_legend_handles_labels()[1]

    # One environment: a readable bar per algorithm with its value, not a lone dot.
    agg = aggregate(runs, {"DescentEnv-v0": {"random": -60.0, "classical": -20.0}})
    fig = aggregate_figure(agg)
    bars = fig.axes[0].patches
    assert len(bars) == 1 and bars[0].get_width() == pytest.approx(agg["final"]["PPO"]["iqm"])
    assert f"{agg['final']['PPO']['iqm']:.2f}" in " ".join(t.get_text() for t in fig.axes[0].texts)
    assert "DescentEnv-v0" in fig.get_suptitle()


def test_the_aggregate_of_one_run_says_1_run_and_draws_no_interval(tmp_path: Path) -> None:
    from matplotlib.container import ErrorbarContainer

    from bluesky_gym.training.plotting import aggregate_figure

    runs = [load_run(_fake_run(tmp_path, "DescentEnv-v0", "PPO", 0, level=1.0, final=0.92))]
    runs += [load_run(_fake_run(tmp_path, "DescentEnv-v0", "SAC", seed, level=0.5, final=0.4 + 0.1 * seed)) for seed in range(2)]
    agg = aggregate(runs, {"DescentEnv-v0": {"random": 0.0, "classical": 1.0}})
    ppo, sac = agg["final"]["PPO"], agg["final"]["SAC"]
    assert ppo["runs"] == 1 and ppo["iqm"] == pytest.approx(0.92)
    assert np.isnan(ppo["ci_low"]) and np.isnan(ppo["ci_high"])  # no interval from one run
    assert sac["runs"] == 2 and sac["ci_low"] < sac["iqm"] < sac["ci_high"]
    assert np.isnan(agg["curve"]["PPO"]["ci_low"]).all() and np.isfinite(agg["curve"]["SAC"]["ci_low"]).all()
    files = plot_aggregate(agg, tmp_path / "plots")
    assert json.loads(files[1].read_text())["final"]["PPO"]["ci_low"] is None

    fig = aggregate_figure(agg)
    bars, curves = fig.axes[:2]
    assert [t.get_text() for t in bars.get_yticklabels()] == ["PPO (1 run)", "SAC (2 runs)"]
    assert [t.get_text() for t in bars.texts] == ["0.92", f"{sac['iqm']:.2f} [{sac['ci_low']:.2f}, {sac['ci_high']:.2f}]"]
    assert sum(isinstance(c, ErrorbarContainer) for c in bars.containers) == 1  # SAC's error bar only
    assert len(curves.collections) == 1  # SAC's band; PPO's curve has none
    # The figure also reads aggregate.json, where a missing interval is null.
    assert [t.get_text() for t in aggregate_figure(json.loads(files[1].read_text())).axes[0].texts][0] == "0.92"
