"""Eby and Swarm conflict resolution against BlueSky 1.1.1's own plugins (``RESO EBY``, ``RESO SWARM``), fixed to run.

Needs the ``bluesky`` extra; skipped when BlueSky cannot be imported.

BlueSky 1.1.1's ``EBY`` and ``SWARM`` plugins crash on their first resolution
(:func:`test_unpatched_plugins_crash`). The fixes of :mod:`bluesky_gym.core.eby` and
:mod:`bluesky_gym.core.swarm` are applied to the plugins' own source text here, as substitutions
(:data:`EBY_FIX`, :data:`SWARM_FIX`, each found exactly once), and the patched methods replace
BlueSky's for the test (``monkeypatch``). On the BlueSky backend with ``ASAS CSTATEBASED``:

* 100 seeded random conflict geometries per method (the MVP tests' generator: ``creconfs``
  intruders of the ownship and of each other, level or with altitude offsets, climbing aircraft,
  a few steps flown), Swarm under the RMETH / RFACH settings it inherits from MVP: BlueSky's
  ``traf.cr.resolve`` and the package's :func:`~bluesky_gym.core.eby.eby` /
  :func:`~bluesky_gym.core.swarm.swarm` of the same state agree within 1e-9 (track, speed,
  vertical speed, absolute) and exactly in the altitude (``sign(vs) * 1e5``); Eby agrees to the
  bit (:data:`TOLERANCE`).
* The s9 creconfs scenario flown 200 s with each method resolving: every step's resolution
  agrees, and so does who follows it (BlueSky's ``cr.active``: ``resumenav``, and for Swarm its
  ``active.fill(True)``), which the package's resolvers decide.
* The core's ``Simulator`` with ``RESO EBY|SWARM`` and the patched BlueSky fly s9 (and a Swarm
  bystander) side by side for 200 s: every state within the reference tolerances.
"""

from __future__ import annotations

import inspect
import textwrap
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

pytest.importorskip("bluesky")

from bluesky_gym.backends.bluesky_sim import BlueSkyPhysics
from bluesky_gym.core.conflicts import LOOKAHEAD, PZ_HEIGHT, PZ_RADIUS, detect
from bluesky_gym.core.eby import EbyResolver, eby
from bluesky_gym.core.resolution import Resolution, ResolutionSettings, mvp, vertical_speed_limits
from bluesky_gym.core.swarm import SwarmResolver, swarm
from bluesky_gym.core.units import FT, KTS

from .test_resolution_bluesky import SETTINGS, _bluesky_resolution, _random_geometry

pytestmark = pytest.mark.bluesky

N_GEOMETRIES = 100
MAX_AC = 8
#: Eby is bit-for-bit (its dot products are BLAS ddot's fused multiply-adds, reproduced); Swarm's means
#: are sums in another order (numpy's pairwise sums over BlueSky's aircraft vs. over the padded slots).
TOLERANCE = {"EBY": 0.0, "SWARM": 1e-9}

#: The fix of BlueSky 1.1.1's ``Eby.Eby_straight``: the pair's zone radius (``conf.rpz`` is per aircraft since 1.0).
EBY_FIX = (("conf.rpz", "np.max(conf.rpz[[idx1, idx2]])", 2),)

