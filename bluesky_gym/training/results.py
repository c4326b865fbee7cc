"""The results page: KPI tables, learning curves and aggregate scores of sweeps, as Markdown.

:func:`build_results` reads one or more sweep directories (``bluesky-gym sweep --out DIR``) and
writes a Markdown page with its figures; ``bluesky-gym results`` is its command line. The page is
generated, never edited by hand: it names the command that made it, and regenerating it from the
same directories gives the same text.

Per environment the page has a KPI table: one row per reference policy (``random``,
``classical`` and, where the environment has traffic, the conflict resolution methods ``mvp``,
``eby``, ``swarm`` and ``ssd``: :data:`PAGE_REFERENCES`) and per trained algorithm, each cell the
mean with a 95% confidence interval; a reference that applies but has no record yet is named
below the table as not evaluated. For a reference policy the interval is over the held-out episodes (the
policies are deterministic given the scenario); for a trained algorithm it is a two-level
bootstrap over seeds and, within each resampled seed, over its held-out episodes, so both
sources of variation are in it. Below the table, the learning curves of the environment (mean
over seeds with a 95% bootstrap band) and its KPI curves.

The aggregate compares the trained algorithms across the environments of one environment
version (``-v0`` and ``-v1`` apart: different MDPs), on the normalised held-out score
``(score - random) / (classical - random)`` (0 = random, 1 = classical controller): interquartile
mean (IQM), mean, median and optimality gap with 95% stratified bootstrap intervals, and the
probability that one algorithm improves on another, computed with ``rliable``.
"""

from __future__ import annotations

import dataclasses
import math
import shlex
import zlib
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from bluesky_gym.core.extras import require_rliable
from bluesky_gym.tasks import REFERENCE_POLICIES, RESOLUTION_REFERENCES
from bluesky_gym.training import ALGORITHMS
from bluesky_gym.training.evaluation import KPI_COLUMNS, format_number, normalised_score
from bluesky_gym.training.io import atomic_path, read_csv_rows, read_json
from bluesky_gym.training.plotting import Run, find_runs, load_run, plot_learning_curves, smoothed

if TYPE_CHECKING:
    from bluesky_gym.training.pack import RunArtifact

#: Bootstrap resamples of every confidence interval on the page.
BOOTSTRAP = 2000
#: The reference policies a page scores, in table order: ``random`` and ``classical`` (the
#: normalised score's 0 and 1), then the conflict resolution methods of the environments with
#: traffic, ``mvp`` and BlueSky's other methods ``eby``, ``swarm``, ``ssd``.
PAGE_REFERENCES: tuple[str, ...] = (*REFERENCE_POLICIES, *RESOLUTION_REFERENCES)
#: The columns of a reference policy's per-episode record (the seed and the KPIs the page reads).
REFERENCE_RECORD_COLUMNS: tuple[str, ...] = ("seed", *dict.fromkeys(key for _, key, _ in KPI_COLUMNS))
#: The command that reproduces the paper's full grid on a Ray cluster.
PAPER_GRID_COMMAND = "bluesky-gym sweep --env all --algos all --seeds 0 1 2 --steps 2e6 --address ray://HEAD:10001 --out sweeps/paper"


@dataclass
class Row:
    """One line of a KPI table: a policy's KPI means and 95% intervals on one environment."""

    policy: str
    runs: int  # seeds (1 for a reference policy)
    episodes: int  # held-out episodes in all
    kpis: dict[str, tuple[float, float, float]] = field(default_factory=dict)  # column -> (mean, low, high)


@dataclass
class EnvResults:
    """Everything the page shows for one environment."""

    env_id: str
    rows: list[Row]
    runs: list[Run]
    references: dict[str, float]  # reference policy -> mean held-out return
    missing: list[str] = field(default_factory=list)  # reference policies that apply but have no record yet


def episode_table(run_dir: Path, name: str = "eval_episodes.csv") -> dict[str, np.ndarray] | None:
    """The held-out episodes of a finished run (``eval_episodes.csv``), by column; None if absent."""
    path = run_dir / name
    if not path.exists():
        return None
    header, rows = read_csv_rows(path)
    return {h: np.array([_num(r[j]) for r in rows], dtype=np.float64) for j, h in enumerate(header)}


def _num(x: str) -> float:
    try:
        return float(x) if x != "" else math.nan
    except ValueError:
        return math.nan


def _kpi_values(table: dict[str, np.ndarray], key: str) -> np.ndarray:
    """One KPI column with the conventions of the evaluation summaries (non-finite values dropped)."""
    n = len(next(iter(table.values()))) if table else 0
    vals = table.get(key, np.full(n, np.nan))
    if key == "kpi_los_count":  # a LoS count is a KPI only in episodes with traffic
        vals = vals[np.isfinite(table.get("kpi_min_separation_nm", np.full(n, np.nan)))]
    return vals[np.isfinite(vals)]


