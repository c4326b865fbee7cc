"""The ``mvp`` reference policy: resolves head-on conflicts in every env with traffic, batches, and is in ``eval``."""

from __future__ import annotations

import json
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import bluesky_gym  # noqa: F401  (registers the environments)
from bluesky_gym.cli import main
from bluesky_gym.core.conflicts import PZ_HEIGHT
from bluesky_gym.core.geo import kwikdist
from bluesky_gym.core.units import KTS
from bluesky_gym.environments.sector_cr.controller import SECTOR_CR_MVP
from bluesky_gym.envs.registry import ENVIRONMENTS
from bluesky_gym.training.evaluation import evaluate, make_policy, reference_scores
from bluesky_gym.training.policies import mvp_mapping, mvp_policy, reference_names, reference_policy

#: Env -> (decision steps flown, time to loss of separation of the head-on intruder [s]).
HEAD_ON = {
    "HorizontalCREnv-v0": (8, 150.0),
    "VerticalCREnv-v0": (10, 150.0),
    "SectorCREnv-v0": (40, 60.0),
    "MergeEnv-v0": (8, 150.0),
}
HEAD_ON.update({env_id.replace("-v0", "-v1"): case for env_id, case in HEAD_ON.items()})


def _head_on_separation(env_id: str, resolve: bool, n: int = 3, method: str = "MVP") -> np.ndarray:
    """Smallest separation (in protected-zone units) between the ownship and a head-on intruder, per episode.

    Each episode's traffic is replaced by one intruder on a collision course (``creconfs`` with
    dcpa 0) through the Physics interface; the ownship then flies MVP (``resolve``) or MVP's
    nominal policy without resolution (``method``: the resolution the policy flies, by ``RESO``
    name). The separation is the horizontal distance over the
    protected-zone radius, for VerticalCR the larger of that and the vertical distance over the
    zone's half height.
    """
    steps, tlosh = HEAD_ON[env_id]
    venv = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point")
    policy = mvp_policy(env_id, method)
    policy.bind(venv)
    venv.reset(seed=list(range(n)))
    sim = venv.unwrapped.task.sim
    for e in range(n):
        sim.delete(e, np.flatnonzero(sim.active[e, 1:]) + 1)
        sim.creconfs(e, 0, 1, 180.0, 0.0, tlosh)
    obs = venv.unwrapped.task.observation()
    rpz_nm = mvp_mapping(env_id).rpz_nm
    worst = np.full(n, np.inf)
    done = np.zeros(n, bool)
    for _ in range(steps):
        action = policy.act(obs) if resolve else policy.nominal.act(obs)
        obs, _, terminated, truncated, _ = venv.step(action)
        done |= terminated | truncated
        ratio = kwikdist(sim.lat[:, 0], sim.lon[:, 0], sim.lat[:, 1], sim.lon[:, 1]) / rpz_nm
        if env_id.startswith("Vertical"):
            ratio = np.maximum(ratio, np.abs(sim.alt[:, 0] - sim.alt[:, 1]) / PZ_HEIGHT)
        worst = np.where(done, worst, np.minimum(worst, ratio))
    venv.close()
    assert not done.all()
    return worst[np.isfinite(worst)]


@pytest.mark.parametrize("env_id", sorted(HEAD_ON))
def test_mvp_resolves_a_head_on_conflict(env_id: str) -> None:
    with_mvp = _head_on_separation(env_id, True)
    without = _head_on_separation(env_id, False)
    assert np.all(with_mvp >= 1.0), f"{env_id}: loss of separation with MVP ({with_mvp})"
    assert np.all(with_mvp > without), (with_mvp, without)


