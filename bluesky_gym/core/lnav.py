"""LNAV: BlueSky 1.1.1's active-waypoint logic, per aircraft [docs/dynamics.md §2.6].

:func:`lnav_one` switches an aircraft to its next waypoint when the active one is reached (fly-by
turn anticipation, ``actwp.reached``) and steers the autopilot track to the active waypoint. The
step kernel calls it before the autopilot; :func:`turn_distances` serves the route commands.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from bluesky_gym.core.geo import degto180, qdrdist_s
from bluesky_gym.core.jit import flat_float_args, grid_range, jit, jit_inline, shaped
from bluesky_gym.core.scalar import RAD
from bluesky_gym.core.scalar import maximum as _maximum
from bluesky_gym.core.scalar import mod as _mod
from bluesky_gym.core.state import (
    I_ACTWP_LAT,
    I_ACTWP_LON,
    I_AP_TRK,
    I_CURLEGDIR,
    I_GS,
    I_LAT,
    I_LON,
    I_NEXT_QDR,
    I_TAS,
    I_TRK,
    I_TURNDIST,
    I_TURNPHI,
)
from bluesky_gym.core.units import BANK_DEFAULT, G0, NM, NO_VALUE

Array = NDArray[np.float64]

#: ``turnphi`` after a waypoint activation: deg2rad(rad2deg(bankdef)), which may differ by one ulp.
BANK_LNAV = float(np.deg2rad(np.rad2deg(np.float64(BANK_DEFAULT))))
#: g0 * tan(bank) of a waypoint turn, as BlueSky's ``calcturn`` evaluates it [m/s^2].
G_TAN_LNAV = G0 * float(np.tan(np.deg2rad(np.rad2deg(np.float64(BANK_DEFAULT)))))
CLOSE_TO_WP_S = 4.0  # s: a waypoint closer than this (at the ground speed) counts as "close"
GS_FLOOR = 0.0001  # m/s, floor of the ground speed in that test


@jit
def turn_distance(tas: float, qdr: float, next_qdr: float) -> float:
    """Fly-by turn anticipation distance [m] (``actwp.calcturn`` with default turn data)."""
    local_next = qdr if next_qdr < -900.0 else next_qdr
    turnrad = tas * tas / G_TAN_LNAV
    return abs(turnrad * math.tan(0.5 * abs(degto180(_mod(qdr, 360.0) - _mod(local_next, 360.0))) * RAD))


@jit_inline
def lnav_one(F, i, swlnav, swvnav, swvnavspd, swlastwp, active, iactwp, nwp, route_lat, route_lon, python_geo):  # type: ignore[no-untyped-def]
    """LNAV of aircraft ``i``: waypoint switching and the autopilot track.

    Args:
        F: The float state block (fields, aircraft).
        i: Aircraft (column of ``F``).
        swlnav: (aircraft,) LNAV switch.
        swvnav: (aircraft,) VNAV switch.
        swvnavspd: (aircraft,) VNAV speed switch.
        swlastwp: (aircraft,) whether the active waypoint is the last.
        active: (aircraft,) slots holding an aircraft.
        iactwp: (aircraft,) active waypoint index.
        nwp: (aircraft,) route length.
        route_lat: (aircraft, waypoints) route latitudes [deg].
        route_lon: (aircraft, waypoints) route longitudes [deg].
        python_geo: Use BlueSky's Python geo forms instead of the compiled ones.
    """
    if not swlnav[i]:
        return
    qdr, distnm = qdrdist_s(python_geo, F[I_LAT, i], F[I_LON, i], F[I_ACTWP_LAT, i], F[I_ACTWP_LON, i])
    dist = distnm * NM
    # actwp.reached [docs/dynamics.md §2.6]; all waypoints here are fly-by.
    close2wp = dist / _maximum(GS_FLOOR, abs(F[I_GS, i])) < CLOSE_TO_WP_S
    tooclose2turn = close2wp and abs(degto180(_mod(F[I_TRK, i], 360.0) - _mod(qdr, 360.0))) > 90.0
    awayorpassed = tooclose2turn or abs(degto180(qdr - F[I_CURLEGDIR, i])) > 90.0
    if active[i] and (awayorpassed or dist < F[I_TURNDIST, i]):
        if swlastwp[i]:
            swlnav[i] = False
            swvnav[i] = False
            swvnavspd[i] = False
        else:
            n = nwp[i]
            iact = iactwp[i]
            lnavon = iact < n - 1
            if lnavon:
                iact += 1
            iactwp[i] = iact
            swlastwp[i] = iact == n - 1
            if iact > -1 and iact < n - 1:
                nq, _ = qdrdist_s(python_geo, route_lat[i, iact], route_lon[i, iact], route_lat[i, iact + 1], route_lon[i, iact + 1])
            else:
                nq = NO_VALUE
            F[I_NEXT_QDR, i] = nq
            if not lnavon:
                swlnav[i] = False
            swvnav[i] = swvnav[i] and swlnav[i]
            wlat, wlon = route_lat[i, iact], route_lon[i, iact]
            F[I_ACTWP_LAT, i] = wlat
            F[I_ACTWP_LON, i] = wlon
            qdr, _ = qdrdist_s(python_geo, F[I_LAT, i], F[I_LON, i], wlat, wlon)
            F[I_CURLEGDIR, i] = qdr
            F[I_TURNDIST, i] = turn_distance(F[I_TAS, i], qdr, nq)
            F[I_TURNPHI, i] = BANK_LNAV
    if swlnav[i]:
        F[I_AP_TRK, i] = _mod(qdr, 360.0)


@jit
def lnav_kernel(F, swlnav, swvnav, swvnavspd, swlastwp, active, iactwp, nwp, route_lat, route_lon, python_geo):  # type: ignore[no-untyped-def]
    """LNAV of every aircraft (flattened arrays; ``route_*`` shaped (aircraft, waypoints))."""
    for i in grid_range(F.shape[1]):
        lnav_one(F, i, swlnav, swvnav, swvnavspd, swlastwp, active, iactwp, nwp, route_lat, route_lon, python_geo)


@jit
def _turn_distance_loop(tas, qdr, next_qdr, out):  # type: ignore[no-untyped-def]
    for i in grid_range(tas.shape[0]):
        out[i] = turn_distance(tas[i], qdr[i], next_qdr[i])


def turn_distances(tas: ArrayLike, qdr: ArrayLike, next_qdr: ArrayLike) -> Array:
    """:func:`turn_distance` [m], broadcast over arrays."""
    shape, (t, q, nq) = flat_float_args(tas, qdr, next_qdr)
    out = np.empty(t.size)
    _turn_distance_loop(t, q, nq, out)
    return shaped(out, shape)  # type: ignore[no-any-return]
