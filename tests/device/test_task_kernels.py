"""The tasks' observation and statistics kernels launched on the device, against their CPU calls."""

from __future__ import annotations

import numpy as np

from bluesky_gym.core import cuda_target
from bluesky_gym.tasks import compiled

from .conftest import assert_agree, needs_device

pytestmark = needs_device

N, M, K = 5, 6, 3  # episodes, aircraft slots, intruders observed


def _airspaces(seed: int = 11) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    active = rng.uniform(size=(N, M)) < 0.8
    active[:, 0] = True
    return {
        "lat": 52 + rng.uniform(-0.5, 0.5, (N, M)),
        "lon": 4 + rng.uniform(-0.5, 0.5, (N, M)),
        "alt": rng.uniform(2000, 4000, (N, M)),
        "hdg": rng.uniform(0, 360, (N, M)),
        "tas": rng.uniform(100, 200, (N, M)),
        "active": active,
    }


def _launch(kernel, rows: int, args: list, outputs: tuple[int, ...]) -> list[np.ndarray]:  # type: ignore[no-untyped-def]
    """Launch the CUDA form of ``kernel`` with device copies of every array argument; return the outputs' host copies."""
    dev = [cuda_target.to_device(a) if isinstance(a, np.ndarray) else a for a in args]
    cuda_target.launch(kernel, rows, *dev)
    return [dev[i].copy_to_host() for i in outputs]


def _fresh(args: list) -> list:  # type: ignore[type-arg]
    return [a.copy() if isinstance(a, np.ndarray) else a for a in args]


def test_sector_and_merge_observations() -> None:
    s = _airspaces()
    envs, own = np.arange(N), np.zeros(N, dtype=np.int64)
    wpt_lat, wpt_lon = s["lat"][:, 0] + 0.2, s["lon"][:, 0] - 0.1
    center = (52.0, 4.0, float(np.cos(np.radians(52.0))))
    scales = (150.0, 20.0, 5000.0, 50.0, 50.0, 10000.0, 5000.0)
    outs = [np.empty(N), np.empty((N, 3)), np.empty((N, 7, K)), np.empty(N, dtype=np.int64)]
    args = [envs, own, s["lat"], s["lon"], s["hdg"], s["tas"], s["active"], wpt_lat, wpt_lon, center, scales, *outs]
    cpu = _fresh(args)
    compiled.sector_observe(*cpu)
    outputs = (11, 12, 13, 14)
    for i, got in zip(outputs, _launch(compiled.sector_observe, N, _fresh(args), outputs)):
        assert_agree(got, cpu[i], 1e-9)
    args = [envs, own, s["lat"], s["lon"], s["hdg"], s["tas"], s["active"], wpt_lat, wpt_lon, (5000.0, 50.0, 10.0),
            np.empty((N, 4)), np.empty((N, 7, K)), np.empty(N, dtype=np.int64)]  # fmt: skip
    cpu = _fresh(args)
    compiled.merge_observe(*cpu)
    outputs = (10, 11, 12)
    for i, got in zip(outputs, _launch(compiled.merge_observe, N, _fresh(args), outputs)):
        assert_agree(got, cpu[i], 1e-9)


def test_intruders_separation_and_goal_for_every_ownship_row() -> None:
    s = _airspaces(12)
    env, own = np.nonzero(s["active"])  # the multi-agent rows: every active slot is an ownship
    rows = env.size
    for nearest in (False, True):
        args = [env, own, s["lat"], s["lon"], s["hdg"], s["tas"], s["active"], nearest, np.empty((5, rows, K)), np.empty(rows, dtype=np.int64)]
        cpu = _fresh(args)
        compiled.intruder_relative_state(*cpu)
        for i, got in zip((8, 9), _launch(compiled.intruder_relative_state, rows, _fresh(args), (8, 9))):
            assert_agree(got, cpu[i], 1e-9)
    args = [env, own, s["lat"], s["lon"], s["alt"], s["active"], 5.0, 300.0, np.empty((rows, M)), np.empty((rows, M), dtype=np.bool_)]
    cpu = _fresh(args)
    compiled.kwik_separation(*cpu)
    for i, got in zip((8, 9), _launch(compiled.kwik_separation, rows, _fresh(args), (8, 9))):
        assert_agree(got, cpu[i], 1e-9)
    args = [env, own, s["lat"], s["lon"], s["hdg"], s["lat"][env, own] + 0.1, s["lon"][env, own], np.empty(rows), np.empty(rows)]
    cpu = _fresh(args)
    compiled.goal_geometry(*cpu)
    for i, got in zip((7, 8), _launch(compiled.goal_geometry, rows, _fresh(args), (7, 8))):
        assert_agree(got, cpu[i], 1e-9)


