"""Readable numpy forms of BlueSky's Python kwik functions (test oracles of ``bluesky_gym.tasks.geometry.ref_kwik*``)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

KWIK_EARTH_RADIUS_M = 6371000.0
KWIK_NM_M = 1852.0


def _kwik_py(lata: ArrayLike, lona: ArrayLike, latb: ArrayLike, lonb: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    lata, lona = np.asarray(lata, dtype=np.float64), np.asarray(lona, dtype=np.float64)
    latb, lonb = np.asarray(latb, dtype=np.float64), np.asarray(lonb, dtype=np.float64)
    dlat = np.radians(latb - lata)
    dlon = np.radians(((lonb - lona) + 180) % 360 - 180)
    cavelat = np.cos(np.radians(lata + latb) * 0.5)
    return dlat, dlon, cavelat


def ref_kwikdist(lata: ArrayLike, lona: ArrayLike, latb: ArrayLike, lonb: ArrayLike) -> np.ndarray:
    """Flat-earth distance [NM] a -> b, as BlueSky's Python ``geo.kwikdist``."""
    dlat, dlon, cavelat = _kwik_py(lata, lona, latb, lonb)
    dangle = np.sqrt(dlat * dlat + dlon * dlon * cavelat * cavelat)
    return KWIK_EARTH_RADIUS_M * dangle / KWIK_NM_M


def ref_kwikqdrdist(lata: ArrayLike, lona: ArrayLike, latb: ArrayLike, lonb: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Flat-earth bearing [deg, 0..360) and distance [NM] a -> b, as BlueSky's Python ``geo.kwikqdrdist``."""
    dlat, dlon, cavelat = _kwik_py(lata, lona, latb, lonb)
    dangle = np.sqrt(dlat * dlat + dlon * dlon * cavelat * cavelat)
    dist = KWIK_EARTH_RADIUS_M * dangle / KWIK_NM_M
    qdr = np.degrees(np.arctan2(dlon * cavelat, dlat)) % 360.0
    return qdr, dist


def ref_kwikdist_matrix(lata: ArrayLike, lona: ArrayLike, latb: ArrayLike, lonb: ArrayLike) -> np.ndarray:
    """Flat-earth distance [NM] a -> b as BlueSky's Python ``geo.kwikdist_matrix``: dlat^2 + (dlon^2)(cavelat^2)."""
    dlat, dlon, cavelat = _kwik_py(lata, lona, latb, lonb)
    dangle = np.sqrt(np.multiply(dlat, dlat) + np.multiply(np.multiply(dlon, dlon), np.multiply(cavelat, cavelat)))
    return KWIK_EARTH_RADIUS_M * dangle / KWIK_NM_M
