"""PPO on the natively batched DescentEnv-v0 clearly beats the random policy within minutes."""

from __future__ import annotations

from pathlib import Path

import pytest

from bluesky_gym.training.evaluation import evaluate, load_result, make_policy, normalised_score
from bluesky_gym.training.hyperparams import DEMO, PAPER, merge
from bluesky_gym.training.runner import make_run_spec, run_training

from .conftest import needs_sb3

pytestmark = needs_sb3

ENV = "DescentEnv-v0"
EPISODES = 50


@pytest.mark.slow
def test_ppo_beats_random_on_batched_descent(tmp_path: Path) -> None:
    spec = make_run_spec(merge(PAPER, DEMO), ENV, "PPO", 0, total_timesteps=40_960, checkpoint_freq=20_480, eval_episodes=EPISODES)
    assert spec.n_envs == 16
    result = run_training(spec, tmp_path / "run", verbose=0)
    assert result["timesteps"] == 40_960
    trained = load_result(tmp_path / "run", "eval")
    random = evaluate(ENV, make_policy("random", ENV), EPISODES)
    classical = evaluate(ENV, make_policy("classical", ENV), EPISODES)
    gap = trained.mean_return - random.mean_return
    ci = trained.summary["return"]["ci95"] + random.summary["return"]["ci95"]
    assert gap > max(20.0, ci), (trained.mean_return, random.mean_return)
    assert normalised_score(trained.mean_return, random.mean_return, classical.mean_return) > 0.3
