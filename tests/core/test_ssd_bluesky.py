"""SSD conflict resolution against BlueSky 1.1.1's own SSD plugin (``PLUGINS LOAD SSD``, ``RESO SSD``), on the same states.

Needs the ``bluesky`` and ``ssd`` extras; skipped when BlueSky or pyclipper cannot be imported.

BlueSky 1.1.1's plugin crashes on its first resolution (first test). The two fixes of
:mod:`bluesky_gym.core.ssd` are applied to BlueSky as monkeypatches: the plugin module's
``geo.qdrdist_matrix`` becomes the pairwise ``geo.qdrdist``, and the plugin's ``resolve`` sees
``conf.rpz`` as the default zone radius ``conf.rpz_def``. With them BlueSky's ``traf.cr.resolve``
and the package's :func:`~bluesky_gym.core.ssd.ssd` (on the backend's state arrays, with the
package's own conflict detection) must give the same track, speed, vertical speed and altitude
of every aircraft **to the bit** (``assert_array_equal``):

* 60 seeded random conflict geometries (``creconfs`` intruders of the ownship and of each other,
  own speeds, some flown into loss of separation, some in wind, so that heading and track
  differ), under several ``RFACH`` factors and ``ZONER`` radii, with A320s or mixed types
  (different speed envelopes);
* a creconfs scenario flown for 150 s with SSD resolving in BlueSky, every state compared, and
  who follows the resolution after every step (BlueSky's ``cr.active``, ``resumenav``);
* the core's ``Simulator`` with ``RESO SSD`` and the fixed BlueSky flying a creconfs scenario side
  by side for 200 s: every state within the tolerances of the recorded reference scenarios.
"""

from __future__ import annotations

import sys
import types
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

pytest.importorskip("bluesky")
pytest.importorskip("pyclipper")

from bluesky_gym.backends.bluesky_sim import BlueSkyPhysics
from bluesky_gym.core.conflicts import LOOKAHEAD, PZ_HEIGHT, detect
from bluesky_gym.core.resolution import Resolution, ResolutionSettings
from bluesky_gym.core.ssd import SSDResolver, ssd
from bluesky_gym.core.units import FT, KTS, NM

pytestmark = [
    pytest.mark.bluesky,
    # The plugin's calculate_resolution calls np.row_stack (deprecated in numpy 2, still the same as np.vstack).
    pytest.mark.filterwarnings("ignore:`row_stack` alias is deprecated:DeprecationWarning"),
]

MAX_AC = 8
N_GEOMETRIES = 60
#: (RFACH, ZONER [NM]) cycled through by the random geometries.
SETTINGS = ((1.05, 5.0), (1.0, 5.0), (1.2, 5.0), (1.05, 3.0), (1.1, 6.5))
MIXED_TYPES = ("A320", "B744", "E190", "A388", "B738", "C550")


@pytest.fixture
def physics() -> Iterator[BlueSkyPhysics]:
    sim = BlueSkyPhysics(MAX_AC, dt=1.0)
    try:
        sim.command("PLUGINS LOAD SSD")
    except RuntimeError as exc:  # loaded by an earlier test of this process
        if "already loaded" not in str(exc):
            raise
    yield sim
    for line in ("RESO OFF", "ASAS OFF", "RFACH 1.05", "ZONER 5"):
        sim.command(line)
    sim.close()


def _plugin() -> types.ModuleType:
    return sys.modules["bluesky.plugins.asas.ssd"]


class _DefaultZone:
    """BlueSky's conflict detection object as the fixed plugin reads it: ``rpz`` is the default radius ``rpz_def``."""

    def __init__(self, cd: Any) -> None:
        object.__setattr__(self, "_cd", cd)

    def __getattr__(self, name: str) -> Any:
        return self._cd.rpz_def if name == "rpz" else getattr(self._cd, name)

    def __setattr__(self, name: str, value: Any) -> None:
        setattr(self._cd, name, value)


