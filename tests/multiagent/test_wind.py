"""The wind option in the multi-agent environments: flown in every episode, not in the per-agent observations."""

from __future__ import annotations

import pytest

pytest.importorskip("pettingzoo")

from bluesky_gym.multiagent import names, parallel_env

WIND = {"lat": 52.0, "lon": 4.0, "vnorth": 5.0, "veast": 3.0, "observe": True}


@pytest.mark.parametrize("name", names())
def test_observed_wind_is_flown_and_left_out_of_the_agents_observations(name: str) -> None:
    env = parallel_env(name, wind=WIND)
    obs, _ = env.reset(seed=0)
    assert env.task.sim.wind.any
    for agent, o in obs.items():
        assert "wind_u" not in o and env.observation_space(agent).contains(o)
    obs = env.step({})[0]
    assert all(env.observation_space(a).contains(o) for a, o in obs.items())
