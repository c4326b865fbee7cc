"""Conflict resolution by Eby's method: BlueSky 1.1.1's ``EBY`` plugin (``RESO EBY``), batched.

Eby's method (``bluesky/plugins/asas/eby.py``) resolves each conflict pair (ownship i, intruder j)
as if both flew straight on: it finds the time ``t*`` at which the intrusion into the (enlarged)
protected zone, divided by the time left, is largest (the roots of a quadratic), and asks for
the velocity change that pushes the relative position at ``t*`` out to the zone's rim in that
time. Unlike MVP it works with the full 3-D relative position and the *true-airspeed* velocity
(track and TAS), and it is symmetric: each pair's change is subtracted from the ownship's
velocity and added to the intruder's (BlueSky lists every conflict twice, (i, j) and (j, i), so
each aircraft gets both halves). The kernels follow the plugin step by step, quirks included:

* a negative discriminant is set to 0; ``t*`` is the smaller of the two roots' magnitudes;
* an exact collision course (miss distance at ``t*`` under 10 m) is turned sideways by 10 m,
  perpendicular to the relative velocity;
* every aircraft (in conflict or not) gets the track of its new velocity, and as its speed the
  *equivalent* airspeed of the new horizontal speed (``vtas2eas``), capped to the CAS envelope
  ``[vmin, vmax]``; the autopilot then flies that value as a TAS (as BlueSky's ``APorASAS`` does);
* the vertical speed is the new vertical velocity (signed), and the altitude ``sign(vs) * 1e5``
  m (``0`` for a level resolution).

**The fix BlueSky 1.1.1 needs.** The plugin crashes on its first resolution (``ValueError: The
truth value of an array with more than one element is ambiguous``): it takes the zone radius as
``conf.rpz * resofach``, but since BlueSky 1.0 ``conf.rpz`` is an array with one radius per
aircraft, so every quantity after it becomes an array. The smallest fix, made here and applied
to BlueSky as a monkeypatch in the parity tests, uses the pair's radius as MVP does:
``max(conf.rpz[[idx1, idx2]]) * resofach``. With the one protected zone of the core, that is
``rpz * resofach``.

Not modelled (as for MVP): ``NORESO``/``RESOOFF`` lists and priority rules (the plugin ignores
them), per-aircraft zones.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from bluesky_gym.core.atmosphere import isa
from bluesky_gym.core.conflicts import PZ_RADIUS, ConflictPairs, Conflicts, float_array
from bluesky_gym.core.jit import fma, jit
from bluesky_gym.core.resolution import (
    ConflictResolver,
    Resolution,
    ResolutionSettings,
    ResolutionState,
    TypedResolutionState,
)
from bluesky_gym.core.scalar import RAD, divide, maximum, minimum, mod, sign
from bluesky_gym.core.units import RHO0

EXACT_COURSE = 10.0  # m: a miss distance at t* under this is an exact collision course
EBY_ALTITUDE = 1e5  # m: the altitude Eby commands, signed by its vertical speed


@jit
def dot3(a0: float, a1: float, a2: float, b0: float, b1: float, b2: float) -> float:
    """The ``np.dot`` of two 3-vectors (and ``np.linalg.norm``'s square) as numpy's BLAS ``ddot`` computes it: fused multiply-adds from 0."""
    return fma(a2, b2, fma(a1, b1, fma(a0, b0, 0.0)))


@jit
def eby_pair(
    qdr_deg: float,
    dist: float,
    dalt: float,
    trk_i: float,
    tas_i: float,
    vs_i: float,
    trk_j: float,
    tas_j: float,
    vs_j: float,
    rpz_m: float,
) -> tuple[float, float, float]:
    """Eby's velocity change for one conflict pair (BlueSky ``Eby.Eby_straight``).

    Args:
        qdr_deg: Bearing ownship -> intruder [deg].
        dist: Horizontal distance [m].
        dalt: Intruder altitude minus ownship altitude [m].
        trk_i: Ownship track [deg] (``tas_i``, ``vs_i``: its true airspeed and vertical speed).
        tas_i: Ownship true airspeed [m/s].
        vs_i: Ownship vertical speed [m/s].
        trk_j: Intruder track [deg].
        tas_j: Intruder true airspeed [m/s].
        vs_j: Intruder vertical speed [m/s].
        rpz_m: Resolution zone radius (protected zone x resofach) [m].

    Returns:
        (east, north, up) [m/s]: subtracted from the ownship's velocity, added to the intruder's.
    """
    q = qdr_deg * RAD
    d0 = math.sin(q) * dist
    d1 = math.cos(q) * dist
    d2 = dalt
    t1 = trk_i * RAD
    t2 = trk_j * RAD
    v0 = math.sin(t2) * tas_j - math.sin(t1) * tas_i
    v1 = math.cos(t2) * tas_j - math.cos(t1) * tas_i
    v2 = vs_j - vs_i
    r2 = rpz_m * rpz_m
    dd = dot3(d0, d1, d2, d0, d1, d2)
    vv = dot3(v0, v1, v2, v0, v1, v2)
    dv = dot3(d0, d1, d2, v0, v1, v2)
    a = r2 * vv - dv * dv
    b = 2.0 * dv * (r2 - dd)
    c = r2 * dd - dd * dd
    discrim = b * b - 4.0 * a * c
    if discrim < 0.0:
        discrim = 0.0
    root = math.sqrt(discrim)
    time1 = abs(divide(-b + root, 2.0 * a))
    time2 = abs(divide(-b - root, 2.0 * a))
    tstar = time2 if time2 < time1 else time1  # Python's min(time1, time2)
    s0 = d0 + v0 * tstar
    s1 = d1 + v1 * tstar
    s2 = d2 + v2 * tstar
    dstarabs = math.sqrt(dot3(s0, s1, s2, s0, s1, s2))
    dif = EXACT_COURSE - dstarabs
    if dif > 0.0:  # exact collision course: move the miss point sideways
        nperp = math.sqrt(dot3(-v1, v0, 0.0, -v1, v0, 0.0))
        s0 = s0 + divide(dif * -v1, nperp)
        s1 = s1 + divide(dif * v0, nperp)
        s2 = s2 + divide(dif * 0.0, nperp)
        dstarabs = math.sqrt(dot3(s0, s1, s2, s0, s1, s2))
    intrusion = rpz_m - dstarabs
    den = dstarabs * tstar
    return divide(intrusion * s0, den), divide(intrusion * s1, den), divide(intrusion * s2, den)


@jit
def eby_loop(own, intruder, qdr, dist, active, alt, trk, tas, vs, vmin, vmax, rpz_m, dv, out_trk, out_spd, out_vs, out_alt):  # type: ignore[no-untyped-def]
    """Eby's resolution of every aircraft from the listed conflict pairs (flat aircraft indices, in BlueSky's pair order).

    ``dv`` (aircraft, 3) starts at zero and gets the summed changes; the outputs get track [deg],
    speed (EAS, capped) [m/s], vertical speed [m/s] and altitude [m] of every active aircraft.
    """
    for p in range(own.shape[0]):
        i = own[p]
        j = intruder[p]
        e0, e1, e2 = eby_pair(qdr[p], dist[p], alt[j] - alt[i], trk[i], tas[i], vs[i], trk[j], tas[j], vs[j], rpz_m)
        dv[i, 0] = dv[i, 0] - e0
        dv[i, 1] = dv[i, 1] - e1
        dv[i, 2] = dv[i, 2] - e2
        dv[j, 0] = dv[j, 0] + e0
        dv[j, 1] = dv[j, 1] + e1
        dv[j, 2] = dv[j, 2] + e2
    for i in range(active.shape[0]):
        if not active[i]:
            continue
        t = trk[i] * RAD
        ve = dv[i, 0] + math.sin(t) * tas[i]
        vn = dv[i, 1] + math.cos(t) * tas[i]
        vz = dv[i, 2] + vs[i]
        out_trk[i] = mod(math.atan2(ve, vn) * 180.0 / math.pi, 360.0)
        gs = math.sqrt(ve * ve + vn * vn)
        eas = gs * math.sqrt(isa(alt[i])[1] / RHO0)
        out_spd[i] = maximum(vmin[i], minimum(vmax[i], eas))
        out_vs[i] = vz
        out_alt[i] = sign(vz) * EBY_ALTITUDE


def eby_pairs(state: ResolutionState, conflicts: ConflictPairs, settings: ResolutionSettings | None = None, *, rpz: float = PZ_RADIUS) -> Resolution:
    """Eby's resolution of every aircraft (BlueSky ``Eby.resolve``, fixed) from the conflicts as pairs.

    Args:
        state: The aircraft state (a :class:`~bluesky_gym.core.physics.Physics`, or anything with
            its arrays), as it was when ``conflicts`` was detected.
        conflicts: The conflict pairs (:func:`~bluesky_gym.core.conflicts.detect_pairs`, or
            :meth:`~bluesky_gym.core.conflicts.ConflictPairs.from_dense` of :func:`~bluesky_gym.core.conflicts.detect`).
        settings: ``resofach`` is the horizontal resolution factor (Eby has no other setting).
        rpz: Protected-zone radius [m].

    Returns:
        Track [deg], speed (EAS, capped; see the module docstring) [m/s], vertical speed [m/s],
        altitude [m] and summed velocity change ``dv`` of every active aircraft; ``tsolv`` is NaN.
    """
    s = settings or ResolutionSettings()
    active = np.ascontiguousarray(state.active, dtype=np.bool_)
    shape = active.shape
    if conflicts.n_aircraft != shape[1]:
        raise ValueError(f"conflicts are of airspaces of {conflicts.n_aircraft} aircraft, the state has {shape[1]}")
    n = shape[0] * shape[1]
    alt, trk, tas, vs, vmin, vmax = (float_array(x, shape).reshape(-1) for x in (state.alt, state.trk, state.tas, state.vs, state.vmin, state.vmax))
    own = np.ascontiguousarray(conflicts.flat_own, dtype=np.int64)
    intruder = np.ascontiguousarray(conflicts.env * shape[1] + conflicts.intruder, dtype=np.int64)
    qdr, dist = (np.ascontiguousarray(x, dtype=np.float64) for x in (conflicts.qdr, conflicts.dist))
    dv = np.zeros((n, 3))
    out_trk, out_spd, out_vs, out_alt = (np.full(n, np.nan) for _ in range(4))
    flat_active = active.reshape(-1)
    eby_loop(own, intruder, qdr, dist, flat_active, alt, trk, tas, vs, vmin, vmax, float(rpz) * s.resofach, dv, out_trk, out_spd, out_vs, out_alt)
    dv[~active.reshape(-1)] = np.nan
    in_conflict = np.zeros(n, np.bool_)
    in_conflict[own] = True
    return Resolution(
        out_trk.reshape(shape),
        out_spd.reshape(shape),
        out_vs.reshape(shape),
        out_alt.reshape(shape),
        dv.reshape(*shape, 3),
        np.full(shape, np.nan),
        in_conflict.reshape(shape) & active,
    )


def eby(state: ResolutionState, conflicts: Conflicts, settings: ResolutionSettings | None = None, *, rpz: float = PZ_RADIUS) -> Resolution:
    """:func:`eby_pairs` from the conflict picture of every pair (:func:`~bluesky_gym.core.conflicts.detect`)."""
    return eby_pairs(state, ConflictPairs.from_dense(conflicts), settings, rpz=rpz)


class EbyResolver(ConflictResolver):
    """``RESO EBY``: :func:`eby` under :class:`~bluesky_gym.core.resolution.ConflictResolver`'s bookkeeping.

    Eby ignores the RMETH switches, ``resofacv`` and the vertical-speed envelope.
    """

    name = "EBY"

    def resolve(self, state: TypedResolutionState, conflicts: Conflicts, vsmin: ArrayLike, vsmax: ArrayLike) -> Resolution:
        """:func:`eby` with this resolver's zone and ``resofach``."""
        return eby(state, conflicts, self.settings, rpz=self.rpz)

    def resolve_pairs(self, state: TypedResolutionState, conflicts: ConflictPairs, vsmin: ArrayLike, vsmax: ArrayLike) -> Resolution:
        """:func:`eby_pairs` with this resolver's zone and ``resofach``."""
        return eby_pairs(state, conflicts, self.settings, rpz=self.rpz)


__all__ = ["EbyResolver", "eby", "eby_pair", "eby_pairs"]
