"""Conflict resolution: BlueSky 1.1.1's Modified Voltage Potential (MVP), batched [docs/baselines.md].

MVP is the classical conflict-resolution method of BlueSky's ASAS module (``RESO MVP``). For
every conflict pair (ownship i, intruder j) that the state-based detection reports, it computes a
velocity change that pushes the predicted closest point of approach out of the (enlarged)
protected zone, in the time left until that point; the ownship takes half of the vertical part
(the intruder resolves the other half, "cooperative"). The changes of all pairs of an aircraft
are summed and added to its ground velocity, and the result is limited to the channels the
``RMETHH`` / ``RMETHV`` settings allow and to the aircraft's envelope.

:func:`mvp` takes the conflict picture of :func:`bluesky_gym.core.conflicts.detect` (the one
conflict detection of the package) and returns what BlueSky's ``MVP.resolve`` returns: the
resolution track, speed, vertical speed and altitude of every aircraft. The kernels follow
BlueSky's formulas step by step, including its quirks (kept, because they are what ``RESO MVP``
flies):

* the resolution speed is a ground speed, but it is capped by the CAS envelope ``vmin``/``vmax``;
* the vertical speed is capped to ``[vsmin, vsmax]`` of each aircraft's performance model
  (BlueSky's ``ownship.perf.vsmin``/``vsmax``, per aircraft from its type:
  :func:`vertical_speed_limits`); OpenAP's ``vsmin`` is the smallest *climb* rate (3.6 m/s for
  the A320), so the capped value is a magnitude and the direction comes from the resolution
  altitude (as BlueSky's autopilot applies it);
* head-on conflicts (miss distance at most 10 m) are resolved sideways, to the right of the
  line of sight;
* aircraft without a conflict get their own velocity back (track from ``atan2`` of the ground
  velocity components).

Not modelled: priority rules (``PRIORULES``, off by default), ``NORESO`` / ``RESOOFF`` lists and
per-aircraft zone sizes (the package uses one protected zone per call).

:class:`AsasConfig` is BlueSky's ASAS switches of one airspace (detection method, ``RESO MVP``,
zones, settings); :meth:`bluesky_gym.core.Simulator.set_conflict_resolution` flies it.

:func:`resume` is BlueSky's ``resumenav`` bookkeeping: which pairs are still being resolved
(before their closest point of approach, in horizontal loss of separation, or "bouncing"), and
so which aircraft still follow their resolution.

**Resolution methods.** :class:`ConflictResolver` is the one interface of every method: it runs
detection and BlueSky's ASAS bookkeeping (renewal, :func:`resume`, waypoint recovery) and asks
its subclass only for ``resolve(state, conflicts, vsmin, vsmax)`` (and ``resolve_pairs`` for the
grid search), BlueSky's ``resolve(conf, ownship, intruder)``. :class:`MVPResolver` is the MVP
subclass; Eby and Swarm are in :mod:`bluesky_gym.core.eby` and :mod:`bluesky_gym.core.swarm`.
The methods are registered by ``RESO`` name in :data:`bluesky_gym.core.resolvers.RESOLVERS`
(a new method, e.g. SSD: one subclass and one entry there), and :attr:`AsasConfig.method` names
the one an airspace flies.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from bluesky_gym.core.aircraft import DEFAULT_TYPE, aircraft_performance
from bluesky_gym.core.atmosphere import tas2cas
from bluesky_gym.core.conflicts import (
    DETECTORS,
    LOOKAHEAD,
    PZ_HEIGHT,
    PZ_RADIUS,
    ConflictPairs,
    Conflicts,
    GridWork,
    detect_pairs,
    detect_with,
    float_array,
)
from bluesky_gym.core.jit import grid_range, jit
from bluesky_gym.core.scalar import RAD, divide, maximum, minimum, mod, sign
from bluesky_gym.core.units import R_EARTH

Array = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

RESO_FACTOR = 1.05  # -, BlueSky's resolution margins asas_marh and asas_marv (settings.cfg)
HEAD_ON_MISS = 10.0  # m: a predicted miss distance at most this is treated as head-on
NO_VERTICAL_SOLUTION = 1e9  # s, BlueSky's "no vertical resolution time" marker (timesolveV)
FLOAT_MAX = float(np.finfo(np.float64).max)  # the largest finite float64, what np.nan_to_num puts for +inf
BOUNCING_TRACK_DIFF = 30.0  # deg: pairs flying within this track difference keep resolving while close

#: ``RMETHH`` values and their aliases, as BlueSky's command accepts them.
RMETHH_VALUES = ("BOTH", "SPD", "HDG", "NONE", "ON", "OFF", "OF")
#: ``RMETHV`` values and their aliases.
RMETHV_VALUES = ("V/S", "NONE", "ON", "OFF", "OF")


@dataclass(frozen=True)
class ResolutionSettings:
    """MVP's switches and margins (BlueSky ``traf.cr``); the defaults are BlueSky's after ``RESO MVP``.

    Attributes:
        swresohoriz: Resolve horizontally only (keep the vertical speed).
        swresospd: With ``swresohoriz``: may change the speed.
        swresohdg: With ``swresohoriz``: may change the track. With neither (the default), or
            both, track and speed both change.
        swresovert: Resolve vertically only (when ``swresohoriz`` is off).
        resofach: Horizontal resolution factor (protected-zone radius multiplier).
        resofacv: Vertical resolution factor (protected-zone height multiplier).
    """

    swresohoriz: bool = True
    swresospd: bool = False
    swresohdg: bool = False
    swresovert: bool = False
    resofach: float = RESO_FACTOR
    resofacv: float = RESO_FACTOR

    @classmethod
    def from_methods(
        cls, rmethh: str | None = None, rmethv: str | None = None, resofach: float = RESO_FACTOR, resofacv: float = RESO_FACTOR
    ) -> ResolutionSettings:
        """The settings after ``RESO MVP``, then ``RMETHH rmethh``, then ``RMETHV rmethv`` (None: not given).

        Args:
            rmethh: ``BOTH``/``ON``, ``SPD``, ``HDG`` or ``NONE``/``OFF``/``OF``.
            rmethv: ``V/S``/``ON`` or ``NONE``/``OFF``/``OF``.
            resofach: ``RFACH`` factor.
            resofacv: ``RFACV`` factor.

        Raises:
            ValueError: An unknown method or a factor that is not a positive number.
        """
        for name, value in (("resofach", resofach), ("resofacv", resofacv)):
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
                raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
        return cls(resofach=float(resofach), resofacv=float(resofacv)).with_methods(rmethh, rmethv)

    def with_methods(self, rmethh: str | None = None, rmethv: str | None = None) -> ResolutionSettings:
        """These settings after ``RMETHH rmethh``, then ``RMETHV rmethv`` (None: not given), as BlueSky's MVP changes its switches.

        Raises:
            ValueError: An unknown method.
        """
        h, spd, hdg, vert = self.swresohoriz, self.swresospd, self.swresohdg, self.swresovert
        if rmethh is not None:
            if rmethh not in RMETHH_VALUES:
                raise ValueError(f"RMETHH {rmethh!r} not understood; choose one of {', '.join(RMETHH_VALUES)}")
            if rmethh in ("ON", "BOTH"):
                h, spd, hdg, vert = True, True, True, False
            elif rmethh in ("OFF", "OF", "NONE"):  # as BlueSky: leaves swresovert as it is
                h, spd, hdg = False, False, False
            elif rmethh == "SPD":
                h, spd, hdg, vert = True, True, False, False
            else:  # HDG
                h, spd, hdg, vert = True, False, True, False
        if rmethv is not None:
            if rmethv not in RMETHV_VALUES:
                raise ValueError(f"RMETHV {rmethv!r} not understood; choose one of {', '.join(RMETHV_VALUES)}")
            if rmethv in ("ON", "V/S"):
                h, spd, hdg, vert = False, False, False, True
            else:  # as BlueSky: leaves swresohoriz as it is
                vert = False
        return ResolutionSettings(h, spd, hdg, vert, self.resofach, self.resofacv)

    @property
    def mode(self) -> int:
        """The velocity channels that change: 0 track+speed, 1 speed, 2 track, 3 vertical, 4 all three."""
        if self.swresohoriz:
            if self.swresospd and not self.swresohdg:
                return 1
            if self.swresohdg and not self.swresospd:
                return 2
            return 0
        return 3 if self.swresovert else 4


@dataclass(frozen=True)
class AsasConfig:
    """BlueSky's ASAS switches for one airspace: conflict detection, the resolution method and their zones.

    Attributes:
        detector: ``ASAS``/``CDMETHOD``: ``"STATEBASED"`` (what ``ASAS ON`` selects),
            ``"CSTATEBASED"``, or None (off, the default).
        resolution: Resolution on (True: ``RESO method``) or ``RESO OFF`` (False, the default).
        settings: ``RMETHH``, ``RMETHV``, ``RFACH``, ``RFACV``.
        rpz: ``ZONER``: protected-zone radius [m].
        hpz: ``ZONEDH``: protected-zone half height [m].
        lookahead: ``DTLOOK``: look-ahead time [s].
        method: The resolution method's ``RESO`` name, a key of
            :data:`bluesky_gym.core.resolvers.RESOLVERS` (``"MVP"``, the default, ``"EBY"``, ``"SWARM"``).
    """

    detector: str | None = None
    resolution: bool = False
    settings: ResolutionSettings = ResolutionSettings()
    rpz: float = PZ_RADIUS
    hpz: float = PZ_HEIGHT
    lookahead: float = LOOKAHEAD
    method: str = "MVP"

    @property
    def resolving(self) -> bool:
        """Whether resolution changes the flight: detection on and ``RESO method``."""
        return self.detector is not None and self.resolution


@jit
def mvp_pair(
    qdr_deg: float,
    dist: float,
    tcpa: float,
    tlos: float,
    dalt: float,
    vrel_e: float,
    vrel_n: float,
    vrel_z: float,
    rpz_m: float,
    hpz_m: float,
    dtlook: float,
) -> tuple[float, float, float, float]:
    """MVP's velocity change for one conflict pair (BlueSky ``MVP.MVP``).

    Args:
        qdr_deg: Bearing ownship -> intruder [deg].
        dist: Horizontal distance [m].
        tcpa: Time to the closest point of approach [s].
        tlos: Time to loss of separation [s].
        dalt: Intruder altitude minus ownship altitude [m].
        vrel_e: Intruder minus ownship ground velocity, east [m/s].
        vrel_n: Same, north [m/s].
        vrel_z: Intruder minus ownship vertical speed [m/s].
        rpz_m: Resolution zone radius (protected zone x resofach) [m].
        hpz_m: Resolution zone half height (x resofacv) [m].
        dtlook: Look-ahead time [s].

    Returns:
        (dv east, dv north, dv up) [m/s], the change that the intruder would make, and the time to
        solve the conflict vertically [s].
    """
    q = qdr_deg * RAD
    drel_e = math.sin(q) * dist
    drel_n = math.cos(q) * dist
    # Horizontal: the miss vector at the closest point of approach.
    dcpa_e = drel_e + vrel_e * tcpa
    dcpa_n = drel_n + vrel_n * tcpa
    dabsh = math.sqrt(dcpa_e * dcpa_e + dcpa_n * dcpa_n)
    ih = rpz_m - dabsh
    if dabsh <= HEAD_ON_MISS:  # head-on: resolve perpendicular to the line of sight
        dabsh = HEAD_ON_MISS
        dcpa_e = divide(drel_n, dist) * dabsh
        dcpa_n = divide(-drel_e, dist) * dabsh
    if rpz_m < dist and dabsh < dist:
        # Outside the zone: aim at the tangent to the zone, not at its rim.
        erratum = math.cos(math.asin(rpz_m / dist) - math.asin(dabsh / dist))
        dv1 = divide((rpz_m / erratum - dabsh) * dcpa_e, abs(tcpa) * dabsh)
        dv2 = divide((rpz_m / erratum - dabsh) * dcpa_n, abs(tcpa) * dabsh)
    else:
        dv1 = divide(ih * dcpa_e, abs(tcpa) * dabsh)
        dv2 = divide(ih * dcpa_n, abs(tcpa) * dabsh)
    # Vertical.
    moving = abs(vrel_z) > 0.0
    iv = hpz_m if moving else hpz_m - abs(dalt)
    tsolv = abs(dalt / vrel_z) if moving else tlos
    if tsolv > dtlook:
        tsolv = tlos
        iv = hpz_m
    dv3 = divide(iv, tsolv) * (-vrel_z / abs(vrel_z)) if moving else divide(iv, tsolv)
    return dv1, dv2, dv3, tsolv


@jit
def mvp_add_pair(
    dve: float,
    dvn: float,
    dvz: float,
    tsol: float,
    qdr_deg: float,
    dist: float,
    tcpa: float,
    tlos: float,
    alt_i: float,
    alt_j: float,
    gseast_i: float,
    gseast_j: float,
    gsnorth_i: float,
    gsnorth_j: float,
    vs_i: float,
    vs_j: float,
    rpz_m: float,
    hpz_m: float,
    dtlook: float,
) -> tuple[float, float, float, float]:
    """Ownship ``i``'s summed velocity change and shortest vertical solving time after adding its conflict with ``j``.

    Args:
        dve: Summed velocity change east so far [m/s] (``dvn`` north, ``dvz`` up).
        dvn: Summed change north [m/s].
        dvz: Summed change up [m/s].
        tsol: Shortest time to solve vertically so far [s].
        qdr_deg: Bearing i -> j [deg] (the detection's; ``dist``, ``tcpa``, ``tlos`` likewise).
        dist: Horizontal distance [m].
        tcpa: Time to CPA [s].
        tlos: Time to loss of separation [s].
        alt_i: Ownship altitude [m] (``_j``: the intruder's; ground speeds east, north and
            vertical speeds likewise).
        alt_j: Intruder altitude [m].
        gseast_i: Ownship ground speed east [m/s].
        gseast_j: Intruder ground speed east [m/s].
        gsnorth_i: Ownship ground speed north [m/s].
        gsnorth_j: Intruder ground speed north [m/s].
        vs_i: Ownship vertical speed [m/s].
        vs_j: Intruder vertical speed [m/s].
        rpz_m: Resolution zone radius [m].
        hpz_m: Resolution zone half height [m].
        dtlook: Look-ahead time [s].
    """
    d1, d2, d3, tv = mvp_pair(qdr_deg, dist, tcpa, tlos, alt_j - alt_i, gseast_j - gseast_i, gsnorth_j - gsnorth_i, vs_j - vs_i, rpz_m, hpz_m, dtlook)
    if tv < tsol:
        tsol = tv
    # Cooperative: the ownship moves away by the whole horizontal and half the vertical change.
    return dve - d1, dvn - d2, dvz - 0.5 * d3, tsol


@jit
def mvp_aircraft(
    dve: float,
    dvn: float,
    dvz: float,
    tsol: float,
    alt: float,
    gseast: float,
    gsnorth: float,
    vs: float,
    trk: float,
    gs: float,
    selalt: float,
    ap_vs: float,
    vmin: float,
    vmax: float,
    vsmin: float,
    vsmax: float,
    dtlook: float,
    mode: int,
    horizontal: float,
) -> tuple[float, float, float, float]:
    """One aircraft's resolution track [deg], ground speed [m/s], vertical speed [m/s] and altitude [m] from its summed change.

    ``dve``, ``dvn``, ``dvz`` and ``tsol`` are what :func:`mvp_add_pair` summed over the
    aircraft's conflicts (0, 0, 0 and :data:`NO_VERTICAL_SOLUTION` without any); the others are
    the aircraft's state, envelope and the settings (:func:`mvp_loop`).
    """
    ve = gseast + dve
    vn = gsnorth + dvn
    vz = vs + dvz
    new_trk = mod(math.atan2(ve, vn) * 180.0 / math.pi, 360.0)
    new_gs = math.sqrt(ve * ve + vn * vn)
    new_vs = vs
    if mode == 1:  # speed only
        new_trk = trk
    elif mode == 2:  # track only
        new_gs = gs
    elif mode == 3:  # vertical only
        new_trk = trk
        new_gs = gs
        new_vs = vz
    elif mode == 4:  # all three
        new_vs = vz
    gs_capped = maximum(vmin, minimum(vmax, new_gs))
    vs_capped = maximum(vsmin, minimum(vsmax, new_vs))
    # The altitude to level off at (BlueSky: follow the autopilot's altitude when it also solves).
    alt_temp = vs_capped * tsol + alt
    sign_dvs = sign(vs_capped - ap_vs * sign(selalt - alt))
    sign_alt = sign(alt_temp - selalt)
    new_alt = alt_temp if (sign_dvs == 0.0 or sign_dvs == sign_alt) else selalt
    if tsol < dtlook and abs(dvz) > 0.0:
        new_alt = alt_temp
    new_alt = new_alt * (1.0 - horizontal) + selalt * horizontal
    return new_trk, gs_capped, vs_capped, new_alt


@jit
def mvp_loop(  # type: ignore[no-untyped-def]
    conflict,
    qdr,
    dist,
    tcpa,
    tlos,
    active,
    alt,
    gseast,
    gsnorth,
    vs,
    trk,
    gs,
    selalt,
    ap_vs,
    vmin,
    vmax,
    vsmin,
    vsmax,
    rpz_m,
    hpz_m,
    dtlook,
    mode,
    horizontal,
    out_trk,
    out_gs,
    out_vs,
    out_alt,
    out_dv,
    out_tsolv,
):
    n_envs, m = active.shape
    for e in grid_range(n_envs):
        for i in range(m):
            if not active[e, i]:
                continue
            dve = 0.0
            dvn = 0.0
            dvz = 0.0
            tsol = NO_VERTICAL_SOLUTION
            for j in range(m):
                if not conflict[e, i, j]:
                    continue
                dve, dvn, dvz, tsol = mvp_add_pair(
                    dve, dvn, dvz, tsol, qdr[e, i, j], dist[e, i, j], tcpa[e, i, j], tlos[e, i, j],
                    alt[e, i], alt[e, j], gseast[e, i], gseast[e, j], gsnorth[e, i], gsnorth[e, j], vs[e, i], vs[e, j],
                    rpz_m, hpz_m, dtlook,
                )  # fmt: skip
            t, g, v, a = mvp_aircraft(
                dve, dvn, dvz, tsol, alt[e, i], gseast[e, i], gsnorth[e, i], vs[e, i], trk[e, i], gs[e, i], selalt[e, i], ap_vs[e, i],
                vmin[e, i], vmax[e, i], vsmin[e, i], vsmax[e, i], dtlook, mode, horizontal,
            )  # fmt: skip
            out_trk[e, i] = t
            out_gs[e, i] = g
            out_vs[e, i] = v
            out_alt[e, i] = a
            out_dv[e, i, 0] = dve
            out_dv[e, i, 1] = dvn
            out_dv[e, i, 2] = dvz
            out_tsolv[e, i] = tsol


@jit
def mvp_listed(  # type: ignore[no-untyped-def]
    i, row, intruder, qdr, dist, tcpa, tlos, alt, gseast, gsnorth, vs, trk, gs, selalt, ap_vs, vmin, vmax, vsmin, vsmax,
    rpz_m, hpz_m, dtlook, mode, horizontal,
):  # fmt: skip
    """MVP of aircraft ``i`` (flat index) from its listed conflicts ``row[i]:row[i + 1]`` (by rising intruder), summed in :func:`mvp_loop`'s order.

    It returns the resolution track, ground speed, vertical speed and altitude
    (:func:`mvp_aircraft`), then the summed change east, north and up, and the shortest vertical
    solving time.
    """
    dve = 0.0
    dvn = 0.0
    dvz = 0.0
    tsol = NO_VERTICAL_SOLUTION
    for p in range(row[i], row[i + 1]):
        j = intruder[p]
        dve, dvn, dvz, tsol = mvp_add_pair(
            dve, dvn, dvz, tsol, qdr[p], dist[p], tcpa[p], tlos[p],
            alt[i], alt[j], gseast[i], gseast[j], gsnorth[i], gsnorth[j], vs[i], vs[j], rpz_m, hpz_m, dtlook,
        )  # fmt: skip
    t, g, v, a = mvp_aircraft(
        dve, dvn, dvz, tsol, alt[i], gseast[i], gsnorth[i], vs[i], trk[i], gs[i], selalt[i], ap_vs[i],
        vmin[i], vmax[i], vsmin[i], vsmax[i], dtlook, mode, horizontal,
    )  # fmt: skip
    return t, g, v, a, dve, dvn, dvz, tsol


@jit
def mvp_pairs_loop(  # type: ignore[no-untyped-def]
    row, intruder, qdr, dist, tcpa, tlos, active, alt, gseast, gsnorth, vs, trk, gs, selalt, ap_vs, vmin, vmax, vsmin, vsmax,
    rpz_m, hpz_m, dtlook, mode, horizontal, out_trk, out_gs, out_vs, out_alt, out_dv, out_tsolv,
):  # fmt: skip
    """:func:`mvp_loop` from a list of conflict pairs: aircraft ``k``'s (flat index) are ``row[k]:row[k + 1]``, by rising intruder.

    The state and the outputs are flat (one entry per aircraft; ``out_dv`` (aircraft, 3)); the
    sums run in the order of :func:`mvp_loop` (:func:`mvp_listed`), so the results are the same to the bit.
    """
    for i in grid_range(active.shape[0]):
        if not active[i]:
            continue
        t, g, v, a, dve, dvn, dvz, tsol = mvp_listed(
            i, row, intruder, qdr, dist, tcpa, tlos, alt, gseast, gsnorth, vs, trk, gs, selalt, ap_vs, vmin, vmax, vsmin, vsmax,
            rpz_m, hpz_m, dtlook, mode, horizontal,
        )  # fmt: skip
        out_trk[i] = t
        out_gs[i] = g
        out_vs[i] = v
        out_alt[i] = a
        out_dv[i, 0] = dve
        out_dv[i, 1] = dvn
        out_dv[i, 2] = dvz
        out_tsolv[i] = tsol


class ResolutionState(Protocol):
    """The per-aircraft state MVP reads, shaped (n_envs, n_aircraft) (the :class:`~bluesky_gym.core.physics.Physics` arrays)."""

    active: BoolArray
    lat: Array  # deg
    lon: Array  # deg
    tas: Array  # m/s
    alt: Array  # m
    gseast: Array  # m/s
    gsnorth: Array  # m/s
    vs: Array  # m/s
    trk: Array  # deg
    gs: Array  # m/s
    selalt: Array  # m
    ap_vs: Array  # m/s
    vmin: Array  # m/s CAS
    vmax: Array  # m/s CAS


class TypedResolutionState(ResolutionState, Protocol):
    """A :class:`ResolutionState` that knows the type of every aircraft (a :class:`~bluesky_gym.core.physics.Physics`)."""

    def aircraft_type(self, env: ArrayLike, slot: ArrayLike) -> list[str]:
        """Type names of aircraft (as given at creation)."""
        ...


def vertical_speed_limits(state: TypedResolutionState) -> tuple[Array, Array]:
    """Every aircraft's vertical-speed envelope ``(vsmin, vsmax)`` [m/s] from its type, (n_envs, n_aircraft) each.

    These are what BlueSky 1.1.1's MVP caps an aircraft's resolution vertical speed with: the
    arrays ``ownship.perf.vsmin`` and ``ownship.perf.vsmax`` of its performance model, which
    holds them per aircraft, set at creation from the aircraft's type (OpenAP limits; an unknown
    type flies as the B744). Empty slots are NaN.

    Args:
        state: The aircraft state with the aircraft types.
    """
    active = np.asarray(state.active, dtype=np.bool_)
    vsmin = np.full(active.shape, np.nan)
    vsmax = np.full(active.shape, np.nan)
    env, slot = np.nonzero(active)
    if env.size:
        types = state.aircraft_type(env, slot)
        perf = {t: aircraft_performance(t) for t in set(types)}
        vsmin[env, slot] = [perf[t].vsmin for t in types]
        vsmax[env, slot] = [perf[t].vsmax for t in types]
    return vsmin, vsmax


@dataclass(frozen=True)
class Resolution:
    """MVP's resolution of every aircraft, (n_envs, n_aircraft) (NaN in empty slots).

    The first four are BlueSky's ``traf.cr.trk``, ``tas``, ``vs`` and ``alt`` after ``resolve``.
    """

    trk: Array  # deg, resolution track in [0, 360)
    gs: Array  # m/s, resolution ground speed, capped to [vmin, vmax] (BlueSky calls it tas)
    vs: Array  # m/s, resolution vertical speed, capped to [vsmin, vsmax]
    alt: Array  # m, altitude to level off at
    dv: Array  # (n_envs, n_aircraft, 3) m/s, summed velocity change east, north, up
    tsolv: Array  # s, shortest time to solve a conflict vertically (1e9 without conflict)
    in_conflict: BoolArray  # the aircraft has at least one conflict


def mvp(
    state: ResolutionState,
    conflicts: Conflicts,
    settings: ResolutionSettings | None = None,
    *,
    rpz: float = PZ_RADIUS,
    hpz: float = PZ_HEIGHT,
    lookahead: float = LOOKAHEAD,
    vsmin: ArrayLike | None = None,
    vsmax: ArrayLike | None = None,
) -> Resolution:
    """MVP's resolution of every aircraft from the conflict picture (BlueSky ``MVP.resolve``).

    Args:
        state: The aircraft state (a :class:`~bluesky_gym.core.physics.Physics`, or anything with
            its arrays), read as it was when ``conflicts`` was detected.
        conflicts: :func:`bluesky_gym.core.conflicts.detect` of that state, with the same ``rpz``,
            ``hpz`` and ``lookahead``.
        settings: RMETH switches and margins (default: BlueSky's after ``RESO MVP``).
        rpz: Protected-zone radius [m].
        hpz: Protected-zone half height [m].
        lookahead: Look-ahead time [s].
        vsmin: Lower vertical-speed limit [m/s], scalar or (n_envs, n_aircraft) (default: the A320's
            :attr:`~bluesky_gym.core.performance.AircraftPerformance.vsmin`; give per-aircraft
            values for a mixed fleet).
        vsmax: Upper vertical-speed limit [m/s] (default: the A320's ``vsmax``).

    Returns:
        The resolution of every active aircraft.
    """
    s, active, floats = _mvp_inputs(state, settings, vsmin, vsmax)
    shape = active.shape
    pairs = shape + (shape[1],)
    if conflicts.conflict.shape != pairs:
        raise ValueError(f"conflicts are shaped {conflicts.conflict.shape}, the state needs {pairs}")
    trk, gs, vs, alt_out = (np.full(shape, np.nan) for _ in range(4))
    dv = np.full((*shape, 3), np.nan)
    tsolv = np.full(shape, np.nan)
    conflict = np.ascontiguousarray(conflicts.conflict, dtype=np.bool_)
    pictures = [np.ascontiguousarray(x, dtype=np.float64) for x in (conflicts.qdr, conflicts.dist, conflicts.tcpa, conflicts.tlos)]
    zone = [float(rpz) * s.resofach, float(hpz) * s.resofacv, float(lookahead), s.mode, 1.0 if s.swresohoriz else 0.0]
    mvp_loop(*[conflict, *pictures, active, *floats, *zone, trk, gs, vs, alt_out, dv, tsolv])
    return Resolution(trk, gs, vs, alt_out, dv, tsolv, conflict.any(axis=-1) & active)


def _mvp_inputs(
    state: ResolutionState, settings: ResolutionSettings | None, vsmin: ArrayLike | None, vsmax: ArrayLike | None
) -> tuple[ResolutionSettings, BoolArray, list[Array]]:
    """The settings, ``active`` and the per-aircraft arrays :func:`mvp_loop` reads after it, ``alt`` .. ``vsmax`` (n_envs, n_aircraft)."""
    if vsmin is None or vsmax is None:
        default = aircraft_performance(DEFAULT_TYPE)
        vsmin = default.vsmin if vsmin is None else vsmin
        vsmax = default.vsmax if vsmax is None else vsmax
    active = np.ascontiguousarray(state.active, dtype=np.bool_)

    floats = (state.alt, state.gseast, state.gsnorth, state.vs, state.trk, state.gs, state.selalt, state.ap_vs, state.vmin, state.vmax, vsmin, vsmax)
    return settings or ResolutionSettings(), active, [float_array(x, active.shape) for x in floats]


def mvp_pairs(
    state: ResolutionState,
    conflicts: ConflictPairs,
    settings: ResolutionSettings | None = None,
    *,
    rpz: float = PZ_RADIUS,
    hpz: float = PZ_HEIGHT,
    lookahead: float = LOOKAHEAD,
    vsmin: ArrayLike | None = None,
    vsmax: ArrayLike | None = None,
) -> Resolution:
    """:func:`mvp` from the conflicts as pairs (:func:`bluesky_gym.core.conflicts.detect_pairs`); the same results to the bit.

    The arguments are :func:`mvp`'s; ``conflicts`` lists the pairs of the same state.
    """
    s, active, floats = _mvp_inputs(state, settings, vsmin, vsmax)
    shape = active.shape
    if conflicts.n_aircraft != shape[1]:
        raise ValueError(f"conflicts are of airspaces of {conflicts.n_aircraft} aircraft, the state has {shape[1]}")
    n = shape[0] * shape[1]
    row = np.zeros(n + 1, np.int64)
    np.cumsum(np.bincount(conflicts.flat_own, minlength=n), out=row[1:])
    intruder = conflicts.env * shape[1] + conflicts.intruder
    trk, gs, vs, alt_out, tsolv = (np.full(n, np.nan) for _ in range(5))
    dv = np.full((n, 3), np.nan)
    pictures = [np.ascontiguousarray(x, dtype=np.float64) for x in (conflicts.qdr, conflicts.dist, conflicts.tcpa, conflicts.tlos)]
    zone = [float(rpz) * s.resofach, float(hpz) * s.resofacv, float(lookahead), s.mode, 1.0 if s.swresohoriz else 0.0]
    mvp_pairs_loop(*[row, intruder, *pictures, active.reshape(-1), *(x.reshape(-1) for x in floats), *zone, trk, gs, vs, alt_out, dv, tsolv])
    in_conflict = (np.diff(row) > 0).reshape(shape) & active
    return Resolution(
        trk.reshape(shape), gs.reshape(shape), vs.reshape(shape), alt_out.reshape(shape), dv.reshape(*shape, 3), tsolv.reshape(shape), in_conflict
    )


@jit
def resume_pair(
    lat_i: float,
    lon_i: float,
    lat_j: float,
    lon_j: float,
    gseast_i: float,
    gseast_j: float,
    gsnorth_i: float,
    gsnorth_j: float,
    trk_i: float,
    trk_j: float,
    rpz: float,
    bounce_dist: float,
) -> bool:
    """Whether the resolution pair (ownship i, intruder j) goes on (BlueSky ``resumenav``; see :func:`resume`).

    Args:
        lat_i: Ownship latitude [deg] (``_j``: the intruder's; longitudes, ground speeds east and
            north and tracks likewise).
        lon_i: Ownship longitude [deg].
        lat_j: Intruder latitude [deg].
        lon_j: Intruder longitude [deg].
        gseast_i: Ownship ground speed east [m/s].
        gseast_j: Intruder ground speed east [m/s].
        gsnorth_i: Ownship ground speed north [m/s].
        gsnorth_j: Intruder ground speed north [m/s].
        trk_i: Ownship track [deg].
        trk_j: Intruder track [deg].
        rpz: Protected-zone radius [m].
        bounce_dist: Distance under which pairs on near tracks keep resolving [m].
    """
    # Flat-earth relative position and velocity of the intruder.
    de = R_EARTH * (((lon_j - lon_i) * RAD) * math.cos(0.5 * ((lat_j + lat_i) * RAD)))
    dn = R_EARTH * ((lat_j - lat_i) * RAD)
    ve = gseast_j - gseast_i
    vn = gsnorth_j - gsnorth_i
    past_cpa = de * ve + dn * vn > 0.0
    hdist = math.sqrt(de * de + dn * dn)
    d = trk_i - trk_j
    while d > 180.0 or d < -180.0:  # BlueSky's anglediff
        d = d - 360.0 if d > 180.0 else d + 360.0
    bouncing = abs(d) < BOUNCING_TRACK_DIFF and hdist < bounce_dist
    return not past_cpa or hdist < rpz or bouncing


@jit
def resume_loop(pairs, lat, lon, gseast, gsnorth, trk, active, rpz, bounce_dist, keep, asas):  # type: ignore[no-untyped-def]
    n_envs, m = active.shape
    for e in grid_range(n_envs):
        for i in range(m):
            asas[e, i] = False
            for j in range(m):
                keep[e, i, j] = False
                if not pairs[e, i, j] or not active[e, i] or not active[e, j]:
                    continue
                if resume_pair(lat[e, i], lon[e, i], lat[e, j], lon[e, j], gseast[e, i], gseast[e, j], gsnorth[e, i], gsnorth[e, j],
                               trk[e, i], trk[e, j], rpz, bounce_dist):  # fmt: skip
                    keep[e, i, j] = True
                    asas[e, i] = True


@jit
def asas_pairs_kernel(  # type: ignore[no-untyped-def]
    m, row, intruder, qdr, dist, tcpa, tlos, active, alt, gseast, gsnorth, vs, trk, gs, selalt, ap_vs, vmin, vmax, vsmin, vsmax,
    rpz_m, hpz_m, dtlook, mode, horizontal, held, keys, lat, lon, rpz, bounce_dist, kept, follow, ended, counts,
):  # fmt: skip
    """One ASAS update of MVP from the conflicts as pairs: the resolution, BlueSky's bookkeeping and ``resumenav`` in one pass.

    The conflicts are :func:`mvp_pairs_loop`'s (aircraft ``k``'s, flat index, are
    ``row[k]:row[k + 1]`` by rising intruder; the state flat). The pairs being resolved, ``keys``
    (sorted keys ``own * m + intruder`` slot, ``own`` the flat ownship), and the current conflicts
    are merged, and :func:`resume_pair` decides which go on: those go to ``kept`` (sorted;
    ``counts[0]`` of them), their ownships ``follow``, and ``ended`` marks the active aircraft that
    had a pair and follow none. In an airspace with a conflict, ``held`` (4, aircraft: track,
    ground speed, vertical speed, altitude) takes MVP's resolution of each aircraft that follows
    one, as :func:`renew_loop`; elsewhere it keeps the last one. MVP runs only for the aircraft
    that follow (in BlueSky it runs for every aircraft, but the others' resolutions are never
    flown, and :func:`release_loop` drops them afterwards).
    """
    n = active.shape[0]
    for i in range(n):
        follow[i] = False
        ended[i] = False  # here: whether the aircraft has a pair (made "ended" at the end)
    # The union of the pairs being resolved and the conflicts, both sorted, each pair through resumenav.
    a = 0
    b = 0
    i = 0
    done = 0
    while a < keys.shape[0] or i < n:
        if i < n and b >= row[i + 1]:
            i += 1
            continue
        new = i * m + intruder[b] % m if i < n else -1
        if a < keys.shape[0] and (i >= n or keys[a] <= new):
            key = keys[a]
            if i < n and keys[a] == new:
                b += 1
            a += 1
        else:
            key = new
            b += 1
        own = key // m
        other = (own // m) * m + key % m
        ended[own] = True
        if (
            active[own]
            and active[other]
            and resume_pair(lat[own], lon[own], lat[other], lon[other], gseast[own], gseast[other], gsnorth[own], gsnorth[other],
                            trk[own], trk[other], rpz, bounce_dist)
        ):  # fmt: skip
            kept[done] = key
            done += 1
            follow[own] = True
    counts[0] = done
    for i in range(n):
        ended[i] = ended[i] and not follow[i] and active[i]
    for e in range(n // m):
        if row[e * m] == row[(e + 1) * m]:
            continue  # no conflict in the airspace: the last resolution stays
        for i in range(e * m, (e + 1) * m):
            if follow[i]:
                t, g, v, a, _, _, _, _ = mvp_listed(
                    i, row, intruder, qdr, dist, tcpa, tlos, alt, gseast, gsnorth, vs, trk, gs, selalt, ap_vs, vmin, vmax, vsmin, vsmax,
                    rpz_m, hpz_m, dtlook, mode, horizontal,
                )  # fmt: skip
                held[0, i] = t
                held[1, i] = g
                held[2, i] = v
                held[3, i] = a


@jit
def resume_pairs_loop(own, intruder, lat, lon, gseast, gsnorth, trk, active, rpz, bounce_dist, keep):  # type: ignore[no-untyped-def]
    """:func:`resume_loop` of listed pairs (flat aircraft indices; the state flat): ``keep[p]`` of each pair."""
    for p in grid_range(own.shape[0]):
        i = own[p]
        j = intruder[p]
        keep[p] = (
            active[i]
            and active[j]
            and resume_pair(lat[i], lon[i], lat[j], lon[j], gseast[i], gseast[j], gsnorth[i], gsnorth[j], trk[i], trk[j], rpz, bounce_dist)
        )


@jit
def renew_loop(conflict, trk, gs, vs, alt, pairs, held):  # type: ignore[no-untyped-def]
    """BlueSky's ASAS bookkeeping before ``resumenav``, per airspace (one per ``grid_range`` index).

    Where the airspace has a conflict, ``held`` (4, n_envs, m: track, ground speed, vertical
    speed, altitude) takes the new resolution of every aircraft; elsewhere it keeps the last one.
    ``pairs`` (n_envs, m, m) gains the current conflicts (the candidates of :func:`resume`).
    """
    n_envs, m = trk.shape
    for e in grid_range(n_envs):
        renew = False
        for i in range(m):
            for j in range(m):
                if conflict[e, i, j]:
                    renew = True
                    pairs[e, i, j] = True
        if renew:
            for i in range(m):
                held[0, e, i] = trk[e, i]
                held[1, e, i] = gs[e, i]
                held[2, e, i] = vs[e, i]
                held[3, e, i] = alt[e, i]


@jit
def release_loop(follow, held):  # type: ignore[no-untyped-def]
    """``held`` (4, n_envs, m) becomes NaN where an aircraft follows no resolution (``follow`` (n_envs, m)), per airspace.

    An aircraft follows a resolution only while it has a pair being resolved, and gains one only
    with a conflict, which renews the resolutions of its airspace: what ``held`` keeps of an
    aircraft that follows none is never flown, so it is dropped.
    """
    n_envs, m = follow.shape
    for e in grid_range(n_envs):
        for i in range(m):
            if not follow[e, i]:
                for r in range(4):
                    held[r, e, i] = math.nan


@jit
def ended_loop(candidates, follow, active, ended, any_ended):  # type: ignore[no-untyped-def]
    """Aircraft whose last resolution pair ended in this update (a candidate pair, no longer following), per airspace.

    ``any_ended[0]`` is set to True where any did (it is left as it is otherwise).
    """
    n_envs, m = active.shape
    for e in grid_range(n_envs):
        for i in range(m):
            had = False
            for j in range(m):
                if candidates[e, i, j]:
                    had = True
            ended[e, i] = had and not follow[e, i] and active[e, i]
            if ended[e, i]:
                any_ended[0] = True


@jit
def finite(x: float) -> float:
    """``x`` with NaN as 0 and infinities as the largest finite floats (``np.nan_to_num``)."""
    if x != x:
        return 0.0
    if x == math.inf:
        return FLOAT_MAX
    if x == -math.inf:
        return -FLOAT_MAX
    return x


@jit
def targets_loop(held, targets):  # type: ignore[no-untyped-def]
    """The resolution the kinematics fly, from ``held`` (track, ground speed, vertical speed, altitude).

    ``targets`` (4, n_envs, m) gets track, ground speed, altitude, vertical speed, with NaN as 0
    and infinities as the largest finite floats (``np.nan_to_num``).
    """
    n_envs = held.shape[1]
    m = held.shape[2]
    for e in grid_range(n_envs):
        for i in range(m):
            targets[0, e, i] = finite(held[0, e, i])
            targets[1, e, i] = finite(held[1, e, i])
            targets[2, e, i] = finite(held[3, e, i])
            targets[3, e, i] = finite(held[2, e, i])


def resolution_targets(held: Array) -> Array:
    """:func:`targets_loop` of ``held`` (4, n_envs, m), as a new array."""
    held = np.ascontiguousarray(held, dtype=np.float64)
    out = np.empty_like(held)
    targets_loop(held, out)
    return out


def resume(
    state: ResolutionState,
    pairs: BoolArray,
    *,
    rpz: float = PZ_RADIUS,
    resofach: float = RESO_FACTOR,
) -> tuple[BoolArray, BoolArray]:
    """Which resolution pairs stay active, and which aircraft still follow their resolution (BlueSky ``resumenav``).

    A pair (ownship i, intruder j) stays while the intruder is ahead of the closest point of
    approach (relative position and velocity on a flat earth), the two are in horizontal loss of
    separation, or they "bounce" (tracks within 30 deg and closer than ``rpz * resofach``). A pair
    with a deleted aircraft ends.

    Args:
        state: The aircraft state (``active``, ``lat``, ``lon``, ``gseast``, ``gsnorth``, ``trk``).
        pairs: (n_envs, n_aircraft, n_aircraft) pairs being resolved (earlier pairs and the
            current conflicts).
        rpz: Protected-zone radius [m].
        resofach: Horizontal resolution factor.

    Returns:
        The pairs kept, and per aircraft whether it still follows its resolution.
    """
    active = np.ascontiguousarray(state.active, dtype=np.bool_)
    keep = np.zeros(pairs.shape, np.bool_)
    asas = np.zeros(active.shape, np.bool_)
    lat, lon, ve, vn, trk = (np.ascontiguousarray(x, dtype=np.float64) for x in (state.lat, state.lon, state.gseast, state.gsnorth, state.trk))
    resume_loop(np.ascontiguousarray(pairs, dtype=np.bool_), lat, lon, ve, vn, trk, active, float(rpz), float(rpz) * resofach, keep, asas)
    return keep, asas


@dataclass(frozen=True)
class ResolutionCommand:
    """What MVP asks of every aircraft, (n_envs, n_aircraft), as BlueSky's ASAS would fly it now.

    Where ``follow`` is False the aircraft follows its own autopilot (no resolution active); the
    other arrays are NaN there (:func:`release_loop`).
    """

    follow: BoolArray  # the aircraft follows its resolution (BlueSky ``cr.active``)
    trk: Array  # deg, resolution track
    gs: Array  # m/s, resolution ground speed
    vs: Array  # m/s, resolution vertical speed (a magnitude, see the module docstring)
    alt: Array  # m, resolution altitude
    track_change: Array  # deg, resolution track minus the current track, in [-180, 180)
    cas_change: Array  # m/s, CAS change giving the resolution ground speed (same TAS change)
    vertical_speed: Array  # m/s, signed vertical speed flown: ``vs`` towards ``alt``
    ended: BoolArray  # the aircraft's last resolution pair ended in this update (BlueSky then sends it DIRECT to its active waypoint)


class ConflictResolver:
    """A conflict-resolution method as BlueSky's ASAS runs it, for batches of airspaces: detection, resolution, and when to stop.

    This is BlueSky's ``ConflictResolution.update`` and ``resumenav``, shared by every method
    (``RESO MVP``, ``RESO EBY``, ``RESO SWARM``, ...); a method is a subclass that gives
    :meth:`resolve` (and, for ``pair_search="grid"``, :meth:`resolve_pairs`): BlueSky's
    ``resolve(conf, ownship, intruder)``, the resolution track, speed, vertical speed and altitude
    of every aircraft from the conflict picture. The methods are registered by their ``RESO``
    name in :data:`bluesky_gym.core.resolvers.RESOLVERS`.

    Each :meth:`update` detects the conflicts of the current state (:func:`~bluesky_gym.core.conflicts.detect`),
    calls :meth:`resolve` and keeps BlueSky's bookkeeping per airspace: the resolution values are
    renewed whenever the airspace has a conflict (BlueSky computes them for every aircraft then)
    and kept otherwise, and an aircraft follows them while one of its pairs is still being
    resolved (:func:`resume`). A method with :attr:`follow_all` (Swarm) also makes every aircraft
    of the airspace follow its values from each resolution on (BlueSky's ``active.fill(True)``),
    until its own pairs end.

    Args:
        settings: RMETH switches and margins (default: BlueSky's after ``RESO MVP``).
        rpz: Protected-zone radius [m].
        hpz: Protected-zone half height [m].
        lookahead: Look-ahead time [s].
        vsmin: Lower vertical-speed limit [m/s], scalar or per aircraft (default: every aircraft's
            own, from its type, as BlueSky: :func:`vertical_speed_limits`).
        vsmax: Upper vertical-speed limit [m/s], scalar or per aircraft (default: every aircraft's own).
        detector: The conflict detection, by BlueSky name: ``"CSTATEBASED"`` (:func:`~bluesky_gym.core.conflicts.detect`,
            the default) or ``"STATEBASED"`` (:func:`~bluesky_gym.core.conflicts.detect_statebased`, what ``ASAS ON`` selects).
        python_geo: STATEBASED with BlueSky's Python geo functions instead of its compiled ones.
        pair_search: ``"all-pairs"`` (the default): the conflict picture of every pair
            (:func:`~bluesky_gym.core.conflicts.detect`) and the pairs being resolved as an
            (n_envs, n_aircraft, n_aircraft) array (:attr:`pairs`); ``"grid"``: the conflicts as a
            list of pairs (:func:`~bluesky_gym.core.conflicts.detect_pairs`, CSTATEBASED searched
            on a grid) and the pairs being resolved as sorted keys ``(env * n + own) * n + intruder``
            (:attr:`pair_keys`), so that memory and time grow about linearly with the number of
            aircraft. Both give the same resolutions to the bit. A method that needs every pair
            (:attr:`pair_searches`) refuses ``"grid"``.
    """

    #: The method's ``RESO`` name.
    name: ClassVar[str] = ""
    #: After a resolution every aircraft of the airspace follows it (BlueSky's Swarm: ``active.fill(True)``).
    follow_all: ClassVar[bool] = False
    #: The pair searches the method supports.
    pair_searches: ClassVar[tuple[str, ...]] = ("all-pairs", "grid")

    def __init__(
        self,
        settings: ResolutionSettings | None = None,
        *,
        rpz: float = PZ_RADIUS,
        hpz: float = PZ_HEIGHT,
        lookahead: float = LOOKAHEAD,
        vsmin: ArrayLike | None = None,
        vsmax: ArrayLike | None = None,
        detector: str = "CSTATEBASED",
        python_geo: bool = False,
        pair_search: str = "all-pairs",
    ) -> None:
        if detector not in DETECTORS:
            raise ValueError(f"conflict detector {detector!r} not known; choose one of {', '.join(DETECTORS)}")
        if pair_search not in ("all-pairs", "grid"):
            raise ValueError(f"pair_search {pair_search!r} not known; choose 'all-pairs' or 'grid'")
        if pair_search not in self.pair_searches:
            allowed = " or ".join(repr(p) for p in self.pair_searches)
            raise ValueError(f"RESO {self.name} needs pair_search {allowed}, got {pair_search!r}")
        self.pair_search = pair_search
        self.pair_keys = np.zeros(0, np.int64)
        self.grid_work = GridWork()  # the grid's work arrays, kept from update to update
        self.detector = detector
        self.python_geo = python_geo
        self.settings = settings or ResolutionSettings()
        self.rpz, self.hpz, self.lookahead = float(rpz), float(hpz), float(lookahead)
        self.vsmin, self.vsmax = vsmin, vsmax
        self.pairs = np.zeros((0, 0, 0), np.bool_)
        self.held = np.zeros((4, 0, 0))  # trk, gs, vs, alt of the last resolution per airspace
        self.following = np.zeros((0, 0), np.bool_)  # who followed its resolution after the last update (used with follow_all)

    def resolve(self, state: TypedResolutionState, conflicts: Conflicts, vsmin: ArrayLike, vsmax: ArrayLike) -> Resolution:
        """The method's resolution of every aircraft from the conflict picture (BlueSky's ``resolve``).

        Args:
            state: The aircraft state the conflicts were detected in.
            conflicts: The conflict picture of every pair (zone and look-ahead of this resolver).
            vsmin: Lower vertical-speed limit of every aircraft [m/s] (scalar or per aircraft).
            vsmax: Upper vertical-speed limit [m/s].

        Returns:
            Track, speed, vertical speed and altitude of every active aircraft (what BlueSky's
            ``cr.trk``, ``cr.tas``, ``cr.vs``, ``cr.alt`` take).
        """
        raise NotImplementedError(f"{type(self).__name__} does not implement resolve")

    def resolve_pairs(self, state: TypedResolutionState, conflicts: ConflictPairs, vsmin: ArrayLike, vsmax: ArrayLike) -> Resolution:
        """:meth:`resolve` from the conflicts as a list of pairs (``pair_search="grid"``); the same results."""
        raise NotImplementedError(f"{type(self).__name__} does not implement resolve_pairs")

    def reset(self, envs: NDArray[np.bool_] | NDArray[np.int64] | None = None) -> None:
        """Forget the resolutions of the airspaces ``envs`` (a boolean mask or indices; all when None)."""
        if envs is None:
            self.pairs = np.zeros((0, 0, 0), np.bool_)
            self.held = np.zeros((4, 0, 0))
            self.pair_keys = np.zeros(0, np.int64)
            self.following = np.zeros((0, 0), np.bool_)
            return
        if self.pair_keys.size:
            m = self.held.shape[2]
            forget = np.zeros(self.held.shape[1], np.bool_)
            forget[envs] = True
            self.pair_keys = self.pair_keys[~forget[self.pair_keys // (m * m)]]
        if self.held.size:
            self.held[:, envs] = np.nan
        if self.pairs.size:
            self.pairs[envs] = False
        if self.following.size:
            self.following[envs] = False

    def update(self, state: TypedResolutionState) -> ResolutionCommand:
        """Detect, resolve and decide who follows a resolution, from the current state (a :class:`~bluesky_gym.core.physics.Physics`)."""
        follow, ended = self.advance(state)
        return self._command(state, follow, ended)

    def advance(self, state: TypedResolutionState) -> tuple[BoolArray, BoolArray]:
        """:meth:`update`, giving only who follows its resolution and whose resolution ended (:class:`ResolutionCommand`'s ``follow``, ``ended``).

        The resolution itself is :attr:`held` (track, ground speed, vertical speed, altitude; NaN
        for the aircraft that follow none, :func:`release_loop`).
        """
        follow, ended = self._advance_pairs(state) if self.pair_search == "grid" else self._advance_all_pairs(state)
        self.held = np.ascontiguousarray(self.held, dtype=np.float64)  # (the paths above leave an array of their own)
        release_loop(np.ascontiguousarray(follow, dtype=np.bool_), self.held)
        return follow, ended

    def _advance_all_pairs(self, state: TypedResolutionState) -> tuple[BoolArray, BoolArray]:
        """:meth:`advance` with the conflicts of every pair (``pair_search="all-pairs"``)."""
        shape = state.active.shape
        if self.pairs.shape != shape + (shape[1],):
            self.pairs = np.zeros(shape + (shape[1],), np.bool_)
            self.held = np.full((4, *shape), np.nan)
        c = detect_with(
            self.detector,
            state.lat,
            state.lon,
            state.alt,
            state.gs,
            state.trk,
            state.vs,
            state.active,
            self.rpz,
            self.hpz,
            self.lookahead,
            self.python_geo,
        )
        vsmin, vsmax = self._limits(state)
        res = self.resolve(state, c, vsmin, vsmax)
        candidates = np.array(self.pairs, dtype=np.bool_, order="C")
        held = np.array(self.held, dtype=np.float64, order="C")
        renew_loop(np.ascontiguousarray(c.conflict, dtype=np.bool_), res.trk, res.gs, res.vs, res.alt, candidates, held)
        self.held = held
        self.pairs, follow = resume(state, candidates, rpz=self.rpz, resofach=self.settings.resofach)
        ended = np.empty(shape, np.bool_)
        ended_loop(candidates, follow, np.ascontiguousarray(state.active, dtype=np.bool_), ended, np.zeros(1, np.bool_))
        if self.follow_all:
            follow = self._follow_all(state, follow, np.asarray(candidates.any(axis=-1)), np.asarray(c.conflict.any(axis=(-1, -2))))
        return follow, ended

    def _follow_all(self, state: TypedResolutionState, follow: BoolArray, had: BoolArray, renewed: BoolArray) -> BoolArray:
        """Who follows with :attr:`follow_all`: ``resumenav`` for aircraft with pairs, everyone after a resolution, else as before."""
        active = np.asarray(state.active, dtype=np.bool_)
        if self.following.shape != active.shape:
            self.following = np.zeros(active.shape, np.bool_)
        kept = np.where(renewed[:, None], True, self.following)
        self.following = np.where(had, follow, kept) & active
        return np.array(self.following)

    def _limits(self, state: TypedResolutionState) -> tuple[ArrayLike, ArrayLike]:
        vsmin, vsmax = self.vsmin, self.vsmax
        if vsmin is None or vsmax is None:
            own_min, own_max = vertical_speed_limits(state)
            vsmin = own_min if vsmin is None else vsmin
            vsmax = own_max if vsmax is None else vsmax
        return vsmin, vsmax

    def _advance_pairs(self, state: TypedResolutionState) -> tuple[BoolArray, BoolArray]:
        """:meth:`advance` with the conflicts and the pairs being resolved as lists (``pair_search="grid"``).

        The method's :meth:`resolve_pairs`, then BlueSky's bookkeeping; MVP runs all of it in one kernel
        (:meth:`MVPResolver._advance_pairs`).
        """
        active = np.ascontiguousarray(state.active, dtype=np.bool_)
        n_envs, m = active.shape
        if self.held.shape != (4, n_envs, m):
            self.pair_keys = np.zeros(0, np.int64)
            self.held = np.full((4, n_envs, m), np.nan)
        c = detect_pairs(
            state.lat, state.lon, state.alt, state.gs, state.trk, state.vs, active, self.rpz, self.hpz, self.lookahead, self.detector,
            self.python_geo, self.grid_work,
        )  # fmt: skip
        vsmin, vsmax = self._limits(state)
        res = self.resolve_pairs(state, c, vsmin, vsmax)
        # BlueSky's bookkeeping (renew_loop): airspaces with a conflict take the new resolution of
        # every aircraft, and the current conflicts join the pairs being resolved.
        renew = np.zeros(n_envs, np.bool_)
        renew[c.env] = True
        held = np.array(self.held, dtype=np.float64, order="C")
        for row, value in enumerate((res.trk, res.gs, res.vs, res.alt)):
            held[row, renew] = value[renew]
        self.held = held
        own = c.flat_own
        candidates = np.union1d(self.pair_keys, own * m + c.intruder)
        cand_own = candidates // m
        cand_intruder = (cand_own // m) * m + candidates % m
        lat, lon, ve, vn, trk = (
            np.ascontiguousarray(x, dtype=np.float64).reshape(-1) for x in (state.lat, state.lon, state.gseast, state.gsnorth, state.trk)
        )
        keep = np.empty(candidates.size, np.bool_)
        resolution = self.settings.resofach
        resume_pairs_loop(cand_own, cand_intruder, lat, lon, ve, vn, trk, active.reshape(-1), self.rpz, self.rpz * resolution, keep)
        self.pair_keys = candidates[keep]
        follow = np.zeros(n_envs * m, np.bool_)
        follow[cand_own[keep]] = True
        had = np.zeros(n_envs * m, np.bool_)
        had[cand_own] = True
        ended = (had & ~follow & active.reshape(-1)).reshape(n_envs, m)
        return follow.reshape(n_envs, m), ended

    def _command(self, state: TypedResolutionState, follow: BoolArray, ended: BoolArray) -> ResolutionCommand:
        """The :class:`ResolutionCommand` of the held resolution."""
        trk, gs, vs, alt = self.held
        with np.errstate(invalid="ignore"):
            tas = np.asarray(state.tas) + (gs - np.asarray(state.gs))
            cas_change = tas2cas(np.where(np.isfinite(tas), tas, 0.0), state.alt) - tas2cas(state.tas, state.alt)
            return ResolutionCommand(
                follow=follow,
                trk=trk.copy(),
                gs=gs.copy(),
                vs=vs.copy(),
                alt=alt.copy(),
                track_change=np.asarray((trk - np.asarray(state.trk) + 180.0) % 360.0 - 180.0),
                cas_change=np.where(np.isfinite(tas), cas_change, np.nan),
                vertical_speed=np.asarray(np.sign(alt - np.asarray(state.alt)) * np.abs(vs)),
                ended=ended,
            )


class MVPResolver(ConflictResolver):
    """``RESO MVP``: :func:`mvp` (and :func:`mvp_pairs` for ``pair_search="grid"``) under :class:`ConflictResolver`'s bookkeeping."""

    name = "MVP"

    def resolve(self, state: TypedResolutionState, conflicts: Conflicts, vsmin: ArrayLike, vsmax: ArrayLike) -> Resolution:
        """:func:`mvp` with this resolver's settings and zone."""
        return mvp(state, conflicts, self.settings, rpz=self.rpz, hpz=self.hpz, lookahead=self.lookahead, vsmin=vsmin, vsmax=vsmax)

    def resolve_pairs(self, state: TypedResolutionState, conflicts: ConflictPairs, vsmin: ArrayLike, vsmax: ArrayLike) -> Resolution:
        """:func:`mvp_pairs` with this resolver's settings and zone."""
        return mvp_pairs(state, conflicts, self.settings, rpz=self.rpz, hpz=self.hpz, lookahead=self.lookahead, vsmin=vsmin, vsmax=vsmax)

    def _advance_pairs(self, state: TypedResolutionState) -> tuple[BoolArray, BoolArray]:
        """:meth:`ConflictResolver._advance_pairs` for MVP in one kernel (:func:`asas_pairs_kernel`): the same resolutions and pairs."""
        active = np.ascontiguousarray(state.active, dtype=np.bool_)
        n_envs, m = active.shape
        n = n_envs * m
        if self.held.shape != (4, n_envs, m):
            self.pair_keys = np.zeros(0, np.int64)
            self.held = np.full((4, n_envs, m), np.nan)
        if self.detector == "CSTATEBASED":  # the grid's own sorted buffers
            w = self.grid_work
            found = w.detect(state.lat, state.lon, state.alt, state.gs, state.trk, state.vs, active, self.rpz, self.hpz, self.lookahead)
            row, intruder, qdr, dist, tcpa, tlos = w.row, w.out_ij[1], w.out_f[0], w.out_f[1], w.out_f[2], w.out_f[4]
        else:
            c = detect_pairs(
                state.lat, state.lon, state.alt, state.gs, state.trk, state.vs, active, self.rpz, self.hpz, self.lookahead, self.detector,
                self.python_geo,
            )  # fmt: skip
            found = c.env.size
            row = np.zeros(n + 1, np.int64)
            np.cumsum(np.bincount(c.flat_own, minlength=n), out=row[1:])
            intruder = c.env * m + c.intruder
            qdr, dist, tcpa, tlos = c.qdr, c.dist, c.tcpa, c.tlos
        vsmin, vsmax = self._limits(state)
        s, _, floats = _mvp_inputs(state, self.settings, vsmin, vsmax)
        held = np.ascontiguousarray(self.held, dtype=np.float64)  # written in place: the resolver's own (or its simulator's)
        kept = np.empty(self.pair_keys.size + found, np.int64)
        follow, ended = np.empty(n, np.bool_), np.empty(n, np.bool_)
        alt, gseast, gsnorth, vs, trk, gs, selalt, ap_vs, vmin, vmax, vsmin_a, vsmax_a = (x.reshape(-1) for x in floats)
        lat, lon = (float_array(x, active.shape).reshape(-1) for x in (state.lat, state.lon))
        counts = np.zeros(1, np.int64)
        zone = (self.rpz * s.resofach, self.hpz * s.resofacv, self.lookahead, s.mode, 1.0 if s.swresohoriz else 0.0)
        asas_pairs_kernel(
            m, row, intruder, qdr, dist, tcpa, tlos, active.reshape(-1), alt, gseast, gsnorth, vs, trk, gs, selalt, ap_vs, vmin, vmax,
            vsmin_a, vsmax_a, *zone, held.reshape(4, n), self.pair_keys, lat, lon, self.rpz, self.rpz * s.resofach, kept, follow, ended, counts,
        )  # fmt: skip
        self.held = held
        self.pair_keys = kept[: counts[0]]
        return follow.reshape(n_envs, m), ended.reshape(n_envs, m)


__all__ = [
    "RESO_FACTOR",
    "AsasConfig",
    "ConflictResolver",
    "MVPResolver",
    "Resolution",
    "ResolutionCommand",
    "ResolutionSettings",
    "ResolutionState",
    "mvp",
    "mvp_pair",
    "mvp_pairs",
    "resume",
]