def seed_episode_bootstrap(groups: Sequence[np.ndarray], rng: np.random.Generator, n_boot: int = BOOTSTRAP) -> tuple[float, float, float]:
    """Mean over seeds of per-seed episode means, with a two-level 95% bootstrap interval.

    Each resample draws the seeds with replacement, then each drawn seed's episodes with
    replacement, and takes the mean over seeds of the episode means.

    Args:
        groups: One array of episode values per seed (empty arrays are left out).
        rng: The bootstrap's generator.
        n_boot: Number of resamples.

    Returns:
        ``(mean, low, high)``; all NaN when there is no value.

    """
    groups = [np.asarray(g, dtype=np.float64) for g in groups if len(g)]
    if not groups:
        return (math.nan, math.nan, math.nan)
    point = float(np.mean([g.mean() for g in groups]))
    stats = np.empty(n_boot)
    k = len(groups)
    for b in range(n_boot):
        picked = rng.integers(0, k, size=k)
        stats[b] = np.mean([groups[i][rng.integers(0, len(groups[i]), size=len(groups[i]))].mean() for i in picked])
    lo, hi = np.percentile(stats, [2.5, 97.5])
    return (point, float(lo), float(hi))


def page_reference_names(env_id: str) -> tuple[str, ...]:
    """The reference policies the page scores on an environment: ``random``, ``classical``, and the four resolution methods where it has ``mvp``."""
    from bluesky_gym.training.policies import optional_reference_names, reference_names

    return reference_names(env_id) + optional_reference_names(env_id)


def _expected_references(env_id: str) -> tuple[str, ...]:
    """:func:`page_reference_names` of a registered environment; none for another id (nothing to say is missing)."""
    try:
        return page_reference_names(env_id)
    except ValueError:
        return ()


def row_generator(seed: int, env_id: str, policy: str) -> np.random.Generator:
    """The bootstrap generator of one row of a KPI table, from the page's seed, the environment and the row's policy.

    Each row draws from its own stream, so a row added to the page (a new reference policy, a new
    algorithm) leaves the intervals of the others as they were.
    """
    return np.random.default_rng([seed, zlib.crc32(env_id.encode()), zlib.crc32(policy.encode())])


def reference_episode_dir(sweep_dir: str | Path) -> Path:
    """Where the per-episode records of a sweep's reference policies are kept."""
    return Path(sweep_dir) / "references" / "episodes"


def _reference_table(sweep_dirs: Sequence[Path], env_id: str, name: str) -> dict[str, np.ndarray] | None:
    for d in sweep_dirs:
        path = reference_episode_dir(d) / f"{env_id}_{name}_episodes.csv"
        if path.exists():
            return episode_table(path.parent, path.name)
    return None


def complete_references(sweep_dirs: Sequence[str | Path], episodes: int | None = None) -> list[str]:
    """Evaluate the reference policies whose per-episode records a sweep lacks, and keep them.

    A sweep caches the summaries of ``random`` and ``classical`` per environment; the page needs
    their per-episode records (for its intervals) and every reference policy that applies (one
    added after the sweep too): ``random``, ``classical``, and where an environment has ``mvp``,
    ``mvp`` and the other resolution methods ``eby``, ``swarm`` and ``ssd``. Those missing are
    evaluated on the first held-out episodes, as many as the runs' evaluations (or ``episodes``),
    and written to ``references/episodes/`` as soon as each is done, one record per environment
    and policy, so an interrupted run resumes where it stopped. The work goes policy by policy in
    :data:`PAGE_REFERENCES` order (the slow ``ssd`` last, environment by environment). A record
    keeps the columns the page reads (:data:`REFERENCE_RECORD_COLUMNS`). A record another of the
    sweeps already keeps (with at least as many episodes) is not evaluated again: the page reads
    the first sweep's that has it.

    Returns:
        One line per evaluation made, for the user.

    """
    from bluesky_gym.training.evaluation import EvalResult, evaluate, make_policy, save_result

    done = []
    dirs = [Path(d) for d in sweep_dirs]
    todo: list[tuple[int, Path, str, str, int]] = []  # (policy's place, sweep, env, policy, episodes)
    for d in dirs:
        runs = [load_run(r) for r in find_runs([d])]
        for env_id in sorted({r.env_id for r in runs}):
            n = episodes
            if n is None:
                n = max(int(read_json(r.path / "config.json").get("eval_episodes", 0)) for r in runs if r.env_id == env_id) or 50
            todo += [(PAGE_REFERENCES.index(name), d, env_id, name, n) for name in page_reference_names(env_id)]
    for _, d, env_id, name, n in sorted(todo, key=lambda t: t[0]):
        kept = _reference_table(dirs, env_id, name)
        if kept is not None and len(next(iter(kept.values()), ())) >= n:
            continue  # this sweep's or an earlier one's: the same first held-out episodes
        result = evaluate(env_id, make_policy(name, env_id), n)
        records = [{k: e[k] for k in REFERENCE_RECORD_COLUMNS if k in e} for e in result.episodes]
        save_result(EvalResult(env_id, name, records, result.wall_time_s), reference_episode_dir(d), stem=f"{env_id}_{name}")
        done.append(f"{env_id}: evaluated {name} on {n} held-out episodes in {result.wall_time_s:.0f} s -> {reference_episode_dir(d)}")
    return done


