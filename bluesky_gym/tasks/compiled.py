"""Optional compiled observation and reward geometry of the traffic tasks.

The numpy code in the task modules is the reference. At one episode a step of SectorCR, Merge or
StaticObstacle issues a hundred small numpy calls (kwik geometry, sorting the intruders, polygon
tests), which cost far more than the physics; at large batches the same code makes a dozen passes
over (episodes, aircraft) arrays. The functions here compute the same quantities in one loop per
episode with numba.

They are bit-identical to the numpy path: the same operations in the same order (numpy's
``deg2rad``/``rad2deg`` factors, its float remainder, left-to-right products), no floating-point
contraction, and the tests compare both paths to the last bit. A task uses them when its physics
runs the fused kernel (numba installed, the ``fast`` extra); ``Simulator(kernel="numpy")`` keeps
the whole task on numpy.
"""

from __future__ import annotations

import math

import numpy as np

from bluesky_gym.core.jit import AVAILABLE, jit, jit_inline
from bluesky_gym.core.scalar import mod as _mod
from bluesky_gym.core.units import NM2KM

__all__ = ["AVAILABLE"]

_RAD = np.pi / 180.0  # numpy's deg2rad factor
_DEG = 180.0 / np.pi  # numpy's rad2deg factor
_KWIK_R = 6371000.0  # m: Earth radius of BlueSky's Python kwik forms
_KWIK_NM = 1852.0  # m per NM in those forms
_M_PER_KM = 1000.0


# --- BlueSky's Python kwik forms (tasks/geometry.ref_kwik*), per pair of points -----------------
@jit_inline
def _kwik_parts(lata, lona, latb, lonb):
    dlat = (latb - lata) * _RAD
    dlon = (_mod((lonb - lona) + 180.0, 360.0) - 180.0) * _RAD
    cavelat = math.cos((lata + latb) * _RAD * 0.5)
    return dlat, dlon, cavelat


@jit_inline
def _kwikdist(lata, lona, latb, lonb):
    """:func:`~bluesky_gym.tasks.geometry.ref_kwikdist` [NM]."""
    dlat, dlon, cavelat = _kwik_parts(lata, lona, latb, lonb)
    return _KWIK_R * math.sqrt(dlat * dlat + dlon * dlon * cavelat * cavelat) / _KWIK_NM


@jit_inline
def _kwikqdrdist(lata, lona, latb, lonb):
    """:func:`~bluesky_gym.tasks.geometry.ref_kwikqdrdist`: bearing [deg, 0..360) and distance [NM]."""
    dlat, dlon, cavelat = _kwik_parts(lata, lona, latb, lonb)
    dist = _KWIK_R * math.sqrt(dlat * dlat + dlon * dlon * cavelat * cavelat) / _KWIK_NM
    qdr = _mod(math.atan2(dlon * cavelat, dlat) * _DEG, 360.0)
    return qdr, dist


@jit_inline
def _kwikdist_matrix(lata, lona, latb, lonb):
    """:func:`~bluesky_gym.tasks.geometry.ref_kwikdist_matrix` [NM] (other product grouping)."""
    dlat, dlon, cavelat = _kwik_parts(lata, lona, latb, lonb)
    return _KWIK_R * math.sqrt(dlat * dlat + (dlon * dlon) * (cavelat * cavelat)) / _KWIK_NM


@jit_inline
def _wrap180(x):
    """The reference's single wrap (:func:`bluesky_gym.tasks.base.wrap180`)."""
    if x > 180.0:
        return x - 360.0
    if x < -180.0:
        return x + 360.0
    return x


