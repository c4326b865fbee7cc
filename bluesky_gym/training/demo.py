"""The main job: train a policy for a few minutes, compare it with the references, plot it.

:func:`run_demo` (``bluesky-gym demo``) runs, in ``out``:

1. PPO on the natively batched environment with ``configs/demo.toml``'s settings, on the fast
   trainer unless told otherwise (a normal, resumable run in ``out/<ID>/PPO/seed_<S>``);
2. a deterministic evaluation of the trained policy, ``random``, ``classical`` and, for the
   environments with traffic, ``mvp`` on the same held-out scenarios, printed as a KPI table
   with normalised scores
   (``out/eval_*.json``, ``out/eval_*_episodes.csv``);
3. the learning curves and the aggregate plot (``out/plots``);
4. a GIF of the trained policy on a held-out scenario (``out/<ID>_ppo.gif``), when the renderer
   (the ``render`` extra) is available;
5. ``out/demo.json``: wall-clock time of every phase and the final KPIs.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

from bluesky_gym.envs.seeds import EVAL_SEED_BASE
from bluesky_gym.training.evaluation import (
    evaluate,
    format_table,
    load_result,
    make_policy,
    normalised_score,
    save_result,
    write_references,
)
from bluesky_gym.training.hyperparams import DEMO, PAPER, merge
from bluesky_gym.training.io import atomic_write_json
from bluesky_gym.training.policies import reference_names
from bluesky_gym.training.runner import make_run_spec, run_dir_for, run_training


def run_demo(
    env_id: str = "DescentEnv-v0",
    out: str | Path = "runs/demo",
    steps: int | None = None,
    n_envs: int | None = None,
    seed: int = 0,
    episodes: int = 100,
    gif: bool = True,
    progress_bar: bool = True,
    verbose: int = 1,
    trainer: str | None = None,
) -> dict[str, Any]:
    """Train, evaluate against the reference policies, plot and render; return ``demo.json``.

    Args:
        env_id: Environment id.
        out: Output directory.
        steps: PPO steps (default: ``DEMO``'s).
        n_envs: Batched environments (default: ``DEMO``'s).
        seed: Run seed.
        episodes: Held-out evaluation episodes per policy.
        gif: Render a GIF of the trained policy if the renderer is available.
        progress_bar: Show the training progress bar.
        verbose: Print progress and results.
        trainer: ``"fast"`` or ``"sb3"`` (default: ``DEMO``'s, the fast trainer).

    """
    from bluesky_gym.training.plotting import aggregate, load_run, plot_aggregate, plot_learning_curves

    out = Path(out)
    timings: dict[str, float] = {}
    t_all = time.perf_counter()

    t = time.perf_counter()
    config = merge(PAPER, DEMO)
    spec = make_run_spec(config, env_id, "PPO", seed, total_timesteps=steps, n_envs=n_envs, eval_episodes=episodes, trainer=trainer)
    run_dir = run_dir_for(out, env_id, "PPO", seed)
    result = run_training(spec, run_dir, progress_bar=progress_bar, verbose=verbose)
    timings["train_s"] = time.perf_counter() - t

    t = time.perf_counter()
    trained = load_result(run_dir, "eval")
    trained.policy = "PPO (trained)"
    refs = {name: evaluate(env_id, make_policy(name, env_id), episodes) for name in reference_names(env_id)}
    for name, res in refs.items():
        save_result(res, out, stem=f"eval_{name}")
    save_result(trained, out, stem="eval_ppo")
    ref_returns = {k: v.mean_return for k, v in refs.items()}
    write_references(out / "references", env_id, episodes, refs)  # where `bluesky-gym plot` looks for them
    table = format_table([trained, *refs.values()], ref_returns)
    timings["evaluate_s"] = time.perf_counter() - t

    t = time.perf_counter()
    run = load_run(run_dir)
    plots = [str(p) for p in plot_learning_curves([run], out / "plots", references={env_id: ref_returns})]
    agg = aggregate([run], {env_id: ref_returns})
    plots += [str(p) for p in plot_aggregate(agg, out / "plots")]
    timings["plot_s"] = time.perf_counter() - t

    gif_path = None
    if gif:
        t = time.perf_counter()
        gif_path = render_gif(env_id, run_dir / "model.zip", out / f"{env_id}_ppo.gif")
        timings["gif_s"] = time.perf_counter() - t
    timings["total_s"] = time.perf_counter() - t_all

    summary = {
        "env_id": env_id,
        "run_dir": str(run_dir),
        "timesteps": result["timesteps"],
        "n_envs": spec.n_envs,
        "train_wall_time_s": result["wall_time_s"],
        "timings_s": timings,
        "eval_episodes": episodes,
        "eval_seed_base": EVAL_SEED_BASE,
        "kpis": {"PPO": trained.summary, **{k: v.summary for k, v in refs.items()}},
        "normalised_score": normalised_score(trained.mean_return, ref_returns["random"], ref_returns["classical"]),
        "plots": plots,
        "gif": str(gif_path) if gif_path else None,
    }
    atomic_write_json(out / "demo.json", summary)
    if verbose:
        print()
        print(table)
        print(f"\nplots: {', '.join(plots)}")
        if gif:
            print(f"GIF: {gif_path}" if gif_path else "GIF: not rendered (the renderer needs the 'render' extra)")
        phases = ", ".join(f"{k[:-2]} {v:.0f} s" for k, v in timings.items())
        print(f"wall-clock: {phases}")
    return summary


def render_gif(env_id: str, model: Path, path: Path) -> Path | None:
    """Render one held-out episode of a trained model to a GIF, if the renderer is available."""
    try:
        from bluesky_gym.training.recording import record
    except ImportError:
        return None
    try:
        written, _ = record(env_id, policy=str(model), episodes=1, out=path, seed=EVAL_SEED_BASE, algo="ppo", fps=10.0)
    except ImportError:
        return None
    return written
