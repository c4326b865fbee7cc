"""Deterministic evaluation on held-out scenarios, KPI tables and reference scores.

An evaluation of ``N`` episodes runs the scenarios of the evaluation seeds
``2**31 .. 2**31 + N - 1`` (:func:`bluesky_gym.envs.seeds.eval_seeds`), never used in
training, as one batch of environments (in chunks of ``batch`` episodes): every environment of
the batch plays exactly one episode and its first episode's final info is recorded. The same
``N`` gives every policy the same scenarios, so results are directly comparable.

The KPI table reports, per policy, the mean and a 95% confidence half-width of: return, success
rate, losses of separation (new ownship LoS events per episode), minimum separation [NM], mean
absolute drift [deg], time to goal [s] (over successful episodes) and episode length [steps].
KPIs an environment does not have (no traffic, no goal) are left empty.
"""

from __future__ import annotations

import contextlib
import math
import sys
import time
import zipfile
import zlib
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bluesky_gym.core.extras import require_sb3
from bluesky_gym.envs.seeds import EVAL_SEED_BASE, eval_seeds
from bluesky_gym.training import algorithm_class, make_vector_env
from bluesky_gym.training.io import DamagedFileError, atomic_write_csv, atomic_write_json, file_damage, latest_checkpoint, read_json
from bluesky_gym.training.policies import SELECTABLE_REFERENCES, Policy, SB3Policy, optional_reference_names, reference_names, reference_policy

#: (column, episode-record key, label) of the KPI table.
KPI_COLUMNS: tuple[tuple[str, str, str], ...] = (
    ("return", "return", "return"),
    ("success", "kpi_success", "success"),
    ("los", "kpi_los_count", "LoS/ep"),
    ("min_sep_nm", "kpi_min_separation_nm", "min sep [NM]"),
    ("los_per_hour", "kpi_los_per_flight_hour", "LoS/flight-h"),
    ("first_los_s", "kpi_time_to_first_los_s", "first LoS [s]"),
    ("drift_deg", "kpi_mean_abs_drift_deg", "drift [deg]"),
    ("time_to_goal_s", "kpi_time_to_goal_s", "time to goal [s]"),
    ("fuel_kg", "kpi_fuel_kg", "fuel [kg]"),
    ("length", "length", "length"),
)
DEFAULT_BATCH = 64


@dataclass
class EvalResult:
    """Episodes of one policy on the held-out scenarios, and their summary."""

    env_id: str
    policy: str
    episodes: list[dict[str, Any]]
    wall_time_s: float
    summary: dict[str, dict[str, float]] = field(init=False)

    def __post_init__(self) -> None:
        self.summary = summarise(self.episodes)

    @property
    def mean_return(self) -> float:
        """Mean episode return."""
        return self.summary["return"]["mean"]

    def to_json(self) -> dict[str, Any]:
        """Return the summary as a JSON-ready dict (episodes are written separately as CSV)."""
        return {
            "env_id": self.env_id,
            "policy": self.policy,
            "episodes": len(self.episodes),
            "eval_seed_base": EVAL_SEED_BASE,
            "wall_time_s": self.wall_time_s,
            "summary": self.summary,
        }


def evaluate(
    env_id: str,
    policy: Policy,
    episodes: int,
    *,
    seed_offset: int = 0,
    batch: int = DEFAULT_BATCH,
    env_options: dict[str, Any] | None = None,
    max_episode_steps: int | None = None,
) -> EvalResult:
    """Play one episode per held-out scenario and record return, length and final info.

    Args:
        env_id: Environment id.
        policy: The batched policy (reference policy or :class:`SB3Policy`).
        episodes: Number of held-out scenarios (evaluation seeds ``2**31 + offset + j``).
        seed_offset: First evaluation seed index.
        batch: Episodes simulated together.
        env_options: Scenario options of the environment.
        max_episode_steps: Override of the time limit.

    Returns:
        The per-episode records (seed, return, length, reward components, final info incl. KPIs).

    """
    seeds = eval_seeds(episodes, seed_offset)
    t0 = time.perf_counter()
    records: list[dict[str, Any]] = []
    kwargs: dict[str, Any] = dict(env_options or {})
    if max_episode_steps is not None:
        kwargs["max_episode_steps"] = max_episode_steps
    for start in range(0, len(seeds), max(1, batch)):
        chunk = seeds[start : start + max(1, batch)]
        venv = make_vector_env(env_id, len(chunk), **kwargs)
        try:
            records.extend(_play_once(venv, policy, chunk))
        finally:
            venv.close()
    return EvalResult(env_id, policy.name, records, time.perf_counter() - t0)


