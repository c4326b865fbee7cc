"""Learning curves and the aggregate across environments, from run directories.

* ``learning_curves.png``: episode return against environment steps, one panel per environment,
  one line per algorithm: the mean over seeds of each run's smoothed curve, with a 95%
  bootstrap confidence band over seeds (like the paper's figure).
* ``kpis_<env>.png``: the same for return and the KPIs that matter for the environment
  (the ``kpis`` of its registry row, :class:`bluesky_gym.envs.registry.EnvEntry`; e.g. altitude
  error and final altitude for Descent, losses of separation and drift for SectorCR).
* Reference policies (``random``, ``classical``, and ``mvp`` where computed) are horizontal lines
  on the return panels. Runs are grouped by configuration: two configurations of an algorithm
  are two lines, each labelled by what differs, with their own seed count. Runs that have not
  logged an episode yet are left out (the caller says which); unfinished runs are counted in
  the legend.
* ``aggregate.png`` / ``aggregate.json``: per algorithm, the interquartile mean (IQM) of
  normalised scores across all environments and seeds, ``(score - random) / (classical -
  random)``, with 95% stratified bootstrap confidence intervals (runs resampled within each
  environment; none for an algorithm with one run per environment, which has no spread to
  resample): (left, bars with their CI and value) of the final held-out return, (right) of the
  smoothed training return over the fraction of training done.

A run's curve at step ``x`` is the mean over episodes that ended in the window ``(x - w, x]``,
``w`` = 5% of the longest run (no value before the first episode, nor in empty windows; the
aggregate curve carries a run's last value over empty windows and uses its first value before).
"""

from __future__ import annotations

import hashlib
import json
import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from bluesky_gym.envs.registry import ALTITUDE_ERROR, ENVIRONMENTS
from bluesky_gym.tasks import REFERENCE_POLICIES, RESOLUTION_REFERENCES
from bluesky_gym.training.io import DamagedFileError, atomic_path, atomic_write_json, read_csv_rows, read_csv_text, read_json

if TYPE_CHECKING:
    from bluesky_gym.training.pack import RunArtifact

Array = NDArray[np.float64]

#: (episode-log column, axis label) of the KPI panels.
CURVE_METRICS: tuple[tuple[str, str], ...] = (
    ("return", "episode return"),
    ("kpi_success", "success rate"),
    ("kpi_los_count", "losses of separation / episode"),
    ("kpi_min_separation_nm", "minimum separation [NM]"),
    ("kpi_mean_abs_drift_deg", "mean |drift| [deg]"),
    ("kpi_time_to_goal_s", "time to goal [s]"),
    ("length", "episode length [steps]"),
)
#: Colour and line style of each reference policy's line: the conflict resolution methods (``mvp``
#: and BlueSky's others) share the dash-dot line, one colour each (BlueSky's others in colours
#: outside matplotlib's default cycle, which the trained agents' curves draw from).
REFERENCE_STYLES: dict[str, tuple[str, str]] = dict(
    zip(
        (*REFERENCE_POLICIES, *RESOLUTION_REFERENCES),
        (("grey", ":"), ("black", "--"), ("tab:purple", "-."), ("darkgoldenrod", "-."), ("teal", "-."), ("magenta", "-.")),
        strict=True,
    )
)
GRID_POINTS = 100
WINDOW_FRACTION = 0.05
BOOTSTRAP = 2000
ALGO_COLOURS = {"PPO": "tab:blue", "SAC": "tab:orange", "TD3": "tab:green", "DDPG": "tab:red"}