def test_mvp_exists_for_the_envs_with_traffic_only() -> None:
    traffic = {"HorizontalCREnv", "VerticalCREnv", "SectorCREnv", "MergeEnv", "DenseSectorCREnv"}
    assert {e.id for e in ENVIRONMENTS if e.mvp} == {f"{name}-{v}" for name in traffic for v in ("v0", "v1")}
    # A -v1 id has its -v0 mapping; SectorCR-v1's speed action is in knots (speed_step_in_knots).
    assert mvp_mapping("SectorCREnv-v1").speed_step == SECTOR_CR_MVP.speed_step * KTS
    assert mvp_mapping("SectorCREnv-v0") is SECTOR_CR_MVP and mvp_mapping("MergeEnv-v1") is mvp_mapping("MergeEnv-v0")
    assert reference_names("MergeEnv-v0") == reference_names("MergeEnv-v1") == ("random", "classical", "mvp")
    assert reference_names("DescentEnv-v0") == reference_names("DescentEnv-v1") == ("random", "classical")
    with pytest.raises(ValueError, match="no MVP mapping for DescentEnv-v0"):
        reference_policy("mvp", "DescentEnv-v0", np.zeros(1), np.ones(1))


def test_mvp_needs_its_environment() -> None:
    policy = make_policy("mvp", "SectorCREnv-v0")
    obs = {"cos(drift)": np.ones((1, 1)), "sin(drift)": np.zeros((1, 1))}
    with pytest.raises(RuntimeError, match=r"bind\(env\)"):
        policy.act(obs)
    other = gym.make_vec("MergeEnv-v0", num_envs=1, vectorization_mode="vector_entry_point")
    with pytest.raises(ValueError, match="needs that environment"):
        policy.bind(other)
    other.close()


@pytest.mark.parametrize("env_id", ["SectorCREnv-v0", "VerticalCREnv-v0"])
def test_batched_mvp_equals_single_episodes(env_id: str) -> None:
    """Episodes evaluated 4 at a time equal the same episodes evaluated one by one."""
    batched = evaluate(env_id, make_policy("mvp", env_id), 4, batch=4, max_episode_steps=40)
    single = evaluate(env_id, make_policy("mvp", env_id), 4, batch=1, max_episode_steps=40)
    assert len(batched.episodes) == 4
    for a, b in zip(batched.episodes, single.episodes, strict=True):
        assert a.keys() == b.keys()
        for k in a:
            assert a[k] == b[k] or (a[k] != a[k] and b[k] != b[k]), (k, a[k], b[k])  # equal, or both NaN


def test_reference_scores_include_mvp_where_it_exists(tmp_path: Path) -> None:
    refs = reference_scores("HorizontalCREnv-v0", 2, tmp_path)
    assert set(refs) == {"random", "classical", "mvp"}
    assert refs["mvp"]["policy"] == "mvp" and refs["mvp"]["episodes"] == 2
    cached = json.loads((tmp_path / "HorizontalCREnv-v0.json").read_text())
    assert "mvp" in cached
    # A cache written without mvp is recomputed, not half read.
    del cached["mvp"]
    (tmp_path / "HorizontalCREnv-v0.json").write_text(json.dumps(cached))
    assert "mvp" in reference_scores("HorizontalCREnv-v0", 2, tmp_path)


def test_eval_cli_with_mvp(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["eval", "HorizontalCREnv-v0", "--model", "mvp", "--model", "classical", "--episodes", "3", "--out", str(tmp_path)])
    assert code == 0
    out = capsys.readouterr().out
    rows = [line.split()[0] for line in out.splitlines()[2:4]]
    assert rows == ["mvp", "classical"]
    result = json.loads((tmp_path / "eval_mvp.json").read_text())
    assert result["policy"] == "mvp" and result["episodes"] == 3
    assert main(["eval", "DescentEnv-v0", "--model", "mvp", "--episodes", "1", "--out", str(tmp_path)]) == 2
    assert "no MVP mapping for DescentEnv-v0" in capsys.readouterr().err


