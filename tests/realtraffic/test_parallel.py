"""The real-traffic PettingZoo environment: agents that appear and leave mid-episode, the API and seed tests, bad actions."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

pytest.importorskip("pettingzoo")

from pettingzoo.test import parallel_api_test, parallel_seed_test

from bluesky_gym.environments.real_traffic.multiagent import RealTrafficParallelEnv

from .synthetic import joining_collection, save


@pytest.fixture(scope="module")
def options(tmp_path_factory) -> dict:
    """Every window of this collection has aircraft appearing and leaving while it plays."""
    path = save(joining_collection(), tmp_path_factory.mktemp("rt-joining"))
    return {"collections": (path,), "min_traffic": 1, "max_traffic": 8}


@pytest.mark.parametrize("name", ["real_traffic_cr_v0", "real_traffic_cr_v1"])
def test_parallel_api(options, name: str) -> None:
    with warnings.catch_warnings():
        # A window has only some of the collection's flights: the episode ends with possible agents that never played.
        warnings.filterwarnings("ignore", message="No agents present but not all possible_agents")
        # The other findings of the API test are warnings too: here they are failures.
        warnings.filterwarnings("error", message="Live agent was not given")
        warnings.filterwarnings("error", message="Agent was given")
        parallel_api_test(RealTrafficParallelEnv(name=name, **options), num_cycles=1000)


@pytest.mark.parametrize("name", ["real_traffic_cr_v0", "real_traffic_cr_v1"])
def test_parallel_seed(options, name: str) -> None:
    parallel_seed_test(lambda: RealTrafficParallelEnv(name=name, **options), num_cycles=50)


def test_v1_spaces_are_float32_with_bounds_that_hold(options) -> None:
    env = RealTrafficParallelEnv(name="real_traffic_cr_v1", **options)
    assert env.metadata["name"] == "real_traffic_cr_v1"
    for seed in (0, 1):
        obs, _ = env.reset(seed=seed)
        while True:
            for agent, o in obs.items():
                space = env.observation_space(agent)
                assert all(b.dtype == np.float32 and np.isfinite(b.low).all() and np.isfinite(b.high).all() for b in space.spaces.values())
                assert space.contains(o), agent
            if not env.agents:
                break
            obs = env.step({a: env.action_space(a).sample() for a in env.agents})[0]
    with pytest.raises(ValueError, match="name must be one of"):
        RealTrafficParallelEnv(name="real_traffic_cr_v2", **options)


def test_an_agent_that_appears_gets_its_first_observation(options) -> None:
    env = RealTrafficParallelEnv(**options)
    joined = 0
    for seed in range(4):
        obs, infos = env.reset(seed=seed)
        assert set(obs) == set(infos) == set(env.agents)
        while env.agents:
            before = list(env.agents)
            obs, rew, term, trunc, infos = env.step({a: np.zeros(2) for a in env.agents})
            new = [a for a in env.agents if a not in before]
            joined += len(new)
            # every dict holds the agents that acted and those that joined, nothing else
            for d in (obs, rew, term, trunc, infos):
                assert set(d) == set(before) | set(new)
            for a in new:
                assert env.observation_space(a).contains(obs[a])
                assert obs[a]["ownship"][1] != 0.0  # cos of the drift: a measured observation, not a blank
                assert rew[a] == 0.0 and not term[a] and not trunc[a]
            # those that left are truncated and not in agents any more
            assert all(trunc[a] for a in before if a not in env.agents)
    assert joined >= 4


def test_a_joined_agent_observes_its_aircraft_as_it_appeared(options) -> None:
    """The first observation of an appearing agent is the single-agent observation of its own slot after that step."""
    from bluesky_gym.environments.real_traffic import task as rt

    env = RealTrafficParallelEnv(**options)
    env.reset(seed=1)
    new: list[str] = []
    while env.agents and not new:
        before = set(env.agents)
        obs, *_ = env.step({a: np.zeros(2) for a in env.agents})
        new = [a for a in env.agents if a not in before]
    assert new, "no aircraft appeared in the episode"
    task = env.task.scenario  # the real-traffic task the multi-agent layout steps
    slot_of = {str(task.flights.flight_id[task.player.flight[0, s]]): s for s in np.flatnonzero(task.sim.active[0])}
    slots = np.array([slot_of[a] for a in new])
    expected = rt.observation(task, rt.measure(task, np.zeros(len(slots), np.int64), slots))
    for i, a in enumerate(new):
        assert all(np.array_equal(obs[a][k], expected[k][i]) for k in expected)


def test_possible_agents_and_state_space(options) -> None:
    env = RealTrafficParallelEnv(**options)
    possible = list(env.possible_agents)
    assert possible, "possible_agents is known before reset()"
    assert len(set(possible)) == len(possible)
    seen: set[str] = set()
    for seed in (0, 1, 2):
        env.reset(seed=seed)
        assert env.possible_agents == possible  # reset does not change it
        assert env.state_space.contains(env.state())
        seen |= set(env.agents)
        while env.agents:
            env.step({})
            seen |= set(env.agents)
            assert env.state_space.contains(env.state())
    assert seen <= set(possible)


@pytest.mark.parametrize(
    ("actions", "message"),
    [
        ([np.zeros(2)], r"actions must be a dict agent -> action, got list"),
        (np.zeros((3, 2)), r"actions must be a dict agent -> action, got ndarray"),
        ("AGENT", r"actions must be a dict agent -> action, got str"),
    ],
)
def test_actions_not_a_dict(options, actions, message) -> None:
    env = RealTrafficParallelEnv(**options)
    env.reset(seed=0)
    with pytest.raises(TypeError, match=message):
        env.step(actions)


@pytest.mark.parametrize(
    ("action", "message"),
    [
        (np.zeros(3), r"action of \S+ has shape \(3,\), expected \(2,\)"),
        (np.zeros((2, 2)), r"action of \S+ has shape \(2, 2\), expected \(2,\)"),
        (["0.5", "0.5"], r"action of \S+ must be an array of real numbers with shape \(2,\)"),
        (np.array([0.5 + 1j, 0.0]), r"action of \S+ must be an array of real numbers"),
        (None, r"action of \S+ must be an array of real numbers"),
        ([0.1, [0.2, 0.3]], r"action of \S+ must be an array of real numbers"),
        (np.array([np.nan, 0.0]), r"action of \S+ contains NaN or infinite values"),
    ],
)
def test_bad_action_of_an_agent(options, action, message) -> None:
    env = RealTrafficParallelEnv(**options)
    env.reset(seed=0)
    with pytest.raises(ValueError, match=message):
        env.step({env.agents[0]: action})


@pytest.mark.parametrize("observe", [False, True])
def test_wind_is_flown_and_not_observed_per_agent(options, observe) -> None:
    """The wind option blows in every episode; its observed entries (the single-agent ownship's) are not in the per-agent observations."""
    env = RealTrafficParallelEnv(wind={"lat": 52.0, "lon": 4.0, "vnorth": 5.0, "veast": 3.0, "observe": observe}, **options)
    obs, _ = env.reset(seed=0)
    assert env.task.sim.wind.any
    assert all(set(o) == {"ownship", "intruders"} for o in obs.values())
    obs = env.step({})[0]
    assert all(env.observation_space(a).contains(o) for a, o in obs.items())


def test_the_shared_policy_adapter_trains_on_real_traffic(options) -> None:
    """The one SB3 adapter takes the real-traffic layout: rows are aircraft slots, appearing aircraft become live, windows restart."""
    pytest.importorskip("stable_baselines3")
    from bluesky_gym.environments.real_traffic.multiagent import RealTrafficMultiAgentTask
    from bluesky_gym.multiagent.sb3 import SharedPolicyVecEnv

    task = RealTrafficMultiAgentTask(2, RealTrafficMultiAgentTask.make_config(options), max_episode_steps=12)
    venv = SharedPolicyVecEnv(task)
    venv.seed(0)
    obs = venv.reset()
    assert venv.num_envs == 2 * task.n_agents and obs["ownship"].shape == (venv.num_envs, 6)
    live_counts = []
    for _ in range(30):
        venv.step_async(np.zeros((venv.num_envs, 2)))
        obs, reward, dones, infos = venv.step_wait()
        live_counts.append(int(venv.live_rows.sum()))
        assert np.all(reward[~venv.live_rows] == 0.0) and np.all(dones[~venv.live_rows])
        for i in np.flatnonzero(dones & venv.live_rows):
            assert "terminal_observation" in infos[i] and infos[i]["TimeLimit.truncated"]  # no agent terminates
    assert venv.episodes_done >= 4  # windows of 12 steps restart inside the step
    assert len(set(live_counts)) > 1  # aircraft appear and leave
