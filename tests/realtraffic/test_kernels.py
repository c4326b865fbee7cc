"""The recorded flights' interpolation and the great-circle bearing as kernels: equal to their readable numpy forms to the last bit."""

from __future__ import annotations

import numpy as np

from bluesky_gym.tasks.geometry import initial_bearing
from tests.oracle.geometry import initial_bearing as oracle_bearing
from tests.oracle.realtraffic import recorded_at

from .synthetic import traffic_collection


def test_recorded_states_equal_the_numpy_interpolation() -> None:
    """Times before, inside and after each flight's span, on samples and between them, in any shape; tracks across north."""
    flights = traffic_collection(n_flights=12, spacing_s=90.0, seed=4)
    flights.trk[::7] = np.where(flights.trk[::7] > 180.0, 359.5, 0.5)  # segments that cross 360
    rng = np.random.default_rng(1)
    f = rng.integers(0, flights.n_flights, (40, 9))
    t = rng.uniform(flights.t0.min() - 600.0, flights.t_end.max() + 600.0, (40, 9))
    t[::3] = np.round(t[::3], -1)  # on the samples
    t[1::5] = flights.t_end[f[1::5]]  # at the last sample
    for args in ((f, t), (f[0], t[0]), (int(f[0, 0]), float(t[0, 0]))):
        got, want = flights.at(*args), recorded_at(flights, *args)
        assert set(got) == set(want)
        for key in want:
            np.testing.assert_array_equal(got[key], want[key], err_msg=key, strict=True)


def test_initial_bearing_equals_the_numpy_formula() -> None:
    rng = np.random.default_rng(3)
    lat1, lon1 = rng.uniform(-80, 80, (25, 1)), rng.uniform(-180, 180, (25, 1))
    lat2, lon2 = rng.uniform(-80, 80, (1, 6)), rng.uniform(-180, 180, (1, 6))
    for args in ((lat1, lon1, lat2, lon2), (47.0, 8.0, 47.5, 8.4), (lat1[:, 0], lon1[:, 0], 47.0, 8.0), (lat1, lon1, lat1 + 1e-3, lon1)):
        np.testing.assert_array_equal(initial_bearing(*args), oracle_bearing(*args), strict=True)


def test_fewer_slots_than_intruder_rows_leave_the_last_rows_empty() -> None:
    """With ``max_traffic`` below the observed intruders the observation keeps its declared shape, the rows without an aircraft all zeros."""
    import gymnasium as gym

    import bluesky_gym

    bluesky_gym.register_envs()
    env = gym.make_vec("RealTrafficCREnv-v0", num_envs=2, max_traffic=2, min_traffic=1)
    obs, _ = env.reset(seed=0)
    for _ in range(2):
        assert obs["intruders"].shape == (2, *env.single_observation_space["intruders"].shape)
        assert env.single_observation_space.contains({k: v[0] for k, v in obs.items()})
        np.testing.assert_array_equal(obs["intruders"][:, 3:], 0.0)  # 3 slots: at most 2 other aircraft, the ownship's own slot never present
        obs, *_ = env.step(np.zeros(env.action_space.shape))
    env.close()