def collect(sweep_dirs: Sequence[str | Path], seed: int = 0, reps: int = BOOTSTRAP, artifact: RunArtifact | None = None) -> list[EnvResults]:
    """Read the runs and references of the sweeps, per environment (sorted by id).

    ``artifact`` (the packed run files, :mod:`bluesky_gym.training.pack`) gives summarised runs
    their raw episode logs back.

    Raises:
        FileNotFoundError: If a directory holds no run.

    """
    dirs = [Path(d) for d in sweep_dirs]
    run_dirs = find_runs(dirs)
    if not run_dirs:
        raise FileNotFoundError(f"no run directories (with config.json) below {', '.join(map(str, dirs))}")
    loaded = [load_run(d, artifact) for d in run_dirs]
    labels = page_labels(loaded)
    by_env: dict[str, list[tuple[Run, dict[str, np.ndarray] | None]]] = {}
    for run in loaded:
        run = dataclasses.replace(run, algo=labels[run.path])
        by_env.setdefault(run.env_id, []).append((run, episode_table(run.path)))
    out = []
    for env_id in sorted(by_env):
        rows = []
        ref_returns = {}
        missing = []
        for name in PAGE_REFERENCES:
            table = _reference_table(dirs, env_id, name)
            if table is None:
                if name in _expected_references(env_id):
                    missing.append(name)
                continue
            row = Row(name, 1, len(next(iter(table.values()))))
            rng = row_generator(seed, env_id, name)
            for col, key, _ in KPI_COLUMNS:
                values = _kpi_values(table, key)
                if len(values):
                    row.kpis[col] = seed_episode_bootstrap([values], rng, reps)
            rows.append(row)
            ref_returns[name] = row.kpis["return"][0]
        by_algo: dict[str, list[dict[str, np.ndarray]]] = {}
        for run, table in by_env[env_id]:
            if table is not None and table:
                by_algo.setdefault(run.algo, []).append(table)
        for algo in sorted(by_algo):
            tables = by_algo[algo]
            row = Row(algo, len(tables), sum(len(next(iter(t.values()))) for t in tables))
            rng = row_generator(seed, env_id, algo)
            for col, key, _ in KPI_COLUMNS:
                groups = [_kpi_values(t, key) for t in tables]
                if any(len(g) for g in groups):
                    row.kpis[col] = seed_episode_bootstrap(groups, rng, reps)
            rows.append(row)
        out.append(EnvResults(env_id, rows, [r for r, _ in by_env[env_id]], ref_returns, missing))
    return out


def _steps(n: int) -> str:
    """A step budget in short form: ``2e6``, ``2.5e5``, ``20000`` below 1e5."""
    if n < 100_000:
        return f"{n:,}"
    exponent = int(math.floor(math.log10(n)))
    mantissa = n / 10**exponent
    return f"{mantissa:g}e{exponent}"


def page_labels(runs: Sequence[Run]) -> dict[Path, str]:
    """The name of each run's algorithm on the page: the algorithm, plus its budget where the page has several.

    Runs of one algorithm that differ in trainer, step budget or number of batched environments
    are different rows, named by what differs, e.g. ``PPO (2e7 steps, 1024 envs)``; where the
    page's runs have different step budgets, every row names its own (``SAC (20,000 steps)``
    beside ``PPO (2e6 steps, 16 envs)``). Other differences (a per-environment learning rate) do
    not split a row.
    """

    def budget(r: Run) -> tuple[str, int, int]:
        identity = r.config.get("identity", {})
        return (str(identity.get("trainer", "sb3")), int(r.total_timesteps), int(identity.get("n_envs", r.config.get("n_envs", 1))))

    out = {}
    budgets_differ = len({budget(r)[1] for r in runs}) > 1  # then every row says its budget
    for algo in {r.algo for r in runs}:
        mine = [r for r in runs if r.algo == algo]
        kinds = {budget(r) for r in mine}
        for r in mine:
            trainer, steps, n_envs = budget(r)
            parts = []
            if len({k[0] for k in kinds}) > 1:
                parts.append(f"{trainer} trainer")
            if budgets_differ:
                parts.append(f"{_steps(steps)} steps")
            if len({k[2] for k in kinds}) > 1:
                parts.append(f"{n_envs} env{'s' if n_envs != 1 else ''}")
            out[r.path] = f"{algo} ({', '.join(parts)})" if parts else algo
    return out