@jit_inline
def _closest(key, active, out, best):
    """Indices of the ``len(out)`` smallest ``key[j]`` over active j (ties: lower j first).

    The first columns of a stable argsort of ``where(active, key, inf)``; empty slots count as
    inf. ``key`` and ``active`` run over the intruders (slots 1.. of the airspace); ``best`` is
    scratch space of ``len(out)`` floats.
    """
    k = out.shape[0]
    filled = 0
    for j in range(key.shape[0]):
        d = key[j] if active[j] else np.inf
        if filled < k:
            pos = filled
            filled += 1
        elif d < best[k - 1]:
            pos = k - 1
        else:
            continue
        while pos > 0 and d < best[pos - 1]:
            best[pos] = best[pos - 1]
            out[pos] = out[pos - 1]
            pos -= 1
        best[pos] = d
        out[pos] = j


@jit_inline
def _polygon_contains(y, x, py, px, nv):
    """Even-odd test of point (lat y, lon x) against the first ``nv`` vertices of (py, px).

    :class:`~bluesky_gym.tasks.geometry.PolygonSet` for one point and one polygon.
    """
    inside = False
    for v in range(nv):
        w = v + 1 if v + 1 < nv else 0
        y1, x1, y2, x2 = py[v], px[v], py[w], px[w]
        if (y1 > y) != (y2 > y) and x < (x2 - x1) * (y - y1) / (y2 - y1) + x1:
            inside = not inside
    return inside


# --- shared by the tasks -----------------------------------------------------------------------
@jit
def kwik_separation(lat, lon, alt, active, intrusion_nm, vertical_m, dist_out, los_out):
    """:meth:`bluesky_gym.tasks.base.Task.kwik_separation` into ``dist_out``/``los_out`` (n, m).

    ``vertical_m`` NaN means a purely horizontal intrusion test.
    """
    for e in range(lat.shape[0]):
        lat0, lon0, alt0 = lat[e, 0], lon[e, 0], alt[e, 0]
        dist_out[e, 0] = np.inf
        los_out[e, 0] = False
        for j in range(1, lat.shape[1]):
            if active[e, j]:
                d = _kwikdist(lat0, lon0, lat[e, j], lon[e, j])
                dist_out[e, j] = d
                los = d < intrusion_nm
                if los and not math.isnan(vertical_m):
                    los = abs(alt0 - alt[e, j]) < vertical_m
                los_out[e, j] = los
            else:
                dist_out[e, j] = np.inf
                los_out[e, j] = False


@jit
def ownship_in_polygons(lat, lon, poly_lat, poly_lon, n_vertices, out):
    """Whether each episode's ownship (slot 0) lies in each of its polygons.

    ``poly_*`` are (n, K, V), ``n_vertices`` (n, K), ``out`` (n, K).
    """
    for e in range(poly_lat.shape[0]):
        for k in range(poly_lat.shape[1]):
            out[e, k] = _polygon_contains(lat[e, 0], lon[e, 0], poly_lat[e, k], poly_lon[e, k], n_vertices[e, k])


@jit
def points_in_owner_polygon(lat, lon, owner, poly_lat, poly_lon, n_vertices, out):
    """Even-odd test of points (P,) each against the polygon of its episode ``owner[p]``.

    ``poly_*`` are (n, V) and ``n_vertices`` (n,); ``out`` is (P,).
    """
    for p in range(lat.shape[0]):
        e = owner[p]
        out[p] = _polygon_contains(lat[p], lon[p], poly_lat[e], poly_lon[e], n_vertices[e])


@jit
def ownship_polygon_counts(track, poly_lat, poly_lon, n_vertices, out):
    """How many of its polygons contain each episode's ownship at each step of a track.

    ``track`` is :meth:`bluesky_gym.core.Simulator.run`'s (steps, 2, n, m) positions, ``poly_*``
    (n, K, V), ``n_vertices`` (n, K) and ``out`` (steps, n).
    """
    for e in range(poly_lat.shape[0]):
        for k in range(track.shape[0]):
            out[k, e] = 0
        for j in range(poly_lat.shape[1]):
            nv = n_vertices[e, j]
            if nv == 0:
                continue
            # A point outside the polygon's latitude range crosses no edge: the even-odd test
            # would say "outside" for it, so only the others are tested.
            lo = hi = poly_lat[e, j, 0]
            for v in range(1, nv):
                lo = min(lo, poly_lat[e, j, v])
                hi = max(hi, poly_lat[e, j, v])
            for k in range(track.shape[0]):
                y = track[k, 0, e, 0]
                if lo <= y < hi and _polygon_contains(y, track[k, 1, e, 0], poly_lat[e, j], poly_lon[e, j], nv):
                    out[k, e] += 1


