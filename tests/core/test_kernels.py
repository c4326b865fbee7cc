"""The array functions of the core (thin loops over the scalar kernels) equal the numpy oracle bit for bit,
and the kernels give the same results run as plain Python (the uncompiled fallback without numba)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from bluesky_gym.core import Simulator, atmosphere, geo, performance
from bluesky_gym.core.aircraft import aircraft_performance
from bluesky_gym.core.jit import python_form
from tests.oracle import atmosphere as o_atm
from tests.oracle import geo as o_geo
from tests.oracle import performance as o_perf

from .test_batch import _random_traffic

ROOT = Path(__file__).resolve().parents[2]


def _same_bits(a: object, b: object) -> None:
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    assert a.shape == b.shape
    np.testing.assert_array_equal(a.view(np.int64), b.view(np.int64))


def _points(n: int = 4000, seed: int = 1) -> tuple[np.ndarray, ...]:
    rng = np.random.default_rng(seed)
    lat1, lat2 = rng.uniform(-80, 80, n), rng.uniform(-80, 80, n)
    lon1, lon2 = rng.uniform(-180, 180, n), rng.uniform(-180, 180, n)
    lat2[: n // 4] = lat1[: n // 4] + rng.normal(0, 0.5, n // 4)  # near pairs as in the tasks
    lon2[: n // 4] = lon1[: n // 4] + rng.normal(0, 0.5, n // 4)
    lat2[n // 4 : n // 4 + 10] = -lat1[n // 4 : n // 4 + 10]  # across the equator
    return lat1, lon1, lat2, lon2


def test_geo_functions_equal_the_oracle() -> None:
    lat1, lon1, lat2, lon2 = _points()
    for ours, oracle in ((geo.qdrdist, o_geo.qdrdist), (geo.qdrdist_python, o_geo.qdrdist_python), (geo.kwikqdrdist, o_geo.kwikqdrdist)):
        for x, y in zip(ours(lat1, lon1, lat2, lon2), oracle(lat1, lon1, lat2, lon2)):
            _same_bits(x, y)
        # One hemisphere only (numpy's shortcut branch) and scalars.
        for x, y in zip(ours(abs(lat1), lon1, abs(lat2), lon2), oracle(abs(lat1), lon1, abs(lat2), lon2)):
            _same_bits(x, y)
    _same_bits(geo.kwikdist(lat1, lon1, lat2, lon2), o_geo.kwikdist(lat1, lon1, lat2, lon2))
    qdr = np.random.default_rng(2).uniform(-400, 400, lat1.size)
    dist = np.random.default_rng(3).uniform(0, 300, lat1.size)
    for x, y in zip(geo.kwikpos(lat1, lon1, qdr, dist), o_geo.kwikpos(lat1, lon1, qdr, dist)):
        _same_bits(x, y)


def test_geo_functions_broadcast_like_numpy() -> None:
    lat = np.linspace(50, 53, 12).reshape(3, 4)
    lon = np.linspace(3, 6, 12).reshape(3, 4)
    d = geo.kwikdist(lat[:, :, None], lon[:, :, None], lat[:, None, :], lon[:, None, :])
    assert d.shape == (3, 4, 4)
    _same_bits(d, o_geo.kwikdist(lat[:, :, None], lon[:, :, None], lat[:, None, :], lon[:, None, :]))
    q, r = geo.kwikqdrdist(52.0, 4.0, lat, 5.0)
    assert q.shape == r.shape == (3, 4)
    s = geo.kwikdist(52.0, 4.0, 52.5, 4.5)  # scalars in, a numpy scalar out, as numpy gives
    assert isinstance(s, np.float64) and s == o_geo.kwikdist(52.0, 4.0, 52.5, 4.5)


def test_atmosphere_functions_equal_the_oracle() -> None:
    rng = np.random.default_rng(4)
    h = np.concatenate([rng.uniform(-100, 25000, 3000), [0.0, 11000.0, 20000.0, 86852.0, 90000.0, -5.0]])
    spd = np.concatenate([rng.uniform(0, 250, 1500), rng.uniform(0.1, 2.0, 1500), [0.1, 2.0, 0.5, 150.0, 0.0, -3.0]])
    for x, y in zip(atmosphere.vcasormach(spd, h), o_atm.vcasormach(spd, h)):
        _same_bits(x, y)
    _same_bits(atmosphere.vcas2tas(spd, h), o_atm.vcas2tas(spd, h))
    _same_bits(atmosphere.tas2cas(spd, h), o_atm.tas2cas(spd, h))
    _same_bits(atmosphere.casormach2tas(spd, h), o_atm.casormach2tas(spd, h))
    for x, y in zip((python_form(atmosphere.isa)(float(v)) for v in h[:50]), zip(*(a[:50] for a in o_atm.vatmos(h)))):
        _same_bits(x, y)
    for k in range(50):
        _same_bits(atmosphere.isa_layered(h[k]), [a[k] for a in o_atm.atmos(h)])


def test_performance_kernel_equals_the_oracle() -> None:
    _same_bits(performance.P_10000FT, o_perf._P10)
    _same_bits(performance.P_35000FT, o_perf._P35)
    _same_bits(performance.VCAS_REF, o_perf._VCAS_REF)
    rng = np.random.default_rng(5)
    n = 3000
    tas = rng.uniform(0, 280, n)
    vs = rng.choice([0.0, 0.5, 0.76, -0.77, 5.0, -12.0, 16.0], n) + rng.normal(0, 0.01, n) * (rng.uniform(size=n) < 0.5)
    alt = np.concatenate([rng.uniform(0, 13000, n - 6), [0.0, 22.86, 304.8, 3048.0, 10668.0, 12000.0]])
    phase = o_perf.flight_phase(tas, vs, alt)
    vmin, vmax = o_perf.speed_envelope(phase)
    axmax = o_perf.max_acceleration(phase, tas, alt, vs)
    drag = o_perf.drag(phase, tas, alt)
    args = performance.perf_tuple(aircraft_performance("A320"))
    for k in range(n):
        ph, vn, vx, ax, d = performance.performance(tas[k], vs[k], alt[k], args)
        assert ph == phase[k], k
        _same_bits([vn, vx, ax, d], [vmin[k], vmax[k], axmax[k], drag[k]])
    assert set(np.unique(phase)) >= {performance.PHASE_GD, performance.PHASE_CL, performance.PHASE_CR, performance.PHASE_DE}


@pytest.mark.parametrize("actype", ["A320", "B744", "E145", "C550", "A388"])
def test_fuel_flow_kernel_equals_the_oracle(actype: str) -> None:
    """Net thrust and fuel flow from drag and the last step's acceleration, every bit, for several types."""
    perf = aircraft_performance(actype)
    rng = np.random.default_rng(11)
    n = 2000
    tas = rng.uniform(30, 280, n)
    alt = rng.uniform(0, 13000, n)
    vs = rng.choice([0.0, 5.0, -12.0], n)
    ax = rng.choice([0.0, 0.5, -0.5, 1.1, 2.0], n) * rng.uniform(0.2, 1.0, n)
    phase = o_perf.flight_phase(tas, vs, alt)
    thrust, fuel = o_perf.thrust_and_fuel_flow(o_perf.drag(phase, tas, alt, perf), ax, perf)
    args = performance.perf_tuple(perf)
    for k in range(n):
        d = performance.performance(tas[k], vs[k], alt[k], args)[4]
        got = performance.fuel_flow(d, ax[k], perf.mass, float(perf.engine_count), perf.engine_max_thrust, perf.fuel_a, perf.fuel_b, perf.fuel_c)
        _same_bits(list(got), [thrust[k], fuel[k]])
    assert np.all(np.isfinite(fuel)) and np.all(np.isfinite(thrust))