def algorithm_of(label: str) -> str:
    """The algorithm of a page label (``PPO`` of ``PPO (2e7 steps)``)."""
    return label.split(" ", 1)[0]


def env_version(env_id: str) -> str:
    """The version suffix of an id (``"v0"`` for ``DescentEnv-v0``)."""
    return env_id.rsplit("-", 1)[-1] if "-" in env_id else ""


def normalised_matrix(results: Sequence[EnvResults], algo: str) -> tuple[np.ndarray, list[str]]:
    """Normalised held-out scores of ``algo``: array (seeds, environments) and the environment ids.

    Environments without both ``random`` and ``classical`` references, or where the two are
    equal, are left out; with unequal seed counts, each environment keeps its first ``min``
    seeds (by seed number) so the matrix is rectangular.
    """
    columns: list[list[float]] = []
    envs = []
    for er in results:
        if "random" not in er.references or "classical" not in er.references:
            continue
        scores = [
            (r.seed, normalised_score(r.final_return, er.references["random"], er.references["classical"]))
            for r in er.runs
            if r.algo == algo and r.final_return is not None
        ]
        scores = [s for s in sorted(scores) if np.isfinite(s[1])]
        if scores:
            columns.append([s for _, s in scores])
            envs.append(er.env_id)
    if not columns:
        return np.zeros((0, 0)), []
    k = min(map(len, columns))
    return np.array([c[:k] for c in columns], dtype=np.float64).T, envs


def aggregate_scores(results: Sequence[EnvResults], seed: int = 0, reps: int = BOOTSTRAP) -> dict[str, Any]:
    """IQM, mean, median, optimality gap and probability of improvement with ``rliable``.

    Returns:
        ``{"algos": {algo: {metric: (point, low, high), "seeds": n, "envs": [...]}},
        "improvement": {(a, b): (p, low, high)}}``; empty when no algorithm has scores.

    """
    library, metrics = require_rliable()
    matrices = {}
    for algo in sorted({r.algo for er in results for r in er.runs}):
        m, envs = normalised_matrix(results, algo)
        if m.size:
            matrices[algo] = (m, envs)
    out: dict[str, Any] = {"algos": {}, "improvement": {}}
    if not matrices:
        return out
    names = ("IQM", "mean", "median", "optimality gap")

    def four(x: np.ndarray) -> np.ndarray:
        return np.array([metrics.aggregate_iqm(x), metrics.aggregate_mean(x), metrics.aggregate_median(x), metrics.aggregate_optimality_gap(x)])

    scores = {a: m for a, (m, _) in matrices.items()}
    points, intervals = _interval_estimates(library, scores, four, reps, seed)
    for algo, (m, envs) in matrices.items():
        out["algos"][algo] = {
            **{name: (float(points[algo][j]), float(intervals[algo][0, j]), float(intervals[algo][1, j])) for j, name in enumerate(names)},
            "seeds": int(m.shape[0]),
            "envs": envs,
        }
    algos = list(matrices)
    for i, a in enumerate(algos):
        for b in algos[i + 1 :]:
            if matrices[a][1] != matrices[b][1]:
                continue  # probability of improvement needs the same environments
            pairs = {f"{a},{b}": (matrices[a][0], matrices[b][0])}
            p, ci = _interval_estimates(library, pairs, metrics.probability_of_improvement, reps, seed)
            key = f"{a},{b}"
            out["improvement"][(a, b)] = (float(np.ravel(p[key])[0]), float(np.ravel(ci[key])[0]), float(np.ravel(ci[key])[1]))
    return out


def _interval_estimates(library: Any, scores: dict[str, Any], func: Any, reps: int, seed: int) -> tuple[dict[str, Any], dict[str, Any]]:
    """``rliable``'s stratified bootstrap, seeded (its seeding argument is deprecated in ``arch``, which warns).

    rliable draws its resamples from NumPy's global generator (its ``random_state`` reaches only
    ``arch``), so the global generator is seeded for the call and restored afterwards: the same
    runs give the same intervals in every process.
    """
    import warnings

    saved = np.random.get_state()
    np.random.seed(seed)
    try:
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", message="random_state is deprecated", category=FutureWarning)
            points, intervals = library.get_interval_estimates(scores, func, reps=reps, random_state=np.random.RandomState(seed))
    finally:
        np.random.set_state(saved)
    return points, intervals


