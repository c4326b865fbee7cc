"""The aircraft-type mix options of HorizontalCR, VerticalCR, SectorCR and Merge."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import bluesky_gym  # noqa: F401  (registers the environments)

ENVS = ["HorizontalCREnv-v0", "VerticalCREnv-v0", "SectorCREnv-v0", "MergeEnv-v0"]
MIX = {"intruder_types": {"A320": 0.4, "B744": 0.3, "E190": 0.3}, "ownship_types": ("C550", "GLF6")}


def _fleet(env: gym.Env, e: int = 0) -> list[str]:
    sim = env.unwrapped.task.sim
    return sim.aircraft_type(e, np.flatnonzero(sim.active[e]))


def _positions(env: gym.Env) -> np.ndarray:
    sim = env.unwrapped.task.sim
    act = sim.active[0]
    return np.stack([sim.lat[0, act], sim.lon[0, act], sim.hdg[0, act], sim.alt[0, act]])


@pytest.mark.parametrize("env_id", ENVS)
def test_type_mix_changes_the_fleet_reproducibly(env_id: str) -> None:
    default = gym.make(env_id)
    default.reset(seed=5)
    assert set(_fleet(default)) == {"A320"}
    one_type = gym.make(env_id, intruder_types=("a320",), ownship_types="A320")
    obs_one, _ = one_type.reset(seed=5)
    obs_default, _ = gym.make(env_id).reset(seed=5)
    for k in obs_default:  # a one-type mix draws nothing: the paper's episode
        np.testing.assert_array_equal(obs_one[k], obs_default[k])
    mixed = gym.make(env_id, **MIX)
    fleets = []
    for seed in (5, 6, 5):
        mixed.reset(seed=seed)
        fleets.append(_fleet(mixed))
        assert fleets[-1][0] in ("C550", "GLF6")
        assert set(fleets[-1][1:]) <= {"A320", "B744", "E190"}
    assert fleets[0] == fleets[2]  # same seed, same fleet
    assert len(set(fleets[0][1:])) > 1 or len(set(fleets[1][1:])) > 1
    again = gym.make(env_id, **MIX)
    again.reset(seed=5)
    assert _fleet(again) == fleets[0]
    for _ in range(3):
        mixed.step(mixed.action_space.sample())


@pytest.mark.parametrize("env_id", ["HorizontalCREnv-v0", "SectorCREnv-v0", "MergeEnv-v0"])
def test_types_are_drawn_after_the_scenario(env_id: str) -> None:
    """The positions, headings and altitudes of a seed do not depend on the type mix."""
    a, b = gym.make(env_id), gym.make(env_id, **MIX)
    a.reset(seed=11)
    b.reset(seed=11)
    np.testing.assert_array_equal(_positions(a), _positions(b))


def test_batched_episode_has_the_single_episode_fleet() -> None:
    venv = gym.make_vec("MergeEnv-v0", num_envs=3, vectorization_mode="vector_entry_point", **MIX)
    venv.reset(seed=20)
    for i in range(3):
        single = gym.make("MergeEnv-v0", **MIX)
        single.reset(seed=20 + i)
        sim = venv.unwrapped.task.sim
        assert sim.aircraft_type(i, np.flatnonzero(sim.active[i])) == _fleet(single)


@pytest.mark.parametrize(
    ("value", "message"),
    [
        (("A320", "XX99"), r"intruder_types: aircraft type 'XX99' is not supported; supported types: A124, .*B744"),
        ("XX35", "'XX35' is not supported; supported types: .*; rotorcraft: EC35, M600"),
        ((), "at least one aircraft type"),
        ({"A320": -1.0}, "intruder_types weight must be >= 0.0"),
        ({"A320": 0.0}, "positive sum"),
        (("A320", "a320"), "names a type twice"),
        (320, "must be a type name"),
    ],
)
def test_bad_type_mix_is_refused(value: object, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        gym.make("HorizontalCREnv-v0", intruder_types=value)


def test_horizontal_cr_flies_rotorcraft() -> None:
    """HorizontalCREnv takes rotorcraft ownships and intruders; they fly BlueSky's rotor model and burn no fuel."""
    env = gym.make("HorizontalCREnv-v0", intruder_types={"A320": 0.5, "EC35": 0.25, "M600": 0.25}, ownship_types="EC35")
    env.reset(seed=3)
    fleet = _fleet(env)
    assert fleet[0] == "EC35" and {"EC35", "M600"} & set(fleet[1:]) and "A320" in fleet[1:]
    sim = env.unwrapped.task.sim
    for _ in range(5):
        obs, _, terminated, truncated, info = env.step(env.action_space.sample())
        assert all(np.isfinite(v).all() for v in obs.values())
    act = np.flatnonzero(sim.active[0])
    rotor = np.array([sim.aircraft_performance(0, int(s)).rotor for s in act])
    assert np.all(sim.axmax[0, act][rotor] == 3.5) and np.all(sim.fuelflow[0, act][rotor] == 0.0)
    assert sim.tas[0, 0] < 150.0  # the EC35 slows from the scenario's 150 m/s towards its 71.95 m/s bound
    while not (terminated or truncated):
        _, _, terminated, truncated, info = env.step(env.action_space.sample())
    assert info["kpi_fuel_kg"] == 0.0  # BlueSky's rotor model has no fuel flow


@pytest.mark.parametrize("env_id", ["VerticalCREnv-v0", "SectorCREnv-v0", "MergeEnv-v0"])
@pytest.mark.parametrize("option", ["intruder_types", "ownship_types"])
def test_rotorcraft_are_refused_where_the_task_does_not_suit_them(env_id: str, option: str) -> None:
    with pytest.raises(
        ValueError, match=f"{option}: aircraft type 'EC35' is a rotorcraft, which this option does not accept; fixed-wing types: A124"
    ):
        gym.make(env_id, **{option: ("A320", "EC35")})


def test_airborne_start_needs_a_rotorcraft_ceiling_above_fl100() -> None:
    gym.make("HorizontalCREnv-v1", ownship_types="EC35", intruder_types="MAVIC")
    with pytest.raises(ValueError, match="intruder_types: rotorcraft M600 cannot fly the airborne start at FL100 .*its ceiling is 2500 m"):
        gym.make("HorizontalCREnv-v1", intruder_types=("A320", "M600"))
