"""DeviceSimulator against Simulator: the same traffic stepped on the device and on the CPU."""

from __future__ import annotations

import numpy as np
import pytest

from bluesky_gym.core import DeviceSimulator, Simulator, cuda_target
from bluesky_gym.core.resolution import AsasConfig

from .conftest import TOLERANCE, assert_agree, needs_device

pytestmark = needs_device

FIELDS = {
    "lat": TOLERANCE["deg"],
    "lon": TOLERANCE["deg"],
    "alt": TOLERANCE["m"],
    "hdg": TOLERANCE["deg"],
    "trk": TOLERANCE["deg"],
    "tas": TOLERANCE["m/s"],
    "cas": TOLERANCE["m/s"],
    "gs": TOLERANCE["m/s"],
    "vs": TOLERANCE["m/s"],
    "distflown": TOLERANCE["m"],
    "ap_trk": TOLERANCE["deg"],
}


def _traffic(
    cls: type[Simulator], seed: int = 3, n_envs: int = 3, m: int = 4, n_aircraft: int | None = None, types: tuple[str, ...] = ("A320", "B738", "E190")
) -> Simulator:
    """Mixed types, climbs and descents, turns, LNAV routes on half the aircraft, uniform wind in one airspace.

    ``n_aircraft`` (default ``m - 1``) aircraft per airspace fill the first slots, of types drawn from ``types``.
    """
    rng = np.random.default_rng(seed)
    sim = cls(n_envs, m, dt=1.0)
    n_aircraft = m - 1 if n_aircraft is None else n_aircraft
    env, slot = np.repeat(np.arange(n_envs), n_aircraft), np.tile(np.arange(n_aircraft), n_envs)
    k = env.size
    sim.create(env, slot, 52 + rng.uniform(-0.3, 0.3, k), 4 + rng.uniform(-0.3, 0.3, k), rng.uniform(0, 360, k),
               rng.uniform(1000, 9000, k), rng.choice([130.0, 150.0, 0.7], k), actype=list(rng.choice(list(types), k)))  # fmt: skip
    sim.cmd_altitude(env[::2], slot[::2], rng.uniform(1000, 9000, k)[::2])
    sim.cmd_heading(env[1::3], slot[1::3], rng.uniform(0, 360, k)[1::3])
    routed = np.arange(k) % 2 == 0
    sim.add_waypoint(env[routed], slot[routed], sim.lat[env[routed], slot[routed]] + 0.05, sim.lon[env[routed], slot[routed]] + 0.05)
    sim.add_waypoint(env[routed], slot[routed], sim.lat[env[routed], slot[routed]] + 0.2, sim.lon[env[routed], slot[routed]] - 0.1)
    sim.wind.add_points(1, [52.0], [4.0], [8.0], [-5.0])
    return sim


def _assert_same_state(dev: Simulator, cpu: Simulator) -> None:
    np.testing.assert_array_equal(dev.active, cpu.active)
    act = cpu.active
    for name, atol in FIELDS.items():
        assert_agree(getattr(dev, name)[act], getattr(cpu, name)[act], atol)
    for name in ("iactwp", "swlnav", "phase"):
        np.testing.assert_array_equal(getattr(dev, name)[act], getattr(cpu, name)[act])


def test_steps_on_the_device_give_the_cpu_core_results() -> None:
    cpu, dev = _traffic(Simulator), _traffic(DeviceSimulator)
    assert isinstance(dev, DeviceSimulator)
    for _ in range(12):
        cpu.step()
        dev.step()
        assert dev.on_device  # stepping alone leaves the state on the device
    assert dev.simt == cpu.simt
    _assert_same_state(dev, cpu)
    assert not dev.on_device  # reading brought it back


def test_rotorcraft_on_the_device_give_the_cpu_core_results() -> None:
    """BlueSky's rotor model on the device: rotorcraft beside fixed-wing aircraft, climbs to their ceilings, turns, routes."""
    types = ("A320", "EC35", "M600", "MAVIC")
    cpu, dev = _traffic(Simulator, seed=4, m=6, types=types), _traffic(DeviceSimulator, seed=4, m=6, types=types)
    assert {"EC35", "M600", "MAVIC"} <= set(cpu.aircraft_types)
    for _ in range(12):
        cpu.step()
        dev.step()
    _assert_same_state(dev, cpu)
    rotor = np.array([[cpu.aircraft_performance(e, s).rotor if cpu.active[e, s] else False for s in range(6)] for e in range(3)])
    assert rotor.any() and np.all(dev.axmax[rotor] == 3.5) and np.all(dev.fuelflow[rotor] == 0.0)


