"""RealTrafficCREnv-v0 on a synthetic collection: contract, determinism, batching, splits."""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import bluesky_gym
from bluesky_gym.environments.real_traffic.task import RealTrafficConfig, episode_data
from bluesky_gym.envs.seeds import EVAL_SEED_BASE

from ..conftest import same_values
from .synthetic import save, traffic_collection

bluesky_gym.register_envs()
ENV = "RealTrafficCREnv-v0"


@pytest.fixture(scope="module")
def options(tmp_path_factory) -> dict:
    path = save(traffic_collection(n_flights=16), tmp_path_factory.mktemp("rt"))
    return {"collections": (path,), "min_traffic": 1, "max_traffic": 8}


def _episode(env, seed: int, actions: np.ndarray) -> list:
    obs, info = env.reset(seed=seed)
    out = [obs]
    for a in actions:
        obs, r, te, tr, info = env.step(a)
        out.append((obs, r, te, tr))
        if te or tr:
            break
    return out


def test_contract_and_kpis(options) -> None:
    env = gym.make(ENV, **options)
    check_env(env.unwrapped, skip_render_check=True)
    obs, info = env.reset(seed=3)
    assert obs["ownship"].shape == (6,) and obs["intruders"].shape == (5, 7)
    assert env.action_space.shape == (2,)
    steps = 0
    while True:
        obs, r, te, tr, info = env.step(np.zeros(2))
        steps += 1
        if te or tr:
            break
    assert (te, tr, steps) == (False, True, 60)
    assert {"kpi_los_count", "kpi_min_separation_nm", "kpi_mean_route_deviation_nm", "reward_route", "reward_intrusion"} <= set(info)
    # with zero actions the ownship follows its recording
    assert info["kpi_mean_route_deviation_nm"] < 0.5
    assert gym.make(ENV, altitude_action=True, **options).action_space.shape == (3,)


def test_same_seed_same_episode_other_seed_different(options) -> None:
    actions = np.random.default_rng(0).uniform(-1, 1, (60, 2))
    a = _episode(gym.make(ENV, **options), 11, actions)
    b = _episode(gym.make(ENV, **options), 11, actions)
    c = _episode(gym.make(ENV, **options), 12, actions)
    assert same_values(a, b)
    assert not same_values(a, c)


def test_batched_equals_single(options) -> None:
    n, seed = 3, 5
    actions = np.random.default_rng(1).uniform(-1, 1, (20, n, 2))
    venv = gym.make_vec(ENV, num_envs=n, vectorization_mode="vector_entry_point", **options)
    obs, _ = venv.reset(seed=seed)
    batched = [obs]
    for a in actions:
        batched.append(venv.step(a))
    for i in range(n):
        env = gym.make(ENV, **options)
        o, _ = env.reset(seed=seed + i)
        assert same_values(o, {k: v[i] for k, v in batched[0].items()})
        for k, a in enumerate(actions):
            o, r, te, tr, _ = env.step(a[i])
            bo, br, bte, btr, _ = batched[k + 1]
            assert same_values(o, {key: v[i] for key, v in bo.items()}) and r == br[i] and (te, tr) == (bte[i], btr[i])


def test_evaluation_seeds_draw_from_the_test_split(options) -> None:
    data = episode_data(RealTrafficConfig(**options))
    train_starts = {w.start for w in data.train}
    test_starts = {w.start for w in data.test}
    assert train_starts and test_starts and max(train_starts) + 600.0 <= min(test_starts)
    env = gym.make(ENV, **options)
    for seed, expected in ((0, train_starts), (EVAL_SEED_BASE, test_starts), (EVAL_SEED_BASE + 7, test_starts), (9, train_starts)):
        env.reset(seed=seed)
        task = env.unwrapped.task
        assert task.window(0).start in expected
    fixed = gym.make(ENV, split="test", **options)
    fixed.reset(seed=0)
    assert fixed.unwrapped.task.window(0).start in test_starts
    venv = gym.make_vec(ENV, num_envs=2, vectorization_mode="vector_entry_point", **options)
    venv.reset(seed=[1, EVAL_SEED_BASE])
    assert venv.unwrapped.task.window(0).start in train_starts and venv.unwrapped.task.window(1).start in test_starts


def test_collection_split(tmp_path) -> None:
    a = save(traffic_collection(n_flights=8, seed=1), tmp_path, "a.npz")
    b = save(traffic_collection(n_flights=8, seed=2), tmp_path, "b.npz")
    cfg = RealTrafficConfig(collections=(a, b), split_by="collection", test_collections=(b,), min_traffic=1, max_traffic=8)
    data = episode_data(cfg)
    n_a = 8
    assert all(max(w.flights) < n_a for w in data.train)
    assert all(min(w.flights) >= n_a for w in data.test)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"split": "dev"}, "split must be one of"),
        ({"window_s": 605.0}, "window_s must be a multiple of 10"),
        ({"test_fraction": 1.0}, "test_fraction must be < 1"),
        ({"split_by": "collection", "test_collections": ("nope",)}, "test_collections must be some but not all"),
        ({"min_traffic": 9}, r"min_traffic \(9\) must be <= max_traffic"),
        ({"labels": "some"}, "labels must be one of"),
    ],
)
def test_bad_options(options, change, message) -> None:
    with pytest.raises(ValueError, match=message):
        gym.make(ENV, **{**options, **change})


