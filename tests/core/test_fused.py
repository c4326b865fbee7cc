"""The fused (numba) kernel is bit-identical to the numpy reference implementation."""

from __future__ import annotations

import numpy as np
import pytest

from bluesky_gym.core import Simulator, fused

from .reference_scenarios import SCENARIOS, run
from .test_batch import _random_traffic

pytestmark = pytest.mark.skipif(not fused.AVAILABLE, reason="numba not installed")

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
    "swlnav",
]


def _bits(a: np.ndarray, active: np.ndarray | None = None) -> np.ndarray:
    """The bit patterns of the values in occupied slots (empty slots carry no meaning)."""
    a = np.ascontiguousarray(a)
    a = a.view(np.int64) if a.dtype == np.float64 else a
    return a if active is None else a[active]


@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_reference_scenarios_bitwise(name: str) -> None:
    sc = SCENARIOS[name]
    out = {}
    for kernel in ("numpy", "fused"):
        sim = Simulator(1, 4, dt=sc.dt, kernel=kernel)
        assert sim.kernel == kernel
        sc.setup(sim, 0)
        out[kernel] = run(sc, sim, 0)
    for col in out["numpy"]:
        np.testing.assert_array_equal(_bits(out["numpy"][col]), _bits(out["fused"][col]), err_msg=col)


@pytest.mark.parametrize("dt", [1.0, 5.0, 0.5])
def test_random_traffic_bitwise(dt: float) -> None:
    """Climbs, descents, ground phase, Mach speeds, turns, LNAV routes and wind fields."""
    sims = {}
    for kernel in ("numpy", "fused"):
        sim = Simulator(200, 4, dt=dt, kernel=kernel)
        _random_traffic(sim, np.arange(200), np.random.default_rng(3))
        sims[kernel] = sim
    rng = np.random.default_rng(9)
    for k in range(150):
        if k % 25 == 0:  # new commands on the way, identical for both
            e = rng.integers(0, 200, 40)
            hdg = rng.uniform(0, 360, 40)
            spd = rng.uniform(70, 170, 40)
            for sim in sims.values():
                sim.cmd_heading(e, 0, hdg)
                sim.cmd_speed(e, 1, spd)
                sim.selalt[e, 2] = np.where(hdg > 180, 0.0, 1e6)
                sim.selvs[e, 2] = spd / 20 - 5
        for sim in sims.values():
            sim.step()
        for f in FIELDS:
            act = sims["numpy"].active
            np.testing.assert_array_equal(_bits(getattr(sims["numpy"], f), act), _bits(getattr(sims["fused"], f), act), err_msg=f"step {k}: {f}")


@pytest.mark.parametrize(("wind", "geo"), [(False, "compiled"), (True, "compiled"), (False, "python")])
def test_run_many_steps_equals_stepping(wind: bool, geo: str) -> None:
    """Simulator.run(n) (aircraft-major loop, LNAV included) is bit-identical to n numpy steps."""
    sims = []
    for kernel in ("fused", "numpy"):
        sim = Simulator(50, 3, dt=1.0, kernel=kernel, geo=geo)
        rng = np.random.default_rng(4)
        e = np.repeat(np.arange(50), 3)
        s = np.tile(np.arange(3), 50)
        sim.create(e, s, rng.uniform(40, 60, 150), rng.uniform(0, 10, 150), rng.uniform(0, 360, 150), rng.choice([0.0, 500.0, 5000.0], 150), 150.0)
        sim.cmd_heading(e, s, rng.uniform(0, 360, 150))
        sim.selalt[:, 1] = 0.0
        sim.selvs[:, 1] = -12.5
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
        np.testing.assert_array_equal(_bits(getattr(sims[0], f), sims[1].active), _bits(getattr(sims[1], f), sims[1].active), err_msg=f)
    assert sims[0].simt == sims[1].simt
    assert (sims[1].iactwp[::2, 2] == 2).all() and not sims[1].swlnav.any()  # every route was flown to its end


@pytest.mark.parametrize("kernel", ["fused", "numpy"])
def test_traced_run_records_the_positions_of_every_step(kernel: str) -> None:
    """run(n, trace=True) gives the positions n single steps pass through, and the same end state."""
    traced, stepped = (Simulator(40, 4, dt=1.0, kernel=kernel) for _ in range(2))
    for sim in (traced, stepped):
        _random_traffic(sim, np.arange(40), np.random.default_rng(5))
        sim.wind.clear()  # uniform or no wind: the fused kernel runs aircraft by aircraft
    track = traced.run(12, trace=True)
    assert track.shape == (12, 2, 40, 4)
    act = stepped.active
    for k in range(12):
        stepped.step()
        np.testing.assert_array_equal(_bits(track[k, 0], act), _bits(stepped.lat, act), err_msg=f"lat after step {k}")
        np.testing.assert_array_equal(_bits(track[k, 1], act), _bits(stepped.lon, act), err_msg=f"lon after step {k}")
    for f in FIELDS:
        np.testing.assert_array_equal(_bits(getattr(traced, f), act), _bits(getattr(stepped, f), act), err_msg=f)
    assert traced.run(3) is None


def test_snapshot_restore_all_and_some_airspaces() -> None:
    sim = Simulator(30, 4, dt=1.0)
    _random_traffic(sim, np.arange(30), np.random.default_rng(6))
    start = sim.snapshot()
    sim.run(20)
    after = {f: getattr(sim, f).copy() for f in FIELDS}
    clocks = sim.simt
    # Back to the start, then the same 20 steps again: the same state.
    sim.restore(start)
    assert sim.simt == start["simt"] != clocks
    sim.run(20)
    for f in FIELDS:
        np.testing.assert_array_equal(_bits(getattr(sim, f), sim.active), _bits(after[f], sim.active), err_msg=f)
    # A partial restore changes only the given airspaces (and not the shared clocks).
    some = np.array([3, 17])
    part = sim.snapshot(some)
    sim.run(5)
    moved = sim.lat.copy()
    sim.restore(part, some)
    np.testing.assert_array_equal(sim.lat[some], after["lat"][some])
    others = np.setdiff1d(np.arange(30), some)
    np.testing.assert_array_equal(sim.lat[others], moved[others])
    assert sim.simt == clocks + 5.0
    with pytest.raises(IndexError, match="environment index"):
        sim.snapshot([30])