@jit
def intruder_relative_state(lat, lon, hdg, gs, out):
    """:func:`bluesky_gym.tasks.vertical_cr.intruder_relative_state` into ``out`` (5, n, m - 1).

    Rows: dist_km, cos_bearing, sin_bearing, x_dif, y_dif.
    """
    for e in range(lat.shape[0]):
        lat0, lon0, hdg0, gs0 = lat[e, 0], lon[e, 0], hdg[e, 0], gs[e, 0]
        for j in range(1, lat.shape[1]):
            qdr, dist = _kwikqdrdist(lat0, lon0, lat[e, j], lon[e, j])
            bearing = _wrap180(hdg0 - qdr) * _RAD
            difference = (hdg0 - hdg[e, j]) * _RAD
            out[0, e, j - 1] = dist * NM2KM
            out[1, e, j - 1] = math.cos(bearing)
            out[2, e, j - 1] = math.sin(bearing)
            out[3, e, j - 1] = -math.cos(difference) * gs[e, j]
            out[4, e, j - 1] = gs0 - math.sin(difference) * gs[e, j]


@jit_inline
def _relative_velocity(hdg, tas, e, j):
    """(vx_r, vy_r) of intruder slot ``j`` (:func:`bluesky_gym.tasks.sector_cr.relative_velocity`)."""
    vx = math.cos(hdg[e, j] * _RAD) * tas[e, j] - math.cos(hdg[e, 0] * _RAD) * tas[e, 0]
    vy = math.sin(hdg[e, j] * _RAD) * tas[e, j] - math.sin(hdg[e, 0] * _RAD) * tas[e, 0]
    return vx, vy


# --- SectorCR ----------------------------------------------------------------------------------
@jit
def sector_observe(envs, lat, lon, hdg, tas, active, wpt_lat, wpt_lon, center, scales, drift_out, own_out, intruder_out):
    """:meth:`bluesky_gym.tasks.sector_cr.SectorCRTask.observe` of episodes ``envs``.

    Args:
        envs: (p,) the episodes to observe; output row i belongs to episode ``envs[i]``.
        lat: (n, m) latitudes [deg].
        lon: (n, m) longitudes [deg].
        hdg: (n, m) headings [deg].
        tas: (n, m) true airspeeds [m/s].
        active: (n, m) occupied slots.
        wpt_lat: (n,) latitude of the agent's waypoint [deg].
        wpt_lon: (n,) its longitude [deg].
        center: (lat, lon, cos(radians(lat))) of the flat projection.
        scales: (airspeed mean, airspeed std, position, vx, vy, distance mean, distance std).
        drift_out: (p,) drift [deg].
        own_out: (p, 3) cos(drift), sin(drift), airspeed.
        intruder_out: (p, 7, k) x_r, y_r, vx_r, vy_r, cos(track), sin(track), distances of the
            k closest intruders.
    """
    spd_mean, spd_std, pos_scale, vx_scale, vy_scale, d_mean, d_std = scales
    clat, clon, ccos = center
    m = lat.shape[1]
    k = intruder_out.shape[2]
    key = np.empty(m - 1)
    order = np.empty(k, np.int64)
    best = np.empty(k)
    rx = np.empty(m - 1)
    ry = np.empty(m - 1)
    for r in range(envs.shape[0]):
        e = envs[r]
        qdr, _ = _kwikqdrdist(lat[e, 0], lon[e, 0], wpt_lat[e], wpt_lon[e])
        drift = _wrap180(hdg[e, 0] - qdr)
        drift_out[r] = drift
        own_out[r, 0] = math.cos(drift * _RAD)
        own_out[r, 1] = math.sin(drift * _RAD)
        own_out[r, 2] = (tas[e, 0] - spd_mean) / spd_std
        # Flat positions [m] around the sector centre (geometry.latlon_to_nm * 1852).
        x0 = (lat[e, 0] - clat) * 60.0 * NM2KM * _M_PER_KM
        y0 = (lon[e, 0] - clon) * 60.0 * ccos * NM2KM * _M_PER_KM
        for j in range(1, m):
            rx[j - 1] = (lat[e, j] - clat) * 60.0 * NM2KM * _M_PER_KM - x0
            ry[j - 1] = (lon[e, j] - clon) * 60.0 * ccos * NM2KM * _M_PER_KM - y0
            key[j - 1] = math.sqrt(rx[j - 1] * rx[j - 1] + ry[j - 1] * ry[j - 1])
        _closest(key, active[e, 1:], order, best)
        for i in range(k):
            j = order[i]
            vx, vy = _relative_velocity(hdg, tas, e, j + 1)
            trk = math.atan2(vy, vx)
            intruder_out[r, 0, i] = rx[j] / pos_scale
            intruder_out[r, 1, i] = ry[j] / pos_scale
            intruder_out[r, 2, i] = vx / vx_scale
            intruder_out[r, 3, i] = vy / vy_scale
            intruder_out[r, 4, i] = math.cos(trk)
            intruder_out[r, 5, i] = math.sin(trk)
            intruder_out[r, 6, i] = (key[j] - d_mean) / d_std


