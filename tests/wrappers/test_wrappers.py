from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import bluesky_gym  # noqa: F401
from bluesky_gym.wrappers import (
    MAX_WIND,
    NoisyObservationWrapper,
    VectorNoisyObservationWrapper,
    VectorWindFieldWrapper,
    WindFieldWrapper,
)


def _wind_env(**kw):
    return WindFieldWrapper(gym.make("DescentEnv-v0"), lat=[52.0], lon=[4.0], vnorth=[[-10.0]], veast=[[15.0]], **kw)


def test_uniform_wind_changes_ground_track_and_obs_frame() -> None:
    env = _wind_env(augment_obs=True)
    assert {"wind_u", "wind_v"} <= set(env.observation_space.spaces)
    obs, _ = env.reset(seed=1)
    # Heading 0 (north): along-heading = north component, cross = east component.
    assert obs["wind_u"][0] == pytest.approx(-10.0 / MAX_WIND)
    assert obs["wind_v"][0] == pytest.approx(15.0 / MAX_WIND)
    obs, *_ = env.step(np.zeros(1))
    sim = env.unwrapped.task.sim
    assert sim.windnorth[0, 0] == -10.0 and sim.windeast[0, 0] == 15.0
    # The autopilot holds the track (north): the aircraft crabs left into the wind from the west
    # side and loses the 10 m/s head wind in ground speed.
    assert 340.0 < sim.hdg[0, 0] < 360.0
    assert sim.trk[0, 0] == pytest.approx(0.0, abs=0.1) or sim.trk[0, 0] == pytest.approx(360.0, abs=0.1)
    assert sim.gsnorth[0, 0] < sim.tas[0, 0] - 9.0
    base = gym.make("DescentEnv-v0")
    base.reset(seed=1)
    base.step(np.zeros(1))
    assert base.unwrapped.task.sim.lat[0, 0] > sim.lat[0, 0]


def test_wind_survives_terminal_step_and_resets() -> None:
    env = _wind_env(augment_obs=True)
    env.reset(seed=2)
    done = False
    while not done:
        obs, _, te, tr, _ = env.step(np.array([-1.0]))
        done = te or tr
    assert np.isfinite(obs["wind_u"][0])  # the reference raised IndexError here
    env.reset()
    assert env.unwrapped.task.sim.wind.count[0] == 1  # no accumulation of points over episodes


def test_point_field_interpolates_between_points() -> None:
    env = WindFieldWrapper(gym.make("DescentEnv-v0"), lat=[51.0, 53.0], lon=[4.0, 4.0], vnorth=[0.0, 0.0], veast=[0.0, 20.0], augment_obs=True)
    obs, _ = env.reset(seed=0)
    # At 52N, equidistant from both points: the mean of their east components.
    assert obs["wind_v"][0] * MAX_WIND == pytest.approx(10.0, rel=1e-9)


def test_wind_rejects_bad_definitions() -> None:
    with pytest.raises(ValueError, match="same"):
        WindFieldWrapper(gym.make("DescentEnv-v0"), lat=[52.0, 53.0], lon=[4.0], vnorth=[1.0], veast=[1.0])
    with pytest.raises(ValueError, match="altitude"):
        WindFieldWrapper(gym.make("DescentEnv-v0"), lat=[52.0], lon=[4.0], vnorth=[1.0], veast=[1.0], alt=[1000.0])
    with pytest.raises(ValueError, match="finite"):
        WindFieldWrapper(gym.make("DescentEnv-v0"), lat=[52.0], lon=[4.0], vnorth=[np.nan], veast=[1.0])


def test_vector_wind_matches_single() -> None:
    venv = VectorWindFieldWrapper(
        gym.make_vec("DescentEnv-v0", num_envs=2, vectorization_mode="vector_entry_point"),
        lat=[52.0],
        lon=[4.0],
        vnorth=[-10.0],
        veast=[15.0],
        augment_obs=True,
    )
    single = _wind_env(augment_obs=True)
    obs_v, _ = venv.reset(seed=5)
    obs_s, _ = single.reset(seed=6)
    rng = np.random.default_rng(0)
    for _ in range(60):
        a = rng.uniform(-1, 1, (2, 1))
        obs_v, r_v, te, tr, info = venv.step(a)
        obs_s, r_s, te_s, tr_s, _ = single.step(a[1])
        assert r_v[1] == r_s
        if te_s or tr_s:
            for k in obs_s:
                np.testing.assert_array_equal(info["final_obs"][k][1], obs_s[k])
            obs_s, _ = single.reset()
        for k in obs_s:
            np.testing.assert_array_equal(obs_v[k][1], obs_s[k])


def test_noise_is_seeded_and_leaves_scenarios_alone() -> None:
    a = NoisyObservationWrapper(gym.make("DescentEnv-v0"), noise_level=0.1)
    b = NoisyObservationWrapper(gym.make("DescentEnv-v0"), noise_level=0.1)
    clean = gym.make("DescentEnv-v0")
    oa, _ = a.reset(seed=3)
    ob, _ = b.reset(seed=3)
    oc, _ = clean.reset(seed=3)
    for k in oa:
        np.testing.assert_array_equal(oa[k], ob[k])
        assert not np.array_equal(oa[k], oc[k])
        assert abs(oa[k][0] - oc[k][0]) < 1.0
    np.testing.assert_array_equal(a.unwrapped.task.target_alt, clean.unwrapped.task.target_alt)
    noise = np.array([oa[k][0] - oc[k][0] for k in oa])
    for _ in range(100):
        o1, _, te, tr, _ = a.step(np.zeros(1))
        o2, *_ = clean.step(np.zeros(1))
        noise = np.append(noise, [o1[k][0] - o2[k][0] for k in o1])
        if te or tr:
            o1, _ = a.reset()
            o2, _ = clean.reset()
    assert 0.07 < noise.std() < 0.13
    with pytest.raises(ValueError, match="noise_level"):
        NoisyObservationWrapper(gym.make("DescentEnv-v0"), noise_level=-1)


def test_vector_noise_perturbs_final_obs_too() -> None:
    venv = VectorNoisyObservationWrapper(gym.make_vec("DescentEnv-v0", num_envs=3, vectorization_mode="vector_entry_point"), noise_level=0.05)
    obs, _ = venv.reset(seed=0)
    clean = gym.make_vec("DescentEnv-v0", num_envs=3, vectorization_mode="vector_entry_point")
    obs_c, _ = clean.reset(seed=0)
    assert not np.array_equal(obs["altitude"], obs_c["altitude"])
    np.testing.assert_allclose(obs["altitude"], obs_c["altitude"], atol=0.5)
