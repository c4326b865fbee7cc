"""Conflict resolution with the Solution Space Diagram (SSD), BlueSky 1.1.1's ``RESO SSD`` plugin, batched [docs/baselines.md §6].

The SSD method of BlueSky's ``plugins/asas/ssd.py`` (Hermes, Mulder, van Paassen et al.) draws
each aircraft in conflict a velocity-space diagram: the ring of ground speeds between its
envelope limits ``vmin`` and ``vmax``, minus the velocity obstacle (VO) of every other aircraft
within ADS-B range (65 NM). A VO is the triangle of own velocities that lead into the other
aircraft's protected zone (enlarged by ``resofach``), its apex at the other aircraft's velocity;
a pair already in loss of separation gets a "dart tip" pointing away from the other aircraft
instead. What is left of the ring is the attainable, conflict-free set (ARV); the resolution is
the point of the ARV closest to the aircraft's current ground velocity (BlueSky's default,
priority code ``RS1``, "shortest way out").

:func:`ssd` follows the plugin's ``resolve``, ``constructSSD`` and ``calculate_resolution``
formula by formula and in the same order: the polygons are clipped with pyclipper (the ``ssd``
extra), with the same paths added in the same order, and the arithmetic is numpy's, as in the
plugin, so that the results equal the plugin's to the bit. Its quirks are kept, because they are
what ``RESO SSD`` flies:

* the resolution velocity is stored in float32 (the plugin's ``asase``/``asasn`` arrays), so the
  track and ground speed of a resolved aircraft are float32 values;
* the resolution is the closest point on the *edges* of the attainable set, also when the current
  velocity is conflict-free already or outside the ring (an aircraft in conflict alone within
  ADS-B range moves to the nearest circle of the ring);
* the track of a resolved aircraft is ``atan2`` of that velocity, in (-180, 180] deg, and an
  aircraft without a resolution gets its *heading* back (not its track) and its ground speed;
* the pair (i, j), i < j, is placed by the WGS-84 bearing and distance from i to j; aircraft j
  sees the mirror image (bearing + 180 deg), not the bearing from j to i;
* the ring is the CAS envelope ``[vmin, vmax]`` taken as ground speeds, and the resolution speed
  is capped to it (as MVP);
* an obstacle triangle reaches ``2 vmax / cos(alpha)`` from its apex (the other aircraft's
  velocity): an intruder whose ground speed exceeds the ownship's ``vmax`` (high altitudes) may
  leave part of the ring uncovered that still leads into its zone;
* the vertical speed and altitude are the aircraft's own (the plugin resolves horizontally only).

BlueSky 1.1.1's plugin does not run: it crashes on its first resolution. Two one-line fixes make
it run, and :func:`ssd` computes what the fixed plugin computes (the BlueSky parity tests apply
the same fixes to BlueSky as monkeypatches):

1. ``geo.qdrdist_matrix`` where the pairwise ``geo.qdrdist`` is meant: the plugin passes the two
   aircraft of every pair as two vectors and expects one bearing and distance per pair;
   BlueSky's compiled ``qdrdist_matrix`` (the default, ``prefer_compiled``) returns the matrix of
   every first against every second aircraft, and the reshape to one value per pair fails
   ("cannot reshape array of size 9 into shape (3,)"). Fix: ``geo.qdrdist``, one value per pair.
2. ``hsep = conf.rpz``: the plugin was written when the protected-zone radius was one number;
   in 1.1.1 ``conf.rpz`` is an array with one radius per aircraft, and the comparison with the
   per-pair distances fails ("operands could not be broadcast together with shapes (6,) (4,)";
   with as many pairs as aircraft, the masked assignment of the radii fails instead). Fix: the
   default radius ``conf.rpz_def`` (``ZONER``), the number the name held before; per-aircraft
   zones (``ZONER r acid``) are not used by SSD.

Priority rules: BlueSky's default (``PRIORULES`` never given: an empty priority code) and ``RS1``
(shortest way out, the same resolution) are supported; the other codes (RS2..RS9: turning
direction, heading or speed first, rules of the air, sequential) are refused with an error.

Aircraft are taken in slot order, which is BlueSky's traffic order for the airspaces the package
builds (pairs, the mirrored VOs of pairs and the order of the clipping paths depend on it).
:func:`ssd` is the plugin's ``resolve``; :class:`SSDResolver` flies it as ``RESO SSD`` under the
bookkeeping every method shares (when the values are renewed, BlueSky's ``resumenav``:
:class:`~bluesky_gym.core.resolution.ConflictResolver`).
"""