def _play_once(venv: Any, policy: Policy, seeds: list[int]) -> list[dict[str, Any]]:
    n = len(seeds)
    policy.bind(venv)
    obs, _ = venv.reset(seed=seeds)
    policy.reset(None)
    ret = np.zeros(n)
    length = np.zeros(n, dtype=np.int64)
    components: dict[str, np.ndarray] = {}
    done = np.zeros(n, dtype=bool)
    final: list[dict[str, Any]] = [{} for _ in range(n)]
    while not done.all():
        action = policy.act(obs)
        obs, reward, terminated, truncated, info = venv.step(action)
        live = ~done
        ret += np.where(live, reward, 0.0)
        length += live
        for k, v in info.items():
            if k.startswith("reward_") and isinstance(v, np.ndarray):
                components.setdefault(k, np.zeros(n))
                components[k] += np.where(live, v, 0.0)
        ended = (np.asarray(terminated) | np.asarray(truncated)) & live
        if ended.any():
            fin = info.get("final_info", info)
            for e in np.flatnonzero(ended).tolist():
                final[e] = {k: _item(v[e]) for k, v in fin.items() if isinstance(v, np.ndarray) and v.ndim == 1 and v.shape[0] == n}
                final[e]["terminated"] = bool(terminated[e])
            done |= ended
        policy.reset(np.asarray(terminated) | np.asarray(truncated))
    out = []
    for i in range(n):
        rec: dict[str, Any] = {"seed": seeds[i], "return": float(ret[i]), "length": int(length[i])}
        rec.update({k: float(v[i]) for k, v in sorted(components.items())})
        rec.update({k: v for k, v in final[i].items() if not k.startswith("reward_")})
        out.append(rec)
    return out


def _item(v: Any) -> Any:
    return v.item() if isinstance(v, np.generic) else v


def summarise(episodes: Sequence[dict[str, Any]]) -> dict[str, dict[str, float]]:
    """Mean, standard deviation, 95% half-width and count of every KPI column.

    Non-finite values (no goal reached, no intruder) are left out of a column's statistics.
    """
    out: dict[str, dict[str, float]] = {}
    # Episodes without traffic have an infinite minimum separation; their LoS count is not a KPI.
    traffic = np.array([np.isfinite(float(e.get("kpi_min_separation_nm", np.nan))) for e in episodes], dtype=bool)
    for col, key, _ in KPI_COLUMNS:
        vals = np.array([float(e.get(key, np.nan)) for e in episodes], dtype=np.float64)
        if col == "los":
            vals = vals[traffic]
        vals = vals[np.isfinite(vals)]
        n = int(vals.size)
        mean = float(vals.mean()) if n else math.nan
        std = float(vals.std(ddof=1)) if n > 1 else (0.0 if n == 1 else math.nan)
        out[col] = {"mean": mean, "std": std, "ci95": 1.96 * std / math.sqrt(n) if n else math.nan, "n": n}
    return out


def normalised_score(score: float, random_score: float, classical_score: float) -> float:
    """``(score - random) / (classical - random)``: 0 = random, 1 = classical controller.

    Returns NaN when the two references are (nearly) equal, where the scale is meaningless.
    """
    span = classical_score - random_score
    if not np.isfinite(span) or abs(span) < 1e-9 * max(1.0, abs(random_score), abs(classical_score)):
        return math.nan
    return (score - random_score) / span


def format_table(results: Sequence[EvalResult], references: dict[str, float] | None = None) -> str:
    """Format a plain-text KPI table, one row per policy.

    Args:
        results: Evaluations of the same environment.
        references: Mean returns of ``random`` and ``classical``; adds a normalised-score column.

    """
    cols = [(c, label) for c, _, label in KPI_COLUMNS if any(r.summary[c]["n"] for r in results)]
    header = ["policy", *[label for _, label in cols]]
    if references:
        header.append("normalised")
    rows = []
    for r in results:
        row = [r.policy]
        for c, _ in cols:
            s = r.summary[c]
            row.append("-" if not s["n"] else f"{format_number(s['mean'])} ± {format_number(s['ci95'])}")
        if references:
            row.append(format_number(normalised_score(r.mean_return, references["random"], references["classical"])))
        rows.append(row)
    widths = [max(len(str(x)) for x in col) for col in zip(header, *rows, strict=True)]
    lines = ["  ".join(str(x).ljust(w) for x, w in zip(header, widths, strict=True))]
    lines.append("  ".join("-" * w for w in widths))
    lines.extend("  ".join(str(x).ljust(w) for x, w in zip(row, widths, strict=True)) for row in rows)
    n = {len(r.episodes) for r in results}
    episodes = "/".join(map(str, sorted(n)))
    lines.append(f"({episodes} held-out episodes per policy, seeds from {EVAL_SEED_BASE}; ± is a 95% confidence half-width)")
    return "\n".join(lines)