def _cell(v: tuple[float, float, float] | None) -> str:
    if v is None or not np.isfinite(v[0]):
        return "–"
    return f"{format_number(v[0])} [{format_number(v[1])}, {format_number(v[2])}]"


def kpi_table(er: EnvResults) -> list[str]:
    """Markdown lines of an environment's KPI table."""
    cols = [(c, label) for c, _, label in KPI_COLUMNS if any(c in r.kpis for r in er.rows)]
    lines = ["| policy | seeds | episodes | " + " | ".join(label for _, label in cols) + " |"]
    lines.append("|---|---:|---:|" + "---:|" * len(cols))
    for r in er.rows:
        seeds = "–" if r.policy in PAGE_REFERENCES else str(r.runs)
        lines.append(f"| {r.policy} | {seeds} | {r.episodes} | " + " | ".join(_cell(r.kpis.get(c)) for c, _ in cols) + " |")
    if er.missing:
        lines += ["", f"Not evaluated yet (no held-out record): {', '.join(er.missing)}; `bluesky-gym results` evaluates it when run again."]
    return lines


def _budget(runs: Sequence[Run], run_configs: dict[Path, dict[str, Any]]) -> list[str]:
    """Markdown lines stating exactly what was run."""
    lines = ["| environment | algorithm | seeds | steps per run | batched envs | held-out episodes | finished |", "|---|---|---|---:|---:|---:|---:|"]
    groups: dict[tuple[str, str], list[Run]] = {}
    for r in runs:
        groups.setdefault((r.env_id, r.algo), []).append(r)
    for (env_id, algo), rs in sorted(groups.items()):
        cfgs = [run_configs[r.path] for r in rs]
        steps = sorted({int(c["total_timesteps"]) for c in cfgs})
        n_envs = sorted({int(c.get("n_envs", 1)) for c in cfgs})
        episodes = sorted({int(c.get("eval_episodes", 0)) for c in cfgs})
        finished = sum(r.final_return is not None for r in rs)
        lines.append(
            f"| {env_id} | {algo} | {' '.join(str(r.seed) for r in sorted(rs, key=lambda r: r.seed))} | "
            f"{'/'.join(f'{s:,}' for s in steps)} | {'/'.join(map(str, n_envs))} | {'/'.join(map(str, episodes))} | {finished}/{len(rs)} |"
        )
    return lines


def _not_run(runs: Sequence[Run]) -> list[str]:
    """A line naming the algorithms of the package that no run of the page used (none when all were)."""
    missing = [a for a in ALGORITHMS if a not in {algorithm_of(r.algo) for r in runs}]
    return [f"Not run for this page: {', '.join(missing)}.", ""] if missing else []


def _plot_aggregate(agg: dict[str, Any], version: str, path: Path) -> None:
    from bluesky_gym.training.plotting import ALGO_COLOURS, pyplot

    plt = pyplot()
    algos = list(agg["algos"])
    names = ("IQM", "mean", "median", "optimality gap")
    fig, axes = plt.subplots(1, len(names), figsize=(3.2 * len(names), 0.6 * len(algos) + 1.4), squeeze=False)
    for ax, name in zip(axes[0], names, strict=True):
        for k, algo in enumerate(algos):
            p, lo, hi = agg["algos"][algo][name]
            ax.barh([k], [hi - lo], left=[lo], height=0.6, color=ALGO_COLOURS.get(algorithm_of(algo), "tab:grey"), alpha=0.6)
            ax.plot([p, p], [k - 0.3, k + 0.3], color="black", lw=1.5)
        ax.set_yticks(range(len(algos)), algos if name == "IQM" else [""] * len(algos))
        ax.set_title(name)
        ax.grid(alpha=0.3, axis="x")
    fig.supxlabel(f"normalised held-out score on the -{version} environments (0 = random, 1 = classical); bars: 95% CIs")
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)


def _training_return(runs: Sequence[Run], at: float, window: float) -> float:
    """Mean over runs of the training return of the episodes that ended in ``(at - window, at]``.

    A run whose learning curve is kept in spans longer than ``window`` (a summarised run: a curve
    of 200 spans of a 2e6-step run has spans of 1e4 steps) gives the mean of the first span that
    ends at or after ``at`` instead, the span holding that step.
    """
    values = []
    for r in runs:
        t, y = r.timesteps, r.metric("return")
        if not t.size:
            continue
        if t.size > 1 and float(np.median(np.diff(t))) > window:
            i = int(np.searchsorted(t, at, side="left"))
            values.append(float(y[i]) if i < t.size else float("nan"))
        else:
            values.append(float(smoothed(t, y, np.array([at]), window)[0]))
    values = [v for v in values if np.isfinite(v)]
    return float(np.mean(values)) if values else float("nan")