#: The fixes of BlueSky 1.1.1's ``Swarm.resolve`` (old-ASAS names; see bluesky_gym.core.swarm).
SWARM_FIX = (
    # The bearings and distances of all pairs, as the STATEBASED detection computes them.
    (
        "qdrrad = np.radians(conf.qdr)",
        "qdr, dist = geo.kwikqdrdist_matrix(np.asmatrix(ownship.lat), np.asmatrix(ownship.lon), "
        "np.asmatrix(intruder.lat), np.asmatrix(intruder.lon))\n"
        "    qdr = np.asarray(qdr)\n"
        "    dist = np.asarray(dist) * nm + 1e9 * np.eye(ownship.ntraf)\n"
        "    qdrrad = np.radians(qdr)",
        1,
    ),
    ("conf.dist", "dist", 2),
    ("conf.rpzswarm", "self.rpzswarm", 1),
    ("asas.u / 100.", "ownship.gseast / 100.", 1),
    ("asas.v / 100.", "ownship.gsnorth / 100.", 1),
    ("asas.Swarmweights", "self.Swarmweights", 4),
    # Return the result, as 1.1.1's ConflictResolution.update expects, instead of writing it to the old asas object.
    ("asas.hdg = ", "out_trk = ", 1),
    ("asas.tas = ", "out_tas = ", 1),
    ("asas.vs = ", "out_vs = ", 1),
    ("asas.alt = ", "out_alt = ", 1),
    ("asas.active.fill(True)", "self.active.fill(True)\n    return out_trk, out_tas, out_vs, out_alt", 1),
    # The patched function is defined outside its class: name the parent explicitly.
    ("super().resolve(conf, ownship, intruder)", "MVP.resolve(self, conf, ownship, intruder)", 1),
)


def _patched(method: Any, fixes: tuple[tuple[str, str, int], ...], extra: dict[str, Any]) -> Any:
    """``method`` recompiled from its source text with ``fixes`` (old, new, expected count) substituted."""
    source = textwrap.dedent(inspect.getsource(method))  # the body at 4 spaces
    for old, new, count in fixes:
        assert source.count(old) == count, f"{old!r} occurs {source.count(old)} times in {method.__qualname__}, expected {count}"
        source = source.replace(old, new)
    namespace = dict(method.__globals__, **extra)
    exec(compile(source, inspect.getsourcefile(method) or "<plugin>", "exec"), namespace)  # noqa: S102 - BlueSky's own source, fixed
    return namespace[method.__name__]


def _plugin_class(sim: BlueSkyPhysics, name: str) -> Any:
    """BlueSky's resolution class of plugin ``name`` (loaded on first use)."""
    from bluesky.traffic.asas import ConflictResolution

    if name not in ConflictResolution.derived():
        sim.command(f"PLUGINS LOAD {name}")
    return ConflictResolution.derived()[name]


@pytest.fixture
def physics() -> Iterator[BlueSkyPhysics]:
    sim = BlueSkyPhysics(MAX_AC, dt=1.0)
    yield sim
    for line in ("RESO OFF", "ASAS OFF"):
        sim.command(line)
    sim.close()


@pytest.fixture
def patched(physics: BlueSkyPhysics, monkeypatch: pytest.MonkeyPatch) -> BlueSkyPhysics:
    """The backend with BlueSky's Eby and Swarm plugins loaded and fixed."""
    from bluesky.tools import geo
    from bluesky.tools.aero import nm

    eby_cls = _plugin_class(physics, "EBY")
    swarm_cls = _plugin_class(physics, "SWARM")
    monkeypatch.setattr(eby_cls, "Eby_straight", _patched(eby_cls.Eby_straight, EBY_FIX, {}))
    monkeypatch.setattr(swarm_cls, "resolve", _patched(swarm_cls.resolve, SWARM_FIX, {"geo": geo, "nm": nm}))
    return physics


def _select(
    sim: BlueSkyPhysics, method: str, rmethh: str | None = None, rmethv: str | None = None, rfach: float = 1.05, rfacv: float = 1.05
) -> ResolutionSettings:
    """``ASAS CSTATEBASED``, ``RESO method`` and the settings; the package's equivalent."""
    sim.command("ASAS CSTATEBASED")
    sim.command(f"RESO {method}")
    cr = sim.traffic.cr
    if method == "SWARM":  # MVP's switches, which Swarm inherits: from BlueSky's defaults
        cr.swresohoriz, cr.swresospd, cr.swresohdg, cr.swresovert = True, False, False, False
        if rmethh is not None:
            sim.command(f"RMETHH {rmethh}")
        if rmethv is not None:
            sim.command(f"RMETHV {rmethv}")
    sim.command(f"RFACH {rfach}")
    sim.command(f"RFACV {rfacv}")
    return ResolutionSettings.from_methods(rmethh, rmethv, rfach, rfacv)