@pytest.mark.parametrize("wind", [False, True])
def test_creconfs_equals_the_oracle(wind: bool) -> None:
    """Intruders placed by the conflict-geometry kernel equal the numpy oracle's, bit for bit."""
    from tests.oracle.simulator import OracleSimulator

    n = 300
    rng = np.random.default_rng(6)
    args = (np.arange(n), 0, 1, rng.uniform(0, 360, n), rng.choice([0.0, 1.0, 2.5, 7.0], n), rng.uniform(60, 900, n))
    options = [{}, {"dh": rng.uniform(-1500, 1500, n)}, {"dh": rng.uniform(-1500, 1500, n), "tlosv": rng.uniform(60, 900, n)},
               {"spd": rng.choice([0.78, 130.0, 160.0], n)}, {"dh": 500.0, "spd": 150.0}]  # fmt: skip
    for opts in options:
        sims = [cls(n, 2, dt=1.0) for cls in (Simulator, OracleSimulator)]
        start = (rng.uniform(-60, 60, n), rng.uniform(-170, 170, n), rng.uniform(0, 360, n))
        for sim in sims:
            sim.create(np.arange(n), 0, *start, 5000.0, 140.0)
            if wind:
                for e in range(0, n, 3):
                    sim.wind.add_points(e, [0.0, 10.0][: 1 + e % 2], [0.0, 5.0][: 1 + e % 2], [5.0, -3.0][: 1 + e % 2], [2.0, 7.0][: 1 + e % 2])
            sim.step()
        for sim in sims:
            sim.creconfs(*args, **opts)
        for f in ("lat", "lon", "alt", "hdg", "trk", "tas", "cas", "mach", "gs", "gsnorth", "gseast", "vs", "selalt", "selvs", "selspd"):
            _same_bits(getattr(sims[0], f)[:, 1], getattr(sims[1], f)[:, 1])