def format_number(x: float | None, missing: str = "-") -> str:
    """A KPI value with three significant digits or decimals (``missing`` for None, NaN or inf)."""
    if x is None or not np.isfinite(x):
        return missing
    if x != 0 and (abs(x) >= 1e4 or abs(x) < 1e-2):
        return f"{x:.3g}"
    return f"{x:.3f}" if abs(x) < 10 else f"{x:.1f}"


def save_result(result: EvalResult, directory: str | Path, stem: str | None = None) -> tuple[Path, Path]:
    """Write ``<stem>.json`` (summary) and ``<stem>_episodes.csv`` atomically; returns both paths."""
    d = Path(directory)
    stem = stem or f"eval_{result.policy}"
    keys: list[str] = []
    for e in result.episodes:
        keys.extend(k for k in e if k not in keys)
    json_path, csv_path = d / f"{stem}.json", d / f"{stem}_episodes.csv"
    atomic_write_csv(csv_path, keys, [[e.get(k, math.nan) for k in keys] for e in result.episodes])
    atomic_write_json(json_path, result.to_json())
    return json_path, csv_path


def load_result(directory: str | Path, stem: str) -> EvalResult:
    """Read an evaluation written by :func:`save_result`."""
    from bluesky_gym.training.io import read_csv_rows

    d = Path(directory)
    meta = read_json(d / f"{stem}.json")
    header, rows = read_csv_rows(d / f"{stem}_episodes.csv")
    episodes = [{k: _parse_cell(v) for k, v in zip(header, row, strict=True)} for row in rows]
    return EvalResult(meta["env_id"], meta["policy"], episodes, float(meta.get("wall_time_s", math.nan)))


def _parse_cell(v: str) -> Any:
    if v == "":
        return math.nan
    try:
        return int(v)
    except ValueError:
        pass
    try:
        return float(v)
    except ValueError:
        return v


# --- trained models ------------------------------------------------------------------------------
def find_model(path: str | Path) -> tuple[Path, str | None]:
    """Find the model file of ``path``, and its algorithm if a run directory says so.

    ``path`` may be a model ``.zip``, or a run directory (its final ``model.zip``, else its last
    checkpoint).

    Raises:
        FileNotFoundError: There is no model at ``path``.
        DamagedFileError: The model file is cut off or damaged: it does not match the size and
            checksum its run recorded, or is not a readable model file (the message names it).

    """
    p = Path(path)
    run_dir: Path | None = None
    record: dict[str, Any] | None = None  # the size and checksum the run recorded for the file
    if p.is_dir():
        run_dir = p
        if (p / "model.zip").exists():
            p = p / "model.zip"
            with contextlib.suppress(DamagedFileError, AttributeError):  # result.json unreadable: the file is checked on its own
                record = read_json(run_dir / "result.json").get("files", {}).get("model.zip") if (run_dir / "result.json").exists() else None
        else:
            ckpt = latest_checkpoint(p)
            if ckpt is None:
                summary = read_json(p / "result.json").get("summarised") if (p / "result.json").exists() else None
                if summary and "model.zip" in summary.get("removed", ()):
                    restore = "bluesky-gym results unpack MANIFEST puts it back"
                    raise FileNotFoundError(f"{path} is a run summary: its model.zip went to the run files' release asset ({restore})")
                raise FileNotFoundError(f"{path} holds neither model.zip nor a checkpoint")
            p = ckpt[1] / "model.zip"
            record = ckpt[0].get("files", {}).get("model.zip")
    elif not p.exists() and p.with_suffix(".zip").exists():
        p = p.with_suffix(".zip")
    if not p.exists():
        raise FileNotFoundError(f"no model at {path}")
    damage = (file_damage(p, record) if record else None) or model_file_damage(p)
    if damage:
        raise DamagedFileError(f"{damage}; it cannot be evaluated")
    config = run_config_of(p, run_dir)
    return p, (str(config[1].get("algo", "")) or None) if config is not None else None


