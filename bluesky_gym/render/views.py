"""Projections from world coordinates to pixels.

The plan view is a local flat-earth (equirectangular) projection around the view centre, the one
BlueSky's ``kwik`` distances use: east = Δlon·60·cos(lat0) NM, north = Δlat·60 NM. North is up
and east is right; one pixel has the same length in both directions.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

Rect = tuple[int, int, int, int]  # x, y, width, height in pixels


@dataclass
class MapView:
    """North-up projection of a lat/lon neighbourhood into a pixel rectangle.

    Attributes:
        lat0: Latitude of the rectangle's centre [deg].
        lon0: Longitude of the rectangle's centre [deg].
        px_per_nm: Scale [pixels per NM].
        rect: Target rectangle (x, y, width, height) [px].
    """

    lat0: float
    lon0: float
    px_per_nm: float
    rect: Rect

    @classmethod
    def fit(cls, lat0: float, lon0: float, half_width_nm: float, rect: Rect) -> MapView:
        """A view centred on (lat0, lon0) showing ``2 * half_width_nm`` across ``rect``."""
        return cls(lat0, lon0, rect[2] / (2.0 * max(half_width_nm, 1e-3)), rect)

    @property
    def coslat0(self) -> float:
        """Cosine of the centre latitude (east-west scale of a degree of longitude)."""
        return math.cos(math.radians(self.lat0))

    def to_nm(self, lat: ArrayLike, lon: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(east, north) offsets [NM] from the centre."""
        dlon = (np.asarray(lon, dtype=np.float64) - self.lon0 + 180.0) % 360.0 - 180.0
        east = dlon * 60.0 * self.coslat0
        north = (np.asarray(lat, dtype=np.float64) - self.lat0) * 60.0
        return east, north

    def to_px(self, lat: ArrayLike, lon: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Pixel coordinates (x right, y down) of points."""
        east, north = self.to_nm(lat, lon)
        x0, y0, w, h = self.rect
        return x0 + w / 2.0 + east * self.px_per_nm, y0 + h / 2.0 - north * self.px_per_nm

    def point(self, lat: float, lon: float) -> tuple[float, float]:
        """Pixel coordinates of one point."""
        x, y = self.to_px(lat, lon)
        return float(x), float(y)

    def offset(self, lat: float, lon: float, east_nm: float, north_nm: float) -> tuple[float, float]:
        """Pixel coordinates of the point ``east_nm``, ``north_nm`` away from (lat, lon)."""
        x, y = self.point(lat, lon)
        return x + east_nm * self.px_per_nm, y - north_nm * self.px_per_nm

    def latlon_of_nm(self, east_nm: float, north_nm: float) -> tuple[float, float]:
        """Latitude and longitude of an (east, north) offset from the centre."""
        return self.lat0 + north_nm / 60.0, self.lon0 + east_nm / (60.0 * self.coslat0)

    def half_extent_nm(self) -> tuple[float, float]:
        """Half the visible (width, height) [NM]."""
        return self.rect[2] / 2.0 / self.px_per_nm, self.rect[3] / 2.0 / self.px_per_nm


def heading_vector(hdg_deg: float) -> tuple[float, float]:
    """Unit vector (x right, y down) on screen of a true heading on a north-up map."""
    h = math.radians(hdg_deg)
    return math.sin(h), -math.cos(h)


@dataclass
class SideView:
    """Altitude against distance to the runway; the runway is on the right.

    Attributes:
        x_max_km: Distance to the runway at the left edge of ``rect`` [km].
        x_min_km: Distance at the right edge [km].
        alt_max: Altitude at the top edge [m] (the bottom edge is 0 m).
        rect: Plot rectangle (x, y, width, height) [px].
    """

    x_max_km: float
    x_min_km: float
    alt_max: float
    rect: Rect

    @property
    def px_per_km(self) -> float:
        """Horizontal scale [pixels per km]."""
        return self.rect[2] / (self.x_max_km - self.x_min_km)

    @property
    def px_per_m(self) -> float:
        """Vertical scale [pixels per metre of altitude]."""
        return self.rect[3] / self.alt_max

    def x(self, dist_km: ArrayLike) -> NDArray[np.float64]:
        """Pixel x of distances to the runway [km]."""
        return self.rect[0] + (self.x_max_km - np.asarray(dist_km, dtype=np.float64)) * self.px_per_km

    def y(self, alt_m: ArrayLike) -> NDArray[np.float64]:
        """Pixel y of altitudes [m]."""
        return self.rect[1] + self.rect[3] - np.asarray(alt_m, dtype=np.float64) * self.px_per_m

    def point(self, dist_km: float, alt_m: float) -> tuple[float, float]:
        """Pixel coordinates of one (distance, altitude) point."""
        return float(self.x(dist_km)), float(self.y(alt_m))


def nice_step(span: float, target_ticks: int = 5) -> float:
    """A 1-2-5 tick step giving about ``target_ticks`` ticks over ``span``."""
    raw = span / max(target_ticks, 1)
    mag = 10.0 ** math.floor(math.log10(raw))
    for m in (1.0, 2.0, 2.5, 5.0, 10.0):
        if raw <= m * mag:
            return m * mag
    return 10.0 * mag


def scale_bar_nm(max_nm: float) -> float:
    """The largest round length [NM] not longer than ``max_nm`` (1, 2, 5, 10, 20, 25, 50, ...)."""
    best = 0.5
    for mag in (1.0, 10.0, 100.0, 1000.0):
        for m in (1.0, 2.0, 2.5, 5.0):
            if m * mag <= max_nm:
                best = m * mag
    return best


__all__ = ["MapView", "Rect", "SideView", "heading_vector", "nice_step", "scale_bar_nm"]
