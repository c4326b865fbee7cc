"""The benchmark grid: every (environment, algorithm, seed), sequentially or on Ray.

Each cell is an ordinary run (:func:`bluesky_gym.training.runner.run_training`) in
``<out>/<env>/<ALGO>/seed_<S>``, so a sweep is resumable cell by cell: rerunning the same sweep
skips finished runs, resumes interrupted ones from their last checkpoint and starts the others.
With Ray, ``<out>`` must be on a file system every node sees (one node: any local directory).

At the end the sweep evaluates the reference policies (``random``, ``classical``) of every
environment on the same held-out scenarios as the runs (cached in ``<out>/references``), and
writes ``<out>/sweep.json``: the status, held-out return and normalised score of every run.
"""

from __future__ import annotations

import time
import traceback
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from bluesky_gym.core.extras import require_ray
from bluesky_gym.envs.seeds import train_env_seeds
from bluesky_gym.training.io import atomic_write_json
from bluesky_gym.training.runner import RunSpec, make_run_spec, run_dir_for, run_status, run_training

REFERENCES_DIR = "references"


@dataclass(frozen=True)
class Cell:
    """One run of the grid."""

    spec: RunSpec
    run_dir: Path


def plan(config: dict[str, Any], envs: Sequence[str], algos: Sequence[str], seeds: Sequence[int], out: str | Path, **run: Any) -> list[Cell]:
    """List the runs of a grid (environments x algorithms x seeds).

    Args:
        config: Merged config (paper defaults and config file).
        envs: Environment ids.
        algos: Algorithm names.
        seeds: Run seeds.
        out: Sweep directory.
        **run: Command-line values of the ``run`` section (None = unset).

    """
    return [
        Cell(make_run_spec(config, env_id, algo, seed, **run), run_dir_for(out, env_id, algo, seed))
        for env_id in envs
        for algo in algos
        for seed in seeds
    ]


def _run_cell(spec: RunSpec, run_dir: str, verbose: int, on_damage: str = "error") -> dict[str, Any]:
    """Run one cell, turning an exception into a ``failed`` result."""
    t0 = time.time()
    try:
        result = run_training(spec, run_dir, progress_bar=False, verbose=verbose, on_damage=on_damage)
        result.setdefault("skipped", False)
        return result
    except Exception as exc:  # noqa: BLE001 - one failed run must not stop the grid
        return {
            "status": "failed",
            "env_id": spec.env_id,
            "algo": spec.algo,
            "seed": spec.seed,
            "error": f"{type(exc).__name__}: {exc}",
            "traceback": traceback.format_exc(),
            "wall_time_s": time.time() - t0,
        }


def run_local(cells: Sequence[Cell], verbose: int = 1, on_damage: str = "error") -> list[dict[str, Any]]:
    """Run the cells one after the other in this process (``on_damage``: see :func:`run_training`)."""
    results = []
    for k, cell in enumerate(cells):
        if verbose:
            print(f"--- run {k + 1}/{len(cells)}: {cell.run_dir} ({run_status(cell.run_dir)})", flush=True)
        results.append(_run_cell(cell.spec, str(cell.run_dir), verbose, on_damage))
    return results


def run_ray(
    cells: Sequence[Cell], address: str | None = None, cpus_per_run: float = 1.0, verbose: int = 1, on_damage: str = "error"
) -> list[dict[str, Any]]:
    """Run the cells as Ray tasks (a local Ray instance, or the cluster at ``address``).

    Args:
        cells: The runs.
        address: Ray cluster address (``ray://host:10001`` or ``host:6379``); None starts Ray
            locally.
        cpus_per_run: CPUs reserved per run.
        verbose: Print each result as it arrives.
        on_damage: What a run does with a damaged run directory (see :func:`run_training`).

    """
    ray = require_ray()
    started_here = not ray.is_initialized()
    if started_here:
        ray.init(address=address, include_dashboard=False, log_to_driver=verbose > 0, configure_logging=False)
    try:
        remote = ray.remote(num_cpus=cpus_per_run, max_retries=0)(_run_cell)
        pending = {remote.remote(c.spec, str(c.run_dir), verbose, on_damage): k for k, c in enumerate(cells)}
        results: list[dict[str, Any] | None] = [None] * len(cells)
        while pending:
            done, _ = ray.wait(list(pending), num_returns=1)
            for ref in done:
                k = pending.pop(ref)
                try:
                    results[k] = ray.get(ref)
                except Exception as exc:  # noqa: BLE001 - a dead worker fails its run only
                    c = cells[k]
                    results[k] = {"status": "failed", "env_id": c.spec.env_id, "algo": c.spec.algo, "seed": c.spec.seed, "error": repr(exc)}
                if verbose:
                    r = results[k]
                    print(f"--- {cells[k].run_dir}: {r['status'] if r else '?'}", flush=True)
        return [r for r in results if r is not None]
    finally:
        if started_here:
            ray.shutdown()


