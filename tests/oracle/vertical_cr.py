"""Readable numpy form of VerticalCR's (and HorizontalCR's) intruder geometry (oracle)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from tests.oracle.task_geometry import ref_kwikqdrdist

Array = NDArray[np.float64]
NM2KM = 1.852


def wrap180(x: Array) -> Array:
    """The reference's single wrap: x > 180 -> x - 360; x < -180 -> x + 360 (once only)."""
    return np.where(x > 180, x - 360, np.where(x < -180, x + 360, x))


def intruder_relative_state(sim_lat: Array, sim_lon: Array, hdg: Array, gs: Array) -> dict[str, Array]:
    """Ownship-relative geometry of the intruders (slots 1..), each (n_envs, max_aircraft - 1).

    ``dist_km`` kwik distance [km]; ``cos_bearing``/``sin_bearing`` of wrap180(hdg_own - qdr);
    ``x_dif``/``y_dif`` [m/s], the intruder velocity in the reference's ownship frame.
    """
    qdr, dist = ref_kwikqdrdist(sim_lat[:, :1], sim_lon[:, :1], sim_lat[:, 1:], sim_lon[:, 1:])
    own_hdg = hdg[:, :1]
    bearing = wrap180(own_hdg - qdr)
    heading_difference = own_hdg - hdg[:, 1:]
    x_dif = -np.cos(np.deg2rad(heading_difference)) * gs[:, 1:]
    y_dif = gs[:, :1] - np.sin(np.deg2rad(heading_difference)) * gs[:, 1:]
    return {
        "dist_km": dist * NM2KM,
        "cos_bearing": np.cos(np.deg2rad(bearing)),
        "sin_bearing": np.sin(np.deg2rad(bearing)),
        "x_dif": x_dif,
        "y_dif": y_dif,
    }
