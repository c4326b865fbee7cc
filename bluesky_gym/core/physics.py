"""The physics interface the tasks program against, implemented by the native core and by BlueSky.

:class:`Physics` is what a task may use of its simulator: the dimensions and clock, read-only
per-aircraft state arrays shaped ``(n_envs, max_aircraft)`` (meaningful where ``active``), the
wind field, and commands. Tasks change aircraft state only through these commands; the two
direct-write commands :meth:`Physics.set_autopilot` and :meth:`Physics.set_state` stand for the
reference gym code's direct writes into BlueSky's arrays.

Implementations: :class:`bluesky_gym.core.Simulator` (the native batched core) and
:class:`bluesky_gym.backends.bluesky_sim.BlueSkyPhysics` (BlueSky 1.1.1 itself, one airspace).
Every index argument ``env``/``slot`` accepts an int or an array; values broadcast over them.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from bluesky_gym.core.resolution import AsasConfig
from bluesky_gym.core.wind import WindField

Array = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
IntArray = NDArray[np.int64]


@runtime_checkable
class Physics(Protocol):
    """A batch of ``n_envs`` airspaces with ``max_aircraft`` aircraft slots each."""

    n_envs: int
    max_aircraft: int
    max_waypoints: int
    dt: float  # s, time step
    simt: float  # s, simulation clock (shared by all airspaces)
    geo: str  # "compiled" or "python": the geo function set LNAV uses

    @property
    def wind(self) -> WindField:
        """The wind of every airspace (add points with ``wind.add_points``)."""
        ...

    # Read-only state, (n_envs, max_aircraft); see bluesky_gym.core.state for units.
    active: BoolArray
    lat: Array  # deg
    lon: Array  # deg
    alt: Array  # m
    hdg: Array  # deg
    trk: Array  # deg
    tas: Array  # m/s
    cas: Array  # m/s
    mach: Array  # -
    gs: Array  # m/s
    gsnorth: Array  # m/s
    gseast: Array  # m/s
    vs: Array  # m/s
    ax: Array  # m/s^2
    windnorth: Array  # m/s
    windeast: Array  # m/s
    distflown: Array  # m
    selspd: Array  # m/s CAS or Mach
    selalt: Array  # m
    selvs: Array  # m/s
    swlnav: BoolArray
    swvnav: BoolArray
    swvnavspd: BoolArray
    ap_trk: Array  # deg
    ap_tas: Array  # m/s
    ap_vs: Array  # m/s
    ap_alt: Array  # m
    turnphi: Array  # rad
    phase: IntArray
    vmin: Array  # m/s CAS
    vmax: Array  # m/s CAS
    axmax: Array  # m/s^2
    thrust: Array  # N, net thrust of the last performance update
    drag: Array  # N
    fuelflow: Array  # kg/s
    fuelburn: Array  # kg, fuel burned since creation (fuelflow times dt, summed over the steps)
    iactwp: IntArray
    nwp: IntArray
    actwp_lat: Array  # deg
    actwp_lon: Array  # deg
    curlegdir: Array  # deg
    turndist: Array  # m
    next_qdr: Array  # deg
    swlastwp: BoolArray
    route_has_dest: BoolArray
    route_lat: Array  # (n_envs, max_aircraft, max_waypoints) deg
    route_lon: Array  # (n_envs, max_aircraft, max_waypoints) deg

    def reset_envs(self, envs: ArrayLike | None = None) -> None:
        """Remove all aircraft and wind from the given airspaces (all when None)."""
        ...

    def create(
        self,
        env: ArrayLike,
        slot: ArrayLike,
        lat: ArrayLike = ...,
        lon: ArrayLike = ...,
        hdg: ArrayLike = ...,
        alt: ArrayLike = ...,
        spd: ArrayLike = ...,
        actype: str | Sequence[str] | NDArray[np.str_] | None = None,
    ) -> None:
        """Create aircraft (BlueSky ``CRE``): position [deg], heading [deg], altitude [m], CAS [m/s] or Mach, type (None: A320)."""
        ...

    def creconfs(
        self,
        env: ArrayLike,
        target: ArrayLike,
        slot: ArrayLike,
        dpsi: ArrayLike,
        dcpa: ArrayLike,
        tlosh: ArrayLike,
        dh: ArrayLike | None = None,
        tlosv: ArrayLike | None = None,
        spd: ArrayLike | None = None,
        actype: str | Sequence[str] | NDArray[np.str_] | None = None,
    ) -> None:
        """Create intruders in conflict with target aircraft (BlueSky ``traf.creconfs``), of type ``actype`` (None: A320)."""
        ...

    def aircraft_type(self, env: ArrayLike, slot: ArrayLike) -> list[str]:
        """Type names of aircraft, upper case, as given at creation (an unknown type keeps its name)."""
        ...

    def delete(self, env: ArrayLike, slot: ArrayLike) -> None:
        """Delete aircraft."""
        ...

    def cmd_heading(self, env: ArrayLike, slot: ArrayLike, hdg: ArrayLike) -> None:
        """``HDG`` [deg]; LNAV off."""
        ...

    def cmd_speed(self, env: ArrayLike, slot: ArrayLike, casmach: ArrayLike) -> None:
        """``SPD``: CAS [m/s] or Mach."""
        ...

    def cmd_altitude(self, env: ArrayLike, slot: ArrayLike, alt: ArrayLike, vs: ArrayLike | None = None) -> None:
        """``ALT alt [vs]`` in SI."""
        ...

    def cmd_vertical_speed(self, env: ArrayLike, slot: ArrayLike, vs: ArrayLike) -> None:
        """``VS`` [m/s]."""
        ...

    def add_waypoint(self, env: ArrayLike, slot: ArrayLike, lat: ArrayLike, lon: ArrayLike) -> None:
        """``ADDWPT``: append a fly-by waypoint [deg]; LNAV on."""
        ...

    def set_destination(self, env: ArrayLike, slot: ArrayLike, lat: ArrayLike, lon: ArrayLike) -> None:
        """``DEST``: set the route's destination [deg]."""
        ...

    def set_autopilot(
        self,
        env: ArrayLike,
        slot: ArrayLike,
        *,
        selalt: ArrayLike | None = None,
        selvs: ArrayLike | None = None,
        swvnav: ArrayLike | None = None,
        ap_trk: ArrayLike | None = None,
    ) -> None:
        """Direct write of autopilot values (None = unchanged): selected altitude [m] and vertical speed [m/s], VNAV switch, track [deg]."""
        ...

    def set_state(self, env: ArrayLike, slot: ArrayLike, *, alt: ArrayLike | None = None, hdg: ArrayLike | None = None) -> None:
        """Direct write of altitude [m] and heading [deg] (None = unchanged)."""
        ...

    def step(self) -> None:
        """Advance every airspace by ``dt``."""
        ...

    def run(self, n_steps: int, trace: bool = False, stop: Callable[[Array], ArrayLike] | None = None) -> Array | None:
        """Advance ``n_steps`` steps; with ``trace`` or ``stop`` return positions (n_steps, 2, n_envs, max_aircraft).

        ``stop(track) -> ended_at`` gets the positions of the first ``k`` steps and returns, per
        airspace, the number of steps after which its episode ended (1..k), or 0. An airspace that
        ended after ``j < n_steps`` steps is left in its state after ``j`` steps; when every
        airspace ended, the clock stops at the largest ``j``.
        """
        ...


@runtime_checkable
class RouteCommands(Protocol):
    """Route commands beyond :class:`Physics`: ``DIRECT`` and ``LNAV`` (the native core and BlueSky have them)."""

    def cmd_direct(self, env: ArrayLike, slot: ArrayLike, waypoint: ArrayLike) -> None:
        """``DIRECT``: make route waypoint ``waypoint`` (0-based index) active and fly to it; LNAV on."""
        ...

    def cmd_lnav(self, env: ArrayLike, slot: ArrayLike, on: ArrayLike) -> None:
        """``LNAV ON/OFF``."""
        ...


@runtime_checkable
class ConflictResolutionCommands(Protocol):
    """BlueSky's conflict detection and MVP resolution flown by the aircraft (the native core and BlueSky have them)."""

    def set_conflict_resolution(self, env: ArrayLike, config: AsasConfig) -> None:
        """Switch the ASAS of airspaces ``env`` to ``config`` (``ASAS``, ``RESO MVP``, zones, RMETH switches and factors)."""
        ...
