"""Wind fields per airspace: none, uniform, or BlueSky's 2-D point field [docs/dynamics.md §6.1]."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
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


#: m/s, normalisation of the wind observation entries.
MAX_WIND = 50.0
#: The wind observation entries: the wind at the ownship along and across its heading.
WIND_KEYS = ("wind_u", "wind_v")


def _points(name: str, value: Any) -> tuple[float, ...]:
    try:
        points = np.atleast_1d(np.asarray(value, dtype=np.float64)).ravel()
    except (TypeError, ValueError):
        raise ValueError(f"wind: {name} must be numbers (one per wind point), got {value!r}") from None
    return tuple(float(x) for x in points)


@dataclass(frozen=True)
class Wind:
    """The wind of a task (its ``wind`` option): definition points installed in every new episode.

    One point gives a uniform wind, several BlueSky's 2-D field (:class:`WindField`); the wind
    is the same at every altitude and acts above 50 ft. As in the reference wrapper, the points
    are added right after each episode's scenario was generated, so aircraft are created without
    wind and it acts from the first step on. With ``observe``, the observation gains the wind at
    the ownship in its heading frame, over :data:`MAX_WIND`:

    * ``wind_u`` = (wn·cos h + we·sin h) / 50: along-heading component (tail wind positive);
    * ``wind_v`` = (−wn·sin h + we·cos h) / 50: cross component (positive toward the right).

    ``gym.make(id, wind=Wind(...))`` or ``gym.make(id, wind={"lat": ..., ...})`` (a mapping of
    these fields). Array-like points are stored as tuples (the configuration stays hashable).
    The multi-agent environments take the option too and fly their aircraft in the wind; their
    per-agent observations do not carry ``observe``'s entries (those are the ownship's, slot 0).

    Attributes:
        lat: Latitudes of the points [deg].
        lon: Longitudes of the points [deg].
        vnorth: North components [m/s] (the direction the wind blows to), one per point.
        veast: East components [m/s].
        observe: Add ``wind_u`` and ``wind_v`` to the observation.
    """

    lat: tuple[float, ...]
    lon: tuple[float, ...]
    vnorth: tuple[float, ...]
    veast: tuple[float, ...]
    observe: bool = False

    def __post_init__(self) -> None:
        for name in ("lat", "lon", "vnorth", "veast"):
            object.__setattr__(self, name, _points(name, getattr(self, name)))
        if not (len(self.lat) == len(self.lon) == len(self.vnorth) == len(self.veast)) or not self.lat:
            raise ValueError("wind: lat, lon, vnorth and veast must have the same, non-zero number of points")
        if not all(math.isfinite(x) for x in (*self.lat, *self.lon, *self.vnorth, *self.veast)):
            raise ValueError("wind: all values must be finite")
        if not isinstance(self.observe, (bool, np.bool_)):
            raise ValueError(f"wind: observe must be True or False, got {self.observe!r}")
        object.__setattr__(self, "observe", bool(self.observe))

    @classmethod
    def of(cls, value: Wind | Mapping[str, Any] | None) -> Wind | None:
        """The wind an option value describes: a :class:`Wind`, a mapping of its fields, or None (no wind).

        Raises:
            ValueError: Anything else, an unknown field, or an altitude profile (``alt``).
        """
        if value is None or isinstance(value, Wind):
            return value
        if not isinstance(value, Mapping):
            raise ValueError(f"wind must be a Wind, a mapping of lat, lon, vnorth, veast (and observe) or None, got {type(value).__name__}")
        fields = dict(value)
        if fields.pop("alt", None) is not None:
            raise ValueError("wind altitude profiles are not supported; pass alt=None for a 2-D field (the same wind at every altitude)")
        names = {"lat", "lon", "vnorth", "veast", "observe"}
        unknown, missing = sorted(set(fields) - names), sorted(names - {"observe"} - set(fields))
        if unknown or missing:
            raise ValueError(f"wind: unknown field(s) {unknown} or missing field(s) {missing}; give lat, lon, vnorth, veast and optionally observe")
        return cls(**fields)

    def on_reset(self, task: Any, envs: NDArray[np.int64]) -> None:
        """Add the wind points to the airspaces of the new episodes ``envs`` of ``task`` (an effect of the task)."""
        lat, lon, vnorth, veast = (np.array(x) for x in (self.lat, self.lon, self.vnorth, self.veast))
        for e in envs:
            task.sim.wind.add_points(int(e), lat, lon, vnorth, veast)


def wind_at_ownship(task: Any, envs: NDArray[np.int64]) -> dict[str, Array]:
    """``wind_u``, ``wind_v``: the wind at the ownship (slot 0) of ``task`` in its heading frame / 50, (len(envs), 1) each."""
    sim = task.sim
    wn, we = sim.wind.at(envs, sim.lat[envs, 0], sim.lon[envs, 0])
    h = np.deg2rad(sim.hdg[envs, 0])
    u = (wn * np.cos(h) + we * np.sin(h)) / MAX_WIND
    v = (-wn * np.sin(h) + we * np.cos(h)) / MAX_WIND
    return {"wind_u": u[:, None], "wind_v": v[:, None]}