def budgets_section(results: Sequence[EnvResults]) -> list[str]:
    """Markdown lines comparing the budgets of an algorithm run with several (e.g. PPO at 2e6 and 2e7 steps); none otherwise.

    Runs that differ in their trainer alone are compared by :func:`trainers_section`, not here.
    """
    labels = sorted({r.algo for er in results for r in er.runs})
    multi = sorted(
        {algorithm_of(a) for a in labels if sum(algorithm_of(b) == algorithm_of(a) for b in labels) > 1 and (" steps" in a or " env" in a)}
    )
    if not multi:
        return []
    lines = ["## Scale: the same algorithm at other budgets", ""]
    refs = [n for n in PAGE_REFERENCES if any(n in er.references for er in results)]
    for algo in multi:
        mine = [a for a in labels if algorithm_of(a) == algo]
        lines += [
            f"Normalised held-out score of {algo} per budget (mean over seeds; 0 = random, 1 = classical), and the held-out return of"
            " the reference policies:",
            "",
            "| environment | " + " | ".join([*mine, *refs]) + " |",
            "|---|" + "---:|" * (len(mine) + len(refs)),
        ]
        for er in results:
            if "random" not in er.references or "classical" not in er.references:
                continue
            cells = []
            for label in mine:
                scores = [
                    normalised_score(r.final_return, er.references["random"], er.references["classical"])
                    for r in er.runs
                    if r.algo == label and r.final_return is not None
                ]
                cells.append(f"{np.mean(scores):.2f} ({len(scores)} seed{'s' if len(scores) != 1 else ''})" if scores else "–")
            cells += [format_number(er.references[n]) if n in er.references else "–" for n in refs]
            lines.append(f"| {er.env_id} | " + " | ".join(cells) + " |")
        lines.append("")
    return lines


def trainers_section(results: Sequence[EnvResults]) -> list[str]:
    """Markdown lines comparing the trainers of an algorithm run with both (SB3 and the fast trainer); none otherwise.

    Per environment: each trainer's held-out return with its 95% interval (seeds and episodes),
    and whether the fast trainer's mean lies within SB3's interval.
    """
    lines: list[str] = []
    for er in results:
        rows = {r.policy: r for r in er.rows}
        for label, row in rows.items():
            if "sb3 trainer" not in label or "return" not in row.kpis:
                continue
            fast = rows.get(label.replace("sb3 trainer", "fast trainer"))
            if fast is None or "return" not in fast.kpis:
                continue
            if not lines:
                lines = [
                    "## Trainers compared",
                    "",
                    "Held-out return of the same algorithm and settings trained by Stable-Baselines3 and by the fast trainer"
                    " (mean, 95% interval over seeds and episodes):",
                    "",
                    "| environment | algorithm | SB3 | fast | fast within SB3's interval |",
                    "|---|---|---:|---:|---|",
                ]
            (m, lo, hi), theirs = fast.kpis["return"], row.kpis["return"]
            inside = "yes" if theirs[1] <= m <= theirs[2] else "no"
            setting = label.replace("sb3 trainer", "").replace("(, ", "(").replace("()", "").strip()
            lines.append(f"| {er.env_id} | {setting} | {_cell(theirs)} | {_cell((m, lo, hi))} | {inside} |")
    return [*lines, ""] if lines else []