@dataclass
class Run:
    """What the plots need from one run directory."""

    path: Path
    env_id: str
    algo: str
    seed: int
    total_timesteps: int
    columns: dict[str, Array]
    final_return: float | None
    config: dict[str, Any]
    finished: bool

    @property
    def digest(self) -> str:
        """Return the hash of the run's configuration without its seed (runs with equal digests differ only in seed).

        ``config.json``'s own ``digest`` covers the seed too; it is used only for runs without an ``identity``.
        """
        identity = self.config.get("identity")
        if not isinstance(identity, dict):
            return str(self.config.get("digest", ""))
        rest = {k: v for k, v in identity.items() if k != "seed"}
        return hashlib.sha256(json.dumps(rest, sort_keys=True).encode()).hexdigest()[:16]

    @property
    def timesteps(self) -> Array:
        """Return the timesteps at which each logged episode ended."""
        return self.columns.get("timesteps", np.zeros(0))

    def metric(self, name: str) -> Array:
        """Return a column with non-finite values as NaN (LoS counts only where there is traffic)."""
        if name == ALTITUDE_ERROR:
            return self._altitude_error()
        y = self.columns.get(name, np.full(self.timesteps.shape, np.nan)).copy()
        if name == "kpi_los_count":
            y[~np.isfinite(self.columns.get("kpi_min_separation_nm", np.full(y.shape, np.nan)))] = np.nan
        y[~np.isfinite(y)] = np.nan
        return y

    def _altitude_error(self) -> Array:
        """Mean |altitude - target| [m] over the flying steps of each episode (all but the last, which ends it)."""
        from bluesky_gym.environments.descent.task import ALT_DIF_REWARD_SCALE

        nan = np.full(self.timesteps.shape, np.nan)
        summed = self.columns.get("reward_altitude", nan)
        flying = np.maximum(self.columns.get("length", nan) - self.columns.get("terminated", np.zeros_like(nan)), 1.0)
        y = summed / ALT_DIF_REWARD_SCALE / flying
        y[~np.isfinite(y)] = np.nan
        return y


def find_runs(paths: Sequence[str | Path]) -> list[Path]:
    """Return every run directory (holding ``config.json``) at or below ``paths``."""
    found: list[Path] = []
    for p in map(Path, paths):
        if (p / "config.json").exists():
            found.append(p)
        elif p.is_dir():
            found.extend(sorted(c.parent for c in p.rglob("config.json")))
        else:
            raise FileNotFoundError(f"{p} is not a run or sweep directory")
    return list(dict.fromkeys(found))


def load_run(path: str | Path, artifact: RunArtifact | None = None) -> Run:
    """Read a run's config, episode log and final held-out return.

    The episode log is the run's ``episodes.csv``; for a run summary, the raw log in ``artifact``
    (the run files packed by ``bluesky-gym results pack``, checked against their SHA-256) where
    given and holding it, else the summary's ``curve.csv`` (one row per span of timesteps).
    """
    d = Path(path)
    cfg = read_json(d / "config.json")
    columns: dict[str, Array] = {}
    log = d / "episodes.csv" if (d / "episodes.csv").exists() else d / "curve.csv"  # a run summary keeps the binned curve
    packed = artifact.get(d / "episodes.csv") if artifact is not None and not (d / "episodes.csv").exists() else None
    if packed is not None:
        header, rows = read_csv_text(packed.decode("utf-8"))
    elif log.exists():
        header, rows = read_csv_rows(log)
    if packed is not None or log.exists():
        data = np.array([[_num(x) for x in r] for r in rows], dtype=np.float64).reshape(len(rows), len(header))
        columns = {h: data[:, j] for j, h in enumerate(header)}
    final = None
    if (d / "eval.json").exists():
        final = read_json(d / "eval.json")["summary"]["return"]["mean"]
    finished = (d / "result.json").exists()
    return Run(d, cfg["env_id"], cfg["algo"], int(cfg["seed"]), int(cfg["total_timesteps"]), columns, final, cfg, finished)


def _num(x: str) -> float:
    try:
        return float(x) if x != "" else math.nan
    except ValueError:
        return math.nan


def smoothed(x: Array, y: Array, grid: Array, window: float) -> Array:
    """Return the mean of ``y`` over points with ``x`` in ``(g - window, g]`` for each grid point ``g``."""
    ok = np.isfinite(y) & np.isfinite(x)
    x, y = x[ok], y[ok]
    order = np.argsort(x, kind="stable")
    x, y = x[order], y[order]
    csum = np.concatenate([[0.0], np.cumsum(y)])
    hi = np.searchsorted(x, grid, side="right")
    lo = np.searchsorted(x, grid - window, side="right")
    n = hi - lo
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(n > 0, (csum[hi] - csum[lo]) / np.maximum(n, 1), np.nan)


