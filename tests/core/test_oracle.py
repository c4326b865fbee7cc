"""The compiled step kernels are bit-identical to the readable numpy oracle (tests/oracle).

Bit equality holds with numpy's AVX-512 math off (NPY_DISABLE_CPU_FEATURES, set by the test
scripts): numpy then calls the same C library functions as the kernels.
"""

from __future__ import annotations

import numpy as np
import pytest

from bluesky_gym.core import Simulator
from tests.oracle.simulator import OracleSimulator

from .conftest import bits
from .reference_scenarios import SCENARIOS, run
from .test_batch import _random_traffic

KINDS = {"kernel": Simulator, "oracle": OracleSimulator}

FIELDS = [
    "lat",
    "lon",
    "alt",
    "hdg",
    "trk",
    "tas",
    "cas",
    "mach",
    "gs",
    "gsnorth",
    "gseast",
    "vs",
    "ax",
    "windnorth",
    "windeast",
    "distflown",
    "selspd",
    "selalt",
    "selvs",
    "ap_trk",
    "ap_tas",
    "ap_vs",
    "ap_alt",
    "phase",
    "vmin",
    "vmax",
    "axmax",
    "thrust",
    "drag",
    "fuelflow",
    "fuelburn",
    "swlnav",
]


@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_reference_scenarios_bitwise(name: str) -> None:
    sc = SCENARIOS[name]
    out = {}
    for kind, cls in KINDS.items():
        sim = cls(1, sc.max_aircraft, dt=sc.dt)
        sc.setup(sim, 0)
        out[kind] = run(sc, sim, 0)
    for col in out["oracle"]:
        np.testing.assert_array_equal(bits(out["oracle"][col]), bits(out["kernel"][col]), err_msg=col)


@pytest.mark.parametrize("dt", [1.0, 5.0, 0.5])
def test_random_traffic_bitwise(dt: float) -> None:
    """Climbs, descents, ground phase, Mach speeds, turns, LNAV routes and wind fields."""
    sims = {}
    for kind, cls in KINDS.items():
        sim = cls(200, 4, dt=dt)
        _random_traffic(sim, np.arange(200), np.random.default_rng(3))
        sims[kind] = sim
    rng = np.random.default_rng(9)
    for k in range(150):
        if k % 25 == 0:  # new commands on the way, identical for both
            e = rng.integers(0, 200, 40)
            hdg = rng.uniform(0, 360, 40)
            spd = rng.uniform(70, 170, 40)
            for sim in sims.values():
                sim.cmd_heading(e, 0, hdg)
                sim.cmd_speed(e, 1, spd)
                sim.set_autopilot(e, 2, selalt=np.where(hdg > 180, 0.0, 1e6), selvs=spd / 20 - 5)
        for sim in sims.values():
            sim.step()
        for f in FIELDS:
            act = sims["oracle"].active
            np.testing.assert_array_equal(bits(getattr(sims["oracle"], f), act), bits(getattr(sims["kernel"], f), act), err_msg=f"step {k}: {f}")


@pytest.mark.parametrize("dt", [1.0, 0.5])
def test_rotorcraft_beside_fixed_wing_bitwise(dt: float) -> None:
    """BlueSky's rotor model: rotorcraft and fixed-wing aircraft climbing, descending, turning, speeding up, hovering, with wind."""
    types = ["EC35", "M600", "MAVIC", "A320", "PHAN4", "B738"]
    sims = {}
    for kind, cls in KINDS.items():
        sim = cls(30, 6, dt=dt)
        rng = np.random.default_rng(8)
        e, s = np.repeat(np.arange(30), 6), np.tile(np.arange(6), 30)
        sim.create(
            e,
            s,
            rng.uniform(50, 54, 180),
            rng.uniform(2, 6, 180),
            rng.uniform(0, 360, 180),
            rng.choice([0.0, 300.0, 2000.0], 180),
            rng.uniform(0, 150, 180),
            actype=types * 30,
        )
        sim.cmd_speed(e, s, rng.choice([0.0, 10.0, 30.0, 120.0], 180))
        sim.set_autopilot(e[::2], s[::2], selalt=rng.choice([0.0, 1e6, 2400.0], 90), selvs=rng.uniform(-12, 12, 90))
        sim.cmd_heading(e[1::3], s[1::3], rng.uniform(0, 360, 60))
        for env in range(0, 30, 4):
            sim.wind.add_points(env, [52.0], [4.0], [rng.normal(0, 8)], [rng.normal(0, 8)])
        sims[kind] = sim
    for k in range(int(200 / dt)):
        for sim in sims.values():
            sim.step()
        for f in FIELDS:
            act = sims["oracle"].active
            np.testing.assert_array_equal(bits(getattr(sims["oracle"], f), act), bits(getattr(sims["kernel"], f), act), err_msg=f"step {k}: {f}")
    rotor = np.array(types * 30).reshape(30, 6) != "A320"
    rotor &= np.array(types * 30).reshape(30, 6) != "B738"
    assert np.all(sims["kernel"].axmax[rotor] == 3.5) and np.all(sims["kernel"].fuelflow[rotor] == 0.0)
    assert np.all(sims["kernel"].fuelflow[~rotor] != 0.0)


