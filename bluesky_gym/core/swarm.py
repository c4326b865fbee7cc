"""Swarm conflict resolution: BlueSky 1.1.1's ``SWARM`` plugin (``RESO SWARM``), batched over airspaces.

Swarm (``bluesky/plugins/asas/swarm.py``) blends three velocities for every aircraft, weighted
10 : 3 : 1 (:data:`SWARM_WEIGHTS`):

1. *collision avoidance*: MVP's resolution (:func:`~bluesky_gym.core.resolution.mvp`, with the
   RMETH switches and factors, which Swarm inherits) for an aircraft in conflict, its autopilot
   track, selected speed and selected vertical speed otherwise;
2. *velocity alignment*: the mean CAS, vertical speed and track difference of its swarm;
3. *flock centering*: towards the mean position (and altitude) of its swarm, at its own CAS.

An aircraft's swarm is itself and every aircraft within :data:`SWARM_RADIUS` horizontally and
:data:`SWARM_HEIGHT` vertically that flies within 90 deg of its track. The blended track (not
wrapped to [0, 360)), CAS capped to ``[vmin, vmax]`` (flown as a TAS, as BlueSky's autopilot
takes it), vertical speed, and the altitude ``sign(vs) * 1e5`` m are the resolution; after each
resolution *every* aircraft of the airspace follows it (the plugin's ``active.fill(True)``),
until ``resumenav`` ends its own conflict pairs. Like the plugin, the code is numpy (the means
are numpy's weighted averages).

**The fixes BlueSky 1.1.1 needs.** The plugin was written for BlueSky's older ASAS and crashes on
its first resolution (``AttributeError: 'StateBased' object has no attribute 'rpzswarm'``; with
more aircraft than conflict pairs, first a broadcast error). The smallest changes that make it
run, made here and applied to BlueSky as a monkeypatch in the parity tests:

* the bearings and distances of *all* aircraft pairs, which the old ASAS kept as matrices
  (``conf.qdr``, ``conf.dist``; 1.1.1 keeps them per conflict pair only), are computed as the
  STATEBASED detection computes them: ``geo.kwikqdrdist_matrix`` of all positions, the distance
  in m with 1e9 on the diagonal (:func:`~bluesky_gym.core.geo.kwikqdrdist_matrix`);
* ``conf.rpzswarm`` becomes ``self.rpzswarm`` and ``asas.Swarmweights`` ``self.Swarmweights``
  (the plugin's own attributes); the undefined ``asas.u``/``asas.v`` become the aircraft's
  ground velocity ``gseast``/``gsnorth`` (what the old ASAS held there);
* the result is returned as ``(track, speed, vs, alt)``, as 1.1.1's ``ConflictResolution.update``
  expects, instead of being written to the old ``asas`` object.

Not modelled: priority rules, ``NORESO``/``RESOOFF`` lists (as for MVP), ``pair_search="grid"``
(the swarms need every pair).
"""

from __future__ import annotations

from typing import Protocol, cast

import numpy as np
from numpy.typing import ArrayLike

from bluesky_gym.core import geo
from bluesky_gym.core.conflicts import SELF_PAIR, Conflicts, float_array
from bluesky_gym.core.resolution import Array, MVPResolver, Resolution, ResolutionState, TypedResolutionState
from bluesky_gym.core.units import FT, NM

SWARM_RADIUS = 7.5 * NM  # m, horizontal reach of an aircraft's swarm (the plugin's rpzswarm)
SWARM_HEIGHT = 1500.0 * FT  # m, vertical reach (dhswarm)
SWARM_TRACK_DIFF = 90.0  # deg: swarm members fly within this of the aircraft's track
SWARM_WEIGHTS = (10.0, 3.0, 1.0)  # -, collision avoidance : velocity alignment : flock centering
SWARM_ALTITUDE = 1e5  # m: the altitude Swarm commands, signed by its vertical speed
FLOCK_VELOCITY_SCALE = 100.0  # s: the aircraft's own ground velocity / this joins its flock position


class SwarmState(ResolutionState, Protocol):
    """The state Swarm reads: :class:`~bluesky_gym.core.resolution.ResolutionState` and the autopilot's and pilot's selections."""

    cas: Array  # m/s
    ap_trk: Array  # deg, autopilot track
    selspd: Array  # m/s CAS, or Mach (selected speed, used as it is, as the plugin does)
    selvs: Array  # m/s, selected vertical speed


