"""Wind fields per airspace: none, uniform, or BlueSky's 2-D point field [docs/dynamics.md §6.1]."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

Array = NDArray[np.float64]

IDW_EPS = 1e-20  # deg^2, avoids division by zero at a definition point


class WindField:
    """Wind definition points of ``n_envs`` airspaces.

    One point gives a uniform wind (BlueSky ``winddim`` 1). Several points give BlueSky's 2-D field:
    inverse-distance-squared weighting in degrees, with longitude differences scaled by the cosine
    of the mean latitude. The wind is the same at every altitude.

    Args:
        n_envs: Number of airspaces.
    """

    def __init__(self, n_envs: int) -> None:
        self.n_envs = n_envs
        self.lat = np.zeros((n_envs, 0))  # (n_envs, points) deg
        self.lon = np.zeros((n_envs, 0))  # (n_envs, points) deg
        self.vnorth = np.zeros((n_envs, 0))  # (n_envs, points) m/s, blowing TO north
        self.veast = np.zeros((n_envs, 0))  # (n_envs, points) m/s, blowing TO east
        self.count = np.zeros(n_envs, dtype=np.int64)  # (n_envs,) points in use

    @property
    def has_wind(self) -> NDArray[np.bool_]:
        """(n_envs,) whether an airspace has any wind defined."""
        return self.count > 0

    @property
    def any(self) -> bool:
        """Whether any airspace has wind."""
        return bool(self.count.any())  # a reduction over n_envs integers

    def clear(self, envs: ArrayLike | slice | None = None) -> None:
        """Remove the wind of the given airspaces (all when None)."""
        idx: Any = slice(None) if envs is None else envs
        self.count[idx] = 0
        if not self.count.any():
            for name in ("lat", "lon", "vnorth", "veast"):
                setattr(self, name, np.zeros((self.n_envs, 0)))

    def add_points(self, env: int, lat: ArrayLike, lon: ArrayLike, vnorth: ArrayLike, veast: ArrayLike) -> None:
        """Append definition points to one airspace (BlueSky ``addpointvne`` without altitudes).

        Args:
            env: Airspace index.
            lat: Latitudes [deg].
            lon: Longitudes [deg].
            vnorth: North components [m/s] (direction blown to).
            veast: East components [m/s].
        """
        lat, lon, vn, ve = (np.atleast_1d(np.asarray(x, dtype=np.float64)).ravel() for x in (lat, lon, vnorth, veast))
        if not (lat.shape == lon.shape == vn.shape == ve.shape):
            raise ValueError("wind points: lat, lon, vnorth and veast must have the same length")
        if not np.all(np.isfinite(np.concatenate([lat, lon, vn, ve]))):
            raise ValueError("wind points must be finite")
        n0 = int(self.count[env])
        need = n0 + lat.size
        if need > self.lat.shape[1]:
            grow = need - self.lat.shape[1]
            for name in ("lat", "lon", "vnorth", "veast"):
                setattr(self, name, np.pad(getattr(self, name), ((0, 0), (0, grow))))
        self.lat[env, n0:need] = lat
        self.lon[env, n0:need] = lon
        self.vnorth[env, n0:need] = vn
        self.veast[env, n0:need] = ve
        self.count[env] = need

    def at(self, env: ArrayLike, lat: ArrayLike, lon: ArrayLike) -> tuple[Array, Array]:
        """Wind (north, east) [m/s] at positions, each in its airspace ``env``."""
        env = np.asarray(env, dtype=np.int64)
        return self._evaluate(self.count[env], self.lat[env], self.lon[env], self.vnorth[env], self.veast[env], np.asarray(lat), np.asarray(lon))

    def at_all(self, lat: Array, lon: Array) -> tuple[Array, Array]:
        """Wind at positions shaped (n_envs, aircraft)."""
        return self._evaluate(
            self.count[:, None], self.lat[:, None, :], self.lon[:, None, :], self.vnorth[:, None, :], self.veast[:, None, :], lat, lon
        )

    @staticmethod
    def _evaluate(count: NDArray[np.int64], plat: Array, plon: Array, pvn: Array, pve: Array, lat: ArrayLike, lon: ArrayLike) -> tuple[Array, Array]:
        lat = np.asarray(lat, dtype=np.float64)
        shape = np.broadcast_shapes(np.shape(count), lat.shape)
        if plat.shape[-1] == 0:
            return np.zeros(shape), np.zeros(shape)
        count = np.broadcast_to(count, shape)
        # Uniform wind: the first point everywhere.
        vn = np.where(count == 1, pvn[..., 0], 0.0)
        ve = np.where(count == 1, pve[..., 0], 0.0)
        multi = count >= 2
        if np.any(multi):
            latx = lat[..., None]
            lonx = np.asarray(lon, dtype=np.float64)[..., None]
            valid = np.arange(plat.shape[-1]) < count[..., None]
            cavelat = np.cos(np.radians(0.5 * (latx + plat)))
            dy = latx - plat
            dx = cavelat * (lonx - plon)
            invd2 = np.where(valid, 1.0 / (IDW_EPS + dx * dx + dy * dy), 0.0)
            total = invd2.sum(axis=-1, keepdims=True)
            w = invd2 / total
            vn = np.where(multi, (pvn * w).sum(axis=-1), vn)
            ve = np.where(multi, (pve * w).sum(axis=-1), ve)
        return vn, ve