from __future__ import annotations

from types import ModuleType
from typing import Any, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from bluesky_gym.core import geo
from bluesky_gym.core.conflicts import PZ_RADIUS, ConflictPairs, Conflicts, float_array
from bluesky_gym.core.extras import missing_extra
from bluesky_gym.core.resolution import NO_VERTICAL_SOLUTION, ConflictResolver, Resolution, ResolutionSettings, ResolutionState, TypedResolutionState
from bluesky_gym.core.units import NM

Array = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

N_ANGLE = 180  # -, points on the velocity circles (the plugin's discretisation)
ALPHA_MAX = 0.4999 * np.pi  # rad, largest half-angle of a velocity obstacle
BETA_LOS = np.pi / 4  # rad, smallest diversion angle in loss of separation
ADSB_RANGE = 65.0 * NM  # m, aircraft farther than this are not in the diagram
DART_TIP_LEG = 1.1  # -, dart-tip leg length in units of vmax / cos(beta)
MIN_EDGE2 = 1e-8  # (m/s)^2, edges of the diagram shorter than this count as points

#: Priority codes (``PRIORULES ON code``) that :func:`ssd` resolves: BlueSky's default (no code) and RS1.
PRIORITY_CODES = ("", "RS1")
#: Every priority code of BlueSky's SSD plugin.
BLUESKY_PRIORITY_CODES = ("RS1", "RS2", "RS3", "RS4", "RS5", "RS6", "RS7", "RS8", "RS9")


def require_pyclipper() -> ModuleType:
    """Import pyclipper, or raise :class:`~bluesky_gym.core.extras.MissingDependencyError` naming the ``ssd`` extra."""
    try:
        import pyclipper
    except ImportError as exc:
        raise missing_extra("SSD conflict resolution needs pyclipper", "ssd") from exc
    module: ModuleType = pyclipper
    return module


def check_priority(priocode: str) -> str:
    """``priocode`` if :func:`ssd` resolves with it; otherwise a one-line :class:`ValueError`.

    Raises:
        ValueError: An unknown code, or one of the plugin's codes that is not supported here.
    """
    if priocode in PRIORITY_CODES:
        return priocode
    if priocode in BLUESKY_PRIORITY_CODES:
        raise ValueError(f"SSD priority code {priocode!r} is not supported; SSD resolves with BlueSky's default rule (RS1, shortest way out)")
    raise ValueError(f"SSD priority code {priocode!r} not understood; BlueSky's are {', '.join(BLUESKY_PRIORITY_CODES)} (supported: RS1)")


class SSDState(ResolutionState, Protocol):
    """The per-aircraft state SSD reads: MVP's (:class:`~bluesky_gym.core.resolution.ResolutionState`) and the heading."""

    hdg: Array  # deg


def pair_indices(n: int) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """The pairs ``(i, j)``, ``i < j``, of ``n`` aircraft in the plugin's order (``qdrdist_matrix_indices``): by ``i``, then ``j``."""
    ind1, ind2 = np.triu_indices(n, 1)
    return ind1.astype(np.int64), ind2.astype(np.int64)


def _circle() -> Array:
    """Unit circle, clockwise from north, (N_ANGLE, 2) (east, north): the plugin's ``xyc``."""
    angles = np.arange(0, 2 * np.pi, 2 * np.pi / N_ANGLE)
    return np.transpose(np.reshape(np.concatenate((np.sin(angles), np.cos(angles))), (2, N_ANGLE)))


