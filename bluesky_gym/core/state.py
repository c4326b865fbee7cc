"""Layout of the simulator state: the per-aircraft fields and the rows of the float block.

All float64 fields of a :class:`~bluesky_gym.core.Simulator` live in one contiguous block
``(fields, aircraft)`` that the compiled kernels update in place; the row of each field is
``FIELD_INDEX[name]`` (also exported as ``I_<NAME>`` for the kernels).
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from bluesky_gym.core.jit import grid_range, jit
from bluesky_gym.core.units import NO_VALUE

Array = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
IntArray = NDArray[np.int64]


class EmptySlot:
    """The value of an empty slot of a state field, as :class:`AircraftState` declares it (a marker, never an array)."""

    __slots__ = ("value",)

    def __init__(self, value: float) -> None:
        self.value = value

    def __repr__(self) -> str:
        return f"empty_slot({self.value!r})"


def empty_slot(value: float) -> Any:
    """Declare a state field of :class:`AircraftState` whose empty slots hold ``value``."""
    return EmptySlot(value)


class AircraftState(Protocol):
    """The per-aircraft state arrays, shaped ``(n_envs, max_aircraft)`` and meaningful where ``active``.

    The one declaration of the state fields, each with its dtype (``Array``: float64,
    ``BoolArray``, ``IntArray``: int64), the value of an empty slot and its unit:
    :data:`STATE_FIELDS` is read from it, :class:`~bluesky_gym.core.physics.Physics` extends it,
    and the native core and the BlueSky backend inherit it (they put their arrays in place of
    the empty-slot markers).
    """

    active: BoolArray = empty_slot(False)
    lat: Array = empty_slot(0.0)  # deg
    lon: Array = empty_slot(0.0)  # deg
    alt: Array = empty_slot(0.0)  # m
    hdg: Array = empty_slot(0.0)  # deg true
    trk: Array = empty_slot(0.0)  # deg true
    tas: Array = empty_slot(0.0)  # m/s
    cas: Array = empty_slot(0.0)  # m/s
    mach: Array = empty_slot(0.0)  # -
    gs: Array = empty_slot(0.0)  # m/s
    gsnorth: Array = empty_slot(0.0)  # m/s
    gseast: Array = empty_slot(0.0)  # m/s
    vs: Array = empty_slot(0.0)  # m/s
    ax: Array = empty_slot(0.0)  # m/s^2, longitudinal acceleration of the last step
    windnorth: Array = empty_slot(0.0)  # m/s, wind at the aircraft
    windeast: Array = empty_slot(0.0)  # m/s
    distflown: Array = empty_slot(0.0)  # m
    # Selected (MCP) values.
    selspd: Array = empty_slot(0.0)  # m/s CAS, or Mach when 0.1 < v < 2
    selalt: Array = empty_slot(0.0)  # m
    selvs: Array = empty_slot(0.0)  # m/s
    swlnav: BoolArray = empty_slot(False)
    swvnav: BoolArray = empty_slot(False)
    swvnavspd: BoolArray = empty_slot(False)
    # Autopilot outputs, before the performance limits.
    ap_trk: Array = empty_slot(0.0)  # deg
    ap_tas: Array = empty_slot(0.0)  # m/s
    ap_vs: Array = empty_slot(NO_VALUE)  # m/s
    ap_alt: Array = empty_slot(0.0)  # m
    turnphi: Array = empty_slot(0.0)  # rad; 0 means "use the default bank"
    # Performance model.
    phase: IntArray = empty_slot(0)
    vmin: Array = empty_slot(67.0)  # m/s CAS
    vmax: Array = empty_slot(163.0)  # m/s CAS
    axmax: Array = empty_slot(2.37)  # m/s^2
    thrust: Array = empty_slot(0.0)  # N, net thrust (drag + mass * ax)
    drag: Array = empty_slot(0.0)  # N
    fuelflow: Array = empty_slot(0.0)  # kg/s, all engines
    fuelburn: Array = empty_slot(0.0)  # kg, fuel burned since creation: the sum of fuelflow * dt over the steps
    # Active waypoint (LNAV) [docs/dynamics.md §2.6].
    iactwp: IntArray = empty_slot(-1)
    nwp: IntArray = empty_slot(0)
    actwp_lat: Array = empty_slot(0.0)  # deg
    actwp_lon: Array = empty_slot(0.0)  # deg
    curlegdir: Array = empty_slot(NO_VALUE)  # deg
    turndist: Array = empty_slot(1.0)  # m
    next_qdr: Array = empty_slot(NO_VALUE)  # deg
    swlastwp: BoolArray = empty_slot(False)
    route_has_dest: BoolArray = empty_slot(False)


#: dtype of each array annotation of :class:`AircraftState` (annotations are strings here).
_DTYPES: dict[str, type] = {"Array": np.float64, "BoolArray": np.bool_, "IntArray": np.int64}

#: (name, dtype, value of an empty slot) of every per-aircraft state array, in declaration order.
STATE_FIELDS: tuple[tuple[str, type, float], ...] = tuple(
    (name, _DTYPES[str(kind)], AircraftState.__dict__[name].value) for name, kind in AircraftState.__annotations__.items()
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


# --- moving the state of some airspaces between copies of the arrays ----------------------------
@jit
def scatter_columns(cols, src, dst):  # type: ignore[no-untyped-def]
    """``dst[:, cols[i]] = src[:, i]``: columns of a (k, N) array (the float block, a flat field as (1, N)) from a (k, len(cols)) one.

    :class:`~bluesky_gym.core.DeviceSimulator` puts the aircraft of airspaces reset on the host
    into its device state with it (one launch per array).
    """
    for i in grid_range(cols.shape[0]):
        c = cols[i]
        for f in range(dst.shape[0]):
            dst[f, c] = src[f, i]


@jit
def scatter_rows(rows, src, dst):  # type: ignore[no-untyped-def]
    """``dst[rows[i], :] = src[i, :]``: rows of an (N, k) array (per-aircraft memo, routes) from a (len(rows), k) one."""
    for i in grid_range(rows.shape[0]):
        r = rows[i]
        for k in range(dst.shape[1]):
            dst[r, k] = src[i, k]


@jit
def gather_columns(cols, src, dst):  # type: ignore[no-untyped-def]
    """``dst[:, i] = src[:, cols[i]]``: the inverse of :func:`scatter_columns` (some aircraft's columns into a (k, len(cols)) array).

    :class:`~bluesky_gym.core.DeviceSimulator` brings named aircraft back to the host with it
    (:meth:`~bluesky_gym.core.DeviceSimulator.edit_on_host`; one launch per array).
    """
    for i in grid_range(cols.shape[0]):
        c = cols[i]
        for f in range(src.shape[0]):
            dst[f, i] = src[f, c]


@jit
def gather_rows(rows, src, dst):  # type: ignore[no-untyped-def]
    """``dst[i, :] = src[rows[i], :]``: the inverse of :func:`scatter_rows`."""
    for i in grid_range(rows.shape[0]):
        r = rows[i]
        for k in range(src.shape[1]):
            dst[i, k] = src[r, k]


@jit
def clear_flagged(flags, active):  # type: ignore[no-untyped-def]
    """``active[i] = False`` where ``flags[i]`` (flat arrays): the flagged aircraft deleted (``DeviceSimulator.delete_flagged``)."""
    for i in grid_range(flags.shape[0]):
        if flags[i]:
            active[i] = False
