"""Scenario geometry of the paper's environments (bluesky-gym 0.2.0 ``envs/common/functions``).

Re-implemented from their description in the environment specification, vectorised where the
tasks need it, with every random draw taken from a generator passed in.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

Array = NDArray[np.float64]

EARTH_RADIUS_KM = 6371.0


def wrap180(angle: ArrayLike) -> Array:
    """Single wrap into [-180, 180]: x > 180 -> x - 360; x < -180 -> x + 360 (once only)."""
    a = np.asarray(angle, dtype=np.float64)
    return np.where(a > 180, -(360 - a), np.where(a < -180, 360 + a, a))


def point_at_distance(lat: ArrayLike, lon: ArrayLike, d_km: ArrayLike, bearing: ArrayLike, radius_km: float = EARTH_RADIUS_KM) -> tuple[Array, Array]:
    """Great-circle destination [deg] at ``d_km`` along initial ``bearing`` [deg] (spherical)."""
    lat1 = np.radians(lat)
    lon1 = np.radians(lon)
    a = np.radians(bearing)
    dr = np.asarray(d_km, dtype=np.float64) / radius_km
    lat2 = np.arcsin(np.sin(lat1) * np.cos(dr) + np.cos(lat1) * np.sin(dr) * np.cos(a))
    lon2 = lon1 + np.arctan2(np.sin(a) * np.sin(dr) * np.cos(lat1), np.cos(dr) - np.sin(lat1) * np.sin(lat2))
    return np.degrees(lat2), np.degrees(lon2)


def point_at_distance_scalar(lat: float, lon: float, d_km: float, bearing: float, radius_km: float = EARTH_RADIUS_KM) -> tuple[float, float]:
    """:func:`point_at_distance` for one point, in scalar Python (the same libm calls and order)."""
    lat1 = math.radians(lat)
    lon1 = math.radians(lon)
    a = math.radians(bearing)
    dr = float(d_km) / radius_km
    lat2 = math.asin(math.sin(lat1) * math.cos(dr) + math.cos(lat1) * math.sin(dr) * math.cos(a))
    lon2 = lon1 + math.atan2(math.sin(a) * math.sin(dr) * math.cos(lat1), math.cos(dr) - math.sin(lat1) * math.sin(lat2))
    return math.degrees(lat2), math.degrees(lon2)


def initial_bearing(lat1: ArrayLike, lon1: ArrayLike, lat2: ArrayLike, lon2: ArrayLike) -> Array:
    """Great-circle initial bearing [deg, 0..360) from point 1 to point 2 (the reference ``get_hdg``).

    The coordinates are converted to radians before the longitude difference is taken, in the
    reference's operation order.
    """
    p1, l1 = np.radians(lat1), np.radians(lon1)
    p2, l2 = np.radians(lat2), np.radians(lon2)
    delta_lon = l2 - l1
    x = np.sin(delta_lon) * np.cos(p2)
    y = np.cos(p1) * np.sin(p2) - np.sin(p1) * np.cos(p2) * np.cos(delta_lon)
    return (np.degrees(np.arctan2(x, y)) + 360) % 360


def sort_points_clockwise(vertices: ArrayLike) -> Array:
    """Sort (north, east) points by atan2(east, north) ascending: clockwise by compass bearing."""
    v = np.asarray(vertices, dtype=np.float64)
    return v[np.argsort(np.arctan2(v[:, 1], v[:, 0]), kind="stable")]


def polygon_area(vertices: ArrayLike) -> float:
    """Absolute shoelace area of a polygon (same unit squared as the vertices)."""
    return _shoelace(np.asarray(vertices, dtype=np.float64).tolist())


def random_convex_polygon(rng: np.random.Generator, radius: float, min_area: float) -> Array:
    """Points drawn on a circle until their sorted polygon has at least ``min_area``.

    Starts with three points, adds one at a time (the reference's polygon generator).
    """
    # Scalar Python on a handful of points: the same operations as the numpy helpers above
    # (libm cos/sin/atan2, a stable sort, the shoelace sum in vertex order), without the
    # per-call overhead of tiny arrays.
    r = float(radius)
    pts = [_point_on_circle(rng, r) for _ in range(3)]
    poly = sorted(pts, key=_compass_key)
    while _shoelace(poly) < min_area:
        pts.append(_point_on_circle(rng, r))
        poly = sorted(pts, key=_compass_key)
    return np.array(poly)


def _point_on_circle(rng: np.random.Generator, radius: float) -> tuple[float, float]:
    """A uniformly random point (x, y) on a circle of ``radius`` around the origin."""
    alpha = 2 * math.pi * rng.uniform(0.0, 1.0)
    return radius * math.cos(alpha), radius * math.sin(alpha)


def _compass_key(p: tuple[float, float]) -> float:
    return math.atan2(p[1], p[0])


def _shoelace(v: list) -> float:
    """Absolute shoelace area of a list of (x, y) points, summed in vertex order (the reference's)."""
    area = 0.0
    n = len(v)
    for i in range(n):
        x1, y1 = v[i]
        x2, y2 = v[(i + 1) % n]
        area += x1 * y2 - y1 * x2
    return abs(area) / 2.0


def nm_to_latlon(center: ArrayLike, points: ArrayLike) -> Array:
    """(north NM, east NM) offsets around ``center`` (lat, lon) to (lat, lon) [deg].

    ``center`` is one (lat, lon) pair or one per point (broadcast against ``points``).
    """
    c = np.asarray(center, dtype=np.float64)
    p = np.asarray(points, dtype=np.float64)
    lat = c[..., 0] + (p[..., 0] / 60)
    lon = c[..., 1] + (p[..., 1] / (60 * np.cos(np.radians(c[..., 0]))))
    return np.stack([lat, lon], axis=-1)


def latlon_to_nm(center: ArrayLike, points: ArrayLike) -> Array:
    """(lat, lon) [deg] to (north NM, east NM) offsets around ``center``."""
    c = np.asarray(center, dtype=np.float64)
    p = np.asarray(points, dtype=np.float64)
    x = (p[..., 0] - c[0]) * 60
    y = (p[..., 1] - c[1]) * 60 * np.cos(np.radians(c[0]))
    return np.stack([x, y], axis=-1)


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


# --- kwik geometry as the reference environments compute it ------------------------------------
# The reference environment modules import ``bluesky.simulation`` (through their screen dummy)
# before ``bs.init`` reads the ``prefer_compiled`` setting, so ``bs.tools.geo`` resolves to
# BlueSky's *Python* geo functions in every reference run, not the compiled ones that
# ``bluesky_gym.core.geo`` mirrors. They differ in operation order (degrees are subtracted before
# the conversion to radians, the longitude difference is wrapped, distances are divided by
# 1852 m, bearings are taken mod 360), i.e. in the last bits. Observations and rewards use these
# forms so that a state gives the reference's numbers exactly. They are computed by the scalar
# kernels of :mod:`bluesky_gym.tasks.compiled` (the readable numpy forms are test oracles).


def _kwik(lata: ArrayLike, lona: ArrayLike, latb: ArrayLike, lonb: ArrayLike, bearing: bool, matrix: bool) -> tuple[Array, Array]:
    """Bearings (when ``bearing``) and distances of broadcast point pairs through :func:`bluesky_gym.tasks.compiled.kwik_pairs`."""
    from bluesky_gym.tasks import compiled

    arrays = np.broadcast_arrays(*(np.asarray(x, dtype=np.float64) for x in (lata, lona, latb, lonb)))
    shape = arrays[0].shape
    flat = [np.array(x, dtype=np.float64).ravel() for x in arrays]  # writeable copies of the broadcast views
    dist = np.empty(flat[0].size)
    qdr = np.empty(dist.size if bearing else 0)
    compiled.kwik_pairs(flat[0], flat[1], flat[2], flat[3], matrix, qdr, dist)
    return (qdr.reshape(shape)[()] if bearing else qdr), dist.reshape(shape)[()]


def ref_kwikdist(lata: ArrayLike, lona: ArrayLike, latb: ArrayLike, lonb: ArrayLike) -> Array:
    """Flat-earth distance [NM] a -> b, as BlueSky's Python ``geo.kwikdist`` (see above; broadcasting)."""
    return _kwik(lata, lona, latb, lonb, False, False)[1]


def ref_kwikqdrdist(lata: ArrayLike, lona: ArrayLike, latb: ArrayLike, lonb: ArrayLike) -> tuple[Array, Array]:
    """Flat-earth bearing [deg, 0..360) and distance [NM] a -> b, as BlueSky's Python ``geo.kwikqdrdist``."""
    return _kwik(lata, lona, latb, lonb, True, False)


def ref_kwikdist_matrix(lata: ArrayLike, lona: ArrayLike, latb: ArrayLike, lonb: ArrayLike) -> Array:
    """Flat-earth distance [NM] a -> b as BlueSky's Python ``geo.kwikdist_matrix`` (broadcasting).

    The formula of :func:`ref_kwikdist` with the products grouped as
    dlat^2 + (dlon^2)(cavelat^2), which can differ in the last bit. The reference sorts the
    intruders and fills ``distances`` with it, and ``x_r``/``y_r`` with ``kwikqdrdist``.
    """
    return _kwik(lata, lona, latb, lonb, False, True)[1]