def observations_section(results: Sequence[EnvResults]) -> list[str]:
    """Markdown lines checking the paper's qualitative observations against these runs (what they allow).

    * *PPO needs more samples than the off-policy algorithms*: at each off-policy algorithm's budget,
      PPO's training return (episodes ending in the last tenth of that budget) against the
      off-policy algorithm's over the same span.
    * *TD3 and DDPG are unstable on Merge*: per algorithm, the drop of the training return from its
      best to its end (smoothed over a tenth of the budget), normalised by classical - random.
    """
    lines = ["## The paper's observations, checked", ""]
    off = sorted({r.algo for er in results for r in er.runs if algorithm_of(r.algo) in ("SAC", "TD3", "DDPG")})
    ppo = sorted({r.algo for er in results for r in er.runs if algorithm_of(r.algo) == "PPO"})
    if not off or not ppo:
        return [*lines, "These need PPO and at least one off-policy algorithm on the same environments; this page has not both.", ""]
    main_ppo = ppo[0]
    lines += [
        f"**PPO needs more samples.** Training return at each off-policy algorithm's budget, {main_ppo} over the same span of steps"
        " (episodes ending in the last tenth of the budget, mean over seeds; a run summarised into a coarser learning curve gives"
        " the span of its curve that holds the budget):",
        "",
        "| environment | algorithm | budget | its return | " + main_ppo + " at that budget | PPO behind |",
        "|---|---|---:|---:|---:|---|",
    ]
    behind = total = 0
    for er in results:
        ppo_runs = [r for r in er.runs if r.algo == main_ppo]
        for label in off:
            runs = [r for r in er.runs if r.algo == label]
            if not runs or not ppo_runs:
                continue
            budget = min(r.total_timesteps for r in runs)
            theirs = _training_return(runs, budget, budget / 10)
            ours = _training_return(ppo_runs, budget, budget / 10)
            if not (np.isfinite(theirs) and np.isfinite(ours)):
                continue
            total += 1
            behind += ours < theirs
            lines.append(
                f"| {er.env_id} | {label} | {_steps(budget)} | {format_number(theirs)} | {format_number(ours)} | {'yes' if ours < theirs else 'no'} |"
            )
    lines += ["", f"PPO is behind in {behind} of {total} comparisons at the off-policy budgets." if total else "No comparison possible.", ""]
    lines += [
        "**TD3 and DDPG are unstable on Merge.** Drop of the smoothed training return from its best to its end, in units of"
        " classical - random (0: no drop):",
        "",
        "| environment | " + " | ".join(sorted({r.algo for er in results for r in er.runs})) + " |",
        "|---|" + "---:|" * len({r.algo for er in results for r in er.runs}),
    ]
    verdicts = []
    for er in results:
        if "random" not in er.references or "classical" not in er.references or not er.env_id.startswith("Merge"):
            continue
        scale = er.references["classical"] - er.references["random"]
        cells = []
        drop_of: dict[str, float] = {}
        for label in sorted({r.algo for e in results for r in e.runs}):
            drops = []
            for r in (r for r in er.runs if r.algo == label and r.timesteps.size):
                grid = np.linspace(r.total_timesteps / 10, r.total_timesteps, 50)
                curve = smoothed(r.timesteps, r.metric("return"), grid, r.total_timesteps / 10)
                if np.isfinite(curve).any():
                    drops.append((np.nanmax(curve) - curve[np.isfinite(curve)][-1]) / abs(scale) if scale else float("nan"))
            cells.append(f"{np.mean(drops):.2f}" if drops else "–")
            if drops and np.isfinite(np.mean(drops)):
                drop_of[label] = float(np.mean(drops))
        lines.append(f"| {er.env_id} | " + " | ".join(cells) + " |")
        verdicts.append(_instability_verdict(er.env_id, drop_of))
    lines += ["", *[v for v in verdicts if v], ""]
    return lines


def _instability_verdict(env_id: str, drop_of: dict[str, float]) -> str:
    """One sentence: whether TD3 and DDPG drop more than every other algorithm on ``env_id`` (the paper's observation)."""
    unstable = {k: v for k, v in drop_of.items() if algorithm_of(k) in ("TD3", "DDPG")}
    others = {k: v for k, v in drop_of.items() if algorithm_of(k) not in ("TD3", "DDPG")}
    if not unstable or not others:
        return ""
    worst = max(drop_of, key=lambda k: drop_of[k])
    if min(unstable.values()) > max(others.values()):
        verdict = "holds: TD3 and DDPG drop more than every other algorithm"
    elif max(unstable.values()) > max(others.values()):
        verdict = "holds in part: one of TD3 and DDPG drops more than every other algorithm, the other does not"
    else:
        verdict = "does not hold here: another algorithm drops at least as much as TD3 and DDPG"
    return f"On {env_id} the observation {verdict} (largest drop: {worst}, {drop_of[worst]:.2f})."