def model_file_damage(path: str | Path) -> str | None:
    """What is wrong with a model file (cut off, a member that fails its CRC, not an SB3 model), or None if it reads."""
    try:
        with zipfile.ZipFile(path) as z:
            bad = z.testzip()
            if bad is not None:
                return f"{path} is damaged (its member {bad!r} does not match its checksum)"
            if "data" not in z.namelist():
                return f"{path} is truncated, damaged or not a Stable-Baselines3 model file (no 'data' member found)"
    except (OSError, EOFError, zipfile.BadZipFile, zlib.error) as exc:
        return f"{path} is not a readable model file, truncated or damaged ({exc})"
    return None


def run_config_of(model_path: Path, run_dir: Path | None = None) -> tuple[Path, dict[str, Any]] | None:
    """The ``config.json`` of the run a model file belongs to (its path and content), if any.

    The file is looked for in ``run_dir`` and up to three directories above the model (a run's
    ``model.zip`` and its ``checkpoints/<step>/model.zip``).
    """
    for d in [run_dir, model_path.parent, model_path.parent.parent, model_path.parent.parent.parent]:
        if d is not None and (d / "config.json").exists():
            return d / "config.json", read_json(d / "config.json")
    return None


def model_algorithm(model_path: Path, requested: str | None = None, run_algo: str | None = None) -> str:
    """The algorithm of a model file: from its run's config or the file itself; ``requested`` must agree.

    Raises:
        ValueError: ``requested`` contradicts the detected algorithm, or none can be told.

    """
    detected = run_algo.upper() if run_algo else algorithm_of_zip(model_path)
    if requested is not None and detected is not None and requested.upper() != detected:
        raise ValueError(f"{model_path} is a {detected} model; --algo {requested.upper()} does not match it (leave --algo out to use {detected})")
    algo = requested.upper() if requested is not None else detected
    if algo is None:
        raise ValueError(f"cannot tell the algorithm of {model_path}; pass --algo")
    return algo


def check_model_spaces(model: Any, model_path: Path, env_id: str, observation_space: Any, action_space: Any) -> None:
    """Raise ``ValueError`` if a model's observation or action space is not the environment's."""
    import gymnasium as gym

    def shapes(space: Any) -> dict[str, tuple[int, ...]]:
        if isinstance(space, gym.spaces.Dict):
            return {k: tuple(v.shape or ()) for k, v in space.spaces.items()}
        return {"": tuple(space.shape or ())}

    mine, theirs = shapes(model.observation_space), shapes(observation_space)
    if mine != theirs:
        differ = sorted(k for k in set(mine) | set(theirs) if mine.get(k) != theirs.get(k))
        raise ValueError(
            f"{model_path} was trained on other observations than {env_id} gives (keys or shapes differ: {', '.join(differ[:6])}"
            f"{', ...' if len(differ) > 6 else ''}); use it with the environment it was trained on"
        )
    if tuple(model.action_space.shape) != tuple(action_space.shape):
        raise ValueError(
            f"{model_path} acts with shape {tuple(model.action_space.shape)}, {env_id} takes actions of shape {tuple(action_space.shape)}"
        )


def algorithm_of_zip(path: str | Path) -> str | None:
    """Tell the algorithm of an SB3 model file from its stored hyperparameters (None if unsure).

    PPO stores ``n_epochs``, SAC ``target_entropy``; TD3 and DDPG store ``policy_delay`` (DDPG is
    TD3 with ``policy_delay=1`` and no target noise clipping).
    """
    import json
    import zipfile

    try:
        with zipfile.ZipFile(path) as z:
            data = json.loads(z.read("data"))
    except (OSError, KeyError, ValueError, zipfile.BadZipFile):
        return None
    if "n_epochs" in data:
        return "PPO"
    if "target_entropy" in data:
        return "SAC"
    if "policy_delay" in data:
        return "DDPG" if data["policy_delay"] == 1 and data.get("target_noise_clip") == 0.0 else "TD3"
    return None


