"""Layout of the simulator state: the per-aircraft fields and the rows of the float block.

All float64 fields of a :class:`~bluesky_gym.core.Simulator` live in one contiguous block
``(fields, aircraft)`` that the compiled kernels update in place; the row of each field is
``FIELD_INDEX[name]`` (also exported as ``I_<NAME>`` for the kernels).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from bluesky_gym.core.units import NO_VALUE

#: (name, dtype, value of an empty slot) of every per-aircraft state array.
STATE_FIELDS: tuple[tuple[str, type, float], ...] = (
    ("active", np.bool_, False),
    ("lat", np.float64, 0.0),  # deg
    ("lon", np.float64, 0.0),  # deg
    ("alt", np.float64, 0.0),  # m
    ("hdg", np.float64, 0.0),  # deg true
    ("trk", np.float64, 0.0),  # deg true
    ("tas", np.float64, 0.0),  # m/s
    ("cas", np.float64, 0.0),  # m/s
    ("mach", np.float64, 0.0),  # -
    ("gs", np.float64, 0.0),  # m/s
    ("gsnorth", np.float64, 0.0),  # m/s
    ("gseast", np.float64, 0.0),  # m/s
    ("vs", np.float64, 0.0),  # m/s
    ("ax", np.float64, 0.0),  # m/s^2, longitudinal acceleration of the last step
    ("windnorth", np.float64, 0.0),  # m/s, wind at the aircraft
    ("windeast", np.float64, 0.0),  # m/s
    ("distflown", np.float64, 0.0),  # m
    # Selected (MCP) values.
    ("selspd", np.float64, 0.0),  # m/s CAS, or Mach when 0.1 < v < 2
    ("selalt", np.float64, 0.0),  # m
    ("selvs", np.float64, 0.0),  # m/s
    ("swlnav", np.bool_, False),
    ("swvnav", np.bool_, False),
    ("swvnavspd", np.bool_, False),
    # Autopilot outputs, before the performance limits.
    ("ap_trk", np.float64, 0.0),  # deg
    ("ap_tas", np.float64, 0.0),  # m/s
    ("ap_vs", np.float64, NO_VALUE),  # m/s
    ("ap_alt", np.float64, 0.0),  # m
    ("turnphi", np.float64, 0.0),  # rad; 0 means "use the default bank"
    # Performance model.
    ("phase", np.int64, 0),
    ("vmin", np.float64, 67.0),  # m/s CAS
    ("vmax", np.float64, 163.0),  # m/s CAS
    ("axmax", np.float64, 2.37),  # m/s^2
    ("thrust", np.float64, 0.0),  # N, net thrust (drag + mass * ax)
    ("drag", np.float64, 0.0),  # N
    ("fuelflow", np.float64, 0.0),  # kg/s, all engines
    ("fuelburn", np.float64, 0.0),  # kg, fuel burned since creation: the sum of fuelflow * dt over the steps
    # Active waypoint (LNAV) [docs/dynamics.md §2.6].
    ("iactwp", np.int64, -1),
    ("nwp", np.int64, 0),
    ("actwp_lat", np.float64, 0.0),  # deg
    ("actwp_lon", np.float64, 0.0),  # deg
    ("curlegdir", np.float64, NO_VALUE),  # deg
    ("turndist", np.float64, 1.0),  # m
    ("next_qdr", np.float64, NO_VALUE),  # deg
    ("swlastwp", np.bool_, False),
    ("route_has_dest", np.bool_, False),
)

#: Names of the float64 fields, in the order of the rows of the float block.
FLOAT_FIELDS: tuple[str, ...] = tuple(name for name, dtype, _ in STATE_FIELDS if dtype is np.float64)
#: Row of each float field in the float block.
FIELD_INDEX: dict[str, int] = {name: i for i, name in enumerate(FLOAT_FIELDS)}
#: Per-aircraft arrays outside the float block (the non-float fields, the route geometry and the
#: aircraft type: a row of the simulator's performance table, not comparable between simulators).
NON_FLOAT_STATE: tuple[str, ...] = (*(name for name, dtype, _ in STATE_FIELDS if dtype is not np.float64), "route_lat", "route_lon", "type_index")

# Rows of the float block, as plain integers for the kernels.
I_LAT = FIELD_INDEX["lat"]
I_LON = FIELD_INDEX["lon"]
I_ALT = FIELD_INDEX["alt"]
I_HDG = FIELD_INDEX["hdg"]
I_TRK = FIELD_INDEX["trk"]
I_TAS = FIELD_INDEX["tas"]
I_CAS = FIELD_INDEX["cas"]
I_MACH = FIELD_INDEX["mach"]
I_GS = FIELD_INDEX["gs"]
I_GSNORTH = FIELD_INDEX["gsnorth"]
I_GSEAST = FIELD_INDEX["gseast"]
I_VS = FIELD_INDEX["vs"]
I_AX = FIELD_INDEX["ax"]
I_WINDNORTH = FIELD_INDEX["windnorth"]
I_WINDEAST = FIELD_INDEX["windeast"]
I_DISTFLOWN = FIELD_INDEX["distflown"]
I_SELSPD = FIELD_INDEX["selspd"]
I_SELALT = FIELD_INDEX["selalt"]
I_SELVS = FIELD_INDEX["selvs"]
I_AP_TRK = FIELD_INDEX["ap_trk"]
I_AP_TAS = FIELD_INDEX["ap_tas"]
I_AP_VS = FIELD_INDEX["ap_vs"]
I_AP_ALT = FIELD_INDEX["ap_alt"]
I_TURNPHI = FIELD_INDEX["turnphi"]
I_VMIN = FIELD_INDEX["vmin"]
I_VMAX = FIELD_INDEX["vmax"]
I_AXMAX = FIELD_INDEX["axmax"]
I_THRUST = FIELD_INDEX["thrust"]
I_DRAG = FIELD_INDEX["drag"]
I_FUELFLOW = FIELD_INDEX["fuelflow"]
I_FUELBURN = FIELD_INDEX["fuelburn"]
I_ACTWP_LAT = FIELD_INDEX["actwp_lat"]
I_ACTWP_LON = FIELD_INDEX["actwp_lon"]
I_CURLEGDIR = FIELD_INDEX["curlegdir"]
I_TURNDIST = FIELD_INDEX["turndist"]
I_NEXT_QDR = FIELD_INDEX["next_qdr"]


def checked_index(index: ArrayLike, bound: int, what: str) -> NDArray[np.int64]:
    """``index`` as a 1-D int64 array, every entry in [0, bound), else ``IndexError``."""
    if isinstance(index, (int, np.integer)) and not isinstance(index, (bool, np.bool_)):
        if not 0 <= index < bound:
            raise IndexError(f"{what} out of range [0, {bound}): {index}")
        return np.array([index], dtype=np.int64)
    a = np.asarray(index, dtype=np.int64)
    if a.ndim != 1:
        a = a.reshape(-1)
    # One reduction checks both ends: negative indices are huge as unsigned integers.
    if a.size and a.view(np.uint64).max() >= bound:
        raise IndexError(f"{what} out of range [0, {bound})")
    return a


def aircraft_index(env: ArrayLike, slot: ArrayLike, n_envs: int, max_aircraft: int) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Validated, broadcast 1-D (env, slot) index arrays, as every command takes them."""
    env_a = checked_index(env, n_envs, "environment index")
    slot_a = checked_index(slot, max_aircraft, "aircraft slot")
    if env_a.shape != slot_a.shape:
        if slot_a.size == 1:
            slot_a = np.full(env_a.shape, slot_a[0])
        elif env_a.size == 1:
            env_a = np.full(slot_a.shape, env_a[0])
        else:
            env_a, slot_a = (a.ravel() for a in np.broadcast_arrays(env_a, slot_a))
    return env_a, slot_a