def build_results(
    sweep_dirs: Sequence[str | Path],
    out: str | Path,
    command: Sequence[str],
    seed: int = 0,
    reps: int = BOOTSTRAP,
    artifact: RunArtifact | None = None,
) -> Path:
    """Write the results page ``out`` (Markdown) and its figures in ``<out stem>/``.

    Args:
        sweep_dirs: Sweep (or run) directories.
        out: The Markdown file to write (e.g. ``docs/results.md``).
        command: The command line that made the page, written at its top.
        seed: Seed of the bootstraps (the page is reproducible).
        reps: Bootstrap resamples per interval.
        artifact: The packed run files of summarised runs (their raw episode logs for the curves).

    Returns:
        The path of the page.

    """
    import bluesky_gym

    out = Path(out)
    fig_dir = out.parent / out.stem
    fig_dir.mkdir(parents=True, exist_ok=True)
    results = collect(sweep_dirs, seed, reps, artifact)
    runs = [r for er in results for r in er.runs]
    configs = {r.path: read_json(r.path / "config.json") for r in runs}
    rel = f"{fig_dir.name}"
    lines = [
        "# Results",
        "",
        "<!-- Generated by the command below from the run directories it names; do not edit by hand. -->",
        "",
        "This page is generated from training runs and evaluations, never edited by hand:",
        "",
        "```bash",
        shlex.join(command),
        "```",
        "",
        f"bluesky-gym {bluesky_gym.__version__}. Every number is measured on held-out scenarios (evaluation seeds from 2**31,"
        " never used in training), the same ones for every policy. Cells are means with 95% confidence intervals in brackets:"
        " over the held-out episodes for the reference policies, and a two-level bootstrap over seeds and their held-out"
        " episodes for trained agents. KPIs that are undefined in an episode (no traffic: no separation; goal not reached: no"
        " time to goal) are left out of that KPI's statistics; `–` means the environment has no such KPI (or the policy's"
        " record was made before the environment reported it).",
        "",
        "Each environment's table starts with the reference policies, evaluated on the same held-out episodes as the trained"
        " agents (seeds `–`: they are deterministic given the scenario). `random` (uniform random actions) and `classical`"
        " (the environment's hand-written controller) fix the normalised score, 0 and 1. On the environments with traffic,"
        " BlueSky's conflict resolution methods follow, each flown through the environment's action mapping: `mvp`"
        " (Modified Voltage Potential), `eby` (Eby's method), `swarm` (Swarm) and `ssd` (Solution Space Diagram). They are"
        " classical CD&R baselines beside the trained agents, not part of the normalised score.",
        "",
        "## What was run",
        "",
        *_budget(runs, configs),
        "",
        *_not_run(runs),
        "The full grid of the paper (all environments and algorithms, 3 seeds, 2e6 steps each) on a Ray cluster:",
        "",
        "```bash",
        PAPER_GRID_COMMAND,
        f"bluesky-gym results sweeps/paper --out {command[command.index('--out') + 1] if '--out' in command else out}",
        "```",
        "",
    ]
    for version in sorted({env_version(er.env_id) for er in results}):
        group = [er for er in results if env_version(er.env_id) == version]
        agg = aggregate_scores(group, seed, reps)
        lines += [f"## Aggregate over the -{version} environments", ""]
        if not agg["algos"]:
            lines += ["No trained run has a held-out score with references yet.", ""]
        else:
            _plot_aggregate(agg, version, fig_dir / f"aggregate_{version}.png")
            lines += [
                "Normalised held-out score `(score - random) / (classical - random)`: 0 is the random policy, 1 the classical"
                " controller. Intervals are 95% stratified bootstrap intervals (rliable).",
                "",
                "| algorithm | seeds | environments | IQM | mean | median | optimality gap |",
                "|---|---:|---:|---:|---:|---:|---:|",
            ]
            for algo, s in agg["algos"].items():
                cells = " | ".join(_cell(s[name]) for name in ("IQM", "mean", "median", "optimality gap"))
                lines.append(f"| {algo} | {s['seeds']} | {len(s['envs'])} | {cells} |")
            lines += ["", f"![aggregate -{version}]({rel}/aggregate_{version}.png)", ""]
            if agg["improvement"]:
                lines += ["Probability of improvement P(X > Y) over environments and seeds:", "", "| X | Y | P(X > Y) |", "|---|---|---:|"]
                lines += [f"| {a} | {b} | {_cell(v)} |" for (a, b), v in agg["improvement"].items()]
                lines.append("")
            else:
                lines += ["Probability of improvement needs two trained algorithms on the same environments; this page has one.", ""]
    lines += trainers_section(results)
    lines += budgets_section(results)
    lines += observations_section(results)
    lines += ["## Per environment", ""]
    for er in results:
        env_dir = fig_dir / er.env_id
        written = plot_learning_curves(er.runs, env_dir, seed=seed, references={er.env_id: er.references})
        lines += [f"### {er.env_id}", "", *kpi_table(er), ""]
        lines += [f"![{er.env_id} learning curves]({rel}/{er.env_id}/{written[0].name})", ""]
        lines += [f"![{er.env_id} KPIs]({rel}/{er.env_id}/{p.name})" for p in written[1:]]
        lines.append("")
    with atomic_path(out) as tmp:
        Path(tmp).write_text("\n".join(lines).rstrip() + "\n", encoding="utf-8")
    return out
