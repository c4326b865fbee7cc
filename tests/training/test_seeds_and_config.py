"""The train/eval seed split, hyperparameters and config files."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from bluesky_gym.envs.seeds import EVAL_SEED_BASE, TRAIN_SEED_LIMIT, eval_seeds, is_eval_seed, train_env_seeds
from bluesky_gym.training import ALGORITHMS
from bluesky_gym.training.hyperparams import DEMO, PAPER, adapt_to_n_envs, load_config_file, merge, resolve, sb3_kwargs

CONFIGS = Path(__file__).resolve().parents[2] / "configs"


def test_train_and_eval_seeds_are_disjoint() -> None:
    train = {s for seed in range(50) for stream in (0, 1000) for s in train_env_seeds(seed, 16, stream)}
    assert all(0 <= s < TRAIN_SEED_LIMIT for s in train)
    assert len(train) == 50 * 2 * 16  # distinct streams for seeds, streams and environments
    ev = eval_seeds(100)
    assert ev[0] == EVAL_SEED_BASE == 2**31 and ev == list(range(2**31, 2**31 + 100))
    assert all(is_eval_seed(s) for s in ev) and not any(is_eval_seed(s) for s in train)
    assert eval_seeds(3, offset=5) == [2**31 + 5, 2**31 + 6, 2**31 + 7]
    assert train_env_seeds(7, 4) == train_env_seeds(7, 4)
    assert train_env_seeds(7, 4)[:2] != train_env_seeds(8, 4)[:2]
    with pytest.raises(ValueError):
        eval_seeds(0)
    with pytest.raises(ValueError):
        train_env_seeds(-1, 2)


def test_paper_toml_is_the_builtin_default() -> None:
    data = load_config_file(CONFIGS / "paper.toml")
    assert merge(PAPER, data) == PAPER
    assert data["algos"] == PAPER["algos"] and data["run"] == PAPER["run"]


def test_demo_toml_is_the_builtin_demo() -> None:
    assert load_config_file(CONFIGS / "demo.toml") == DEMO


def test_paper_hyperparameters() -> None:
    run, hp, _ = resolve(PAPER, "DescentEnv-v0", "PPO")
    assert run["total_timesteps"] == 2_000_000 and run["n_envs"] == 1
    assert hp["learning_rate"] == 3e-4 and hp["n_steps"] == 2048 and hp["batch_size"] == 64
    _, hp, _ = resolve(PAPER, "StaticObstacleEnv-v0", "PPO")
    assert hp["learning_rate"] == 1e-4
    _, hp, _ = resolve(PAPER, "StaticObstacleEnv-v0", "SAC")
    assert hp["learning_rate"] == 3e-4 and hp["batch_size"] == 256 and hp["ent_coef"] == "auto"
    for algo in ("TD3", "DDPG"):  # SB3 2.2.1 defaults, as stored in the paper's models
        _, hp, _ = resolve(PAPER, "MergeEnv-v0", algo)
        assert hp["batch_size"] == 100 and hp["gradient_steps"] == -1 and hp["train_freq"] == [1, "episode"]
        assert sb3_kwargs(hp)["train_freq"] == (1, "episode")
    assert set(PAPER["algos"]) == set(ALGORITHMS)


def test_adapt_to_several_envs_keeps_one_update_per_transition() -> None:
    _, hp, _ = resolve(PAPER, "DescentEnv-v0", "DDPG")
    same, notes = adapt_to_n_envs("DDPG", hp, 1)
    assert same == hp and notes == []
    many, notes = adapt_to_n_envs("DDPG", hp, 8)
    assert many["train_freq"] == 1 and many["gradient_steps"] == -1 and len(notes) == 1
    _, hp, _ = resolve(PAPER, "DescentEnv-v0", "SAC")
    many, notes = adapt_to_n_envs("SAC", hp, 8)
    assert many["gradient_steps"] == -1 and len(notes) == 1
    _, hp, _ = resolve(PAPER, "DescentEnv-v0", "PPO")
    assert adapt_to_n_envs("PPO", hp, 8) == (hp, [])
    with pytest.raises(ValueError, match="train_freq"):
        adapt_to_n_envs("TD3", {"train_freq": [1, "episode"], "gradient_steps": 5}, 4)


def test_config_file_overrides_and_errors(tmp_path: Path) -> None:
    good = tmp_path / "c.json"
    good.write_text(json.dumps({"run": {"n_envs": 4}, "algos": {"PPO": {"n_steps": 128, "envs": {"MergeEnv-v0": {"gamma": 0.9}}}}}))
    cfg = merge(PAPER, load_config_file(good))
    run, hp, _ = resolve(cfg, "MergeEnv-v0", "PPO")
    assert run["n_envs"] == 4 and hp["n_steps"] == 128 and hp["gamma"] == 0.9 and hp["batch_size"] == 64
    _, hp, _ = resolve(cfg, "DescentEnv-v0", "PPO")
    assert hp["gamma"] == 0.99
    for bad, match in (
        ({"algo": {}}, "unknown section"),
        ({"run": {"steps": 5}}, "unknown \\[run\\] key"),
        ({"algos": {"A2C": {}}}, "unknown algorithm"),
    ):
        p = tmp_path / "bad.json"
        p.write_text(json.dumps(bad))
        with pytest.raises(ValueError, match=match):
            load_config_file(p)
    with pytest.raises(ValueError, match=".toml or .json"):
        load_config_file(tmp_path / "c.yaml")


@pytest.mark.parametrize(
    ("name", "text", "words"),
    [
        ("c.json", '{"run": {"n_envs": "four"}}', r"c\.json:1: \[run\] n_envs must be an integer, got 'four'"),
        ("c.json", '{\n  "run": {\n    "eval_episodes": 2.5\n  }\n}', r"c\.json:3: \[run\] eval_episodes must be an integer, got 2\.5"),
        ("c.toml", "[run]\ndevice = 0\ntorch_threads = true\n", r"c\.toml:2: \[run\] device must be a string, got 0"),
        ("c.toml", "[run]\ntorch_threads = true\n", r"c\.toml:2: \[run\] torch_threads must be an integer, got True"),
        ("c.toml", '[run]\ntrainer = "sb3"\ncompile = "yes"\n', r"c\.toml:3: \[run\] compile must be true, false or \"auto\", got 'yes'"),
        ("c.toml", '[algos.PPO]\nn_steps = 64\nlearning_rate = "fast"\n', r"c\.toml:3: \[algos\.PPO\] learning_rate must be a number, got 'fast'"),
        ("c.json", '{"algos": {"SAC": {"envs": {"MergeEnv-v0": {"gamma": "0.9"}}}}}', r'\[algos\.SAC\.envs\."MergeEnv-v0"\] gamma must be a number'),
    ],
    ids=["run-string", "run-fraction", "run-device", "run-bool", "run-compile", "hyperparameter", "per-env-hyperparameter"],
)
def test_a_config_value_of_the_wrong_type_names_the_file_line_and_key(tmp_path: Path, name: str, text: str, words: str) -> None:
    p = tmp_path / name
    p.write_text(text)
    with pytest.raises(ValueError, match=words) as info:
        load_config_file(p)
    assert str(p) in str(info.value) and "\n" not in str(info.value)


def test_config_values_of_the_right_type_pass(tmp_path: Path) -> None:
    p = tmp_path / "c.toml"
    p.write_text(
        '[run]\ntotal_timesteps = 2e6\ndevice = "cpu"\ntrainer = "fast"\ncompile = true\n[algos.SAC]\nent_coef = 0.1\ntrain_freq = [1, "episode"]\n'
    )
    p.write_text(p.read_text() + "[algos.PPO]\nclip_range = 0.1\n")
    cfg = merge(PAPER, load_config_file(p))
    spec_run, hp, _ = resolve(cfg, "DescentEnv-v0", "SAC")
    assert spec_run["total_timesteps"] == 2e6 and hp["ent_coef"] == 0.1 and hp["train_freq"] == [1, "episode"]