def write_summary(
    out: str | Path, cells: Sequence[Cell], results: Sequence[dict[str, Any]], reference_episodes: int, extra_references: Sequence[str] = ()
) -> dict[str, Any]:
    """Compute reference scores and write ``<out>/sweep.json``; return its content.

    ``extra_references`` (``eby``, ``swarm``, ``ssd``) are evaluated too where an environment has them.
    """
    from bluesky_gym.training.evaluation import normalised_score, reference_returns, reference_scores

    out = Path(out)
    refs: dict[str, dict[str, float]] = {}
    if reference_episodes > 0:
        for env_id in dict.fromkeys(c.spec.env_id for c in cells):
            refs[env_id] = reference_returns(reference_scores(env_id, reference_episodes, out / REFERENCES_DIR, extra_references))
    runs = []
    for cell, res in zip(cells, results, strict=True):
        ret = None
        if res.get("eval"):
            ret = res["eval"]["return"]["mean"]
        ref = refs.get(cell.spec.env_id)
        norm = normalised_score(ret, ref["random"], ref["classical"]) if (ret is not None and ref) else None
        runs.append(
            {
                "env_id": cell.spec.env_id,
                "algo": cell.spec.algo,
                "seed": cell.spec.seed,
                "run_dir": str(cell.run_dir.relative_to(out)) if cell.run_dir.is_relative_to(out) else str(cell.run_dir),
                "status": res.get("status"),
                "skipped": res.get("skipped", False),
                "resumed_from": res.get("resumed_from"),
                "timesteps": res.get("timesteps"),
                "wall_time_s": res.get("wall_time_s"),
                "eval_return": ret,
                "normalised_score": norm,
                "error": res.get("error"),
            }
        )
    summary = {"runs": runs, "references": refs, "reference_episodes": reference_episodes}
    atomic_write_json(out / "sweep.json", summary)
    return summary


def _timed(fn: Any) -> tuple[float, float]:
    """Run ``fn()`` and return its wall-clock and process CPU seconds."""
    w, c = time.perf_counter(), time.process_time()
    fn()
    return time.perf_counter() - w, time.process_time() - c


