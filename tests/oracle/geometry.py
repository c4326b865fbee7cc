"""Readable numpy forms of the task-layer geometry (oracles of ``bluesky_gym.tasks.geometry`` and its kernels).

The package computes these quantities with the scalar kernels of ``bluesky_gym.tasks.compiled``;
the tests compare them with the array formulas below to the last bit (numpy's AVX-512 dispatch
off, as for every bit-exact comparison).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

Array = NDArray[np.float64]

EARTH_RADIUS_KM = 6371.0
KWIK_EARTH_RADIUS_M = 6371000.0
KWIK_NM_M = 1852.0


def point_at_distance(lat: ArrayLike, lon: ArrayLike, d_km: ArrayLike, bearing: ArrayLike, radius_km: float = EARTH_RADIUS_KM) -> tuple[Array, Array]:
    """Great-circle destination [deg] at ``d_km`` along initial ``bearing`` [deg] (spherical)."""
    lat1 = np.radians(lat)
    lon1 = np.radians(lon)
    a = np.radians(bearing)
    dr = np.asarray(d_km, dtype=np.float64) / radius_km
    lat2 = np.arcsin(np.sin(lat1) * np.cos(dr) + np.cos(lat1) * np.sin(dr) * np.cos(a))
    lon2 = lon1 + np.arctan2(np.sin(a) * np.sin(dr) * np.cos(lat1), np.cos(dr) - np.sin(lat1) * np.sin(lat2))
    return np.degrees(lat2), np.degrees(lon2)


class PolygonSet:
    """Polygons in (lat, lon) prepared for repeated even-odd point-in-polygon tests.

    BlueSky's 2-D ``checkInside`` (a matplotlib path test without altitude limits), batched.

    Args:
        poly_lat: Vertices, shape (..., K, V), padded beyond ``n_vertices``.
        poly_lon: Same shape as ``poly_lat``.
        n_vertices: Vertex count of each polygon, shape (..., K); 0 means no polygon.
    """

    def __init__(self, poly_lat: ArrayLike, poly_lon: ArrayLike, n_vertices: ArrayLike) -> None:
        py = np.asarray(poly_lat, dtype=np.float64)
        px = np.asarray(poly_lon, dtype=np.float64)
        nv = np.asarray(n_vertices)[..., :, None]  # (..., K, 1)
        v = np.arange(py.shape[-1])
        last = v + 1 >= nv  # the closing edge goes back to vertex 0
        # Edge v runs from vertex v to vertex v + 1 (or 0).
        qy = np.where(last, py[..., :1], np.concatenate([py[..., 1:], py[..., :1]], axis=-1))
        qx = np.where(last, px[..., :1], np.concatenate([px[..., 1:], px[..., :1]], axis=-1))
        self._py, self._px = py[..., None, :, :], px[..., None, :, :]  # (..., 1, K, V)
        self._qy, self._qx = qy[..., None, :, :], qx[..., None, :, :]
        self._valid = (v < nv)[..., None, :, :]
        self._dx = self._qx - self._px
        self._dy = self._qy - self._py

    def contains(self, lat: ArrayLike, lon: ArrayLike) -> NDArray[np.bool_]:
        """Inside flags, shape (..., P, K), of points (..., P)."""
        y = np.asarray(lat, dtype=np.float64)[..., :, None, None]  # (..., P, 1, 1)
        x = np.asarray(lon, dtype=np.float64)[..., :, None, None]
        py, px, qy = self._py, self._px, self._qy
        with np.errstate(divide="ignore", invalid="ignore"):
            crosses = ((py > y) != (qy > y)) & (x < self._dx * (y - py) / self._dy + px)
        return (np.count_nonzero(crosses & self._valid, axis=-1) % 2) == 1


def points_in_polygons(lat: ArrayLike, lon: ArrayLike, poly_lat: ArrayLike, poly_lon: ArrayLike, n_vertices: ArrayLike) -> NDArray[np.bool_]:
    """Even-odd point-in-polygon test on (lat, lon), batched (BlueSky's 2-D ``checkInside``).

    Args:
        lat: Points, shape (..., P).
        lon: Points, shape (..., P).
        poly_lat: Polygon vertices, shape (..., K, V) (padded beyond ``n_vertices``).
        poly_lon: Same shape as ``poly_lat``.
        n_vertices: Vertex count of each polygon, shape (..., K); 0 means no polygon.

    Returns:
        Inside flags, shape (..., P, K).
    """
    return PolygonSet(poly_lat, poly_lon, n_vertices).contains(lat, lon)


def _kwik_py(lata: ArrayLike, lona: ArrayLike, latb: ArrayLike, lonb: ArrayLike) -> tuple[Array, Array, Array]:
    lata, lona = np.asarray(lata, dtype=np.float64), np.asarray(lona, dtype=np.float64)
    latb, lonb = np.asarray(latb, dtype=np.float64), np.asarray(lonb, dtype=np.float64)
    dlat = np.radians(latb - lata)
    dlon = np.radians(((lonb - lona) + 180) % 360 - 180)
    cavelat = np.cos(np.radians(lata + latb) * 0.5)
    return dlat, dlon, cavelat


def ref_kwikdist(lata: ArrayLike, lona: ArrayLike, latb: ArrayLike, lonb: ArrayLike) -> Array:
    """Flat-earth distance [NM] a -> b, as BlueSky's Python ``geo.kwikdist`` (see above)."""
    dlat, dlon, cavelat = _kwik_py(lata, lona, latb, lonb)
    dangle = np.sqrt(dlat * dlat + dlon * dlon * cavelat * cavelat)
    return KWIK_EARTH_RADIUS_M * dangle / KWIK_NM_M


def ref_kwikqdrdist(lata: ArrayLike, lona: ArrayLike, latb: ArrayLike, lonb: ArrayLike) -> tuple[Array, Array]:
    """Flat-earth bearing [deg, 0..360) and distance [NM] a -> b, as BlueSky's Python ``geo.kwikqdrdist``."""
    dlat, dlon, cavelat = _kwik_py(lata, lona, latb, lonb)
    dangle = np.sqrt(dlat * dlat + dlon * dlon * cavelat * cavelat)
    dist = KWIK_EARTH_RADIUS_M * dangle / KWIK_NM_M
    qdr = np.degrees(np.arctan2(dlon * cavelat, dlat)) % 360.0
    return qdr, dist


def ref_kwikdist_matrix(lata: ArrayLike, lona: ArrayLike, latb: ArrayLike, lonb: ArrayLike) -> Array:
    """Flat-earth distance [NM] a -> b as BlueSky's Python ``geo.kwikdist_matrix`` (broadcasting).

    The formula of :func:`ref_kwikdist` with the products grouped as
    dlat^2 + (dlon^2)(cavelat^2), which can differ in the last bit. The reference sorts the
    intruders and fills ``distances`` with it, and ``x_r``/``y_r`` with ``kwikqdrdist``.
    """
    dlat, dlon, cavelat = _kwik_py(lata, lona, latb, lonb)
    dangle = np.sqrt(np.multiply(dlat, dlat) + np.multiply(np.multiply(dlon, dlon), np.multiply(cavelat, cavelat)))
    return KWIK_EARTH_RADIUS_M * dangle / KWIK_NM_M


def sort_points_clockwise(vertices: ArrayLike) -> Array:
    """Sort (north, east) points by atan2(east, north) ascending: clockwise by compass bearing."""
    v = np.asarray(vertices, dtype=np.float64)
    return v[np.argsort(np.arctan2(v[:, 1], v[:, 0]), kind="stable")]


def initial_bearing(lat1: ArrayLike, lon1: ArrayLike, lat2: ArrayLike, lon2: ArrayLike) -> Array:
    """Great-circle initial bearing [deg, 0..360) from point 1 to point 2 (the reference ``get_hdg``), in numpy."""
    p1, l1 = np.radians(lat1), np.radians(lon1)
    p2, l2 = np.radians(lat2), np.radians(lon2)
    delta_lon = l2 - l1
    x = np.sin(delta_lon) * np.cos(p2)
    y = np.cos(p1) * np.sin(p2) - np.sin(p1) * np.cos(p2) * np.cos(delta_lon)
    bearing: Array = (np.degrees(np.arctan2(x, y)) + 360) % 360
    return bearing