def _fix_plugin(monkeypatch: pytest.MonkeyPatch, qdrdist: bool = True, zone: bool = True) -> None:
    """Apply the fixes of :mod:`bluesky_gym.core.ssd` to BlueSky's SSD plugin for this test."""
    plugin = _plugin()
    if qdrdist:  # fix 1: one bearing and distance per pair
        from bluesky.tools import geo

        monkeypatch.setattr(plugin, "geo", types.SimpleNamespace(qdrdist_matrix=geo.qdrdist))
    if zone:  # fix 2: the default zone radius, a number
        resolve = plugin.SSD.resolve
        monkeypatch.setattr(plugin.SSD, "resolve", lambda self, conf, ownship, intruder: resolve(self, _DefaultZone(conf), ownship, intruder))


def _configure(sim: BlueSkyPhysics, rfach: float = 1.05, zoner_nm: float = 5.0) -> None:
    sim.command("ZONER " + repr(zoner_nm))
    sim.command("ASAS CSTATEBASED")
    sim.command("RESO SSD")
    sim.command("RFACH " + repr(rfach))


def _random_geometry(sim: BlueSkyPhysics, rng: np.random.Generator, types_: tuple[str, ...] | None, wind: bool) -> None:
    """An ownship and intruders in conflict with it or with each other, maybe in wind, flown 0 to 3 s (or 40 s more: losses of separation)."""
    lat0, lon0 = rng.uniform(-60.0, 60.0), rng.uniform(-170.0, 170.0)
    if wind:
        sim.wind.add_points(0, [lat0], [lon0], [rng.uniform(-25.0, 25.0)], [rng.uniform(-25.0, 25.0)])
    drawn = [str(t) for t in rng.choice(types_, MAX_AC)] if types_ is not None else [None] * MAX_AC
    sim.create(0, 0, lat0, lon0, rng.uniform(0.0, 360.0), rng.uniform(2000.0, 9000.0), rng.uniform(110.0, 160.0), actype=drawn[0])
    n = int(rng.integers(1, MAX_AC))
    for slot in range(1, n + 1):
        target = 0 if slot == 1 or rng.random() < 0.6 else int(rng.integers(0, slot))
        spd = float(rng.uniform(100.0, 170.0)) if rng.random() < 0.5 else None
        dcpa = 0.0 if rng.random() < 0.15 else float(rng.uniform(0.0, 7.0))
        sim.creconfs(0, target, slot, rng.uniform(0.0, 360.0), dcpa, rng.uniform(10.0, 400.0), None, None, spd, actype=drawn[slot])
    sim.run(int(rng.integers(0, 4)) + (40 if rng.random() < 0.3 else 0))


def _bluesky_resolution(sim: BlueSkyPhysics) -> tuple[np.ndarray, ...]:
    """BlueSky's conflict detection and SSD resolution of the current state, in slot order."""
    from bluesky.core.entity import getproxied

    traf = sim.traffic
    traf.cd.update(traf, traf)
    # The selected method object itself: ``traf.cr`` (a proxy) holds the methods it had when SSD was selected.
    out = getproxied(traf.cr).resolve(traf.cd, traf, traf)
    slots = np.flatnonzero(sim.active[0])
    idx = np.array(traf.id2idx([sim.acid(s) for s in slots]))
    res = []
    for values in out:
        full = np.full(sim.max_aircraft, np.nan)
        full[slots] = np.asarray(values, dtype=np.float64)[idx]
        res.append(full[None])
    return tuple(res)