def _attainable(
    pyclipper: ModuleType,
    i: int,
    vmin: float,
    vmax: float,
    xyc: Array,
    ind1: NDArray[np.int64],
    ind2: NDArray[np.int64],
    qdr: Array,
    dist: Array,
    hsepm: float,
    x1: Array,
    x2: Array,
    y1: Array,
    y2: Array,
    gseast: Array,
    gsnorth: Array,
) -> list[Any]:
    """Aircraft ``i``'s attainable conflict-free velocities (the plugin's ``ARV_calc`` for RS1): a list of polygons of [east, north] points."""
    n = gseast.shape[0]
    beta = np.pi / 4 + BETA_LOS / 2
    # Outer circle counter-clockwise, inner circle clockwise, as pyclipper wants them.
    circle_tup = (tuple(map(tuple, np.flipud(xyc * vmax))), tuple(map(tuple, xyc * vmin)))
    circle_lst = [list(map(list, np.flipud(xyc * vmax))), list(map(list, xyc * vmin))]
    ind = np.where(np.logical_or(ind1 == i, ind2 == i))[0]
    if len(ind) == 0:  # alone in the airspace
        return circle_lst
    i_other = np.delete(np.arange(0, n), i)
    ac_adsb = np.where(dist[ind] < ADSB_RANGE)[0]
    ind = ind[ac_adsb]
    i_other = i_other[ac_adsb]
    # The VO of the pair (j, i), j < i, is the mirror image of that of (i, j).
    fix = np.ones(np.shape(i_other))
    fix[i_other < i] = -1
    x = np.concatenate((gseast[i_other], x1[ind] * fix + gseast[i_other], x2[ind] * fix + gseast[i_other]))
    y = np.concatenate((gsnorth[i_other], y1[ind] * fix + gsnorth[i_other], y2[ind] * fix + gsnorth[i_other]))
    x = np.transpose(x.reshape(3, np.shape(i_other)[0]))
    y = np.transpose(y.reshape(3, np.shape(i_other)[0]))
    xy = np.dstack((x, y))
    pc = pyclipper.Pyclipper()
    pc.AddPaths(pyclipper.scale_to_clipper(circle_tup), pyclipper.PT_SUBJECT, True)
    for j in range(np.shape(i_other)[0]):
        if dist[ind[j]] > hsepm:
            vo = pyclipper.scale_to_clipper(tuple(map(tuple, xy[j, :, :])))
        else:  # loss of separation: a dart tip pointing away from the other aircraft
            qdr_los = qdr[ind[j]] + np.pi if i_other[j] < i else qdr[ind[j]]
            leg = DART_TIP_LEG * vmax / np.cos(beta) * np.array([1, 1, 1, 0])
            angles_los = np.array([qdr_los + 2 * beta, qdr_los, qdr_los - 2 * beta, 0.0])
            xy_los = np.vstack((leg * np.sin(angles_los), leg * np.cos(angles_los))).T
            vo = pyclipper.scale_to_clipper(tuple(map(tuple, xy_los)))
        pc.AddPath(vo, pyclipper.PT_CLIP, True)
    frv = pyclipper.scale_from_clipper(pc.Execute(pyclipper.CT_INTERSECTION, pyclipper.PFT_NONZERO, pyclipper.PFT_NONZERO))
    arv = pyclipper.scale_from_clipper(pc.Execute(pyclipper.CT_DIFFERENCE, pyclipper.PFT_NONZERO, pyclipper.PFT_NONZERO))
    if len(arv) == 0:  # no conflict-free velocity
        return []
    if len(frv) == 0:  # no obstacle inside the ring
        return circle_lst
    return list(arv)


def _closest(arv: list[Any], ve: float, vn: float) -> tuple[float, float]:
    """The point of the polygons ``arv`` closest to the velocity (ve, vn) (the plugin's ``calculate_resolution``, RS1)."""
    p_list = []
    q_list = []
    for j in range(len(arv)):
        p_list.append(np.array(arv[j]))
        q_list.append(np.diff(np.vstack((p_list[j], p_list[j][0])), axis=0))
    p = np.concatenate(p_list)
    q = np.concatenate(q_list)
    l2 = np.sum(q**2, axis=1)
    same = l2 < MIN_EDGE2
    l2[same] = 1.0
    t = np.sum((np.array([ve, vn]) - p) * q, axis=1) / l2
    t = np.clip(t, 0.0, 1.0)
    t[same] = 0.0
    x1 = p[:, 0] + t * q[:, 0]
    y1 = p[:, 1] + t * q[:, 1]
    d2 = (x1 - ve) ** 2 + (y1 - vn) ** 2
    order = np.argsort(d2)
    return x1[order][0], y1[order][0]


