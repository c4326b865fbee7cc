"""PettingZoo environments: API and seed tests, agent removal, global state, rendering."""

from __future__ import annotations

import re
import sys
import warnings

import numpy as np
import pytest

pytest.importorskip("pettingzoo")

from pettingzoo.test import parallel_api_test, parallel_seed_test

from bluesky_gym.core import geo
from bluesky_gym.core.extras import install_hint
from bluesky_gym.multiagent import names, parallel_env, require_pettingzoo
from bluesky_gym.multiagent.base import STATE_FEATURES
from bluesky_gym.tasks import merge as mg
from bluesky_gym.tasks import sector_cr
from bluesky_gym.tasks.geometry import point_at_distance

from ..conftest import same_values

NAMES = names()


@pytest.mark.parametrize("name", NAMES)
def test_parallel_api(name: str) -> None:
    with warnings.catch_warnings():
        # SectorCR sizes its agent slots for the densest traffic, so an episode ends with unused
        # possible agents, which the API test reports as a warning.
        warnings.filterwarnings("ignore", message="No agents present but not all possible_agents")
        parallel_api_test(parallel_env(name), num_cycles=1000)


@pytest.mark.parametrize("name", NAMES)
def test_parallel_seed(name: str) -> None:
    parallel_seed_test(lambda: parallel_env(name), num_cycles=50)


def test_every_traffic_problem_has_a_v0_and_a_v1_name() -> None:
    assert sorted(NAMES) == sorted(f"{p}_{v}" for p in ("horizontal_cr", "sector_cr", "merge", "dense_sector_cr") for v in ("v0", "v1"))


@pytest.mark.parametrize("name", [n for n in NAMES if n.endswith("_v1")])
def test_v1_spaces_are_float32_with_finite_bounds_that_hold(name: str) -> None:
    env = parallel_env(name)
    assert env.metadata["name"] == name and env.task.name == name
    obs, _ = env.reset(seed=0)
    for step in range(30):
        for agent, o in obs.items():
            space = env.observation_space(agent)
            for key, box in space.spaces.items():
                assert box.dtype == np.float32 and np.all(np.isfinite(box.low)) and np.all(np.isfinite(box.high)), key
            assert space.contains(o), (step, agent)
        if not env.agents:
            break
        obs = env.step({a: env.action_space(a).sample() for a in env.agents})[0]
        assert all(env.action_space(a).dtype == np.float32 for a in env.agents)


def test_sector_v1_speed_action_is_in_knots() -> None:
    from bluesky_gym.core.units import KTS, MPS2KT

    changes, expected = {}, {}
    for name in ("sector_cr_v0", "sector_cr_v1"):
        env = parallel_env(name)
        env.reset(seed=2)
        task = env.task
        agent = env.agents[0]
        k = env.agent_name_mapping[agent]
        cas = task.sim.cas[0, k]
        env.step({agent: np.array([0.0, 1.0])})
        changes[name] = task.sim.selspd[0, k]
        step = sector_cr.D_VELOCITY * (KTS if name.endswith("v1") else 1.0)
        expected[name] = (cas + step) * MPS2KT * KTS  # SectorCREnv's command: CAS + step, in knots
    assert changes == expected


@pytest.mark.parametrize(
    ("name", "option"), [("sector_cr_v0", "exit_ends_episode"), ("merge_v0", "faf_same_step"), ("merge_v1", "normalise_airspeed")]
)
def test_single_agent_step_options_are_refused(name: str, option: str) -> None:
    with pytest.raises(ValueError, match=f"does not have the option.*{option}"):
        parallel_env(name, **{option: True})


@pytest.mark.parametrize("name", NAMES)
def test_reset_seed_gives_the_same_episode(name: str) -> None:
    env = parallel_env(name)
    rng = np.random.default_rng(0)
    runs = []
    for seed in (7, 7, 8):
        obs, _ = env.reset(seed=seed)
        out = [obs]
        for _ in range(5):
            actions = {a: rng.uniform(-1, 1, env.action_space(a).shape) for a in env.agents}
            out.append(env.step(actions)[:2])
        rng = np.random.default_rng(0)
        runs.append(out)
    assert same_values(runs[0], runs[1])
    assert not same_values(runs[0][0], runs[2][0])
    # A reset without a seed continues the generator: a new scenario.
    env.reset(seed=7)
    obs, _ = env.reset()
    assert not same_values(obs, runs[0][0])