def _ours(sim: BlueSkyPhysics, rfach: float = 1.05, zoner_nm: float = 5.0) -> Resolution:
    rpz = zoner_nm * NM
    conflicts = detect(sim.lat, sim.lon, sim.alt, sim.gs, sim.trk, sim.vs, sim.active, rpz, PZ_HEIGHT, LOOKAHEAD)
    inconf = np.zeros(sim.max_aircraft, bool)
    slots = np.flatnonzero(sim.active[0])
    inconf[slots] = np.asarray(sim.traffic.cd.inconf, bool)[sim.traffic.id2idx([sim.acid(s) for s in slots])]
    np.testing.assert_array_equal(conflicts.in_conflict[0], inconf, err_msg="conflict list")
    return ssd(sim, conflicts, ResolutionSettings(resofach=rfach), rpz=rpz, python_geo=sim.geo == "python")


def _assert_same(ours: Resolution, theirs: tuple[np.ndarray, ...], where: str) -> None:
    for name, value in zip(("trk", "gs", "vs", "alt"), theirs, strict=True):
        np.testing.assert_array_equal(getattr(ours, name), value, err_msg=f"{where}: {name}")


def _one_conflict(sim: BlueSkyPhysics) -> None:
    sim.create(0, 0, 52.0, 4.0, 45.0, 6000.0, 130.0)
    sim.creconfs(0, 0, 1, 90.0, 1.0, 120.0)
    sim.creconfs(0, 0, 2, 200.0, 0.0, 150.0)


def test_bluesky_plugin_crashes_without_the_fixes(physics: BlueSkyPhysics, monkeypatch: pytest.MonkeyPatch) -> None:
    """BlueSky 1.1.1's SSD plugin fails on its first resolution; each of the two fixes removes one failure."""
    _configure(physics)
    _one_conflict(physics)
    # With BlueSky's compiled geo functions (its default) qdrdist_matrix gives a matrix where the
    # plugin wants one value per pair. With its Python forms (bluesky.tools.geo imported before
    # bs.init, e.g. by an earlier test in this process) that result reshapes, and the zone failure
    # below is the first.
    first = "cannot reshape" if physics.geo == "compiled" else "could not be broadcast|cannot assign"
    with pytest.raises(ValueError, match=first):
        _bluesky_resolution(physics)
    _fix_plugin(monkeypatch, qdrdist=True, zone=False)
    # conf.rpz has one radius per aircraft, the distances one per pair: numpy refuses to broadcast
    # them, or (as many pairs as aircraft, here 3) to assign the radii where the mask is true.
    with pytest.raises(ValueError, match="could not be broadcast|cannot assign"):
        _bluesky_resolution(physics)
    _fix_plugin(monkeypatch, qdrdist=False, zone=True)
    trk, gs, _, _ = _bluesky_resolution(physics)
    assert np.all(np.isfinite(trk[0, :3])) and np.all(gs[0, :3] > 0)


def test_random_geometries_bit_for_bit(physics: BlueSkyPhysics, monkeypatch: pytest.MonkeyPatch) -> None:
    """60 random conflict geometries: the package's detection + SSD equals the fixed plugin's resolution to the bit."""
    _fix_plugin(monkeypatch)
    rng = np.random.default_rng(20261127)
    resolved = los = hdg_kept = 0
    for k in range(N_GEOMETRIES):
        physics.reset_envs()
        rfach, zoner = SETTINGS[k % len(SETTINGS)]
        _configure(physics, rfach, zoner)
        _random_geometry(physics, rng, MIXED_TYPES if k % 3 == 1 else None, wind=k % 3 == 2)
        theirs = _bluesky_resolution(physics)
        ours = _ours(physics, rfach, zoner)
        _assert_same(ours, theirs, f"geometry {k} (RFACH {rfach}, ZONER {zoner})")
        took = np.abs(ours.dv[..., :2]).sum(-1) > 0
        resolved += int(took.sum())
        hdg_kept += int(np.sum(~took & physics.active & (physics.hdg != physics.trk)))
        dist = physics.traffic.cd.dist
        los += int(np.sum(np.asarray(dist) < zoner * NM * rfach))
    # The geometries exercise the plugin: many resolutions, pairs in loss of separation (dart
    # tips), and aircraft in wind that keep their heading (not their track).
    assert resolved > 2 * N_GEOMETRIES and los > 10 and hdg_kept > 5