def ssd_airspace(
    in_conflict: BoolArray,
    lat: Array,
    lon: Array,
    hdg: Array,
    gs: Array,
    gseast: Array,
    gsnorth: Array,
    vmin: Array,
    vmax: Array,
    hsepm: float,
    python_geo: bool = False,
) -> tuple[Array, Array, BoolArray, NDArray[np.float32], NDArray[np.float32]]:
    """SSD of the aircraft of one airspace, in BlueSky's traffic order (the plugin's ``resolve`` for RS1).

    Args:
        in_conflict: (n,) aircraft in conflict (BlueSky's ``cd.inconf``).
        lat: (n,) latitude [deg].
        lon: (n,) longitude [deg].
        hdg: (n,) heading [deg].
        gs: (n,) ground speed [m/s].
        gseast: (n,) ground speed east [m/s].
        gsnorth: (n,) ground speed north [m/s].
        vmin: (n,) lower speed limit [m/s] (the CAS envelope, used as ground speed).
        vmax: (n,) upper speed limit [m/s].
        hsepm: Resolution zone radius [m]: protected-zone radius x ``resofach``.
        python_geo: Bearings and distances with BlueSky's Python ``geo.qdrdist`` instead of its compiled one.

    Returns:
        Track [deg] and ground speed [m/s] (before the envelope cap), whether the aircraft takes
        the SSD velocity, and that velocity east and north [m/s] (float32, zero where none).
    """
    pyclipper = require_pyclipper()
    n = lat.shape[0]
    asase = np.zeros(n, dtype=np.float32)
    asasn = np.zeros(n, dtype=np.float32)
    if n > 0 and np.any(in_conflict):
        ind1, ind2 = pair_indices(n)
        qdr_deg, dist_nm = (geo.qdrdist_python if python_geo else geo.qdrdist)(lat[ind1], lon[ind1], lat[ind2], lon[ind2])
        qdr = np.deg2rad(np.asarray(qdr_deg, dtype=np.float64))
        dist = np.asarray(dist_nm, dtype=np.float64) * NM
        dist[dist < hsepm] = hsepm  # in loss of separation the VO is drawn as if on the zone's edge
        alpha = np.arcsin(hsepm / dist)
        alpha[alpha > ALPHA_MAX] = ALPHA_MAX
        sinqdr = np.sin(qdr)
        cosqdr = np.cos(qdr)
        tanalpha = np.tan(alpha)
        cosqdrtanalpha = cosqdr * tanalpha
        sinqdrtanalpha = sinqdr * tanalpha
        xyc = _circle()
        for i in range(n):
            if not in_conflict[i]:
                continue
            lo, hi = vmin[i], vmax[i]
            if lo == hi == 0:  # no envelope yet: no diagram (BlueSky's first step)
                continue
            # Vertices of the VOs in relative velocity space (the plugin's appendix).
            x1 = (sinqdr + cosqdrtanalpha) * 2 * hi
            x2 = (sinqdr - cosqdrtanalpha) * 2 * hi
            y1 = (cosqdr - sinqdrtanalpha) * 2 * hi
            y2 = (cosqdr + sinqdrtanalpha) * 2 * hi
            arv = _attainable(pyclipper, i, lo, hi, xyc, ind1, ind2, qdr, dist, hsepm, x1, x2, y1, y2, gseast, gsnorth)
            if len(arv) > 0:
                asase[i], asasn[i] = _closest(arv, gseast[i], gsnorth[i])
    new_trk = np.arctan2(asase, asasn) * 180 / np.pi
    new_gs = np.sqrt(asase**2 + asasn**2)
    command = np.logical_and(in_conflict, new_gs > 0)
    trk = np.copy(hdg)
    out_gs = np.copy(gs)
    trk[command] = new_trk[command]
    out_gs[command] = new_gs[command]
    return trk, out_gs, command, asase, asasn