def test_episode_statistics() -> None:
    rng = np.random.default_rng(13)
    envs = np.arange(N)
    sep = rng.uniform(0, 10, (N, M))
    los = sep < 3.0
    stats = [np.zeros((N, M), dtype=np.bool_), np.full(N, np.inf), np.zeros(N, dtype=np.int64), np.zeros(N, dtype=np.int64),
             np.zeros(N, dtype=np.int64), np.zeros(N), np.zeros(N), np.zeros(N, dtype=np.int64), np.full(N, np.nan)]  # fmt: skip
    args = [envs, sep, los, True, rng.uniform(-1, 0, N), rng.uniform(-30, 30, N), rng.uniform(size=N) < 0.5, 5.0, 12, *stats]
    cpu = _fresh(args)
    compiled.record_step(*cpu)
    outputs = tuple(range(9, 18))
    for i, got in zip(outputs, _launch(compiled.record_step, N, _fresh(args), outputs)):
        assert_agree(got, cpu[i], 1e-12)


def test_task_kernels_on_the_device_state_of_seeded_steps_with_conflict_resolution() -> None:
    """A task's step on the device: physics with CD&R, then measure, observe and record kernels on the device's own state arrays.

    Nothing comes back to the host between steps (the statistics accumulate on the device); after
    each step the outputs are compared with the CPU kernels run on the CPU core's state.
    """
    from bluesky_gym.core import DeviceSimulator, Simulator

    from .test_device_simulator import _conflicting

    launched = {}
    for n in (2, 8):
        cpu, dev = _conflicting(Simulator, n_envs=n), _conflicting(DeviceSimulator, n_envs=n)
        assert isinstance(dev, DeviceSimulator)
        m = cpu.max_aircraft
        envs, own = np.arange(n), np.zeros(n, dtype=np.int64)
        stats = [np.zeros((n, m), dtype=np.bool_), np.full(n, np.inf), np.zeros(n, dtype=np.int64), np.zeros(n, dtype=np.int64),
                 np.zeros(n, dtype=np.int64), np.zeros(n), np.zeros(n), np.zeros(n, dtype=np.int64), np.full(n, np.nan)]  # fmt: skip
        stats_dev = [cuda_target.to_device(a) for a in stats]
        reward, drift, goal = np.linspace(-1.0, 0.0, n), np.linspace(-20.0, 20.0, n), np.arange(n) % 2 == 0
        center, scales = (52.0, 4.0, float(np.cos(np.radians(52.0)))), (150.0, 20.0, 5000.0, 50.0, 50.0, 10000.0, 5000.0)
        wpt_lat, wpt_lon = np.full(n, 52.2), np.full(n, 4.1)
        up = cuda_target.to_device
        for step in range(3):
            cpu.step()
            dev.step()
            before = cuda_target.launches()
            lat, lon, alt, hdg, tas, gs, active = dev.device_arrays("lat", "lon", "alt", "hdg", "tas", "gs", "active")
            sep_d, los_d = up(np.empty((n, m))), up(np.empty((n, m), dtype=np.bool_))
            cuda_target.launch(compiled.kwik_separation, n, up(envs), up(own), lat, lon, alt, active, 15.0, 1000.0 * 0.3048, sep_d, los_d)
            cuda_target.launch(compiled.record_step, n, up(envs), sep_d, los_d, step > 0, up(reward), up(drift), up(goal), 5.0, 12, *stats_dev)
            obs_d = [up(np.empty(n)), up(np.empty((n, 3))), up(np.empty((n, 7, K))), up(np.empty(n, dtype=np.int64))]
            cuda_target.launch(
                compiled.sector_observe, n, up(envs), up(own), lat, lon, hdg, tas, active, up(wpt_lat), up(wpt_lon), center, scales, *obs_d
            )
            rel_d = [up(np.empty((5, n, K))), up(np.empty(n, dtype=np.int64))]
            cuda_target.launch(compiled.intruder_relative_state, n, up(envs), up(own), lat, lon, hdg, gs, active, True, *rel_d)
            launched[n, step] = cuda_target.launches() - before
            assert dev.on_device  # the kernels read the device state in place

            sep, los = np.empty((n, m)), np.empty((n, m), dtype=np.bool_)
            compiled.kwik_separation(envs, own, cpu.lat, cpu.lon, cpu.alt, cpu.active, 15.0, 1000.0 * 0.3048, sep, los)
            compiled.record_step(envs, sep, los, step > 0, reward, drift, goal, 5.0, 12, *stats)
            obs = [np.empty(n), np.empty((n, 3)), np.empty((n, 7, K)), np.empty(n, dtype=np.int64)]
            compiled.sector_observe(envs, own, cpu.lat, cpu.lon, cpu.hdg, cpu.tas, cpu.active, wpt_lat, wpt_lon, center, scales, *obs)
            rel = [np.empty((5, n, K)), np.empty(n, dtype=np.int64)]
            compiled.intruder_relative_state(envs, own, cpu.lat, cpu.lon, cpu.hdg, cpu.gs, cpu.active, True, *rel)
            for got, want in zip([sep_d, los_d, *stats_dev, *obs_d, *rel_d], [sep, los, *stats, *obs, *rel]):
                assert_agree(got.copy_to_host(), want, 1e-9)
        assert int(stats[3].sum()) > 0, "the scenario must count losses of separation"
    assert set(launched.values()) == {4}, launched  # one launch per kernel, whatever the number of airspaces