def estimate(
    config: dict[str, Any],
    envs: Sequence[str],
    algos: Sequence[str],
    probe_env: str,
    probe_steps: int,
    env_probe_steps: int = 600,
    verbose: int = 1,
    **run: Any,
) -> dict[str, Any]:
    """Measure training throughput and extrapolate the time of a grid, without training it.

    The cost of a training step is modelled as the environment's cost plus the algorithm's:

    * environment: random actions on the batched environment (``env_probe_steps`` steps), for
      every environment of the grid;
    * algorithm: a short training run of every algorithm on ``probe_env`` (after its warm-up:
      ``learning_starts`` for off-policy algorithms; whole rollouts for PPO), minus
      ``probe_env``'s environment cost.

    Both wall-clock and process CPU time are measured; CPU time is what a dedicated core would
    need, wall-clock what this machine gave under its current load.

    Returns:
        ``{"per_run": [...], "total": {...}}`` with seconds per step and per run.

    """
    import numpy as np

    from bluesky_gym.training import make_vector_env
    from bluesky_gym.training.runner import new_model, set_torch_threads
    from bluesky_gym.training.sb3_vec_env import SB3VecEnv

    n_envs = int(run.get("n_envs") or config["run"]["n_envs"])
    env_cost: dict[str, tuple[float, float]] = {}
    for env_id in dict.fromkeys([*envs, probe_env]):
        venv = make_vector_env(env_id, n_envs, **config.get("env_options", {}).get(env_id, {}))
        venv.reset(seed=0)
        rng = np.random.default_rng(0)
        shape = (n_envs, *venv.single_action_space.shape)
        vec_steps = max(1, env_probe_steps // n_envs)
        wall, cpu = _timed(lambda: [venv.step(rng.uniform(-1, 1, shape)) for _ in range(vec_steps)])
        venv.close()
        env_cost[env_id] = (wall / (vec_steps * n_envs), cpu / (vec_steps * n_envs))
        if verbose:
            print(f"environment {env_id}: {1 / env_cost[env_id][0]:.0f} steps/s wall, {1 / env_cost[env_id][1]:.0f} steps/s CPU", flush=True)
    algo_cost: dict[str, tuple[float, float]] = {}
    for algo in algos:
        spec = make_run_spec(config, probe_env, algo, 0, **run)
        set_torch_threads(spec.torch_threads)
        venv = SB3VecEnv(probe_env, num_envs=spec.n_envs, **spec.env_options)
        model = new_model(spec, venv)
        if algo == "PPO":
            rollout = spec.hyperparams.get("n_steps", 2048) * spec.n_envs
            warm, steps = rollout if spec.compile else 0, rollout * max(1, -(-probe_steps // rollout))  # compiling is not timed
        else:
            warm, steps = int(spec.hyperparams.get("learning_starts", 100)) + spec.n_envs, probe_steps
        if spec.trainer == "fast":
            from bluesky_gym.training.fast import trainer_class

            trainer = trainer_class(algo)(model, venv.venv, seed=0, compile=spec.compile)
            trainer.start(train_env_seeds(0, spec.n_envs))
            trainer.learn(warm)
            wall, cpu = _timed(lambda: trainer.learn(trainer.num_timesteps + steps))
        else:
            if warm:
                model.learn(warm)
            wall, cpu = _timed(lambda: model.learn(steps, reset_num_timesteps=False))
        venv.close()
        done = steps
        w_env, c_env = env_cost[probe_env]
        algo_cost[algo] = (max(wall / done - w_env, 0.0), max(cpu / done - c_env, 0.0))
        if verbose:
            print(f"{algo} on {probe_env}: {done / wall:.0f} steps/s wall, {done / cpu:.0f} steps/s CPU", flush=True)
    per_run = []
    for env_id in envs:
        for algo in algos:
            spec = make_run_spec(config, env_id, algo, 0, **run)
            w = env_cost[env_id][0] + algo_cost[algo][0]
            c = env_cost[env_id][1] + algo_cost[algo][1]
            per_run.append(
                {
                    "env_id": env_id,
                    "algo": algo,
                    "steps": spec.total_timesteps,
                    "steps_per_s_wall": 1 / w,
                    "steps_per_s_cpu": 1 / c,
                    "hours_wall": spec.total_timesteps * w / 3600,
                    "hours_cpu": spec.total_timesteps * c / 3600,
                }
            )
    return {
        "n_envs": n_envs,
        "probe_env": probe_env,
        "probe_steps": probe_steps,
        "per_run": per_run,
        "total": {"hours_wall": sum(r["hours_wall"] for r in per_run), "hours_cpu": sum(r["hours_cpu"] for r in per_run)},
    }


def format_estimate(est: dict[str, Any], seeds: int, workers: float) -> str:
    """Format a grid-time estimate for ``seeds`` seeds and ``workers`` runs in parallel."""
    lines = [f"{'environment':<22} {'algo':<5} {'steps/s (CPU)':>14} {'steps/s (wall)':>15} {'h/run (CPU)':>12}"]
    for r in est["per_run"]:
        lines.append(f"{r['env_id']:<22} {r['algo']:<5} {r['steps_per_s_cpu']:>14.0f} {r['steps_per_s_wall']:>15.0f} {r['hours_cpu']:>12.1f}")
    cpu = est["total"]["hours_cpu"] * seeds
    wall = est["total"]["hours_wall"] * seeds
    lines.append(
        f"grid of {len(est['per_run'])} runs x {seeds} seed(s), {est['n_envs']} environment(s) per run: {cpu:.0f} CPU-hours "
        f"(~{cpu / workers:.0f} h = {cpu / workers / 24:.1f} days on {workers:g} parallel runs); "
        f"at this machine's measured wall-clock rates {wall:.0f} run-hours ({wall / workers / 24:.1f} days on {workers:g})"
    )
    return "\n".join(lines)


def format_summary(summary: dict[str, Any]) -> str:
    """Format a table of held-out return and normalised score per (environment, algorithm)."""
    groups: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for r in summary["runs"]:
        groups.setdefault((r["env_id"], r["algo"]), []).append(r)
    lines = [f"{'environment':<22} {'algo':<5} {'runs':>4} {'failed':>6} {'held-out return':>22} {'normalised':>16}"]
    for (env_id, algo), rs in groups.items():
        ok = [r for r in rs if r["status"] == "finished"]
        rets = np.array([r["eval_return"] for r in ok if r["eval_return"] is not None], dtype=float)
        norms = np.array([r["normalised_score"] for r in ok if r["normalised_score"] is not None], dtype=float)
        ret_s = f"{rets.mean():.2f} ± {rets.std():.2f}" if rets.size else "-"
        norm_s = f"{norms.mean():.2f} ± {norms.std():.2f}" if norms.size else "-"
        lines.append(f"{env_id:<22} {algo:<5} {len(ok):>4} {len(rs) - len(ok):>6} {ret_s:>22} {norm_s:>16}")
    for env_id, ref in summary["references"].items():
        lines.append(f"reference {env_id}: " + ", ".join(f"{name} {value:.2f}" for name, value in ref.items()))
    lines.append("(mean ± standard deviation over seeds; normalised: 0 = random, 1 = classical controller)")
    return "\n".join(lines)