def ssd(
    state: SSDState,
    conflicts: Conflicts | ConflictPairs,
    settings: ResolutionSettings | None = None,
    *,
    rpz: float = PZ_RADIUS,
    priocode: str = "",
    python_geo: bool = False,
) -> Resolution:
    """SSD's resolution of every aircraft from the conflict picture (BlueSky's SSD plugin ``resolve``, fixed as the module says).

    Args:
        state: The aircraft state (a :class:`~bluesky_gym.core.physics.Physics`, or anything with
            its arrays), read as it was when ``conflicts`` was detected.
        conflicts: :func:`bluesky_gym.core.conflicts.detect` of that state, or its pairs
            (:func:`~bluesky_gym.core.conflicts.detect_pairs`); SSD reads which aircraft are in
            conflict, and both give the same resolution.
        settings: Resolution settings; SSD reads ``resofach`` (``RFACH``) only.
        rpz: Protected-zone radius [m] (``ZONER``).
        priocode: Priority code (:data:`PRIORITY_CODES`).
        python_geo: Bearings and distances with BlueSky's Python geo functions (see
            :class:`~bluesky_gym.core.resolution.MVPResolver`).

    Returns:
        The resolution of every active aircraft (NaN in empty slots): ``trk`` in (-180, 180] for
        resolved aircraft (the heading otherwise), ``gs`` capped to ``[vmin, vmax]``, the own
        ``vs`` and selected altitude ``alt``; ``dv`` is the velocity change east and north taken
        (0 up, 0 where none), ``tsolv`` is :data:`~bluesky_gym.core.resolution.NO_VERTICAL_SOLUTION`.

    Raises:
        ValueError: An unsupported priority code, or conflicts of another shape.
        MissingDependencyError: pyclipper is not installed (the ``ssd`` extra).
    """
    check_priority(priocode)
    s = settings or ResolutionSettings()
    active = np.ascontiguousarray(state.active, dtype=np.bool_)
    shape = active.shape
    if isinstance(conflicts, ConflictPairs):
        if conflicts.n_aircraft != shape[1]:
            raise ValueError(f"conflicts are of airspaces of {conflicts.n_aircraft} aircraft, the state has {shape[1]}")
        listed = np.zeros(shape[0] * shape[1], np.bool_)
        listed[conflicts.flat_own] = True
        in_conflict = listed.reshape(shape) & active
    else:
        if conflicts.conflict.shape != shape + (shape[1],):
            raise ValueError(f"conflicts are shaped {conflicts.conflict.shape}, the state needs {shape + (shape[1],)}")
        in_conflict = np.asarray(conflicts.in_conflict, dtype=np.bool_) & active
    names = ("lat", "lon", "hdg", "gs", "gseast", "gsnorth", "vmin", "vmax", "vs", "selalt")
    x = {name: float_array(getattr(state, name), shape) for name in names}
    trk, gs, vs, alt = (np.full(shape, np.nan) for _ in range(4))
    dv = np.full((*shape, 3), np.nan)
    tsolv = np.full(shape, np.nan)
    hsepm = float(rpz) * s.resofach
    for e in range(shape[0]):
        slots = np.flatnonzero(active[e])
        if slots.size == 0:
            continue
        a = {name: x[name][e, slots] for name in names}
        t, g, command, ve, vn = ssd_airspace(
            in_conflict[e, slots], a["lat"], a["lon"], a["hdg"], a["gs"], a["gseast"], a["gsnorth"], a["vmin"], a["vmax"], hsepm, python_geo
        )
        trk[e, slots] = t
        gs[e, slots] = np.maximum(a["vmin"], np.minimum(a["vmax"], g))
        vs[e, slots] = a["vs"]
        alt[e, slots] = a["selalt"]
        dv[e, slots, 0] = np.where(command, ve.astype(np.float64) - a["gseast"], 0.0)
        dv[e, slots, 1] = np.where(command, vn.astype(np.float64) - a["gsnorth"], 0.0)
        dv[e, slots, 2] = 0.0
        tsolv[e, slots] = NO_VERTICAL_SOLUTION
    return Resolution(trk, gs, vs, alt, dv, tsolv, in_conflict)


class SSDResolver(ConflictResolver):
    """``RESO SSD``: :func:`ssd` under :class:`~bluesky_gym.core.resolution.ConflictResolver`'s bookkeeping.

    SSD reads ``resofach`` and the zone radius; it ignores the RMETH switches, ``resofacv``, the
    zone height and the vertical-speed envelope (it resolves horizontally). Its priority code is
    :attr:`priocode` (BlueSky's default, RS1). Both pair searches give the same resolutions (SSD
    needs only which aircraft are in conflict); the diagram of an aircraft still takes every other
    aircraft of its airspace within ADS-B range, as the plugin does.
    """

    name = "SSD"
    #: The priority code (``PRIORULES ON code``), one of :data:`PRIORITY_CODES`.
    priocode = ""

    def resolve(self, state: TypedResolutionState, conflicts: Conflicts, vsmin: ArrayLike, vsmax: ArrayLike) -> Resolution:
        """:func:`ssd` with this resolver's zone, ``resofach`` and geo functions."""
        return ssd(state, conflicts, self.settings, rpz=self.rpz, priocode=self.priocode, python_geo=self.python_geo)  # type: ignore[arg-type]

    def resolve_pairs(self, state: TypedResolutionState, conflicts: ConflictPairs, vsmin: ArrayLike, vsmax: ArrayLike) -> Resolution:
        """:func:`ssd` of the conflicts as pairs (the same results)."""
        return ssd(state, conflicts, self.settings, rpz=self.rpz, priocode=self.priocode, python_geo=self.python_geo)  # type: ignore[arg-type]


__all__ = ["PRIORITY_CODES", "SSDResolver", "SSDState", "check_priority", "pair_indices", "require_pyclipper", "ssd", "ssd_airspace"]
