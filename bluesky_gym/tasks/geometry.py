"""Scenario geometry of the paper's environments (bluesky-gym 0.2.0 ``envs/common/functions``).

Re-implemented from their description in the environment specification, vectorised where the
tasks need it, with every random draw taken from a generator passed in. The great-circle and kwik
functions are array faces of the scalar kernels in :mod:`bluesky_gym.tasks.compiled` (one formula
each); the readable numpy forms they are tested against live in the test suite's oracles.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from bluesky_gym.tasks import compiled

Array = NDArray[np.float64]

EARTH_RADIUS_KM = 6371.0


def wrap180(angle: ArrayLike) -> Array:
    """The reference's single wrap: x > 180 -> x - 360; x < -180 -> x + 360 (once only; not into [-180, 180] for |x| > 540)."""
    a = np.asarray(angle, dtype=np.float64)
    return np.where(a > 180, a - 360, np.where(a < -180, a + 360, a))


def point_at_distance(lat: ArrayLike, lon: ArrayLike, d_km: ArrayLike, bearing: ArrayLike, radius_km: float = EARTH_RADIUS_KM) -> tuple[Array, Array]:
    """Great-circle destination [deg] at ``d_km`` along initial ``bearing`` [deg] (spherical; broadcasting)."""
    shape, (la, lo, d, b) = _grid(lat, lon, d_km, bearing)
    lat2, lon2 = np.empty(shape[1]), np.empty(shape[1])
    compiled.point_at_distance(la, lo, d, b, float(radius_km), lat2, lon2)
    return lat2.reshape(shape[0])[()], lon2.reshape(shape[0])[()]


def initial_bearing(lat1: ArrayLike, lon1: ArrayLike, lat2: ArrayLike, lon2: ArrayLike) -> Array:
    """Great-circle initial bearing [deg, 0..360) from point 1 to point 2 (the reference ``get_hdg``).

    The kernel :func:`bluesky_gym.tasks.compiled.initial_bearing` (its scalar form
    :func:`~bluesky_gym.tasks.compiled.initial_bearing_scalar`).
    """
    shape, (a, b, c, d) = _grid(lat1, lon1, lat2, lon2)
    out = np.empty(shape[1])
    compiled.initial_bearing(a, b, c, d, out)
    bearing: Array = out.reshape(shape[0])[()]
    return bearing


def polygon_area(vertices: ArrayLike) -> float:
    """Absolute shoelace area of a polygon (same unit squared as the vertices)."""
    return _shoelace(np.asarray(vertices, dtype=np.float64).tolist())


def random_convex_polygon(rng: np.random.Generator, radius: float, min_area: float) -> Array:
    """Points drawn on a circle until their sorted polygon has at least ``min_area``.

    Starts with three points, adds one at a time (the reference's polygon generator).
    """
    # Scalar Python on a handful of points (libm cos/sin/atan2, a stable sort by compass bearing,
    # the shoelace sum in vertex order), without the per-call overhead of tiny arrays.
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


# --- kwik geometry as the reference environments compute it ------------------------------------
# The reference environment modules import ``bluesky.simulation`` (through their screen dummy)
# before ``bs.init`` reads the ``prefer_compiled`` setting, so ``bs.tools.geo`` resolves to
# BlueSky's *Python* geo functions in every reference run, not the compiled ones that
# ``bluesky_gym.core.geo`` mirrors. They differ in operation order (degrees are subtracted before
# the conversion to radians, the longitude difference is wrapped, distances are divided by
# 1852 m, bearings are taken mod 360), i.e. in the last bits. Observations and rewards use these
# forms so that a state gives the reference's numbers exactly.
#
# The scalar forms are in :mod:`bluesky_gym.tasks.compiled`; these functions apply them elementwise
# over broadcast arrays.


def ref_kwikdist(lata: ArrayLike, lona: ArrayLike, latb: ArrayLike, lonb: ArrayLike) -> Array:
    """Flat-earth distance [NM] a -> b, as BlueSky's Python ``geo.kwikdist`` (see above; broadcasting)."""
    shape, (a0, a1, b0, b1) = _grid(lata, lona, latb, lonb)
    dist = np.empty(shape[1])
    compiled.kwikdist(a0, a1, b0, b1, dist)
    return dist.reshape(shape[0])[()]


def ref_kwikqdrdist(lata: ArrayLike, lona: ArrayLike, latb: ArrayLike, lonb: ArrayLike) -> tuple[Array, Array]:
    """Flat-earth bearing [deg, 0..360) and distance [NM] a -> b, as BlueSky's Python ``geo.kwikqdrdist``."""
    shape, (a0, a1, b0, b1) = _grid(lata, lona, latb, lonb)
    qdr, dist = np.empty(shape[1]), np.empty(shape[1])
    compiled.kwikqdrdist(a0, a1, b0, b1, qdr, dist)
    return qdr.reshape(shape[0])[()], dist.reshape(shape[0])[()]


def _grid(*arrays: ArrayLike) -> tuple[tuple[tuple[int, ...], tuple[int, int]], list[Array]]:
    """Broadcast ``arrays`` for the 2-D kernels: ((result shape, its 2-D form), the arrays as 2-D float64).

    Arrays of up to two dimensions are passed as they are (a length-1 dimension repeats in the
    kernel); higher dimensions are broadcast and flattened to (1, size).
    """
    out = []
    rows = cols = 1
    ndim = 0
    for a in arrays:
        x = a if type(a) is np.ndarray and a.dtype == np.float64 else np.asarray(a, dtype=np.float64)
        if x.ndim != 2:
            if x.ndim > 2:
                return _grid_nd(arrays)
            ndim = max(ndim, x.ndim)
            x = x.reshape((1, x.size) if x.ndim == 1 else (1, 1))
        else:
            ndim = 2
        r, c = x.shape
        if r != 1:
            if rows not in (1, r):
                raise ValueError(f"shapes {[np.shape(a) for a in arrays]} do not broadcast")
            rows = r
        if c != 1:
            if cols not in (1, c):
                raise ValueError(f"shapes {[np.shape(a) for a in arrays]} do not broadcast")
            cols = c
        out.append(x)
    return ((rows, cols)[2 - ndim :], (rows, cols)), out


def _grid_nd(arrays: tuple[ArrayLike, ...]) -> tuple[tuple[tuple[int, ...], tuple[int, int]], list[Array]]:
    """:func:`_grid` with an array of more than two dimensions: broadcast and flattened to (1, size)."""
    b = [np.asarray(a, dtype=np.float64) for a in arrays]
    shape = np.broadcast_shapes(*(x.shape for x in b))
    flat = [_broadcast(x, shape).reshape(1, -1) for x in b]
    return (shape, flat[0].shape), flat


def _broadcast(a: NDArray, shape: tuple[int, ...]) -> NDArray:
    """``a`` broadcast to ``shape`` as a contiguous array (a copy where it had to be broadcast)."""
    return np.ascontiguousarray(a) if a.shape == shape else np.broadcast_to(a, shape).copy()