def test_commands_between_device_steps_reach_the_device() -> None:
    cpu, dev = _traffic(Simulator, seed=5), _traffic(DeviceSimulator, seed=5)
    for sim in (cpu, dev):
        for _ in range(3):
            sim.step()
        sim.cmd_heading(0, 0, 250.0)
        sim.cmd_speed([1, 2], 1, 160.0)
        sim.set_state(2, 2, alt=4000.0)
        sim.delete(1, 0)
        sim.create(1, 3, 52.1, 4.1, 45.0, 3000.0, 140.0)
        for _ in range(4):
            sim.step()
    _assert_same_state(dev, cpu)


def test_run_with_trace_and_stop_on_the_device() -> None:
    cpu, dev = _traffic(Simulator, seed=7), _traffic(DeviceSimulator, seed=7)
    track_cpu, track_dev = cpu.run(6, trace=True), dev.run(6, trace=True)
    assert track_cpu is not None and track_dev is not None
    act = cpu.active
    assert_agree(track_dev[:, :, act], track_cpu[:, :, act], TOLERANCE["deg"])
    _assert_same_state(dev, cpu)

    def stop(track: np.ndarray) -> np.ndarray:
        return np.array([2, 0, 4])

    cpu.run(5, stop=stop)
    dev.run(5, stop=stop)
    _assert_same_state(dev, cpu)


def test_what_the_device_does_not_model_is_refused() -> None:
    dev = _traffic(DeviceSimulator)
    dev.wind.add_points(2, [52.0, 53.0], [4.0, 5.0], [5.0, -3.0], [3.0, 1.0])
    with pytest.raises(NotImplementedError, match="several points"):
        dev.step()
    dev = _traffic(DeviceSimulator)
    dev.set_conflict_resolution(0, AsasConfig(detector="CSTATEBASED", resolution=True))  # airspaces 1 and 2 do not resolve
    with pytest.raises(NotImplementedError, match="same CSTATEBASED configuration"):
        dev.step()
    dev.set_conflict_resolution([0, 1, 2], AsasConfig(detector="STATEBASED", resolution=True))
    with pytest.raises(NotImplementedError, match="same CSTATEBASED configuration"):
        dev.step()
    with pytest.raises(ValueError, match="aircraft per airspace"):
        DeviceSimulator(1, 200)


def _conflicting(cls: type[Simulator], n_envs: int = 3, seed: int = 3) -> Simulator:
    """Traffic with ASAS (CSTATEBASED, MVP) on in every airspace: conflicts made with creconfs, routes, level changes."""
    sim = _traffic(cls, seed=seed, n_envs=n_envs, m=6, n_aircraft=4)
    envs = np.arange(n_envs)
    sim.creconfs(envs, 0, 4, np.linspace(20.0, 160.0, n_envs), 0.5, 120.0)  # slots 0-3 are taken by _traffic
    sim.creconfs(envs[::2], 1, 5, 45.0, 1.0, 200.0, dh=200.0, tlosv=100.0)
    sim.set_conflict_resolution(envs, AsasConfig(detector="CSTATEBASED", resolution=True))
    return sim


def test_conflict_detection_and_resolution_on_the_device_give_the_cpu_core_results() -> None:
    cpu, dev = _conflicting(Simulator), _conflicting(DeviceSimulator)
    recovered: dict[str, list[tuple[int, int]]] = {"cpu": [], "device": []}
    for name, sim in (("cpu", cpu), ("device", dev)):  # count BlueSky's waypoint recovery (DIRECT after a resolution ends)
        find = sim._find_active
        sim._find_active = lambda e, k, find=find, name=name: recovered[name].append((e, k)) or find(e, k)  # type: ignore[method-assign]
    resolving_steps = 0
    for k in range(30):  # (an aircraft of airspace 1 recovers its route at 22 s)
        cpu.step()
        dev.step()
        if k % 10 == 9:  # reading the state mid-run brings it back; the next step uploads it again
            _assert_same_state(dev, cpu)
            np.testing.assert_array_equal(dev._reso_pairs, cpu._reso_pairs)
            assert_agree(dev._reso_held, cpu._reso_held, TOLERANCE["m/s"])
        resolving_steps += int(cpu._reso_pairs.any())
    _assert_same_state(dev, cpu)
    assert resolving_steps > 5, "the scenario must resolve conflicts for several steps"
    assert recovered["cpu"], "the scenario must end a resolution of an aircraft with a route"
    assert recovered["device"] == recovered["cpu"]


def test_a_device_step_is_a_fixed_number_of_launches_whatever_the_number_of_airspaces() -> None:
    from bluesky_gym.core import cuda_target

    counts = {}
    for n_envs in (2, 8):
        dev = _conflicting(DeviceSimulator, n_envs=n_envs)
        dev.step()  # the upload
        before = cuda_target.launches()
        for _ in range(3):
            dev.step()
        counts[n_envs] = cuda_target.launches() - before
        dev = _traffic(DeviceSimulator, n_envs=n_envs)
        dev.step()
        before = cuda_target.launches()
        dev.step()
        counts[n_envs, "no ASAS"] = cuda_target.launches() - before
    # LNAV, autopilot, detection, MVP, bookkeeping, resumenav, ended, release, targets, kinematics; LNAV and the step without ASAS.
    assert counts == {2: 30, 8: 30, (2, "no ASAS"): 2, (8, "no ASAS"): 2}


