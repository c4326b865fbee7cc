"""The Physics interface of the native core: run(stop=...), set_autopilot, set_state."""

from __future__ import annotations

import numpy as np
import pytest

from bluesky_gym.core import Physics, Simulator
from tests.oracle.simulator import OracleSimulator

from .conftest import bits
from .test_batch import _random_traffic

FIELDS = ("lat", "lon", "alt", "hdg", "trk", "tas", "cas", "gs", "vs", "ax", "axmax", "ap_trk", "distflown", "iactwp", "swlnav")


def _pair(n_envs: int, wind: bool, seed: int = 11) -> tuple[Simulator, Simulator]:
    sims = []
    for _ in range(2):
        sim = Simulator(n_envs, 4, dt=1.0)
        _random_traffic(sim, np.arange(n_envs), np.random.default_rng(seed))
        if not wind:
            sim.wind.clear()
        sims.append(sim)
    return sims[0], sims[1]


def test_simulator_implements_physics() -> None:
    assert isinstance(Simulator(1, 1), Physics)


@pytest.mark.parametrize("wind", [False, True])
def test_run_with_stop_leaves_each_airspace_after_its_end(wind: bool) -> None:
    """Each airspace ends up exactly as if stepped j times (its end), or n_steps times if it did not end."""
    n_envs, n_steps = 12, 7
    ends = np.array([0, 1, 3, 7, 0, 2, 3, 5, 0, 6, 1, 0])
    run_sim, ref = _pair(n_envs, wind)
    seen = []

    def stop(track: np.ndarray) -> np.ndarray:
        seen.append(track.shape)
        return ends

    t0 = run_sim.simt
    track = run_sim.run(n_steps, stop=stop)
    assert track is not None and track.shape == (n_steps, 2, n_envs, 4) and seen
    assert run_sim.simt == t0 + n_steps * run_sim.dt  # some airspaces ran to the end
    act = ref.active
    states = []
    for _ in range(n_steps):
        ref.step()
        states.append({f: getattr(ref, f).copy() for f in FIELDS})
    for e in range(n_envs):
        j = ends[e] if ends[e] else n_steps
        for f in FIELDS:
            np.testing.assert_array_equal(
                bits(getattr(run_sim, f)[e], act[e]), bits(states[j - 1][f][e], act[e]), err_msg=f"airspace {e} (end {j}): {f}"
            )
        # The track holds the positions up to the end.
        np.testing.assert_array_equal(bits(track[j - 1, 0, e], act[e]), bits(states[j - 1]["lat"][e], act[e]))
    # Stepping on afterwards continues from there, for every airspace alike.
    run_sim.step()
    ref.step()
    assert run_sim.simt == ref.simt


def test_run_with_stop_when_every_airspace_ended_stops_the_clock_at_the_last_end() -> None:
    run_sim, ref = _pair(5, wind=False)
    ends = np.array([2, 4, 1, 4, 3])
    t0 = run_sim.simt
    run_sim.run(10, stop=lambda track: ends)
    assert run_sim.simt == t0 + 4 * run_sim.dt
    act = ref.active
    states = []
    for _ in range(4):
        ref.step()
        states.append(ref.lat.copy())
    for e in range(5):
        np.testing.assert_array_equal(bits(run_sim.lat[e], act[e]), bits(states[ends[e] - 1][e], act[e]))
    # Nothing ended: the same as run(n).
    a, b = _pair(3, wind=False)
    a.run(6, stop=lambda track: np.zeros(3, np.int64))
    b.run(6)
    np.testing.assert_array_equal(a.lat, b.lat)
    assert a.simt == b.simt


def test_run_with_stop_checks_the_answer() -> None:
    sim, _ = _pair(2, wind=False)
    with pytest.raises(ValueError, match="stop must return"):
        sim.run(3, stop=lambda track: np.array([4, 0]))
    with pytest.raises(ValueError, match="stop must return"):
        sim.run(3, stop=lambda track: np.array([1]))


def test_run_with_stop_on_the_oracle_is_the_same() -> None:
    """The rewind uses the same stepping as everything else: the oracle agrees bit for bit."""
    ends = np.array([3, 0, 1, 5])
    sims = []
    for cls in (Simulator, OracleSimulator):
        sim = cls(4, 4, dt=1.0)
        _random_traffic(sim, np.arange(4), np.random.default_rng(2))
        sim.run(5, stop=lambda track: ends)
        sims.append(sim)
    for f in FIELDS:
        np.testing.assert_array_equal(bits(getattr(sims[0], f), sims[0].active), bits(getattr(sims[1], f), sims[0].active), err_msg=f)


def test_set_autopilot_and_set_state_write_only_what_is_given() -> None:
    sim = Simulator(3, 2, dt=1.0)
    sim.create([0, 1, 2], 0, 52.0, 4.0, 90.0, 3000.0, 150.0)
    sim.add_waypoint([0, 1, 2], 0, 52.5, 4.5)
    sim.swvnav[:, 0] = True
    before = {f: getattr(sim, f).copy() for f in ("selalt", "selvs", "swvnav", "ap_trk", "alt", "hdg", "swlnav")}
    sim.set_autopilot([0, 2], 0, selalt=np.array([100.0, 200.0]), selvs=-5.0)
    np.testing.assert_array_equal(sim.selalt[:, 0], [100.0, before["selalt"][1, 0], 200.0])
    np.testing.assert_array_equal(sim.selvs[:, 0], [-5.0, before["selvs"][1, 0], -5.0])
    np.testing.assert_array_equal(sim.swvnav, before["swvnav"])
    np.testing.assert_array_equal(sim.ap_trk, before["ap_trk"])
    np.testing.assert_array_equal(sim.swlnav, before["swlnav"])  # not a command: LNAV stays on
    sim.set_autopilot(1, 0, swvnav=False, ap_trk=33.0)
    assert not sim.swvnav[1, 0] and sim.swvnav[0, 0] and sim.ap_trk[1, 0] == 33.0
    sim.set_state(np.arange(3), 0, hdg=np.array([10.0, 20.0, 30.0]))
    np.testing.assert_array_equal(sim.hdg[:, 0], [10.0, 20.0, 30.0])
    np.testing.assert_array_equal(sim.alt, before["alt"])
    sim.set_state(2, 0, alt=1234.0)
    assert sim.alt[2, 0] == 1234.0 and sim.alt[1, 0] == before["alt"][1, 0]
    with pytest.raises(IndexError):
        sim.set_state(3, 0, alt=1.0)


def test_set_autopilot_is_the_direct_write_of_the_reference() -> None:
    """set_autopilot/set_state are the writes the reference gym code makes: the same flight as writing the arrays."""
    a, b = Simulator(1, 1, dt=5.0), Simulator(1, 1, dt=5.0)
    for sim in (a, b):
        sim.create(0, 0, 52.0, 4.0, 0.0, 3000.0, 150.0)
    a.set_autopilot(0, 0, selalt=0.0, selvs=-12.5)
    a.set_state(0, 0, hdg=45.0)
    a.set_autopilot(0, 0, ap_trk=45.0)
    b.selalt[0, 0], b.selvs[0, 0], b.hdg[0, 0], b.ap_trk[0, 0] = 0.0, -12.5, 45.0, 45.0
    a.run(20)
    b.run(20)
    for f in FIELDS:
        np.testing.assert_array_equal(getattr(a, f), getattr(b, f))
    assert a.alt[0, 0] < 3000.0 and a.hdg[0, 0] == 45.0