def bootstrap_mean_ci(curves: Array, rng: np.random.Generator, n_boot: int = BOOTSTRAP) -> tuple[Array, Array, Array]:
    """Return the mean over runs (axis 0) and its 95% percentile-bootstrap band, ignoring NaN."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN columns (no episode yet)
        mean = np.nanmean(curves, axis=0)
        if curves.shape[0] < 2:
            return mean, mean.copy(), mean.copy()
        idx = rng.integers(0, curves.shape[0], size=(n_boot, curves.shape[0]))
        boots = np.nanmean(curves[idx], axis=1)
        return mean, np.nanpercentile(boots, 2.5, axis=0), np.nanpercentile(boots, 97.5, axis=0)


def iqm(x: Array, axis: int = -1) -> Array:
    """Interquartile mean: the mean after cutting ``floor(n/4)`` values from each end."""
    x = np.sort(np.asarray(x, dtype=np.float64), axis=axis)
    n = x.shape[axis]
    k = int(math.floor(0.25 * n))
    return np.take(x, np.arange(k, n - k), axis=axis).mean(axis=axis)


def stratified_bootstrap_iqm(scores: dict[str, Array], rng: np.random.Generator, n_boot: int = BOOTSTRAP) -> tuple[Array, Array, Array]:
    """IQM of pooled scores and its 95% CI, resampling runs within each environment.

    Args:
        scores: Environment id -> normalised scores of its runs (1-D, or 2-D runs x points).
        rng: Random generator.
        n_boot: Bootstrap samples.

    """
    pooled = np.concatenate([np.asarray(v, dtype=np.float64) for v in scores.values()], axis=0)
    point = iqm(pooled, axis=0)
    samples = []
    for _ in range(n_boot):
        parts = [v[rng.integers(0, len(v), len(v))] for v in map(np.asarray, scores.values())]
        samples.append(iqm(np.concatenate(parts, axis=0), axis=0))
    s = np.asarray(samples)
    return point, np.percentile(s, 2.5, axis=0), np.percentile(s, 97.5, axis=0)


def pyplot() -> Any:
    """Import matplotlib's pyplot with the non-interactive Agg backend, or raise naming the extra."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError as exc:
        from bluesky_gym.core.extras import missing_extra

        raise missing_extra("plotting needs matplotlib", "train") from exc
    return plt


def _save(fig: Any, path: Path) -> None:
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=120, bbox_inches="tight", format="png")


def _groups(runs: Sequence[Run]) -> dict[str, dict[str, list[Run]]]:
    """Environment -> configuration label -> runs (the seeds of one configuration)."""
    by_env: dict[str, dict[tuple[str, str], list[Run]]] = {}
    for r in runs:
        by_env.setdefault(r.env_id, {}).setdefault((r.algo, r.digest), []).append(r)
    out: dict[str, dict[str, list[Run]]] = {}
    for env_id, configs in by_env.items():
        labelled = {}
        for (algo, _), rs in configs.items():
            siblings = [v[0] for (a, _), v in configs.items() if a == algo]
            labelled[config_label(rs[0], siblings)] = rs
        out[env_id] = dict(sorted(labelled.items()))
    return out


def config_label(run: Run, siblings: Sequence[Run]) -> str:
    """Label a run's configuration among those of the same algorithm: the algorithm, plus what differs."""
    if len(siblings) <= 1:
        return run.algo
    identity = run.config.get("identity", {})
    flat = {**{k: v for k, v in identity.items() if k not in ("hyperparams", "seed")}, **identity.get("hyperparams", {})}
    others = [
        {
            **{k: v for k, v in o.config.get("identity", {}).items() if k not in ("hyperparams", "seed")},
            **o.config.get("identity", {}).get("hyperparams", {}),
        }
        for o in siblings
    ]
    differs = [k for k in sorted(flat) if any(o.get(k) != flat[k] for o in others)]
    text = ", ".join(f"{k}={flat[k]}" for k in differs if not isinstance(flat[k], dict))
    return f"{run.algo} {text}" if text and len(text) <= 40 else f"{run.algo} config {run.digest[:6]}"


def _curves(runs: Sequence[Run], metric: str, grid: Array, window: float) -> Array:
    rows = []
    for r in runs:
        if r.timesteps.size == 0:
            rows.append(np.full(grid.shape, np.nan))
            continue
        rows.append(smoothed(r.timesteps, r.metric(metric), grid, window))
    return np.asarray(rows)


def _fill_gaps(curve: Array) -> Array:
    """Carry the last value over empty windows; before the first value, use the first."""
    y = np.asarray(curve, dtype=np.float64).copy()
    valid = np.isfinite(y)
    if not valid.any():
        return y
    idx = np.where(valid, np.arange(y.size), 0)
    np.maximum.accumulate(idx, out=idx)
    first = int(np.argmax(valid))
    y = y[idx]
    y[:first] = y[first]
    return y