def test_creconfs_scenario_flown_with_ssd(physics: BlueSkyPhysics, monkeypatch: pytest.MonkeyPatch) -> None:
    """Four aircraft in conflict, flown 150 s with BlueSky's SSD resolving: every state's resolution agrees to the bit."""
    _fix_plugin(monkeypatch)
    _configure(physics)
    physics.create(0, 0, 52.0, 4.0, 45.0, 200 * 100 * FT, 250 * KTS)
    physics.creconfs(0, 0, 1, 90.0, 1.0, 120.0)
    physics.creconfs(0, 0, 2, 200.0, 0.0, 150.0, None, None, 200 * KTS)
    physics.creconfs(0, 0, 3, 300.0, 2.0, 100.0)
    resolver = SSDResolver(ResolutionSettings(resofach=1.05), python_geo=physics.geo == "python")
    resolving = following = 0
    for t in range(150):
        theirs = _bluesky_resolution(physics)
        ours = _ours(physics)
        _assert_same(ours, theirs, f"t={t}")
        resolving += int(ours.in_conflict.any())
        follow = resolver.update(physics).follow[0]
        physics.step()  # BlueSky's ASAS sees the same state in this step, then resumenav decides who follows
        active = np.zeros(physics.max_aircraft, bool)
        slots = np.flatnonzero(physics.active[0])
        active[slots] = np.asarray(physics.traffic.cr.active, bool)[physics.traffic.id2idx([physics.acid(s) for s in slots])]
        np.testing.assert_array_equal(follow, active, err_msg=f"t={t}: who follows the resolution")
        following += int(follow.any())
    assert resolving > 10 and following > resolving  # resolutions are held after the conflicts end
    assert abs(physics.trk[0, 0] - 45.0) > 1.0  # SSD did act: the ownship left its track


def test_core_flies_ssd_as_patched_bluesky(physics: BlueSkyPhysics, monkeypatch: pytest.MonkeyPatch) -> None:
    """The core's Simulator with RESO SSD and the fixed BlueSky fly the same 200 s side by side, state by state.

    The tolerances are those of the recorded reference scenarios (``test_reference.TOL``).
    """
    from bluesky_gym.core import Simulator
    from bluesky_gym.core.resolution import AsasConfig

    from .test_reference import TOL

    _fix_plugin(monkeypatch)
    _configure(physics)
    core = Simulator(1, MAX_AC, dt=1.0, geo=physics.geo)
    core.set_conflict_resolution(0, AsasConfig("CSTATEBASED", True, method="SSD"))
    for sim in (core, physics):
        sim.create(0, 0, 52.0, 4.0, 45.0, 200 * 100 * FT, 250 * KTS)
        sim.creconfs(0, 0, 1, 90.0, 1.0, 120.0)
        sim.creconfs(0, 0, 2, 200.0, 0.0, 150.0, None, None, 200 * KTS)
        sim.creconfs(0, 0, 3, 300.0, 2.0, 100.0)
        sim.create(0, 4, 52.03, 3.95, 50.0, 200 * 100 * FT + 300.0, 240 * KTS)
    slots = np.flatnonzero(physics.active[0])
    turned = 0.0
    for t in range(200):
        core.step()
        physics.step()
        for name in ("lat", "lon", "alt", "tas", "gs", "vs", "trk"):
            ours, theirs = getattr(core, name)[0, slots], getattr(physics, name)[0, slots]
            err = np.abs(ours - theirs)
            if name == "trk":
                err = np.minimum(err, 360.0 - err)
            assert np.all(err <= TOL[name]), f"t={t + 1} {name}: {ours} vs {theirs}"
        turned = max(turned, abs((core.trk[0, 0] - 45.0 + 180.0) % 360.0 - 180.0))
    assert turned > 1.0  # SSD did act
