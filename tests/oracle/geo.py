"""Oracle: geodesy as readable numpy array code (BlueSky 1.1.1's ``_cgeo``, Python ``geo`` and ``kwikpos``).

The package computes these with scalar kernels (bluesky_gym.core.geo); the tests compare them
with this form to the last bit.

All functions broadcast over numpy arrays of any shape. Angles are degrees, distances NM, as in
BlueSky [docs/dynamics.md §4]. The arithmetic follows the compiled C++ code operation by operation
(convert to radians first, then difference), so results are bit-identical to BlueSky's.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from bluesky_gym.core.units import DEG2RAD, M2NM, R_EARTH, RAD2DEG, WGS84_A, WGS84_B

Array = NDArray[np.float64]

_A2 = WGS84_A * WGS84_A
_B2 = WGS84_B * WGS84_B
_A4 = _A2 * _A2
_B4 = _B2 * _B2


def rwgs84_sc(sinlat: ArrayLike, coslat: ArrayLike) -> Array:
    """WGS-84 geocentric radius [m] from sin and cos of the latitude."""
    sinlat2 = sinlat * sinlat
    coslat2 = coslat * coslat
    return np.sqrt((_A4 * coslat2 + _B4 * sinlat2) / (_A2 * coslat2 + _B2 * sinlat2))


def rwgs84(latd: ArrayLike) -> Array:
    """WGS-84 geocentric radius [m] at latitude ``latd`` [deg]."""
    lat = DEG2RAD * np.asarray(latd, dtype=np.float64)
    return rwgs84_sc(np.sin(lat), np.cos(lat))


def qdrdist(latd1: ArrayLike, lond1: ArrayLike, latd2: ArrayLike, lond2: ArrayLike) -> tuple[Array, Array]:
    """Great-circle initial bearing [deg, (-180, 180]] and haversine distance [NM].

    The distance uses the WGS-84 radius at the mean latitude, or BlueSky's latitude-weighted mix
    when the points lie in opposite hemispheres [docs/dynamics.md §4].
    """
    lat1 = DEG2RAD * np.asarray(latd1, dtype=np.float64)
    lon1 = DEG2RAD * np.asarray(lond1, dtype=np.float64)
    lat2 = DEG2RAD * np.asarray(latd2, dtype=np.float64)
    lon2 = DEG2RAD * np.asarray(lond2, dtype=np.float64)
    sinlat1, coslat1 = np.sin(lat1), np.cos(lat1)
    sinlat2, coslat2 = np.sin(lat2), np.cos(lat2)
    dlon = lon2 - lon1
    qdr = RAD2DEG * np.arctan2(np.sin(dlon) * coslat2, sinlat2 * coslat1 - sinlat1 * coslat2 * np.cos(dlon))

    sindlat2 = np.sin(0.5 * (lat2 - lat1))
    sindlon2 = np.sin(0.5 * dlon)
    mid = 0.5 * (lat1 + lat2)
    r_same = rwgs84_sc(np.sin(mid), np.cos(mid))
    same = lat1 * lat2 >= 0.0
    if np.all(same):
        r = r_same
    else:
        with np.errstate(divide="ignore", invalid="ignore"):
            r_mix = (
                0.5
                * (np.abs(lat1) * (rwgs84_sc(sinlat1, coslat1) + WGS84_A) + np.abs(lat2) * (rwgs84_sc(sinlat2, coslat2) + WGS84_A))
                / (np.abs(lat1) + np.abs(lat2))
            )
        r = np.where(same, r_same, r_mix)
    root = sindlat2 * sindlat2 + coslat1 * coslat2 * sindlon2 * sindlon2
    dist = 2.0 * r * np.arctan2(np.sqrt(root), np.sqrt(1.0 - root))
    return qdr, M2NM * dist


def qdrpos(latd1: ArrayLike, lond1: ArrayLike, qdr: ArrayLike, dist: ArrayLike) -> tuple[Array, Array]:
    """Position [deg] at bearing ``qdr`` [deg] and distance ``dist`` [NM] on the WGS-84 sphere."""
    lat1 = DEG2RAD * np.asarray(latd1, dtype=np.float64)
    lon1 = DEG2RAD * np.asarray(lond1, dtype=np.float64)
    q = DEG2RAD * np.asarray(qdr, dtype=np.float64)
    sinlat, coslat = np.sin(lat1), np.cos(lat1)
    r = rwgs84_sc(sinlat, coslat)
    d = np.asarray(dist, dtype=np.float64) * 1852.0
    sdr, cdr = np.sin(d / r), np.cos(d / r)
    lat2 = np.arcsin(sinlat * cdr + coslat * sdr * np.cos(q))
    lon2 = lon1 + np.arctan2(np.sin(q) * sdr * coslat, cdr - sinlat * np.sin(lat2))
    return RAD2DEG * lat2, RAD2DEG * lon2


def _kwik(latd1: ArrayLike, lond1: ArrayLike, latd2: ArrayLike, lond2: ArrayLike) -> tuple[Array, Array, Array]:
    lat1 = DEG2RAD * np.asarray(latd1, dtype=np.float64)
    lon1 = DEG2RAD * np.asarray(lond1, dtype=np.float64)
    lat2 = DEG2RAD * np.asarray(latd2, dtype=np.float64)
    lon2 = DEG2RAD * np.asarray(lond2, dtype=np.float64)
    return lat2 - lat1, lon2 - lon1, np.cos(0.5 * (lat1 + lat2))


def kwikdist(latd1: ArrayLike, lond1: ArrayLike, latd2: ArrayLike, lond2: ArrayLike) -> Array:
    """Flat-earth (equirectangular) distance [NM], no longitude wrap (compiled 1.1.1)."""
    dlat, dlon, cavelat = _kwik(latd1, lond1, latd2, lond2)
    return M2NM * (R_EARTH * np.sqrt(dlat * dlat + dlon * dlon * cavelat * cavelat))


def kwikqdrdist(latd1: ArrayLike, lond1: ArrayLike, latd2: ArrayLike, lond2: ArrayLike) -> tuple[Array, Array]:
    """Flat-earth bearing [deg, (-180, 180]] and distance [NM], as the compiled scalar form."""
    dlat, dlon, cavelat = _kwik(latd1, lond1, latd2, lond2)
    dist = M2NM * (R_EARTH * np.sqrt(dlat * dlat + dlon * dlon * cavelat * cavelat))
    qdr = RAD2DEG * np.fmod(np.arctan2(dlon * cavelat, dlat), 360.0)
    return qdr, dist


def kwikpos(latd1: ArrayLike, lond1: ArrayLike, qdr: ArrayLike, dist: ArrayLike) -> tuple[Array, Array]:
    """BlueSky's Python ``geo.kwikpos``: flat earth, 60 NM per degree of latitude.

    Args:
        latd1: Reference latitude [deg].
        lond1: Reference longitude [deg].
        qdr: Bearing [deg].
        dist: Distance [NM].

    Returns:
        Latitude and longitude [deg]; the longitude is wrapped to [-180, 180).
    """
    dx = dist * np.sin(np.radians(qdr))
    dy = dist * np.cos(np.radians(qdr))
    dlat = dy / 60.0
    dlon = dx / (np.maximum(0.01, 60.0 * np.cos(np.radians(latd1))))
    return latd1 + dlat, ((lond1 + dlon) + 180) % 360 - 180


def degto180(angle: ArrayLike) -> Array:
    """Wrap an angle [deg] to [-180, 180) (BlueSky ``misc.degto180``)."""
    return (angle + 180.0) % 360 - 180.0


# --- BlueSky's Python geo module (``bluesky.tools.geo._geo``) -------------------------------------
# BlueSky uses these instead of the compiled ones when ``bluesky.tools.geo`` is imported before
# the ``prefer_compiled`` setting is read, which is the case in the reference gym environments.


def rwgs84_python(latd: ArrayLike) -> Array:
    """WGS-84 geocentric radius [m] (Python form, its own operation order)."""
    lat = np.radians(latd)
    coslat = np.cos(lat)
    sinlat = np.sin(lat)
    an = WGS84_A * WGS84_A * coslat
    bn = WGS84_B * WGS84_B * sinlat
    ad = WGS84_A * coslat
    bd = WGS84_B * sinlat
    return np.sqrt((an * an + bn * bn) / (ad * ad + bd * bd))


def qdrdist_python(latd1: ArrayLike, lond1: ArrayLike, latd2: ArrayLike, lond2: ArrayLike) -> tuple[Array, Array]:
    """Bearing [deg, (-180, 180]] and distance [NM] as BlueSky's Python ``qdrdist``.

    Spherical law of cosines for the distance (the compiled form uses haversine), WGS-84 radius
    at the mean latitude, or a latitude-weighted mix across the equator.
    """
    latd1 = np.asarray(latd1, dtype=np.float64)
    latd2 = np.asarray(latd2, dtype=np.float64)
    res1 = rwgs84_python(0.5 * (latd1 + latd2))
    if np.all(latd1 * latd2 >= 0.0):
        r = res1
    else:
        r1 = rwgs84_python(latd1)
        r2 = rwgs84_python(latd2)
        res2 = 0.5 * (np.abs(latd1) * (r1 + WGS84_A) + np.abs(latd2) * (r2 + WGS84_A)) / np.maximum(0.000001, np.abs(latd1) + np.abs(latd2))
        sw = latd1 * latd2 >= 0.0
        r = sw * res1 + (1 - sw) * res2
    lat1 = np.radians(latd1)
    lon1 = np.radians(lond1)
    lat2 = np.radians(latd2)
    lon2 = np.radians(lond2)
    d = r * np.arccos(np.cos(lat1) * np.cos(lat2) * np.cos(lon2 - lon1) + np.sin(lat1) * np.sin(lat2))
    coslat1 = np.cos(lat1)
    coslat2 = np.cos(lat2)
    qdr = np.degrees(np.arctan2(np.sin(lon2 - lon1) * coslat2, coslat1 * np.sin(lat2) - np.sin(lat1) * coslat2 * np.cos(lon2 - lon1)))
    return qdr, d / NM_M


NM_M = 1852.0  # m per NM, as the Python geo module divides