def kpi_panels(env_id: str, runs: Sequence[Run]) -> list[tuple[str, str]]:
    """The (metric, label) panels of an environment's KPI figure: its registry row's ``kpis``, else every KPI that varies.

    Metrics without a finite value in any run are left out.
    """
    table = next((e.kpis for e in ENVIRONMENTS if e.id == env_id and e.kpis), None)  # a -v1 row has its -v0 row's
    candidates = table if table is not None else CURVE_METRICS
    out = []
    for metric, label in candidates:
        values = np.concatenate([r.metric(metric) for r in runs]) if runs else np.zeros(0)
        values = values[np.isfinite(values)]
        if values.size == 0:
            continue
        if table is None and metric != "return" and np.ptp(values) <= 1e-9 * max(1.0, float(np.abs(values).max())):
            continue  # near-constant: says nothing
        out.append((metric, label))
    return out


def plot_learning_curves(
    runs: Sequence[Run], out_dir: str | Path, seed: int = 0, references: dict[str, dict[str, float]] | None = None
) -> list[Path]:
    """Write ``learning_curves.png`` and one ``kpis_<env>.png`` per environment.

    Args:
        runs: The runs; those without a logged episode are left out.
        out_dir: Output directory.
        seed: Seed of the bootstrap.
        references: Environment id -> reference policy name -> mean return (drawn as lines).

    Raises:
        ValueError: No run has logged an episode yet.

    """
    plt = pyplot()
    written = []
    for name, fig in learning_curve_figures(runs, seed, references).items():
        path = Path(out_dir) / f"{name}.png"
        _save(fig, path)
        plt.close(fig)
        written.append(path)
    return written


def learning_curve_figures(runs: Sequence[Run], seed: int = 0, references: dict[str, dict[str, float]] | None = None) -> dict[str, Any]:
    """The figures of :func:`plot_learning_curves`, by file stem (``learning_curves``, ``kpis_<env>``)."""
    runs = [r for r in runs if r.timesteps.size]
    if not runs:
        raise ValueError("no run has logged an episode yet: nothing to plot")
    refs = references or {}
    plt = pyplot()
    rng = np.random.default_rng(seed)
    groups = _groups(runs)
    figures = {}
    n = len(groups)
    cols = min(n, 4)
    fig, axes = plt.subplots(math.ceil(n / cols), cols, figsize=(4.2 * cols, 3.2 * math.ceil(n / cols)), squeeze=False)
    for ax, (env_id, by_config) in zip(axes.flat, groups.items(), strict=False):
        _panel(ax, by_config, "return", rng, refs.get(env_id, {}))
        ax.set_title(env_id)
        ax.set_ylabel("episode return")
    for ax in list(axes.flat)[n:]:
        ax.set_visible(False)
    fig.tight_layout()
    figures["learning_curves"] = fig

    for env_id, by_config in groups.items():
        metrics = kpi_panels(env_id, [r for rs in by_config.values() for r in rs])
        if not metrics:
            continue
        cols = min(len(metrics), 3)
        rows = math.ceil(len(metrics) / cols)
        fig, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, 3.0 * rows), squeeze=False)
        for ax, (metric, label) in zip(axes.flat, metrics, strict=False):
            _panel(ax, by_config, metric, rng, refs.get(env_id, {}) if metric == "return" else {})
            ax.set_ylabel(label)
        for ax in list(axes.flat)[len(metrics) :]:
            ax.set_visible(False)
        fig.suptitle(env_id)
        fig.tight_layout()
        figures[f"kpis_{env_id}"] = fig
    return figures


def legend_label(label: str, runs: Sequence[Run]) -> str:
    """Legend entry of one configuration: its label, its number of seeds and of unfinished runs."""
    seeds = len({r.seed for r in runs})
    unfinished = sum(not r.finished for r in runs)
    return f"{label} ({seeds} seed{'s' if seeds != 1 else ''}{f', {unfinished} unfinished' if unfinished else ''})"