def swarm(state: SwarmState, conflicts: Conflicts, avoidance: Resolution, *, python_geo: bool = False) -> Resolution:
    """Swarm's resolution of every aircraft (BlueSky ``Swarm.resolve``, fixed; see the module docstring).

    Args:
        state: The aircraft state (a :class:`~bluesky_gym.core.physics.Physics`, or anything with
            its arrays and ``cas``, ``ap_trk``, ``selspd``, ``selvs``), as it was when
            ``conflicts`` was detected; (n_envs, n_aircraft) each.
        conflicts: The conflict picture of that state.
        avoidance: MVP's resolution of that state (:func:`~bluesky_gym.core.resolution.mvp`).
        python_geo: Pair bearings with BlueSky's Python geo functions instead of its compiled ones.

    Returns:
        Track [deg], speed (CAS, capped) [m/s], vertical speed [m/s] and altitude [m] of every
        active aircraft; ``dv``, ``tsolv`` and ``in_conflict`` are MVP's.
    """
    active = np.asarray(state.active, dtype=np.bool_)
    shape = active.shape
    n = shape[1]
    lat, lon, alt, trk, cas, vs, ve, vn, ap_trk, selspd, selvs, vmin, vmax = (
        float_array(x, shape)
        for x in (state.lat, state.lon, state.alt, state.trk, state.cas, state.vs, state.gseast, state.gsnorth)
        + (state.ap_trk, state.selspd, state.selvs, state.vmin, state.vmax)
    )
    eye = np.eye(n)
    with np.errstate(all="ignore"):
        qdr, dist_nm = geo.kwikqdrdist_matrix(lat, lon, python_geo)
        dist = dist_nm * NM + SELF_PAIR * eye
        qdrrad = np.radians(qdr)
        dx = dist * np.sin(qdrrad)
        dy = dist * np.cos(qdrrad) - eye * SELF_PAIR  # the aircraft itself at 0
        dalt = alt[..., None, :] - alt[..., :, None]
        close = (dx**2 + dy**2 < SWARM_RADIUS**2) & (np.abs(dalt) < SWARM_HEIGHT)
        dtrk = (trk[..., None, :] - trk[..., :, None] + 180.0) % 360.0 - 180.0
        members = ((close & (np.abs(dtrk) < SWARM_TRACK_DIFF)) | (eye > 0)) & active[..., None, :]
        count = members.sum(axis=-1, dtype=np.float64)

        def mean(values: np.ndarray) -> np.ndarray:
            """The swarm mean of ``values`` (n_envs, n, n) over the members j of each aircraft's row."""
            return np.asarray(np.where(members, values, 0.0).sum(axis=-1) / count)

        inconf = conflicts.in_conflict & active
        ca_trk = np.where(inconf, avoidance.trk, ap_trk)
        ca_cas = np.where(inconf, avoidance.gs, selspd)
        ca_vs = np.where(inconf, avoidance.vs, selvs)
        rows = np.ones((1, n, 1))
        va_cas = mean(rows * cas[..., None, :])
        va_vs = mean(rows * vs[..., None, :])
        va_trk = trk + mean(dtrk)
        fc_dx = mean(dx + eye * ve[..., None, :] / FLOCK_VELOCITY_SCALE)
        fc_dy = mean(dy + eye * vn[..., None, :] / FLOCK_VELOCITY_SCALE)
        fc_dz = mean(rows * alt[..., None, :]) - alt
        fc_trk = np.degrees(np.arctan2(fc_dx, fc_dy))
        fc_cas = cas
        ttoreach = np.sqrt(fc_dx**2 + fc_dy**2) / fc_cas
        fc_vs = np.where(ttoreach == 0, 0.0, fc_dz / ttoreach)
        trks = np.radians(np.stack((ca_trk, va_trk, fc_trk)))
        cass = np.stack((ca_cas, va_cas, fc_cas))
        vss = np.stack((ca_vs, va_vs, fc_vs))
        w = np.array(SWARM_WEIGHTS).reshape(3, *(1,) * len(shape))
        total = float(sum(SWARM_WEIGHTS))
        vx = (cass * np.sin(trks) * w).sum(axis=0) / total
        vy = (cass * np.cos(trks) * w).sum(axis=0) / total
        hdg = np.degrees(np.arctan2(vx, vy))
        spd = np.maximum(vmin, np.minimum(vmax, (cass * w).sum(axis=0) / total))
        vz = (vss * w).sum(axis=0) / total
        new_alt = np.sign(vz) * SWARM_ALTITUDE
    out = [np.where(active, x, np.nan) for x in (hdg, spd, vz, new_alt)]
    return Resolution(out[0], out[1], out[2], out[3], avoidance.dv, avoidance.tsolv, avoidance.in_conflict)


class SwarmResolver(MVPResolver):
    """``RESO SWARM``: :func:`swarm` on MVP's resolution, under :class:`~bluesky_gym.core.resolution.ConflictResolver`'s bookkeeping.

    Swarm takes MVP's RMETH switches and factors; after each resolution every aircraft of the
    airspace follows it (:attr:`follow_all`). Only ``pair_search="all-pairs"``.
    """

    name = "SWARM"
    follow_all = True
    pair_searches = ("all-pairs",)

    def resolve(self, state: TypedResolutionState, conflicts: Conflicts, vsmin: ArrayLike, vsmax: ArrayLike) -> Resolution:
        """:func:`swarm` of :meth:`MVPResolver.resolve`'s resolution."""
        return swarm(cast(SwarmState, state), conflicts, super().resolve(state, conflicts, vsmin, vsmax), python_geo=self.python_geo)


__all__ = ["SWARM_HEIGHT", "SWARM_RADIUS", "SWARM_WEIGHTS", "SwarmResolver", "swarm"]