@pytest.mark.parametrize(("wind", "geo"), [(False, "compiled"), (True, "compiled"), (False, "python")])
def test_run_many_steps_equals_stepping(wind: bool, geo: str) -> None:
    """Simulator.run(n) (aircraft-major loop, LNAV included) is bit-identical to n oracle steps."""
    sims = []
    for cls in (Simulator, OracleSimulator):
        sim = cls(50, 3, dt=1.0, geo=geo)
        rng = np.random.default_rng(4)
        e = np.repeat(np.arange(50), 3)
        s = np.tile(np.arange(3), 50)
        sim.create(e, s, rng.uniform(40, 60, 150), rng.uniform(0, 10, 150), rng.uniform(0, 360, 150), rng.choice([0.0, 500.0, 5000.0], 150), 150.0)
        sim.cmd_heading(e, s, rng.uniform(0, 360, 150))
        sim.set_autopilot(np.arange(50), 1, selalt=0.0, selvs=-12.5)
        if wind:
            for env in range(0, 50, 3):
                sim.wind.add_points(env, [50.0], [5.0], [rng.normal(0, 10)], [rng.normal(0, 10)])
        routed = np.arange(0, 50, 2)  # LNAV: three fly-by waypoints, then straight on
        for dlat, dlon in [(0.15, 0.1), (0.3, -0.05), (0.2, -0.3)]:
            sim.add_waypoint(routed, 2, sim.lat[routed, 2] + dlat, sim.lon[routed, 2] + dlon)
        sims.append(sim)
    for _ in range(30):  # 900 s: long enough to fly every route to its end
        sims[0].run(30)
        for _ in range(30):
            sims[1].step()
    for f in FIELDS + ["iactwp", "swlastwp", "turndist", "curlegdir", "next_qdr"]:
        np.testing.assert_array_equal(bits(getattr(sims[0], f), sims[1].active), bits(getattr(sims[1], f), sims[1].active), err_msg=f)
    assert sims[0].simt == sims[1].simt
    assert (sims[1].iactwp[::2, 2] == 2).all() and not sims[1].swlnav.any()  # every route was flown to its end


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_traced_run_records_the_positions_of_every_step(kind: str) -> None:
    """run(n, trace=True) gives the positions n single steps pass through, and the same end state."""
    traced, stepped = (KINDS[kind](40, 4, dt=1.0) for _ in range(2))
    for sim in (traced, stepped):
        _random_traffic(sim, np.arange(40), np.random.default_rng(5))
        sim.wind.clear()  # uniform or no wind: the kernel runs aircraft by aircraft
    track = traced.run(12, trace=True)
    assert track.shape == (12, 2, 40, 4)
    act = stepped.active
    for k in range(12):
        stepped.step()
        np.testing.assert_array_equal(bits(track[k, 0], act), bits(stepped.lat, act), err_msg=f"lat after step {k}")
        np.testing.assert_array_equal(bits(track[k, 1], act), bits(stepped.lon, act), err_msg=f"lon after step {k}")
    for f in FIELDS:
        np.testing.assert_array_equal(bits(getattr(traced, f), act), bits(getattr(stepped, f), act), err_msg=f)
    assert traced.run(3) is None


def test_snapshot_restore_all_and_some_airspaces() -> None:
    """The native core's private snapshots (behind run(stop=...)) restore all or some airspaces."""
    sim = Simulator(30, 4, dt=1.0)
    _random_traffic(sim, np.arange(30), np.random.default_rng(6))
    start = sim._snapshot()
    sim.run(20)
    after = {f: getattr(sim, f).copy() for f in FIELDS}
    clocks = sim.simt
    # Back to the start, then the same 20 steps again: the same state.
    sim._restore(start)
    assert sim.simt == start["simt"] != clocks
    sim.run(20)
    for f in FIELDS:
        np.testing.assert_array_equal(bits(getattr(sim, f), sim.active), bits(after[f], sim.active), err_msg=f)
    # A partial restore changes only the given airspaces (and not the shared clocks).
    some = np.array([3, 17])
    part = sim._snapshot(some)
    sim.run(5)
    moved = sim.lat.copy()
    sim._restore(part, some)
    np.testing.assert_array_equal(sim.lat[some], after["lat"][some])
    others = np.setdiff1d(np.arange(30), some)
    np.testing.assert_array_equal(sim.lat[others], moved[others])
    assert sim.simt == clocks + 5.0
    with pytest.raises(IndexError, match="environment index"):
        sim._snapshot([30])