def _panel(ax: Any, by_config: dict[str, list[Run]], metric: str, rng: np.random.Generator, references: dict[str, float]) -> None:
    horizon = max(max(r.total_timesteps, float(np.nanmax(r.timesteps, initial=0))) for rs in by_config.values() for r in rs)
    grid = np.linspace(0.0, horizon, GRID_POINTS + 1)[1:]
    window = WINDOW_FRACTION * horizon
    for label, rs in by_config.items():
        curves = _curves(rs, metric, grid, window)
        mean, lo, hi = bootstrap_mean_ci(curves, rng)
        colour = ALGO_COLOURS.get(label) if label in ALGO_COLOURS else None
        line = ax.plot(grid, mean, label=legend_label(label, rs), color=colour)[0]
        ax.fill_between(grid, lo, hi, alpha=0.25, color=line.get_color(), linewidth=0)
    for name, value in references.items():
        colour, style = REFERENCE_STYLES.get(name, ("grey", "-."))
        if np.isfinite(value):
            ax.axhline(value, color=colour, ls=style, lw=1.0, label=name)
    ax.set_xlabel("environment steps")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)


def aggregate(runs: Sequence[Run], references: dict[str, dict[str, float]], seed: int = 0) -> dict[str, Any]:
    """IQM of normalised scores per algorithm across environments, with bootstrap CIs.

    Args:
        runs: The runs (environments without references are left out).
        references: Environment id -> ``{"random": mean return, "classical": mean return}``.
        seed: Seed of the bootstrap.

    Returns:
        ``{"final": {algo: {iqm, ci_low, ci_high, runs, envs}}, "curve": {algo: {x, iqm, ci_low,
        ci_high}}, "normalised_runs": [...]}``. An algorithm with one run per environment has no
        confidence interval (``ci_low`` and ``ci_high`` are NaN, ``null`` in JSON).

    """
    from bluesky_gym.training.evaluation import normalised_score

    rng = np.random.default_rng(seed)
    grid = np.linspace(0.0, 1.0, GRID_POINTS + 1)[1:]
    final: dict[str, dict[str, list[float]]] = {}
    curve: dict[str, dict[str, list[Array]]] = {}
    listing = []
    for r in runs:
        ref = references.get(r.env_id)
        if ref is None:
            continue
        span = ref["classical"] - ref["random"]
        score = r.final_return
        if score is None and r.timesteps.size:
            tail = r.columns["return"][r.timesteps >= 0.9 * r.timesteps.max()]
            score = float(np.mean(tail)) if tail.size else None
        if score is not None:
            norm = normalised_score(score, ref["random"], ref["classical"])
            if np.isfinite(norm):
                final.setdefault(r.algo, {}).setdefault(r.env_id, []).append(norm)
                listing.append({"env_id": r.env_id, "algo": r.algo, "seed": r.seed, "score": score, "normalised": norm})
        if r.timesteps.size and np.isfinite(span) and abs(span) > 0:
            c = smoothed(r.timesteps / max(r.total_timesteps, 1), r.columns["return"], grid, WINDOW_FRACTION)
            curve.setdefault(r.algo, {}).setdefault(r.env_id, []).append(_fill_gaps((c - ref["random"]) / span))
    out: dict[str, Any] = {"final": {}, "curve": {}, "normalised_runs": listing, "references": references}
    for algo, by_env in sorted(final.items()):
        point, lo, hi = stratified_bootstrap_iqm({k: np.asarray(v) for k, v in by_env.items()}, rng)
        if max(map(len, by_env.values())) < 2:  # one run per environment: resampling cannot vary, there is no interval
            lo = hi = np.asarray(math.nan)
        out["final"][algo] = {
            "iqm": float(point),
            "ci_low": float(lo),
            "ci_high": float(hi),
            "runs": sum(map(len, by_env.values())),
            "envs": sorted(by_env),
        }
    for algo, curves in sorted(curve.items()):
        point, lo, hi = stratified_bootstrap_iqm({k: np.asarray(v) for k, v in curves.items()}, rng, n_boot=500)
        if max(map(len, curves.values())) < 2:
            lo = hi = np.full_like(point, math.nan)
        out["curve"][algo] = {"x": grid.tolist(), "iqm": point.tolist(), "ci_low": lo.tolist(), "ci_high": hi.tolist()}
    return out