def load_policy(path: str | Path, algo: str | None = None, device: str = "cpu", env_id: str | None = None) -> SB3Policy:
    """Load a trained SB3 model as a deterministic :class:`SB3Policy`.

    Args:
        path: Model ``.zip`` or run directory.
        algo: Algorithm (default: from the run directory's config, else read from the file); if
            given, it must agree with them.
        device: Torch device.
        env_id: The environment the policy is to act in: it must be the run's (if its
            ``config.json`` is found) and have the model's observation and action spaces.

    Raises:
        ValueError: The model does not fit ``env_id`` or ``algo``, or its file is damaged.

    """
    require_sb3()  # first: without it no model file can be used, damaged or not
    model_path, run_algo = find_model(path)
    config = run_config_of(model_path, Path(path) if Path(path).is_dir() else None)
    if env_id is not None and config is not None:
        trained_on = config[1].get("env_id")
        if trained_on and trained_on != env_id:
            raise ValueError(f"{path} was trained on {trained_on} (its {config[0]}), not {env_id}; evaluate it with --env {trained_on}")
    algo = model_algorithm(model_path, algo, run_algo)
    try:
        model = algorithm_class(algo).load(model_path, device=device)
    except Exception as exc:  # a file that reads as a zip but not as a model of this algorithm
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
        raise ValueError(f"{model_path} cannot be loaded as a {algo} model ({type(exc).__name__}: {first})") from exc
    if env_id is not None:
        venv = make_vector_env(env_id, 1)
        try:
            check_model_spaces(model, model_path, env_id, venv.single_observation_space, venv.single_action_space)
        finally:
            venv.close()
    return SB3Policy(model, deterministic=True, name=f"{algo}:{Path(path).name}")


def make_policy(spec: str, env_id: str, algo: str | None = None) -> Policy:
    """Make a policy from a command-line spec: ``random``, ``classical``, ``mvp``, ``eby``, ``swarm``, ``ssd`` or a model path."""
    if spec in SELECTABLE_REFERENCES:
        venv = make_vector_env(env_id, 1)
        try:
            space = venv.single_action_space
            return reference_policy(spec, env_id, space.low, space.high)
        finally:
            venv.close()
    return load_policy(spec, algo, env_id=env_id)


# --- reference scores ------------------------------------------------------------------------------
def reference_scores(env_id: str, episodes: int, cache_dir: str | Path | None = None, extra: Sequence[str] = ()) -> dict[str, dict[str, Any]]:
    """Summaries of the reference policies (``random``, ``classical``, and ``mvp`` with traffic) on the first ``episodes`` held-out scenarios.

    ``extra`` adds selectable references (``eby``, ``swarm``, ``ssd``) where the environment has them
    (:func:`~bluesky_gym.training.policies.optional_reference_names`; others are skipped).

    With ``cache_dir``, results are read from / written to ``<cache_dir>/<env_id>.json`` (reused
    only if computed on the same number of episodes by the same package version).

    Returns:
        ``{"random": summary-json, "classical": summary-json, ...}`` (the :meth:`EvalResult.to_json` form).

    """
    import bluesky_gym

    unknown = [n for n in extra if n not in SELECTABLE_REFERENCES]
    if unknown:
        raise ValueError(f"unknown reference policy {unknown[0]!r}; choose from {', '.join(SELECTABLE_REFERENCES)}")
    optional = optional_reference_names(env_id)
    names = reference_names(env_id) + tuple(n for n in dict.fromkeys(extra) if n in optional)
    path = Path(cache_dir) / f"{env_id}.json" if cache_dir is not None else None
    if path is not None and path.exists():
        try:
            cached = read_json(path)
            if cached.get("episodes") == episodes and cached.get("version") == bluesky_gym.__version__ and all(k in cached for k in names):
                return {k: cached[k] for k in names}
        except (DamagedFileError, AttributeError) as exc:  # a cache cut off or edited: computed again
            what = exc if isinstance(exc, DamagedFileError) else f"{path} is not a JSON object"
            print(f"reference cache damaged, computing it again: {what}", file=sys.stderr)
    results = {name: evaluate(env_id, make_policy(name, env_id), episodes) for name in names}
    if cache_dir is not None:
        write_references(cache_dir, env_id, episodes, results)
    return {k: v.to_json() for k, v in results.items()}


def write_references(cache_dir: str | Path, env_id: str, episodes: int, results: dict[str, EvalResult]) -> Path:
    """Cache reference evaluations as ``<cache_dir>/<env_id>.json`` (read by :func:`reference_scores`)."""
    import bluesky_gym

    path = Path(cache_dir) / f"{env_id}.json"
    atomic_write_json(
        path, {"env_id": env_id, "episodes": episodes, "version": bluesky_gym.__version__, **{k: v.to_json() for k, v in results.items()}}
    )
    return path


def reference_returns(refs: dict[str, Any]) -> dict[str, float]:
    """Mean returns of the reference policies from :func:`reference_scores`' result."""
    return {k: float(v["summary"]["return"]["mean"]) for k, v in refs.items()}