# --- Merge -------------------------------------------------------------------------------------
@jit
def merge_observe(envs, lat, lon, hdg, tas, active, target_lat, target_lon, scales, own_out, intruder_out):
    """:meth:`bluesky_gym.tasks.merge.MergeTask.observe` of episodes ``envs``.

    Args:
        envs: (p,) the episodes to observe; output row i belongs to episode ``envs[i]``.
        lat: (n, m) latitudes [deg].
        lon: (n, m) longitudes [deg].
        hdg: (n, m) headings [deg].
        tas: (n, m) true airspeeds [m/s].
        active: (n, m) occupied slots.
        target_lat: (n,) latitude of the ownship's current target [deg].
        target_lon: (n,) its longitude [deg].
        scales: (position, speed, distance) divisors.
        own_out: (p, 4) drift [deg], target distance [NM], cos(drift), sin(drift).
        intruder_out: (p, 7, k) x_r, y_r, vx_r, vy_r, cos(track), sin(track), distances of the
            k closest intruders.
    """
    pos_scale, spd_scale, d_scale = scales
    m = lat.shape[1]
    k = intruder_out.shape[2]
    key = np.empty(m - 1)
    order = np.empty(k, np.int64)
    best = np.empty(k)
    for r in range(envs.shape[0]):
        e = envs[r]
        lat0, lon0 = lat[e, 0], lon[e, 0]
        qdr, dist = _kwikqdrdist(lat0, lon0, target_lat[e], target_lon[e])
        drift = _wrap180(hdg[e, 0] - qdr)
        own_out[r, 0] = drift
        own_out[r, 1] = dist
        own_out[r, 2] = math.cos(drift * _RAD)
        own_out[r, 3] = math.sin(drift * _RAD)
        for j in range(1, m):
            key[j - 1] = _kwikdist_matrix(lat0, lon0, lat[e, j], lon[e, j])
        _closest(key, active[e, 1:], order, best)
        for i in range(k):
            j = order[i] + 1
            brg, d_int = _kwikqdrdist(lat0, lon0, lat[e, j], lon[e, j])
            d_m = d_int * NM2KM * _M_PER_KM
            vx, vy = _relative_velocity(hdg, tas, e, j)
            trk = math.atan2(vy, vx)
            intruder_out[r, 0, i] = d_m * math.cos(brg * _RAD) / pos_scale
            intruder_out[r, 1, i] = d_m * math.sin(brg * _RAD) / pos_scale
            intruder_out[r, 2, i] = vx / spd_scale
            intruder_out[r, 3, i] = vy / spd_scale
            intruder_out[r, 4, i] = math.cos(trk)
            intruder_out[r, 5, i] = math.sin(trk)
            intruder_out[r, 6, i] = key[j - 1] / d_scale