def plot_aggregate(agg: dict[str, Any], out_dir: str | Path) -> list[Path]:
    """Write ``aggregate.png`` and ``aggregate.json``."""
    plt = pyplot()
    out = Path(out_dir)
    atomic_write_json(out / "aggregate.json", agg)
    fig = aggregate_figure(agg)
    _save(fig, out / "aggregate.png")
    plt.close(fig)
    return [out / "aggregate.png", out / "aggregate.json"]


def aggregate_figure(agg: dict[str, Any]) -> Any:
    """The figure of :func:`plot_aggregate`: a bar per algorithm with its CI and value, and the IQM curves."""
    plt = pyplot()
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 3.6))
    algos = list(agg["final"])
    intervals = 0
    for k, algo in enumerate(algos):
        s = agg["final"][algo]
        colour = ALGO_COLOURS.get(algo)
        if _finite(s["ci_low"]) and _finite(s["ci_high"]):
            err = [[s["iqm"] - s["ci_low"]], [s["ci_high"] - s["iqm"]]]
            ax1.barh([k], [s["iqm"]], xerr=err, color=colour, alpha=0.8, capsize=4, height=0.6)
            text, end = f"{s['iqm']:.2f} [{s['ci_low']:.2f}, {s['ci_high']:.2f}]", max(s["ci_high"], s["iqm"])
            intervals += 1
        else:  # one run per environment: no interval to draw
            ax1.barh([k], [s["iqm"]], color=colour, alpha=0.8, height=0.6)
            text, end = f"{s['iqm']:.2f}", s["iqm"]
        ax1.annotate(
            text,
            (end, k),
            xytext=(4, 0),
            textcoords="offset points",
            va="center",
            fontsize=8,
        )
    ax1.set_yticks(range(len(algos)), [f"{a} ({n} run{'s' if n != 1 else ''})" for a in algos for n in [agg["final"][a]["runs"]]])
    ax1.set_ylim(-0.6, max(len(algos), 1) - 0.4)
    ax1.axvline(0.0, color="grey", lw=0.8, ls="--")
    ax1.axvline(1.0, color="black", lw=0.8, ls="--")
    ax1.set_xlabel("IQM normalised held-out score\n(0 = random, 1 = classical)")
    ax1.grid(alpha=0.3, axis="x")
    for algo, c in agg["curve"].items():
        colour = ALGO_COLOURS.get(algo)
        ax2.plot(c["x"], c["iqm"], label=algo, color=colour)
        if any(_finite(v) for v in c["ci_low"]):
            lo, hi = (np.array([math.nan if v is None else v for v in c[k]], dtype=np.float64) for k in ("ci_low", "ci_high"))
            ax2.fill_between(c["x"], lo, hi, alpha=0.25, color=colour, linewidth=0)
    ax2.axhline(0.0, color="grey", lw=0.8, ls="--")
    ax2.axhline(1.0, color="black", lw=0.8, ls="--")
    ax2.set_xlabel("fraction of training")
    ax2.set_ylabel("IQM normalised training return")
    ax2.grid(alpha=0.3)
    if agg["curve"]:
        ax2.legend(fontsize=8)
    envs = sorted({e for s in agg["final"].values() for e in s["envs"]})
    cis = "95% bootstrap CIs over runs" if intervals or not algos else "one run each: no confidence interval"
    if len(envs) == 1:
        fig.suptitle(f"{envs[0]}: normalised scores ({cis})")
    else:
        fig.suptitle(f"Aggregate over {len(envs)} environments ({cis.replace('bootstrap', 'stratified bootstrap')})")
    fig.tight_layout()
    return fig


def _finite(x: Any) -> bool:
    """True for a finite number (a missing interval is NaN in memory and None in ``aggregate.json``)."""
    return x is not None and bool(np.isfinite(x))


def find_references(run_dirs: Sequence[Path], env_ids: Sequence[str]) -> dict[str, dict[str, float]]:
    """Return reference returns cached in a ``references`` directory above the runs, if any."""
    from bluesky_gym.training.evaluation import reference_returns

    found: dict[str, dict[str, float]] = {}
    for d in run_dirs:
        for parent in [d, *d.parents]:
            for env_id in env_ids:
                p = parent / "references" / f"{env_id}.json"
                if env_id not in found and p.exists():
                    try:
                        data = read_json(p)
                        found[env_id] = reference_returns({k: data[k] for k in REFERENCE_STYLES if k in data})
                    except (DamagedFileError, KeyError, TypeError):
                        continue  # a damaged cache: the scores are computed again
    return found