def _run_uncompiled(sim: Simulator, n: int) -> None:
    """Step ``sim`` n times through the plain-Python source of the kernels."""
    from bluesky_gym.core import lnav, step

    for _ in range(n):
        do_perf = sim._performance_due()
        sim.simt += sim.dt
        if sim.swlnav.any():
            python_form(lnav.lnav_kernel)(sim._float_flat, *sim._lnav_args())
        wn, we, haswind, any_wind = sim._wind_args()
        args = (sim._phase_flat, wn, we, haswind, any_wind, do_perf, sim.dt, sim._table, sim._type_args(), sim._memo, sim._active_flat)
        python_form(step.step_kernel)(sim._float_flat, *args)


def test_kernels_run_as_plain_python_give_the_compiled_results() -> None:
    """The uncompiled fallback (numba absent) runs the same source: same numbers, to the last bit.

    The top-level kernels run as Python here; the helpers they call stay compiled. The subprocess
    test below hides numba altogether.
    """
    sims = [Simulator(6, 4, dt=1.0) for _ in range(2)]
    for sim in sims:
        _random_traffic(sim, np.arange(6), np.random.default_rng(8))
        sim.wind.clear()
        sim.wind.add_points(1, [50.0], [5.0], [3.0], [-4.0])
    sims[0].run(15)
    _run_uncompiled(sims[1], 15)
    act = sims[0].active
    for f in ("lat", "lon", "alt", "hdg", "trk", "tas", "cas", "vs", "gs", "axmax", "ap_trk"):
        _same_bits(getattr(sims[0], f)[act], getattr(sims[1], f)[act])


_SCRIPT = """
import builtins, sys, warnings
HIDE = sys.argv[1] == "hide"
real_import = builtins.__import__
def fake_import(name, *a, **k):
    if HIDE and (name == "numba" or name.startswith("numba.")):
        raise ImportError("numba hidden")
    return real_import(name, *a, **k)
builtins.__import__ = fake_import
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    from bluesky_gym.core import Simulator, geo, jit
warned = any("numba is not installed" in str(w.message) for w in caught)
assert jit.AVAILABLE != HIDE and warned == HIDE, caught
import numpy as np
sim = Simulator(2, 3, dt=1.0)
sim.create([0, 0, 1], [0, 1, 0], [52.0, 52.1, 51.0], [4.0, 4.2, 3.0], [90.0, 200.0, 10.0], [3000.0, 500.0, 9000.0], [150.0, 120.0, 0.78])
sim.creconfs(1, 0, 1, 90.0, 1.0, 120.0)
sim.add_waypoint(0, 1, 52.3, 4.1)
sim.set_autopilot(1, 0, selalt=0.0, selvs=-10.0)
sim.wind.add_points(0, [52.0], [4.0], [3.0], [2.0])
sim.run(5)
for _ in range(3):
    sim.step()
print(repr(np.concatenate([sim.lat.ravel(), sim.lon.ravel(), sim.alt.ravel(), sim.tas.ravel(), sim.hdg.ravel()]).view(np.int64).tolist()))
print(repr(geo.kwikdist(52.0, 4.0, 52.5, 4.5).item()))
"""


def test_package_runs_without_numba_with_a_warning() -> None:
    """With numba hidden the kernels run as plain Python, with one warning, and give the compiled numbers."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    out = {}
    for mode in ("hide", "keep"):
        res = subprocess.run([sys.executable, "-c", _SCRIPT, mode], capture_output=True, text=True, env=env, timeout=600, cwd=ROOT)
        assert res.returncode == 0, res.stderr
        out[mode] = res.stdout.splitlines()
    assert len(out["hide"]) == 2 and out["hide"] == out["keep"]