def test_mvp_caps_the_ownship_vertical_speed_with_its_own_type() -> None:
    """VerticalCR with a B744 ownship: MVP's vertical speed is capped with the B744's envelope (BlueSky's perf per aircraft)."""
    from bluesky_gym.core.aircraft import aircraft_performance
    from bluesky_gym.environments.descent.task import ACTION_2_MS

    b744, a320 = aircraft_performance("B744"), aircraft_performance("A320")
    venv = gym.make_vec("VerticalCREnv-v0", num_envs=4, vectorization_mode="vector_entry_point", ownship_types="B744")
    own, fixed = mvp_policy("VerticalCREnv-v0"), mvp_policy("VerticalCREnv-v0")
    own.bind(venv)
    fixed.bind(venv)
    fixed.resolver.vsmin, fixed.resolver.vsmax = a320.vsmin, a320.vsmax  # one envelope for every aircraft
    obs, _ = venv.reset(seed=0)
    assert venv.unwrapped.task.sim.aircraft_type(range(4), 0) == ["B744"] * 4
    followed = differ = 0
    for _ in range(60):
        nominal = own.nominal.act(obs)[:, 0]
        a, b = own.act(obs)[:, 0], fixed.act(obs)[:, 0]
        resolving = a != nominal
        followed += int(resolving.sum())
        differ += int((a != b).sum())
        # A capped vertical speed is at least vsmin in magnitude: the B744's, not the A320's.
        assert np.all(np.abs(a[resolving]) >= b744.vsmin / ACTION_2_MS - 1e-12)
        obs, _, terminated, truncated, _ = venv.step(a[:, None])
        own.reset(terminated | truncated)
        fixed.reset(terminated | truncated)
    venv.close()
    assert followed > 0 and differ > 0


