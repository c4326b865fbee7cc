"""Contract tests run on every registered environment id."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import bluesky_gym
from bluesky_gym.registration import available_envs

from ..conftest import same_values
from .expected_spaces import ACTION_SHAPE, DTYPE, MAX_EPISODE_STEPS, OBSERVATION, REFERENCE_INFO_KEYS

IDS = available_envs()


def _rollout(env, seed: int, n: int, action_seed: int = 0):
    rng = np.random.default_rng(action_seed)
    obs, info = env.reset(seed=seed)
    out = [(obs, None, None, None, info)]
    for _ in range(n):
        a = rng.uniform(-1, 1, env.action_space.shape)
        obs, r, te, tr, info = env.step(a)
        out.append((obs, r, te, tr, info))
        if te or tr:
            obs, info = env.reset()
            out.append((obs, None, None, None, info))
    return out


def test_all_seven_registered() -> None:
    bluesky_gym.register_envs()
    bluesky_gym.register_envs()  # idempotent
    for env_id in OBSERVATION:
        assert env_id in gym.registry
        # The task owns the time limit: no Gymnasium TimeLimit wrapper, the made env's spec reports the task's limit.
        assert gym.registry[env_id].max_episode_steps is None
        env = gym.make(env_id)
        assert env.spec.max_episode_steps == env.unwrapped.spec.max_episode_steps == MAX_EPISODE_STEPS[env_id]
        assert not any(isinstance(w, gym.wrappers.TimeLimit) for w in _wrappers(env))
        venv = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point")
        assert venv.spec.max_episode_steps == MAX_EPISODE_STEPS[env_id]


def _wrappers(env):
    while isinstance(env, gym.Wrapper):
        yield env
        env = env.env


@pytest.mark.parametrize("env_id", IDS)
def test_check_env(env_id: str) -> None:
    env = gym.make(env_id)
    check_env(env.unwrapped, skip_render_check=True)
    env.close()


@pytest.mark.parametrize("env_id", IDS)
def test_spaces_match_specification(env_id: str) -> None:
    env = gym.make(env_id)
    space = env.observation_space
    assert isinstance(space, gym.spaces.Dict)
    assert set(space.spaces) == set(OBSERVATION[env_id]), "observation keys differ from the specification"
    for key, (shape, low, high) in OBSERVATION[env_id].items():
        box = space[key]
        assert box.shape == shape, key
        assert box.dtype == DTYPE[env_id], key
        assert np.all(box.low == low) and np.all(box.high == high), key
    assert env.action_space.shape == ACTION_SHAPE[env_id]
    assert np.all(env.action_space.low == -1) and np.all(env.action_space.high == 1)
    assert env.action_space.dtype == DTYPE[env_id]
    obs, info = env.reset(seed=3)
    assert REFERENCE_INFO_KEYS[env_id] <= set(info)
    for key, value in obs.items():
        assert value.dtype == DTYPE[env_id] and value.shape == OBSERVATION[env_id][key][0]
    obs, r, te, tr, info = env.step(env.action_space.sample())
    assert type(te) is bool and type(tr) is bool and isinstance(r, float)
    assert REFERENCE_INFO_KEYS[env_id] <= set(info)
    env.close()


@pytest.mark.parametrize("env_id", IDS)
def test_same_seed_same_episode_other_seed_differs(env_id: str) -> None:
    a = _rollout(gym.make(env_id), seed=11, n=40)
    b = _rollout(gym.make(env_id), seed=11, n=40)
    c = _rollout(gym.make(env_id), seed=12, n=40)
    assert len(a) == len(b) and all(same_values(x, y) for x, y in zip(a, b))
    assert not same_values(a[0][0], c[0][0]), "another seed gave the same initial observation"


@pytest.mark.parametrize("env_id", IDS)
def test_vector_episode_equals_single_env(env_id: str) -> None:
    """Episode i of the native batched env equals a single env seeded seed + i, across resets."""
    n, steps, seed = 3, 60, 5
    venv = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point")
    assert venv.metadata["autoreset_mode"] == venv.autoreset_mode == gym.vector.AutoresetMode.SAME_STEP  # attribute as in Gymnasium's
    rng = np.random.default_rng(1)
    actions = rng.uniform(-1, 1, (steps, n, *venv.single_action_space.shape))
    obs, _ = venv.reset(seed=seed)
    vec_obs, vec_rew, vec_done = [obs], [], []
    for t in range(steps):
        obs, r, te, tr, info = venv.step(actions[t])
        vec_rew.append(r)
        vec_done.append(te | tr)
        final = {
            k: np.where(np.reshape(te | tr, (-1,) + (1,) * (v.ndim - 1)), info["final_obs"][k], v) if "final_obs" in info else v
            for k, v in obs.items()
        }
        vec_obs.append(final)
    for i in range(n):
        env = gym.make(env_id)
        o, _ = env.reset(seed=seed + i)
        assert same_values(o, {k: v[i] for k, v in vec_obs[0].items()})
        for t in range(steps):
            o, r, te, tr, _ = env.step(actions[t, i])
            assert r == vec_rew[t][i], f"episode {i} step {t}: reward {r} != {vec_rew[t][i]}"
            assert same_values(o, {k: v[i] for k, v in vec_obs[t + 1].items()}), f"episode {i} step {t}: observation differs"
            assert (te or tr) == vec_done[t][i]
            if te or tr:
                o, _ = env.reset()
    venv.close()


@pytest.mark.parametrize("env_id", IDS)
def test_bad_input_is_rejected_clearly(env_id: str) -> None:
    env = gym.make(env_id).unwrapped
    with pytest.raises(RuntimeError, match="reset"):
        env.step(env.action_space.sample())
    env.reset(seed=0)
    shape = env.action_space.shape
    with pytest.raises(ValueError, match="NaN or infinite"):
        env.step(np.full(shape, np.nan))
    with pytest.raises(ValueError, match="NaN or infinite"):
        env.step(np.full(shape, np.inf))
    with pytest.raises(ValueError, match="shape"):
        env.step(np.zeros((shape[0] + 1,)))
    with pytest.raises(TypeError, match="unknown option"):
        gym.make(env_id, not_an_option=3)
    with pytest.raises(ValueError, match="backend"):
        gym.make(env_id, backend="xplane")
    with pytest.raises(ValueError, match="render_mode"):
        gym.make(env_id, render_mode="ascii")


@pytest.mark.parametrize("env_id", IDS)
def test_out_of_range_actions_are_clipped(env_id: str) -> None:
    a, b = gym.make(env_id).unwrapped, gym.make(env_id).unwrapped
    a.reset(seed=4)
    b.reset(seed=4)
    shape = a.action_space.shape
    ra = a.step(np.full(shape, 7.0))
    rb = b.step(np.full(shape, 1.0))
    assert same_values(ra[0], rb[0]) and ra[1] == rb[1]


@pytest.mark.parametrize("env_id", IDS)
def test_step_after_episode_end_raises(env_id: str) -> None:
    env = gym.make(env_id).unwrapped
    env.reset(seed=0)
    for _ in range(env.task.time_limit):
        _, _, te, tr, info = env.step(env.action_space.sample())
        if te or tr:
            break
    assert te or tr, "episode did not end within max_episode_steps"
    assert any(k.startswith("kpi_") for k in info), "KPIs missing at the end of the episode"
    fuel = float(info["kpi_fuel_kg"])
    assert math.isfinite(fuel) and fuel > 0.0, f"kpi_fuel_kg {fuel!r}"
    with pytest.raises(RuntimeError, match="ended"):
        env.step(env.action_space.sample())


NOT_NUMBERS = [
    pytest.param("0.5", id="numeric-string"),
    pytest.param(b"1", id="bytes"),
    pytest.param(np.array([0.5 + 1j]), id="complex"),
    pytest.param([[0.1, 0.2], [0.3]], id="ragged"),
    pytest.param({"a": 1}, id="dict"),
    pytest.param(10**400, id="huge-int"),
    pytest.param(None, id="none"),
]


@pytest.mark.parametrize("bad", NOT_NUMBERS)
@pytest.mark.parametrize("env_id", IDS)
def test_actions_that_are_not_real_numbers_are_refused_by_the_env(env_id: str, bad: object) -> None:
    env = gym.make(env_id).unwrapped
    env.reset(seed=0)
    with pytest.raises(ValueError, match="real numbers"):
        env.step(bad)


@pytest.mark.parametrize("bad", NOT_NUMBERS)
def test_batched_actions_that_are_not_real_numbers_are_refused(bad: object) -> None:
    venv = gym.make_vec(IDS[0], num_envs=2, vectorization_mode="vector_entry_point")
    venv.reset(seed=0)
    with pytest.raises(ValueError, match="real numbers"):
        venv.step(bad)
    venv.close()


@pytest.mark.parametrize("num_envs", [2.5, "4", True, 0, -1])
def test_make_vec_refuses_a_batch_size_that_is_not_a_positive_integer(num_envs: object) -> None:
    with pytest.raises(ValueError, match="num_envs"):
        gym.make_vec(IDS[0], num_envs=num_envs, vectorization_mode="vector_entry_point")


def test_integer_options_beyond_int64_are_refused() -> None:
    with pytest.raises(ValueError, match="64-bit"):
        gym.make("HorizontalCREnv-v0", dcpa_max=2**63)
    with pytest.raises(ValueError, match="64-bit"):
        gym.make("HorizontalCREnv-v0", max_episode_steps=None, num_intruders=-(2**70))


def test_render_before_reset_is_an_error_not_a_picture_of_nothing() -> None:
    pytest.importorskip("pygame")
    env = gym.make(IDS[0], render_mode="rgb_array").unwrapped
    with pytest.raises(RuntimeError, match="before reset"):
        env.render()
    env.reset(seed=0)
    assert env.render().ndim == 3
    venv = gym.make_vec(IDS[0], num_envs=2, vectorization_mode="vector_entry_point", render_mode="rgb_array")
    with pytest.raises(RuntimeError, match="before reset"):
        venv.render()
    venv.reset(seed=0)
    assert venv.render().ndim == 3


@pytest.mark.parametrize("options", [5, "abc", [("a", 1)], 0.5])
def test_reset_options_that_are_not_a_dict_are_named(options: object) -> None:
    env = gym.make(IDS[0]).unwrapped
    with pytest.raises(ValueError, match=r"^reset options must be a dict or None, got "):
        env.reset(options=options)
    venv = gym.make_vec(IDS[0], num_envs=2, vectorization_mode="vector_entry_point")
    with pytest.raises(ValueError, match=r"^reset options must be a dict or None, got "):
        venv.reset(options=options)


@pytest.mark.parametrize(
    ("seed", "message"),
    [
        (1.5, r"^seed must be None, a non-negative integer or a list of 2 seeds \(integers or None\), got 1\.5$"),
        ("7", r"^seed must be None, a non-negative integer or a list of 2 seeds \(integers or None\), got '7'$"),
        (True, r"^seed must be None, a non-negative integer or a list of 2 seeds"),
        (-1, r"^seed must be None, a non-negative integer or a list of 2 seeds \(integers or None\), got -1$"),
        ([1, 2.5], r"^seed\[1\] must be a non-negative integer or None, got 2\.5$"),
        ([None, -3], r"^seed\[1\] must be a non-negative integer or None, got -3$"),
        ([1, 2, 3], r"^got 3 seeds for 2 environments$"),
    ],
)
def test_batched_reset_seeds_that_are_not_seeds_are_named(seed: object, message: str) -> None:
    venv = gym.make_vec(IDS[0], num_envs=2, vectorization_mode="vector_entry_point")
    with pytest.raises(ValueError, match=message):
        venv.reset(seed=seed)
    obs, _ = venv.reset(seed=np.array([3, 4]))  # an array of integers is a list of seeds
    single = gym.make(IDS[0])
    first, _ = single.reset(seed=4)
    assert all(np.array_equal(obs[k][1], first[k]) for k in first)


def test_a_batch_too_large_for_memory_says_how_much_it_needs() -> None:
    """Far more episodes than any machine holds: a MemoryError that gives the size, not numpy's message about one array."""
    with pytest.raises(MemoryError, match=r"^MergeEnv-v0: num_envs=10000000000000 needs about [0-9.]+ PiB of memory \([0-9.]+ KiB per episode\)"):
        gym.make_vec("MergeEnv-v0", num_envs=10**13, vectorization_mode="vector_entry_point")