def _ours(sim: BlueSkyPhysics, method: str, settings: ResolutionSettings) -> Resolution:
    conflicts = detect(sim.lat, sim.lon, sim.alt, sim.gs, sim.trk, sim.vs, sim.active, PZ_RADIUS, PZ_HEIGHT, LOOKAHEAD)
    if method == "EBY":
        return eby(sim, conflicts, settings, rpz=PZ_RADIUS)
    vsmin, vsmax = vertical_speed_limits(sim)
    # Swarm's pair bearings come from BlueSky's geo functions: the Python forms when BlueSky's geo module
    # was imported before its init (as by an earlier test in the same process), else the compiled ones.
    return swarm(sim, conflicts, mvp(sim, conflicts, settings, vsmin=vsmin, vsmax=vsmax), python_geo=sim.geo == "python")


def _assert_same(ours: Resolution, theirs: tuple[np.ndarray, ...], where: str, tol: float) -> None:
    trk, spd, vs, alt = theirs
    live = np.isfinite(trk)
    np.testing.assert_array_equal(np.isfinite(ours.trk), live, err_msg=where)
    dtrk = (ours.trk - trk + 180.0) % 360.0 - 180.0
    assert np.all(np.abs(dtrk[live]) <= tol), f"{where}: track differs by {np.max(np.abs(dtrk[live]))} deg"
    np.testing.assert_allclose(ours.gs[live], spd[live], rtol=0.0, atol=tol, err_msg=f"{where}: speed")
    np.testing.assert_allclose(ours.vs[live], vs[live], rtol=0.0, atol=tol, err_msg=f"{where}: vertical speed")
    np.testing.assert_array_equal(ours.alt[live], alt[live], err_msg=f"{where}: altitude")


def test_unpatched_plugins_crash(physics: BlueSkyPhysics) -> None:
    """BlueSky 1.1.1's own Eby and Swarm fail on their first resolution (the reason for the fixes)."""
    for method, error in (("EBY", "truth value of an array"), ("SWARM", "rpzswarm|could not be broadcast")):
        _plugin_class(physics, method)
        physics.reset_envs()
        _select(physics, method)
        physics.create(0, 0, 52.0, 4.0, 90.0, 3000.0, 130.0)
        physics.creconfs(0, 0, 1, 45.0, 0.5, 100.0)
        physics.creconfs(0, 0, 2, 300.0, 1.0, 150.0)
        traf = physics.traffic
        traf.cd.update(traf, traf)
        assert traf.cd.confpairs
        with pytest.raises((ValueError, AttributeError), match=error):
            traf.cr.resolve(traf.cd, traf, traf)


@pytest.mark.parametrize("method", ["EBY", "SWARM"])
def test_random_geometries(patched: BlueSkyPhysics, method: str) -> None:
    """100 random conflict geometries: the package's method equals BlueSky's patched plugin on the same state."""
    rng = np.random.default_rng(20261127 + len(method))
    conflicts_seen = 0
    for k in range(N_GEOMETRIES):
        patched.reset_envs()
        setting = SETTINGS[k % len(SETTINGS)] if method == "SWARM" else SETTINGS[0]
        settings = _select(patched, method, *setting)
        _random_geometry(patched, rng)
        theirs = _bluesky_resolution(patched)
        conflicts_seen += len(patched.traffic.cd.confpairs)
        _assert_same(_ours(patched, method, settings), theirs, f"{method} geometry {k} {setting}", TOLERANCE[method])
    assert conflicts_seen > 2 * N_GEOMETRIES  # the geometries do produce conflicts