@pytest.mark.parametrize("env_id", sorted(e.id for e in ENVIRONMENTS if e.mvp))
def test_render_and_eval_commands_fly_mvp(env_id: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``render --policy mvp`` (single and batched) and ``eval --model mvp`` work for every environment with MVP."""
    pytest.importorskip("pygame")
    out = tmp_path / "mvp.gif"
    assert main(["render", "--env", env_id, "--policy", "mvp", "--episodes", "2", "--max-steps", "3", "--out", str(out)]) == 0
    assert out.stat().st_size > 1000
    assert capsys.readouterr().err.count("episode ") == 2
    grid = tmp_path / "grid.gif"
    assert main(["render", "--env", env_id, "--policy", "mvp", "--grid", "2", "--max-frames", "3", "--out", str(grid)]) == 0
    assert grid.stat().st_size > 1000
    assert main(["eval", "--env", env_id, "--model", "mvp", "--episodes", "1", "--num-envs", "1", "--out", str(tmp_path / "eval")]) == 0
    assert json.loads((tmp_path / "eval" / "eval_mvp.json").read_text())["policy"] == "mvp"


def test_render_command_refuses_mvp_without_traffic(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["render", "--env", "DescentEnv-v1", "--policy", "mvp", "--max-frames", "2", "--out", str(tmp_path / "d.gif")]) == 2
    assert "no MVP mapping for DescentEnv-v1" in capsys.readouterr().err


@pytest.mark.slow
def test_demo_compares_with_mvp_where_it_exists(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The demo on an environment with traffic evaluates mvp with the other references (and caches it with them)."""
    pytest.importorskip("stable_baselines3")
    out = tmp_path / "demo"
    common = ["--steps", "512", "--num-envs", "4", "--episodes", "2", "--out", str(out), "--no-progress", "--no-gif"]
    assert main(["demo", "--env", "MergeEnv-v0", *common]) == 0  # 50-step episodes: some end within 128 steps per env
    rows = [line.split()[0] for line in capsys.readouterr().out.splitlines() if line.split()[:1] in (["mvp"], ["classical"], ["random"])]
    assert sorted(rows) == ["classical", "mvp", "random"]
    demo = json.loads((out / "demo.json").read_text())
    assert set(demo["kpis"]) == {"PPO", "random", "classical", "mvp"}
    assert json.loads((out / "eval_mvp.json").read_text())["policy"] == "mvp"
    cached = json.loads((out / "references" / "MergeEnv-v0.json").read_text())
    assert {"random", "classical", "mvp"} <= set(cached)  # a complete cache: reference_scores reads it as it is


def test_eby_and_swarm_references_are_selectable_not_default(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``eby`` and ``swarm``: the mvp mapping flying BlueSky's Eby or Swarm; in eval and as extra references, not scored by default."""
    assert reference_names("HorizontalCREnv-v0") == ("random", "classical", "mvp")
    for name, method in (("eby", "EBY"), ("swarm", "SWARM")):
        policy = reference_policy(name, "SectorCREnv-v0", np.zeros(2), np.ones(2))
        assert policy.name == name and policy.method == method and policy.resolver is not None and policy.resolver.name == method
    with pytest.raises(ValueError, match="no MVP mapping for DescentEnv-v0"):
        reference_policy("eby", "DescentEnv-v0", np.zeros(1), np.ones(1))
    refs = reference_scores("HorizontalCREnv-v0", 2, tmp_path, extra=("swarm", "eby"))
    assert list(refs) == ["random", "classical", "mvp", "swarm", "eby"] and refs["eby"]["policy"] == "eby"
    assert set(reference_scores("DescentEnv-v0", 1, tmp_path, extra=("eby",))) == {"random", "classical"}
    with pytest.raises(ValueError, match="unknown reference policy 'fancy'"):
        reference_scores("HorizontalCREnv-v0", 1, extra=("fancy",))
    assert main(["eval", "HorizontalCREnv-v0", "--model", "eby", "--model", "swarm", "--episodes", "2", "--out", str(tmp_path)]) == 0
    assert [line.split()[0] for line in capsys.readouterr().out.splitlines()[2:4]] == ["eby", "swarm"]
    assert json.loads((tmp_path / "eval_swarm.json").read_text())["policy"] == "swarm"


@pytest.mark.parametrize("name", ["eby", "swarm"])
def test_eby_and_swarm_policies_act_on_a_head_on_conflict(name: str) -> None:
    """The policy turns the ownship away from a head-on intruder where the nominal policy would not."""
    env_id = "HorizontalCREnv-v0"
    venv = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point")
    policy = make_policy(name, env_id)
    policy.bind(venv)
    venv.reset(seed=[0, 1])
    sim = venv.unwrapped.task.sim
    for e in range(2):
        sim.delete(e, np.flatnonzero(sim.active[e, 1:]) + 1)
        sim.creconfs(e, 0, 1, 180.0, 0.0, 150.0)
    obs = venv.unwrapped.task.observation()
    acted = 0.0
    for _ in range(4):
        action = policy.act(obs)
        acted = max(acted, float(np.abs(action - policy.nominal.act(obs)).max()))
        obs, *_ = venv.step(action)
    venv.close()
    assert acted > 0.05


def test_sweep_takes_extra_references(capsys: pytest.CaptureFixture[str]) -> None:
    from bluesky_gym.cli import build_parser

    args = build_parser().parse_args(["sweep", "--env", "all", "--references", "eby", "swarm"])
    assert args.references == ["eby", "swarm"]
    assert build_parser().parse_args(["sweep", "--env", "all"]).references == []
    with pytest.raises(SystemExit):
        build_parser().parse_args(["sweep", "--env", "all", "--references", "fancy"])
    assert "invalid choice: 'fancy'" in capsys.readouterr().err
    assert build_parser().parse_args(["sweep", "--env", "all", "--references", "ssd"]).references == ["ssd"]


def test_the_sweep_summary_prints_every_reference_it_evaluated() -> None:
    from bluesky_gym.training.sweep import format_summary

    refs = {"random": -3.0, "classical": 1.0, "mvp": 0.5, "eby": 0.25, "ssd": 0.75}
    text = format_summary({"runs": [], "references": {"SectorCREnv-v0": refs}})
    assert "reference SectorCREnv-v0: random -3.00, classical 1.00, mvp 0.50, eby 0.25, ssd 0.75" in text.splitlines()