def test_a_collection_named_twice_is_refused(options, tmp_path) -> None:
    """Twice the same collection would play every window twice (and hold it out twice)."""
    path = options["collections"][0]
    with pytest.raises(ValueError, match=r"collections name .*synthetic.npz.* more than once"):
        gym.make(ENV, **{**options, "collections": (path, path)})
    with pytest.raises(ValueError, match="collections name 'switzerland' more than once"):
        RealTrafficConfig(collections=("switzerland", "quickstart", "switzerland")).validate()
    # the same file by two spellings is the same collection
    spelled = str(Path(path).parent / "." / Path(path).name)
    with pytest.raises(ValueError, match="more than once"):
        gym.make(ENV, **{**options, "collections": (path, spelled)})
    with pytest.raises(ValueError, match="test_collections name 'quickstart' more than once"):
        RealTrafficConfig(split_by="collection", test_collections=("quickstart", "quickstart")).validate()


def test_missing_collection_file(tmp_path) -> None:
    with pytest.raises(ValueError, match="nothing.npz: no such recorded-flights file"):
        gym.make(ENV, collections=(str(tmp_path / "nothing.npz"),))


def test_classical_avoids_more_than_random(options) -> None:
    from bluesky_gym.training.evaluation import evaluate
    from bluesky_gym.training.policies import reference_policy

    space = gym.make(ENV, **options).action_space
    random = evaluate(ENV, reference_policy("random", ENV, space.low, space.high), 8, env_options=options)
    classical = evaluate(ENV, reference_policy("classical", ENV, space.low, space.high), 8, env_options=options)
    assert classical.mean_return > random.mean_return


def test_pettingzoo_every_recorded_aircraft_is_an_agent(options) -> None:
    pytest.importorskip("pettingzoo")
    from pettingzoo.test import parallel_api_test

    from bluesky_gym.environments.real_traffic.multiagent import RealTrafficParallelEnv

    parallel_api_test(RealTrafficParallelEnv(**options), num_cycles=80)
    env = RealTrafficParallelEnv(**options)
    obs, _ = env.reset(seed=4)
    assert env.agents and set(obs) == set(env.agents) and set(env.agents) <= set(env.possible_agents)
    seen = set(env.agents)
    zero_dev = []
    while env.agents:
        obs, rew, term, trunc, infos = env.step({a: np.zeros(2) for a in env.agents})
        seen |= set(env.agents)
        zero_dev += [abs(i["route_deviation_nm"]) for i in infos.values() if i]
    assert seen <= set(env.possible_agents) and len(seen) >= 2
    assert np.median(zero_dev) < 0.5  # all-zero actions replay the recording
    # same seed, same episode
    a, b = RealTrafficParallelEnv(**options), RealTrafficParallelEnv(**options)
    oa, _ = a.reset(seed=9)
    ob, _ = b.reset(seed=9)
    assert oa.keys() == ob.keys() and all(np.array_equal(oa[k]["intruders"], ob[k]["intruders"]) for k in oa)


def test_cache_directory_order_and_availability(tmp_path, monkeypatch) -> None:
    from bluesky_gym.envs.registry import entry
    from bluesky_gym.realtraffic.cache import cache_dir, collection_path
    from bluesky_gym.registration import available_envs

    monkeypatch.setenv("BLUESKY_GYM_CACHE", str(tmp_path / "env"))
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cache_dir(str(tmp_path / "opt")) == tmp_path / "opt"
    assert cache_dir() == tmp_path / "env"
    monkeypatch.delenv("BLUESKY_GYM_CACHE")
    assert cache_dir() == tmp_path / "xdg" / "bluesky-gym"
    assert collection_path("switzerland") == tmp_path / "xdg" / "bluesky-gym" / "realtraffic" / "switzerland-v1.npz"
    # no prepared data: registered and listed all the same (the first reset prepares them)
    assert not entry(ENV).data_ready() and ENV in available_envs() and ENV in gym.registry
    for name in ("switzerland", "quickstart"):
        path = collection_path(name)
        path.parent.mkdir(parents=True, exist_ok=True)
        traffic_collection(n_flights=2).save(path)
    assert entry(ENV).data_ready() and ENV in available_envs()


@pytest.fixture
def empty_cache(tmp_path, monkeypatch):
    """An empty cache directory, and a cleaning that fails: nothing may clean a sample collection unasked."""
    from bluesky_gym.realtraffic import sources

    def refuse(name: str, **_: object) -> None:
        raise RuntimeError(f"cleaned {name}")

    monkeypatch.setenv("BLUESKY_GYM_CACHE", str(tmp_path / "empty-cache"))
    monkeypatch.setattr(sources, "load_sample", refuse)
    return tmp_path / "empty-cache"