def test_sector_agent_leaves_when_it_exits() -> None:
    env = parallel_env("sector_cr_v0")
    env.reset(seed=3)
    task = env.task
    leaving = env.agents[1]
    k = env.agent_name_mapping[leaving]
    n = len(env.agents)
    # Put the aircraft 10 NM outside the sector's northernmost vertex.
    nv = task.scenario.n_vertices[0]
    top = int(np.argmax(task.scenario.poly_lat[0, :nv]))
    task.sim.lat[0, k] = task.scenario.poly_lat[0, top] + 10 / 60
    task.sim.lon[0, k] = task.scenario.poly_lon[0, top]
    obs, rew, term, trunc, info = env.step({a: np.zeros(2) for a in env.agents})
    assert trunc[leaving] and not term[leaving]
    assert info[leaving]["completed"]
    assert leaving in obs and leaving in rew
    assert leaving not in env.agents and len(env.agents) == n - 1
    assert not task.sim.active[0, k]
    assert not any(trunc[a] or term[a] for a in env.agents)
    obs, *_ = env.step({a: np.zeros(2) for a in env.agents})
    assert leaving not in obs
    # The others no longer see it: the state row of its slot is empty.
    state = env.state().reshape(task.n_agents, len(STATE_FEATURES))
    assert np.all(state[k] == 0.0) and state[env.agent_name_mapping[env.agents[0]], 0] == 1.0


def test_horizontal_agent_terminates_at_its_waypoint() -> None:
    env = parallel_env("horizontal_cr_v0")
    env.reset(seed=5)
    task = env.task
    agent = env.agents[3]
    k = env.agent_name_mapping[agent]
    # 2 km before its waypoint, heading straight at it.
    wlat, wlon = task.wpt_lat[0, k], task.wpt_lon[0, k]
    lat, lon = point_at_distance(wlat, wlon, 2.0, 180.0)
    task.sim.lat[0, k], task.sim.lon[0, k] = lat, lon
    task.sim.hdg[0, k] = task.sim.trk[0, k] = task.sim.ap_trk[0, k] = 0.0
    task.ac_hdg[0, k] = 0.0
    obs, rew, term, trunc, info = env.step({a: np.zeros(1) for a in env.agents})
    assert term[agent] and not trunc[agent]
    assert rew[agent] > 0.5  # +1 reach reward, small drift penalty
    assert agent not in env.agents and not task.sim.active[0, k]
    assert all(not term[a] for a in env.agents)


def test_merge_agent_arrives_after_the_faf() -> None:
    env = parallel_env("merge_v0")
    env.reset(seed=2)
    task = env.task
    agent = env.agents[4]
    k = env.agent_name_mapping[agent]
    # Past the FAF (flag set), 15 NM north of the runway: within the 20 NM goal.
    task.wpt_reach[0, k] = 1
    lat, lon = point_at_distance(mg.RWY_LAT, mg.RWY_LON, 15 * 1.852, 0.0)
    task.sim.lat[0, k], task.sim.lon[0, k] = lat, lon
    assert geo.kwikdist(lat, lon, mg.RWY_LAT, mg.RWY_LON) < mg.GOAL_MARGIN
    obs, rew, term, trunc, info = env.step({a: np.zeros(2) for a in env.agents})
    assert term[agent]
    assert obs[agent]["faf_reached"][0] == 1.0
    assert agent not in env.agents and not task.sim.active[0, k]
    assert len(env.agents) == task.n_agents - 1


@pytest.mark.parametrize("name", NAMES)
def test_episode_ends_with_kpis_at_the_time_limit(name: str) -> None:
    env = parallel_env(name, max_episode_steps=3)
    env.reset(seed=1)
    for _ in range(3):
        obs, rew, term, trunc, info = env.step({a: np.zeros(env.action_space(a).shape) for a in env.agents})
    assert env.agents == []
    assert all(trunc.values())
    for i in info.values():
        assert {"kpi_los_count", "kpi_min_separation_nm", "kpi_completion_rate", "return", "intrusions"} <= set(i)
        assert all(np.isfinite(v) for v in i.values())
    with pytest.raises(RuntimeError):
        env.step({})