def test_reset_on_host_moves_only_the_reset_airspaces_and_equals_the_cpu() -> None:
    """Airspace 1 reset and refilled on the host (a new type and a route among them) while the state is on the device: the rest never comes back."""
    dev, cpu = _traffic(DeviceSimulator, n_aircraft=2, types=("A320",)), _traffic(Simulator, n_aircraft=2, types=("A320",))
    for sim in (dev, cpu):
        sim.run(4)
    dev.device_arrays("lat")  # the state is on the device
    assert dev.on_device

    def refill(sim: Simulator) -> None:
        sim.reset_envs([1])
        sim.create([1, 1, 1], [0, 1, 2], [52.1, 52.2, 51.9], [4.1, 3.9, 4.2], [10.0, 200.0, 300.0], 4000.0, 140.0, actype=["A320", "B744", "A320"])
        sim.add_waypoint([1], [0], [52.4], [4.3])

    dev.reset_on_host(np.array([1]), lambda: refill(dev))
    assert dev.on_device, "the state stays on the device: only airspace 1 went there"
    refill(cpu)
    for sim in (dev, cpu):
        sim.run(6)
    _assert_same_state(dev, cpu)


def test_reset_on_host_refused_midway_keeps_the_device_state() -> None:
    dev, cpu = _traffic(DeviceSimulator), _traffic(Simulator)
    for sim in (dev, cpu):
        sim.run(3)
    dev.device_arrays("lat")

    def fail() -> None:
        raise ValueError("a scenario that cannot be drawn")

    with pytest.raises(ValueError, match="cannot be drawn"):
        dev.reset_on_host(np.array([0]), fail)
    assert dev.on_device
    _assert_same_state(dev, cpu)


def test_create_delete_and_waypoints_on_the_device_move_only_those_aircraft(monkeypatch: pytest.MonkeyPatch) -> None:
    """Traffic entering and leaving mid-run while the state is on the device: the same results as the CPU, the rest never comes back."""
    dev, cpu = _traffic(DeviceSimulator, m=5, n_aircraft=2), _traffic(Simulator, m=5, n_aircraft=2)
    for sim in (dev, cpu):
        sim.run(4)
    dev.device_arrays("lat")
    whole_state_reads: list[int] = []
    to_host = dev._to_host
    monkeypatch.setattr(dev, "_to_host", lambda: (whole_state_reads.append(1), to_host())[1])

    def change(sim: Simulator) -> None:
        sim.delete([0], [1])
        sim.create([1, 2, 2], [3, 2, 4], [52.1, 52.2, 51.9], [4.1, 3.9, 4.2], [10.0, 200.0, 300.0], 4000.0, 140.0, actype=["A320", "B744", "E190"])
        # slot 0 of airspace 0 flew on the device: its position comes back for the new leg
        sim.add_waypoint([1, 2, 0], [3, 4, 0], [52.4, 52.0, 52.3], [4.3, 4.5, 3.8])

    change(dev)
    assert dev.on_device and not whole_state_reads, "only the changed aircraft crossed"
    change(cpu)
    with pytest.raises(ValueError, match="already exists"):
        dev.create([1], [3])
    assert dev.on_device and not whole_state_reads
    for sim in (dev, cpu):
        sim.run(6)
    assert dev.on_device and not whole_state_reads
    _assert_same_state(dev, cpu)
    assert whole_state_reads  # the comparison read it
    np.testing.assert_array_equal(dev.route_lat, cpu.route_lat)
    assert dev.aircraft_type([2], [2]) == ["B744"]


def test_aircraft_deleted_on_the_device_stay_deleted() -> None:
    """``delete_flagged`` on the device: the host sees the deletions, and they survive the state's next trip to the device."""
    dev, cpu = _traffic(DeviceSimulator), _traffic(Simulator)
    flags = np.zeros((dev.n_envs, dev.max_aircraft), bool)
    flags[0, 1] = flags[2, 0] = True
    for sim in (dev, cpu):
        sim.run(3)
    dev.delete_flagged(cuda_target.to_device(flags))
    cpu.delete(*np.nonzero(flags))
    np.testing.assert_array_equal(dev.active, cpu.active)  # brought back: the deletions show
    for sim in (dev, cpu):
        sim.run(3)  # to the device again
    _assert_same_state(dev, cpu)
    with pytest.raises(ValueError, match=r"flags must have shape \(3, 4\)"):
        dev.delete_flagged(cuda_target.to_device(np.zeros(3, bool)))