@pytest.mark.parametrize(("method", "resolver_cls"), [("EBY", EbyResolver), ("SWARM", SwarmResolver)])
def test_creconfs_scenario_s9(patched: BlueSkyPhysics, method: str, resolver_cls: type) -> None:
    """The s9 creconfs scenario flown 200 s with the method resolving: each step's resolution and who follows it agree."""
    settings = _select(patched, method)
    patched.create(0, 0, 52.0, 4.0, 45.0, 200 * 100 * FT, 250 * KTS)
    patched.creconfs(0, 0, 1, 90.0, 1.0, 120.0)
    patched.creconfs(0, 0, 2, 200.0, 0.0, 150.0, None, None, 200 * KTS)
    patched.creconfs(0, 0, 3, 300.0, 2.0, 100.0, 500.0, 90.0)
    resolver = resolver_cls(settings, python_geo=patched.geo == "python")
    resolving = following = 0
    for t in range(200):
        was_active = np.array(patched.traffic.cr.active)  # resolve() of Swarm sets it: keep BlueSky's own flight
        theirs = _bluesky_resolution(patched)
        patched.traffic.cr.active[:] = was_active
        resolving += int(bool(patched.traffic.cd.confpairs))
        _assert_same(_ours(patched, method, settings), theirs, f"{method} s9 t={t}", TOLERANCE[method])
        follow = resolver.update(patched).follow[0]
        patched.step()
        active = np.zeros(patched.max_aircraft, bool)
        slots = np.flatnonzero(patched.active[0])
        active[slots] = np.asarray(patched.traffic.cr.active, bool)[patched.traffic.id2idx([patched.acid(s) for s in slots])]
        np.testing.assert_array_equal(follow, active, err_msg=f"{method} s9 t={t}: who follows the resolution")
        following += int(follow.any())
    assert resolving >= 5 and following > 0
    assert abs(patched.trk[0, 0] - 45.0) > 1.0  # the method did act


def _s9(sim: Any) -> None:
    """The s9 creconfs geometry, with a bystander flying alongside the ownship (a Swarm member)."""
    sim.create(0, 0, 52.0, 4.0, 45.0, 200 * 100 * FT, 250 * KTS)
    sim.creconfs(0, 0, 1, 90.0, 1.0, 120.0)
    sim.creconfs(0, 0, 2, 200.0, 0.0, 150.0, None, None, 200 * KTS)
    sim.creconfs(0, 0, 3, 300.0, 2.0, 100.0, 500.0, 90.0)
    sim.create(0, 4, 52.03, 3.95, 50.0, 200 * 100 * FT + 300.0, 240 * KTS)


@pytest.mark.parametrize("method", ["EBY", "SWARM"])
def test_core_flies_the_method_as_patched_bluesky(patched: BlueSkyPhysics, method: str) -> None:
    """The core's Simulator with RESO method and the patched BlueSky fly the same 200 s, state by state."""
    from bluesky_gym.core import Simulator
    from bluesky_gym.core.resolution import AsasConfig

    from .test_reference import TOL

    core = Simulator(1, MAX_AC, dt=1.0, pair_search="all-pairs", geo=patched.geo)
    _select(patched, method)
    core.set_conflict_resolution(0, AsasConfig("CSTATEBASED", True, method=method))
    for sim in (core, patched):
        _s9(sim)
    slots = np.flatnonzero(patched.active[0])
    turned = 0.0
    for t in range(200):
        core.step()
        patched.step()
        for name in ("lat", "lon", "alt", "tas", "gs", "vs", "trk"):
            ours, theirs = getattr(core, name)[0, slots], getattr(patched, name)[0, slots]
            err = np.abs(ours - theirs)
            if name == "trk":
                err = np.minimum(err, 360.0 - err)
            assert np.all(err <= TOL[name]), f"{method} t={t + 1} {name}: {ours} vs {theirs}"
        turned = max(turned, abs((core.trk[0, 0] - 45.0 + 180.0) % 360.0 - 180.0))
    assert turned > 1.0  # the method did act


def test_bluesky_backend_refuses_the_crashing_plugins(physics: BlueSkyPhysics) -> None:
    from bluesky_gym.core.resolution import AsasConfig

    for method in ("EBY", "SWARM"):
        with pytest.raises(ValueError, match=f"RESO {method} is a BlueSky plugin that crashes on its first resolution in BlueSky 1.1.1"):
            physics.set_conflict_resolution(0, AsasConfig("CSTATEBASED", True, method=method))
    physics.set_conflict_resolution(0, AsasConfig("CSTATEBASED", True))  # MVP: as before
    from bluesky.traffic.asas import ConflictResolution

    assert ConflictResolution.selected().__name__ == "MVP"
    physics.set_conflict_resolution(0, AsasConfig())
