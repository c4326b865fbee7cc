"""Geodesy, reproducing BlueSky 1.1.1's compiled ``_cgeo`` module, its Python ``geo`` module and ``geo.kwikpos``.

Angles are degrees, distances NM, as in BlueSky [docs/dynamics.md §4]. The arithmetic follows BlueSky's
code operation by operation, so results are bit-identical to BlueSky's.

The geometry is written once, as scalar kernels (:func:`qdrdist_compiled`, :func:`qdrdist_py`,
:func:`kwikdist_s`, :func:`kwikqdrdist_s`, :func:`kwikpos_s`, ...); the array functions
(:func:`qdrdist`, :func:`qdrdist_python`, :func:`kwikdist`, :func:`kwikqdrdist`, :func:`kwikpos`)
broadcast their arguments like numpy and loop over the kernels.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from bluesky_gym.core.jit import flat_float_args, fmod, grid_range, jit, shaped
from bluesky_gym.core.scalar import RAD
from bluesky_gym.core.scalar import maximum as _maximum
from bluesky_gym.core.scalar import mod as _mod
from bluesky_gym.core.units import DEG2RAD, M2NM, NM, R_EARTH, RAD2DEG, WGS84_A, WGS84_B

Array = NDArray[np.float64]

_A2 = WGS84_A * WGS84_A
_B2 = WGS84_B * WGS84_B
_A4 = _A2 * _A2
_B4 = _B2 * _B2
_DEG = 180.0 / np.pi  # numpy's rad2deg factor (BlueSky's Python module uses np.degrees)
KWIKPOS_NM_PER_DEG = 60.0  # NM per degree of latitude in BlueSky's Python kwikpos
KWIKPOS_MIN_COS = 0.01  # floor of 60 cos(lat) in kwikpos


# --- Scalar kernels: BlueSky's compiled geo module ------------------------------------------------
@jit
def rwgs84_sc(sinlat: float, coslat: float) -> float:
    """WGS-84 geocentric radius [m] from sin and cos of the latitude."""
    s2 = sinlat * sinlat
    c2 = coslat * coslat
    return math.sqrt((_A4 * c2 + _B4 * s2) / (_A2 * c2 + _B2 * s2))


@jit
def qdrdist_compiled(latd1: float, lond1: float, latd2: float, lond2: float) -> tuple[float, float]:
    """Great-circle initial bearing [deg, (-180, 180]] and haversine distance [NM] (compiled ``qdrdist``).

    The distance uses the WGS-84 radius at the mean latitude, or BlueSky's latitude-weighted mix
    when the points lie in opposite hemispheres [docs/dynamics.md §4].
    """
    lat1 = DEG2RAD * latd1
    lon1 = DEG2RAD * lond1
    lat2 = DEG2RAD * latd2
    lon2 = DEG2RAD * lond2
    sinlat1, coslat1 = math.sin(lat1), math.cos(lat1)
    sinlat2, coslat2 = math.sin(lat2), math.cos(lat2)
    dlon = lon2 - lon1
    qdr = RAD2DEG * math.atan2(math.sin(dlon) * coslat2, sinlat2 * coslat1 - sinlat1 * coslat2 * math.cos(dlon))
    sindlat2 = math.sin(0.5 * (lat2 - lat1))
    sindlon2 = math.sin(0.5 * dlon)
    if lat1 * lat2 >= 0.0:
        mid = 0.5 * (lat1 + lat2)
        r = rwgs84_sc(math.sin(mid), math.cos(mid))
    else:
        r = (
            0.5
            * (abs(lat1) * (rwgs84_sc(sinlat1, coslat1) + WGS84_A) + abs(lat2) * (rwgs84_sc(sinlat2, coslat2) + WGS84_A))
            / (abs(lat1) + abs(lat2))
        )
    root = sindlat2 * sindlat2 + coslat1 * coslat2 * sindlon2 * sindlon2
    dist = 2.0 * r * math.atan2(math.sqrt(root), math.sqrt(1.0 - root))
    return qdr, M2NM * dist


# --- Scalar kernels: BlueSky's Python geo module (``bluesky.tools.geo._geo``) ----------------------
# BlueSky uses these instead of the compiled ones when ``bluesky.tools.geo`` is imported before
# the ``prefer_compiled`` setting is read, which is the case in the reference gym environments.
@jit
def rwgs84_py(latd: float) -> float:
    """WGS-84 geocentric radius [m] at ``latd`` [deg] (Python form, its own operation order)."""
    lat = latd * RAD
    coslat = math.cos(lat)
    sinlat = math.sin(lat)
    an = WGS84_A * WGS84_A * coslat
    bn = WGS84_B * WGS84_B * sinlat
    ad = WGS84_A * coslat
    bd = WGS84_B * sinlat
    return math.sqrt((an * an + bn * bn) / (ad * ad + bd * bd))


@jit
def qdrdist_py(latd1: float, lond1: float, latd2: float, lond2: float) -> tuple[float, float]:
    """Bearing [deg, (-180, 180]] and distance [NM] as BlueSky's Python ``qdrdist``.

    Spherical law of cosines for the distance (the compiled form uses haversine), WGS-84 radius
    at the mean latitude, or a latitude-weighted mix across the equator.
    """
    res1 = rwgs84_py(0.5 * (latd1 + latd2))
    if latd1 * latd2 >= 0.0:
        r = res1
    else:
        r1 = rwgs84_py(latd1)
        r2 = rwgs84_py(latd2)
        res2 = 0.5 * (abs(latd1) * (r1 + WGS84_A) + abs(latd2) * (r2 + WGS84_A)) / _maximum(0.000001, abs(latd1) + abs(latd2))
        r = 0.0 * res1 + 1.0 * res2  # BlueSky's sw * res1 + (1 - sw) * res2
    lat1 = latd1 * RAD
    lon1 = lond1 * RAD
    lat2 = latd2 * RAD
    lon2 = lond2 * RAD
    d = r * math.acos(math.cos(lat1) * math.cos(lat2) * math.cos(lon2 - lon1) + math.sin(lat1) * math.sin(lat2))
    coslat1 = math.cos(lat1)
    coslat2 = math.cos(lat2)
    qdr = math.atan2(math.sin(lon2 - lon1) * coslat2, coslat1 * math.sin(lat2) - math.sin(lat1) * coslat2 * math.cos(lon2 - lon1)) * _DEG
    return qdr, d / NM


@jit
def qdrdist_s(python_geo: bool, latd1: float, lond1: float, latd2: float, lond2: float) -> tuple[float, float]:
    """:func:`qdrdist_py` when ``python_geo``, else :func:`qdrdist_compiled`."""
    if python_geo:
        return qdrdist_py(latd1, lond1, latd2, lond2)
    return qdrdist_compiled(latd1, lond1, latd2, lond2)


# --- Scalar kernels: flat-earth forms ------------------------------------------------------------
@jit
def kwikqdrdist_s(latd1: float, lond1: float, latd2: float, lond2: float) -> tuple[float, float]:
    """Flat-earth bearing [deg, (-180, 180]] and distance [NM], no longitude wrap (compiled 1.1.1)."""
    lat1 = DEG2RAD * latd1
    lon1 = DEG2RAD * lond1
    lat2 = DEG2RAD * latd2
    lon2 = DEG2RAD * lond2
    dlat = lat2 - lat1
    dlon = lon2 - lon1
    cavelat = math.cos(0.5 * (lat1 + lat2))
    dist = M2NM * (R_EARTH * math.sqrt(dlat * dlat + dlon * dlon * cavelat * cavelat))
    qdr = RAD2DEG * fmod(math.atan2(dlon * cavelat, dlat), 360.0)
    return qdr, dist


@jit
def kwikdist_s(latd1: float, lond1: float, latd2: float, lond2: float) -> float:
    """Flat-earth (equirectangular) distance [NM], no longitude wrap (compiled 1.1.1)."""
    return kwikqdrdist_s(latd1, lond1, latd2, lond2)[1]


@jit
def kwikpos_s(latd1: float, lond1: float, qdr: float, dist: float) -> tuple[float, float]:
    """BlueSky's Python ``geo.kwikpos``: flat earth, 60 NM per degree of latitude.

    Args:
        latd1: Reference latitude [deg].
        lond1: Reference longitude [deg].
        qdr: Bearing [deg].
        dist: Distance [NM].

    Returns:
        Latitude and longitude [deg]; the longitude is wrapped to [-180, 180).
    """
    dx = dist * math.sin(qdr * RAD)
    dy = dist * math.cos(qdr * RAD)
    dlat = dy / KWIKPOS_NM_PER_DEG
    dlon = dx / _maximum(KWIKPOS_MIN_COS, KWIKPOS_NM_PER_DEG * math.cos(latd1 * RAD))
    return latd1 + dlat, _mod((lond1 + dlon) + 180.0, 360.0) - 180.0


@jit
def degto180(angle: float) -> float:
    """Wrap an angle [deg] to [-180, 180) (BlueSky ``misc.degto180``)."""
    return _mod(angle + 180.0, 360.0) - 180.0


# --- Array functions (loops over the kernels) ----------------------------------------------------
@jit
def _pair_loop(which, a, b, c, d, out1, out2):  # type: ignore[no-untyped-def]
    for i in grid_range(a.shape[0]):
        if which == 0:
            out1[i], out2[i] = qdrdist_compiled(a[i], b[i], c[i], d[i])
        elif which == 1:
            out1[i], out2[i] = qdrdist_py(a[i], b[i], c[i], d[i])
        elif which == 2:
            out1[i], out2[i] = kwikqdrdist_s(a[i], b[i], c[i], d[i])
        elif which == 3:
            out1[i] = kwikdist_s(a[i], b[i], c[i], d[i])
        else:
            out1[i], out2[i] = kwikpos_s(a[i], b[i], c[i], d[i])


def _pairs(which: int, *args: ArrayLike, two: bool = True) -> tuple[Array, Array] | Array:
    shape, (a, b, c, d) = flat_float_args(*args)
    out1 = np.empty(a.size)
    out2 = np.empty(a.size) if two else out1
    _pair_loop(which, a, b, c, d, out1, out2)
    if two:
        return shaped(out1, shape), shaped(out2, shape)
    return shaped(out1, shape)  # type: ignore[no-any-return]


def qdrdist(latd1: ArrayLike, lond1: ArrayLike, latd2: ArrayLike, lond2: ArrayLike) -> tuple[Array, Array]:
    """Great-circle bearing [deg, (-180, 180]] and distance [NM] (BlueSky's compiled ``qdrdist``), broadcast."""
    return _pairs(0, latd1, lond1, latd2, lond2)  # type: ignore[return-value]


def qdrdist_python(latd1: ArrayLike, lond1: ArrayLike, latd2: ArrayLike, lond2: ArrayLike) -> tuple[Array, Array]:
    """Bearing [deg] and distance [NM] as BlueSky's Python ``qdrdist``, broadcast."""
    return _pairs(1, latd1, lond1, latd2, lond2)  # type: ignore[return-value]


def kwikqdrdist(latd1: ArrayLike, lond1: ArrayLike, latd2: ArrayLike, lond2: ArrayLike) -> tuple[Array, Array]:
    """Flat-earth bearing [deg, (-180, 180]] and distance [NM] (compiled scalar form), broadcast."""
    return _pairs(2, latd1, lond1, latd2, lond2)  # type: ignore[return-value]


def kwikdist(latd1: ArrayLike, lond1: ArrayLike, latd2: ArrayLike, lond2: ArrayLike) -> Array:
    """Flat-earth (equirectangular) distance [NM], no longitude wrap (compiled 1.1.1), broadcast."""
    return _pairs(3, latd1, lond1, latd2, lond2, two=False)  # type: ignore[return-value]


def kwikqdrdist_matrix_python(lat: Array, lon: Array) -> tuple[Array, Array]:
    """BlueSky's Python ``kwikqdrdist_matrix`` of every ordered pair (i, j) of each airspace, in its operation order.

    Args:
        lat: (..., n) latitudes [deg].
        lon: (..., n) longitudes [deg].

    Returns:
        Bearing i -> j [deg, [0, 360)] and distance [NM], each (..., n, n). Unlike the compiled
        form BlueSky 1.1.1 prefers, it wraps the longitude difference and gives every pair its own bearing.
    """
    lata, latb = lat[..., :, None], lat[..., None, :]
    lona, lonb = lon[..., :, None], lon[..., None, :]
    dlat = np.radians(latb - lata)
    dlon = np.radians(((lonb - lona) + 180) % 360 - 180)
    cavelat = np.cos(np.radians(latb + lata) * 0.5)
    dangle = np.sqrt(np.multiply(dlat, dlat) + np.multiply(np.multiply(dlon, dlon), np.multiply(cavelat, cavelat)))
    dist = R_EARTH * dangle / NM
    qdr = np.degrees(np.arctan2(np.multiply(dlon, cavelat), dlat)) % 360.0
    return qdr, dist


def kwikqdrdist_matrix(lat: Array, lon: Array, python_geo: bool = False) -> tuple[Array, Array]:
    """BlueSky 1.1.1's ``geo.kwikqdrdist_matrix`` of every ordered pair (i, j) of each airspace, as its STATEBASED detection calls it.

    The compiled form (BlueSky's default, ``python_geo=False``) computes each pair once, for
    i < j, and copies it into (j, i): the pair (i, j) with i > j gets the bearing j -> i. The Python
    form (:func:`kwikqdrdist_matrix_python`) gives every pair its own bearing. The diagonal is 0.

    Args:
        lat: (..., n) latitudes [deg].
        lon: (..., n) longitudes [deg].
        python_geo: BlueSky's Python geo functions instead of its compiled ones.

    Returns:
        Bearing [deg] and distance [NM], each (..., n, n).
    """
    if python_geo:
        return kwikqdrdist_matrix_python(lat, lon)
    n = lat.shape[-1]
    upper = np.triu(np.ones((n, n), dtype=bool), 1)
    eye = np.eye(n) > 0
    q_ij, d_ij = kwikqdrdist(lat[..., :, None], lon[..., :, None], lat[..., None, :], lon[..., None, :])
    qdr = np.where(upper, q_ij, np.swapaxes(q_ij, -1, -2))  # the matrix form copies i -> j into (j, i)
    qdr = np.where(eye, 0.0, qdr)
    dist_nm = np.where(eye, 0.0, np.where(upper, d_ij, np.swapaxes(d_ij, -1, -2)))
    return qdr, dist_nm


def kwikpos(latd1: ArrayLike, lond1: ArrayLike, qdr: ArrayLike, dist: ArrayLike) -> tuple[Array, Array]:
    """BlueSky's Python ``geo.kwikpos`` (see :func:`kwikpos_s`), broadcast: (lat, lon) [deg]."""
    return _pairs(4, latd1, lond1, qdr, dist)  # type: ignore[return-value]
