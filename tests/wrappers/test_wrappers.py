from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import bluesky_gym  # noqa: F401
from bluesky_gym.core.wind import Wind
from bluesky_gym.wrappers import (
    MAX_WIND,
    NoisyObservationWrapper,
    VectorNoisyObservationWrapper,
)

#: The uniform wind of these tests: 10 m/s to the south, 15 m/s to the east.
WIND = {"lat": [52.0], "lon": [4.0], "vnorth": [[-10.0]], "veast": [[15.0]]}


def _wind_env(observe: bool = False) -> gym.Env:
    return gym.make("DescentEnv-v0", wind=Wind(**WIND, observe=observe))


def _wind_venv(env_id: str = "DescentEnv-v0", num_envs: int = 2, observe: bool = True) -> gym.vector.VectorEnv:
    return gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point", wind=Wind(**WIND, observe=observe))


def test_uniform_wind_changes_ground_track_and_obs_frame() -> None:
    env = _wind_env(observe=True)
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
    env = _wind_env(observe=True)
    env.reset(seed=2)
    done = False
    while not done:
        obs, _, te, tr, _ = env.step(np.array([-1.0]))
        done = te or tr
    assert np.isfinite(obs["wind_u"][0])  # the reference raised IndexError here
    env.reset()
    assert env.unwrapped.task.sim.wind.count[0] == 1  # no accumulation of points over episodes


def test_point_field_interpolates_between_points() -> None:
    env = gym.make("DescentEnv-v0", wind={"lat": [51.0, 53.0], "lon": [4.0, 4.0], "vnorth": [0.0, 0.0], "veast": [0.0, 20.0], "observe": True})
    obs, _ = env.reset(seed=0)
    # At 52N, equidistant from both points: the mean of their east components.
    assert obs["wind_v"][0] * MAX_WIND == pytest.approx(10.0, rel=1e-9)


def test_wind_rejects_bad_definitions() -> None:
    with pytest.raises(ValueError, match="same"):
        gym.make("DescentEnv-v0", wind={"lat": [52.0, 53.0], "lon": [4.0], "vnorth": [1.0], "veast": [1.0]})
    with pytest.raises(ValueError, match="altitude"):
        gym.make("DescentEnv-v0", wind={"lat": [52.0], "lon": [4.0], "vnorth": [1.0], "veast": [1.0], "alt": [1000.0]})
    with pytest.raises(ValueError, match="finite"):
        gym.make("DescentEnv-v0", wind={"lat": [52.0], "lon": [4.0], "vnorth": [np.nan], "veast": [1.0]})
    with pytest.raises(ValueError, match=r"unknown field\(s\) \['speed'\]"):
        gym.make("DescentEnv-v0", wind={"lat": [52.0], "lon": [4.0], "vnorth": [1.0], "veast": [1.0], "speed": 3})
    with pytest.raises(ValueError, match="observe must be True or False"):
        Wind(**WIND, observe="yes")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="^wind must be a Wind"):
        gym.make("DescentEnv-v0", wind=15.0)
    with pytest.raises(ValueError, match="^DescentEnv-v1: wind must be a Wind"):
        gym.make("DescentEnv-v1", wind=15.0)


def test_vector_wind_matches_single() -> None:
    venv = _wind_venv()
    single = _wind_env(observe=True)
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


def _count_physics_calls(monkeypatch, sim) -> dict[str, list[int]]:
    calls: dict[str, list[int]] = {"run": [], "step": []}
    run, step = sim.run, sim.step

    def counted_run(n_steps, *args, **kwargs):
        calls["run"].append(n_steps)
        return run(n_steps, *args, **kwargs)

    def counted_step():
        calls["step"].append(1)
        step()

    monkeypatch.setattr(sim, "run", counted_run)
    monkeypatch.setattr(sim, "step", counted_step)
    return calls


