"""A short shared-policy PPO run reduces losses of separation below the random policy's (slow)."""

from __future__ import annotations

import pytest

pytest.importorskip("stable_baselines3")

from bluesky_gym.multiagent.evaluation import evaluate, summarise
from bluesky_gym.multiagent.policies import RandomPolicy, SharedSB3Policy
from bluesky_gym.multiagent.train import main, train


@pytest.mark.slow
def test_short_training_run_reduces_losses_of_separation() -> None:
    # Merge: 16 parallel episodes x 20 agents, 250k row-steps on one PyTorch thread (tests/conftest.py):
    # 19 s on a loaded 2-core machine (400k row-steps with PyTorch's default threads took 930 s).
    # Fewer row-steps cut the number of losses of separation, but not yet the time spent in them.
    model, normalizer = train("merge_v0", 250_000, episodes=16, seed=1)
    episodes = 16
    trained = summarise(evaluate("merge_v0", SharedSB3Policy(model, normalizer=normalizer), episodes))
    random = summarise(evaluate("merge_v0", RandomPolicy(seed=0), episodes))
    assert trained["kpi_los_count"][0] < 0.75 * random["kpi_los_count"][0]
    assert trained["kpi_los_steps"][0] < random["kpi_los_steps"][0]
    assert trained["return"][0] > random["return"][0]


@pytest.mark.slow
def test_training_script_prints_the_kpi_table(capfd: pytest.CaptureFixture[str]) -> None:
    # The deprecated entry runs `bluesky-gym train-ma` in a new interpreter: its output is the process's.
    assert main(["--env", "sector_cr_v0", "--timesteps", "2000", "--episodes", "2", "--eval-episodes", "2"]) == 0
    out = capfd.readouterr().out
    assert "trained sector_cr_v0" in out
    for row in ("random", "classical", "shared PPO"):
        assert row in out