@pytest.mark.parametrize("env_id", ["RealTrafficCREnv-v0", "RealTrafficCREnv-v1"])
def test_the_id_is_known_before_its_data_are_prepared(empty_cache, capsys, env_id) -> None:
    """``list``, ``info`` and the documentation know the id with an empty cache; ``make`` cleans nothing, the first reset prepares the data."""
    import importlib.util
    import sys

    from bluesky_gym.cli import main
    from bluesky_gym.cli.catalog import describe
    from bluesky_gym.registration import available_envs

    assert env_id in available_envs()
    facts = describe(env_id)
    assert facts["id"] == env_id and set(facts["observation"]) == {"ownship", "intruders"}
    assert main(["info", "--env", env_id]) == 0
    said = capsys.readouterr().out
    assert said.startswith(f"{env_id}: ") and "not prepared" in said and "realtraffic prepare --sample switzerland" in said
    hooks_path = Path(__file__).resolve().parents[2] / "docs" / "hooks.py"
    spec = importlib.util.spec_from_file_location("docs_hooks_rt", hooks_path)
    hooks = importlib.util.module_from_spec(spec)
    sys.modules["docs_hooks_rt"] = hooks
    try:
        spec.loader.exec_module(hooks)
        assert hooks.env_page(env_id).startswith(f"# {env_id}")
    finally:
        del sys.modules["docs_hooks_rt"]
    env = gym.make(env_id)
    with pytest.raises(RuntimeError, match="cleaned switzerland"):
        env.reset(seed=0)
    assert not empty_cache.exists() or not any(empty_cache.rglob("*.npz"))


def test_list_shows_the_id_before_its_data_are_prepared(empty_cache, capsys) -> None:
    from bluesky_gym.cli import main

    assert main(["list"]) == 0
    rows = [line.split()[0] for line in capsys.readouterr().out.splitlines() if line.strip()]
    assert ENV in rows


def test_an_episode_written_as_scn_replays_exactly(options) -> None:
    """``render --scn`` of an episode with an agent acting: the recorded traffic's commands are in the file too, and it replays bit for bit."""
    from bluesky_gym.core.simulator import Simulator
    from bluesky_gym.scenarios import ScenarioPlayer, parse_scenario
    from bluesky_gym.scenarios.export import ScenarioRecorder
    from bluesky_gym.scenarios.player import slots_needed, waypoints_needed

    env = gym.make(ENV, **options)
    rec = env.unwrapped.task.wrap_physics(ScenarioRecorder)
    env.reset(seed=5)
    env.action_space.seed(5)
    sim = env.unwrapped.task.sim
    track = []
    for _ in range(30):
        env.step(env.action_space.sample())
        track.append((sim.simt - rec.episodes[0][-1].start, sim.lat[0].copy(), sim.lon[0].copy(), sim.alt[0].copy(), sim.active[0].copy()))
    scenario = parse_scenario(rec.scenario_text(), "episode.scn")
    assert len(scenario.callsigns) >= 2 and sum(c.__class__.__name__ == "Heading" for c in scenario.commands) == 30  # the agent's turns
    replay = Simulator(1, slots_needed(scenario), dt=sim.dt, max_waypoints=waypoints_needed(scenario))
    player = ScenarioPlayer([scenario], replay)
    for t, lat, lon, alt, active in track:
        player.advance(int(round(t / sim.dt)) - player.steps_done)
        slot_of = {acid: s for s, acid in player.slots(0)}
        assert set(slot_of) == {f"AC{s:03d}" for s in np.flatnonzero(active)}
        for s in np.flatnonzero(active):
            j = slot_of[f"AC{s:03d}"]
            assert (replay.lat[0, j], replay.lon[0, j], replay.alt[0, j]) == (lat[s], lon[s], alt[s])


def test_episode_data_follows_the_cache_directory(tmp_path, monkeypatch) -> None:
    """The same options read from another cache directory (or a rewritten file) give that directory's flights, not the first ones read."""
    from bluesky_gym.realtraffic.cache import collection_path

    config = RealTrafficConfig(collections=("switzerland",), min_traffic=1)
    flights = {}
    for k, n in ((0, 16), (1, 24)):
        monkeypatch.setenv("BLUESKY_GYM_CACHE", str(tmp_path / f"cache{k}"))
        path = collection_path("switzerland")
        path.parent.mkdir(parents=True)
        traffic_collection(n_flights=n, seed=k).save(path)
        flights[k] = episode_data(config).flights.n_flights
    assert flights == {0: 16, 1: 24}
    traffic_collection(n_flights=20, seed=2).save(path)  # rewritten in place
    assert episode_data(config).flights.n_flights == 20