# --- array forms of the scenario and kwik geometry (tasks/geometry.py wraps these) -------------
@jit_inline
def _point_at_distance(lat, lon, d_km, bearing, radius_km):
    """Great-circle destination (lat, lon) [deg] at ``d_km`` along ``bearing`` [deg] (spherical)."""
    lat1 = lat * _RAD
    lon1 = lon * _RAD
    a = bearing * _RAD
    dr = d_km / radius_km
    lat2 = math.asin(math.sin(lat1) * math.cos(dr) + math.cos(lat1) * math.sin(dr) * math.cos(a))
    lon2 = lon1 + math.atan2(math.sin(a) * math.sin(dr) * math.cos(lat1), math.cos(dr) - math.sin(lat1) * math.sin(lat2))
    return lat2 * _DEG, lon2 * _DEG


@jit_inline
def _at(a, i, j):
    """``a[i, j]`` of a 2-D array broadcast against (i, j): a dimension of length 1 repeats."""
    return a[i if a.shape[0] > 1 else 0, j if a.shape[1] > 1 else 0]


@jit
def point_at_distance(lat, lon, d_km, bearing, radius_km, lat_out, lon_out):
    """:func:`bluesky_gym.tasks.geometry.point_at_distance` of 2-D inputs broadcast to the outputs' shape."""
    for i in range(lat_out.shape[0]):
        for j in range(lat_out.shape[1]):
            lat_out[i, j], lon_out[i, j] = _point_at_distance(_at(lat, i, j), _at(lon, i, j), _at(d_km, i, j), _at(bearing, i, j), radius_km)


@jit
def kwikdist(lata, lona, latb, lonb, dist_out):
    """:func:`bluesky_gym.tasks.geometry.ref_kwikdist` of 2-D inputs broadcast to the output's shape."""
    for i in range(dist_out.shape[0]):
        for j in range(dist_out.shape[1]):
            dist_out[i, j] = _kwikdist(_at(lata, i, j), _at(lona, i, j), _at(latb, i, j), _at(lonb, i, j))


@jit
def kwikqdrdist(lata, lona, latb, lonb, qdr_out, dist_out):
    """:func:`bluesky_gym.tasks.geometry.ref_kwikqdrdist` of 2-D inputs broadcast to the outputs' shape."""
    for i in range(dist_out.shape[0]):
        for j in range(dist_out.shape[1]):
            qdr_out[i, j], dist_out[i, j] = _kwikqdrdist(_at(lata, i, j), _at(lona, i, j), _at(latb, i, j), _at(lonb, i, j))


@jit
def kwikdist_matrix(lata, lona, latb, lonb, dist_out):
    """:func:`bluesky_gym.tasks.geometry.ref_kwikdist_matrix` of 2-D inputs broadcast to the output's shape."""
    for i in range(dist_out.shape[0]):
        for j in range(dist_out.shape[1]):
            dist_out[i, j] = _kwikdist_matrix(_at(lata, i, j), _at(lona, i, j), _at(latb, i, j), _at(lonb, i, j))


@jit
def points_in_polygons(lat, lon, poly_lat, poly_lon, n_vertices, out):
    """Even-odd test of points (B, P) against polygons (B, K, V) with ``n_vertices`` (B, K) into ``out`` (B, P, K)."""
    for b in range(lat.shape[0]):
        for p in range(lat.shape[1]):
            for k in range(poly_lat.shape[1]):
                out[b, p, k] = _polygon_contains(lat[b, p], lon[b, p], poly_lat[b, k], poly_lon[b, k], n_vertices[b, k])
