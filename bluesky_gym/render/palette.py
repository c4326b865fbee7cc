"""The one colour palette of every BlueSky-Gym picture (RGB tuples).

A dark radar-scope theme: the controlled aircraft (ownship) is green, other traffic amber, a loss
of separation red, goals (waypoints, FAF, target altitude) blue, airspace grey-blue and
restricted areas orange-red. Map and side views use the same meanings.
"""

from __future__ import annotations

Color = tuple[int, int, int]

BACKGROUND: Color = (16, 24, 35)
GRID: Color = (36, 50, 68)
AXIS: Color = (105, 122, 145)
TEXT: Color = (226, 231, 238)
TEXT_DIM: Color = (138, 151, 170)
PANEL: Color = (10, 15, 23)
PANEL_EDGE: Color = (52, 68, 90)

OWNSHIP: Color = (88, 230, 120)
INTRUDER: Color = (245, 190, 70)
INTRUDER_FAR: Color = (128, 112, 78)
LOS: Color = (255, 60, 60)

GOAL: Color = (80, 170, 255)
GOAL_DONE: Color = (100, 110, 125)
RUNWAY: Color = (235, 235, 235)
ROUTE: Color = (70, 110, 160)

AIRSPACE_FILL: Color = (24, 36, 52)
AIRSPACE_EDGE: Color = (150, 170, 200)
OBSTACLE_FILL: Color = (92, 34, 30)
OBSTACLE_EDGE: Color = (240, 110, 70)

SKY_TOP: Color = (14, 22, 34)
SKY_BOTTOM: Color = (30, 46, 66)
GROUND: Color = (48, 62, 36)
GROUND_EDGE: Color = (96, 120, 64)


def mix(a: Color, b: Color, t: float) -> Color:
    """The colour a fraction ``t`` (0..1) of the way from ``a`` to ``b``."""
    t = min(max(t, 0.0), 1.0)
    return (round(a[0] + (b[0] - a[0]) * t), round(a[1] + (b[1] - a[1]) * t), round(a[2] + (b[2] - a[2]) * t))