@pytest.mark.parametrize("vector", [False, True])
def test_wind_keeps_the_one_call_fast_path(monkeypatch, vector: bool) -> None:
    if vector:
        env = _wind_venv(num_envs=3)
        action = np.zeros((3, 1))
    else:
        env = _wind_env(observe=True)
        action = np.zeros(1)
    task = env.unwrapped.task
    calls = _count_physics_calls(monkeypatch, task.sim)
    env.reset(seed=0)
    for _ in range(40):  # through the end of the first episodes
        _, _, te, tr, _ = env.step(action)
        if not vector and (te or tr):
            env.reset()
    assert calls["run"] == [task.action_frequency] * 40
    assert calls["step"] == []


def test_wind_is_part_of_the_task_observation() -> None:
    env = _wind_env(observe=True)
    task = env.unwrapped.task
    assert not hasattr(task, "reset_hooks") and not hasattr(task, "substep_hooks")
    assert list(task.observation_spec)[-2:] == ["wind_u", "wind_v"]
    assert {"wind_u", "wind_v"} <= set(env.unwrapped.observation_space.spaces)
    obs, _ = env.reset(seed=1)
    assert obs in env.unwrapped.observation_space
    np.testing.assert_array_equal(task.observation()["wind_u"], obs["wind_u"][None])
    with pytest.raises(ValueError, match="only once"):
        task.add_wind(Wind(**WIND, observe=True))


def test_vector_wind_final_obs_is_the_ended_state() -> None:
    venv = _wind_venv()
    venv.reset(seed=0)
    while True:
        obs, _, te, tr, info = venv.step(np.full((2, 1), -1.0))
        if (te | tr).any():
            break
    ended = np.flatnonzero(te | tr)
    # The final observation is taken before the reset: a crashed aircraft's frame, and the new episode's own wind entries.
    for k in ("wind_u", "wind_v"):
        assert np.isfinite(info["final_obs"][k][ended]).all()
    assert np.all(info["final_obs"]["altitude"][ended] != obs["altitude"][ended])


def test_wind_terms_with_a_task_of_its_own_sub_step_loop() -> None:
    venv = _wind_venv("StaticObstacleEnv-v0", num_envs=4)
    venv.reset(seed=0)
    ended = False
    for _ in range(100):
        obs, _, te, tr, info = venv.step(np.zeros((4, 2)))
        assert obs in venv.observation_space
        if (te | tr).any():
            ended = True
            assert {"wind_u", "wind_v"} <= set(info["final_obs"])
    assert ended


def test_task_effects_and_observation_terms() -> None:
    from bluesky_gym.tasks.base import BoxSpec, ObservationTerms

    venv = gym.make_vec("DescentEnv-v0", num_envs=3, vectorization_mode="vector_entry_point")
    task = venv.unwrapped.task
    started: list[list[int]] = []

    class Count:
        def on_reset(self, t, envs) -> None:
            assert t is task
            started.append(sorted(int(e) for e in envs))

    task.add_effect(Count())
    task.add_observation_terms(ObservationTerms({"env_index": BoxSpec((1,))}, lambda t, envs: {"env_index": envs[:, None].astype(np.float64)}))
    assert venv.single_observation_space["env_index"].shape == (1,)
    obs, _ = venv.reset(seed=0)
    assert started == [[0, 1, 2]]
    np.testing.assert_array_equal(obs["env_index"][:, 0], [0, 1, 2])
    while True:
        obs, _, te, tr, info = venv.step(np.full((3, 1), -1.0))
        np.testing.assert_array_equal(obs["env_index"][:, 0], [0, 1, 2])
        if (te | tr).any():
            break
    ended = np.flatnonzero(te | tr)
    assert started[-1] == ended.tolist()
    np.testing.assert_array_equal(info["final_obs"]["env_index"][ended, 0], ended)
    with pytest.raises(ValueError, match="already has"):
        task.add_observation_terms(ObservationTerms({"altitude": BoxSpec((1,))}, lambda t, envs: {"altitude": envs[:, None]}))
    with pytest.raises(TypeError, match="on_reset"):
        task.add_effect(lambda t, envs: None)