@pytest.mark.parametrize("name", NAMES)
def test_state_space_and_unknown_agent(name: str) -> None:
    env = parallel_env(name)
    env.reset(seed=0)
    state = env.state()
    assert env.state_space.contains(state)
    rows = state.reshape(env.task.n_agents, len(STATE_FEATURES))
    assert rows[:, 0].sum() == len(env.agents)
    with pytest.raises(KeyError):
        env.step({"no_such_aircraft": np.zeros(env.action_space(env.agents[0]).shape)})


@pytest.mark.parametrize("name", NAMES)
def test_missing_actions_keep_heading(name: str) -> None:
    env = parallel_env(name)
    env.reset(seed=4)
    hdg = env.task.sim.hdg[0].copy()
    env.step({})
    active = env.task.sim.active[0]
    turn = (env.task.sim.hdg[0][active] - hdg[active] + 180.0) % 360.0 - 180.0
    assert np.allclose(turn, 0.0, atol=1e-6)


@pytest.mark.parametrize("name", NAMES)
def test_render_rgb_array(name: str, monkeypatch: pytest.MonkeyPatch) -> None:
    pytest.importorskip("pygame")
    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")
    env = parallel_env(name, render_mode="rgb_array")
    env.reset(seed=0)
    first = env.render()
    env.step({a: np.ones(env.action_space(a).shape) for a in env.agents})
    frame = env.render()
    assert frame.dtype == np.uint8 and frame.ndim == 3 and frame.shape[2] == 3
    assert not np.array_equal(first, frame)
    env.close()


def test_human_render(monkeypatch: pytest.MonkeyPatch) -> None:
    pytest.importorskip("pygame")
    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")
    env = parallel_env("horizontal_cr_v0", render_mode="human")
    env.reset(seed=0)
    assert env.render() is None
    env.step({a: np.zeros(1) for a in env.agents})
    env.close()


def test_missing_pettingzoo_names_the_extra(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "pettingzoo", None)
    with pytest.raises(ImportError, match=re.escape(install_hint("multiagent"))):
        require_pettingzoo()


#: Actions that are not arrays of real numbers: each is refused with a message naming the agent.
NOT_NUMBERS = [
    pytest.param(["0.5", "0.5"], id="numeric-strings"),
    pytest.param("0.5", id="numeric-string"),
    pytest.param(b"1", id="bytes"),
    pytest.param(np.array([0.5 + 1j, 0.0]), id="complex"),
    pytest.param(np.array([0.5 + 1j]), id="complex-one"),
    pytest.param([[0.1, 0.2], [0.3]], id="ragged"),
    pytest.param(10**400, id="huge-int"),
    pytest.param(None, id="none"),
]


@pytest.mark.parametrize("bad", NOT_NUMBERS)
@pytest.mark.parametrize("name", NAMES)
def test_actions_that_are_not_real_numbers_are_refused(name: str, bad: object) -> None:
    env = parallel_env(name)
    env.reset(seed=0)
    agent = env.agents[0]
    with pytest.raises(ValueError, match=rf"^action of {agent} must be an array of real numbers with shape"):
        env.step({agent: bad})


@pytest.mark.parametrize("name", NAMES)
def test_bad_action_shapes_and_values_name_the_agent(name: str) -> None:
    env = parallel_env(name)
    env.reset(seed=0)
    agent = env.agents[0]
    shape = env.action_space(agent).shape
    with pytest.raises(ValueError, match=rf"^action of {agent} has shape \(7,\), expected \({shape[0]},\)$"):
        env.step({agent: np.zeros(7)})
    with pytest.raises(ValueError, match=rf"^action of {agent} contains NaN or infinite values"):
        env.step({agent: np.full(shape, np.nan)})
    with pytest.raises(TypeError, match=r"^actions must be a dict agent -> action, got list"):
        env.step([np.zeros(shape)])
