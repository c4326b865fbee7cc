"""What a picture shows, independent of how it is drawn.

A scene builder reads a task's state for one episode and returns a :class:`MapScene` (a
north-up plan view, positions in latitude/longitude) or a :class:`SideScene` (a vertical
profile: altitude against distance to the runway). The renderer adds trails, the scale, the
text panel and turns the scene into pixels.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

from bluesky_gym.render.palette import Color

Role = Literal["own", "intruder"]


@dataclass
class MapAircraft:
    """An aircraft on the plan view.

    Attributes:
        key: Simulator slot (identifies the aircraft's trail).
        lat: Latitude [deg].
        lon: Longitude [deg].
        hdg: True heading [deg]; the symbol points along it.
        trk: True ground track [deg]; the speed vector points along it.
        gs: Ground speed [m/s] (length of the speed vector).
        alt: Altitude [m].
        callsign: Label text.
        role: ``"own"`` for the controlled aircraft, ``"intruder"`` for other traffic.
        los: Whether it is in a loss of separation with the ownship (drawn red).
        ring_nm: Radius of its protected-zone ring [NM], or None for no ring.
        dim: Draw it faded (e.g. traffic vertically separated from the ownship).
    """

    key: int
    lat: float
    lon: float
    hdg: float
    trk: float
    gs: float
    alt: float
    callsign: str
    role: Role = "intruder"
    los: bool = False
    ring_nm: float | None = None
    dim: bool = False


@dataclass
class Fix:
    """A waypoint or fix.

    Attributes:
        lat: Latitude [deg].
        lon: Longitude [deg].
        label: Name shown next to the symbol.
        done: Whether it has been reached (drawn grey).
        capture_nm: Radius of the capture ring [NM], or None.
        kind: ``"waypoint"`` (triangle), ``"faf"`` (final approach fix, a diamond) or ``"ring"``
            (only the capture ring, e.g. around a runway).
    """

    lat: float
    lon: float
    label: str = ""
    done: bool = False
    capture_nm: float | None = None
    kind: Literal["waypoint", "faf", "ring"] = "waypoint"


@dataclass
class Area:
    """A polygon: the sector to stay in, or a restricted area to avoid.

    Attributes:
        lat: Vertex latitudes [deg].
        lon: Vertex longitudes [deg].
        kind: ``"sector"`` or ``"obstacle"``.
        label: Optional name.
        violated: Whether the ownship is inside a restricted area (drawn brighter).
    """

    lat: list[float]
    lon: list[float]
    kind: Literal["sector", "obstacle"] = "obstacle"
    label: str = ""
    violated: bool = False


@dataclass
class Runway:
    """A runway, drawn as a thick white bar from its threshold along its direction.

    Attributes:
        lat: Threshold latitude [deg].
        lon: Threshold longitude [deg].
        hdg: Landing direction [deg true].
        length_km: Length [km].
        label: Name.
    """

    lat: float
    lon: float
    hdg: float
    length_km: float = 3.0
    label: str = "RWY"


@dataclass
class Line:
    """A polyline on the map (routes, approach path, boundaries).

    Attributes:
        lat: Point latitudes [deg].
        lon: Point longitudes [deg].
        color: Colour.
        dashed: Dashed rather than solid.
        width: Width in pixels.
    """

    lat: list[float]
    lon: list[float]
    color: Color
    dashed: bool = True
    width: int = 1


@dataclass
class MapScene:
    """A north-up plan view.

    Attributes:
        center_lat: Latitude of the view centre [deg] (fixed for an episode).
        center_lon: Longitude of the view centre [deg].
        half_width_nm: Half the visible width [NM] (the height follows the canvas).
        aircraft: Aircraft; the ownship first.
        fixes: Waypoints and fixes.
        areas: Sector and restricted-area polygons.
        runways: Runways.
        lines: Other lines.
        follow: Key of the aircraft the view pans to keep in sight, or None.
        traffic_details: Label other traffic with flight level and ground speed too (the ownship
            always is); off where all traffic shares them.
        label_range_nm: Label only the traffic within this distance of the ownship (and any in a
            loss of separation); None labels all.
        labels: Draw labels at all; when False only the aircraft under the mouse pointer of the
            window is labelled.
        panel: Scene-specific (label, value) lines of the text panel.
        legend: (colour, text) entries of the legend.
    """

    center_lat: float
    center_lon: float
    half_width_nm: float
    aircraft: list[MapAircraft] = field(default_factory=list)
    fixes: list[Fix] = field(default_factory=list)
    areas: list[Area] = field(default_factory=list)
    runways: list[Runway] = field(default_factory=list)
    lines: list[Line] = field(default_factory=list)
    follow: int | None = 0
    traffic_details: bool = False
    label_range_nm: float | None = None
    labels: bool = True
    panel: list[tuple[str, str]] = field(default_factory=list)
    legend: list[tuple[Color, str]] = field(default_factory=list)


@dataclass
class SideAircraft:
    """An aircraft on the side view.

    Attributes:
        key: Simulator slot (identifies the aircraft's trail).
        x_km: Distance to the runway along the ownship's route [km].
        alt: Altitude [m].
        vx: Ground speed component towards the runway [m/s] (its sign sets the symbol's direction).
        vs: Vertical speed [m/s].
        callsign: Label text.
        role: ``"own"`` or ``"intruder"``.
        los: In a loss of separation with the ownship (drawn red).
        box: (half width [km], half height [m]) of its separation box, or None.
        dim: Laterally far from the ownship's route (drawn faded: the projection hides the offset).
        note: Extra label text (e.g. the lateral offset).
    """

    key: int
    x_km: float
    alt: float
    vx: float
    vs: float
    callsign: str
    role: Role = "intruder"
    los: bool = False
    box: tuple[float, float] | None = None
    dim: bool = False
    note: str = ""


@dataclass
class SideScene:
    """A vertical profile: altitude against distance to the runway (runway on the right).

    Attributes:
        x_max_km: Distance to the runway at the left edge [km].
        x_min_km: Distance at the right edge [km] (negative: past the runway).
        alt_max: Altitude at the top [m] (raised automatically to fit the aircraft).
        aircraft: Aircraft; the ownship first.
        target_alt: Target altitude [m], or None.
        runway_km: Runway length drawn past the threshold [km], or None for no runway.
        inset: Optional plan view drawn in a corner (e.g. to show lateral offsets).
        panel: Scene-specific (label, value) lines of the text panel.
        legend: (colour, text) entries of the legend.
    """

    x_max_km: float
    x_min_km: float
    alt_max: float
    aircraft: list[SideAircraft] = field(default_factory=list)
    target_alt: float | None = None
    runway_km: float | None = 3.0
    inset: MapScene | None = None
    panel: list[tuple[str, str]] = field(default_factory=list)
    legend: list[tuple[Color, str]] = field(default_factory=list)


Scene = MapScene | SideScene