def test_step_end_kernels() -> None:
    """Truncation, the episode means, the KPIs and the -v1 clip of the device step against their CPU calls."""
    rng = np.random.default_rng(14)
    steps, terminated, cut = rng.integers(0, 6, N), rng.uniform(size=N) < 0.4, rng.uniform(size=N) < 0.4
    args = [steps, 4, terminated, cut, np.empty(N, dtype=np.bool_)]
    cpu = _fresh(args)
    compiled.truncation(*cpu)
    assert_agree(_launch(compiled.truncation, N, _fresh(args), (4,))[0], cpu[4], 0.0)
    total, count = rng.uniform(0, 9, N), np.array([0, 1, 3, 0, 2])
    args = [total, count, 0.0, np.empty(N)]
    cpu = _fresh(args)
    compiled.sample_means(*cpu)
    assert_agree(_launch(compiled.sample_means, N, _fresh(args), (3,))[0], cpu[3], 1e-12)
    stats = [steps, rng.integers(0, 4, N), rng.integers(0, 4, N), rng.uniform(0, 9, N), total, count,
             rng.uniform(0, 3e5, (N, M)), rng.uniform(0, 900, (N, M)), 5.0, 12]  # fmt: skip
    args = [*stats, *(np.empty(N) for _ in range(7))]
    cpu = _fresh(args)
    compiled.episode_kpis(*cpu)
    outputs = tuple(range(10, 17))
    for i, got in zip(outputs, _launch(compiled.episode_kpis, N, _fresh(args), outputs)):
        assert_agree(got, cpu[i], 1e-12)
    values = rng.uniform(-3, 3, (N, 7))
    values[0] = (-0.0, 0.0, np.nan, np.inf, -np.inf, 1.0, -1.0)
    args = [values, np.array([0.0, 0.0, -1, -1, -1, -1, -1]), np.array([0.0, 0.0, 1, 1, 1, 1, 1]), np.empty_like(values)]
    cpu = _fresh(args)
    compiled.clip_to_bounds(*cpu)
    got = _launch(compiled.clip_to_bounds, N, _fresh(args), (3,))[0]
    assert_agree(got, cpu[3], 0.0)
    np.testing.assert_array_equal(np.signbit(got), np.signbit(cpu[3]))
