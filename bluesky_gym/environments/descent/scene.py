"""DescentEnv-v0: side view of the descent towards the runway."""

from __future__ import annotations

from typing import Any

from bluesky_gym.core.units import FT, MPS2KT
from bluesky_gym.render import palette as pal
from bluesky_gym.render.scene import SideAircraft, SideScene
from bluesky_gym.render.scenes.common import OWNSHIP_CALLSIGN

LEGEND = [(pal.OWNSHIP, "ownship and its profile"), (pal.GOAL, "target altitude"), (pal.RUNWAY, "runway")]


def side_ownship(task: Any, i: int, rd_km: float) -> list[SideAircraft]:
    """The ownship of a vertical task as a side-view aircraft (empty before the first reset)."""
    sim = task.sim
    if not sim.active[i, 0]:
        return []
    return [
        SideAircraft(
            key=0,
            x_km=rd_km,
            alt=float(sim.alt[i, 0]),
            vx=float(sim.gs[i, 0]),
            vs=float(sim.vs[i, 0]),
            callsign=OWNSHIP_CALLSIGN,
            role="own",
        )
    ]


def vertical_lines(task: Any, i: int, rd_km: float) -> list[tuple[str, str]]:
    """Panel lines of the vertical tasks: altitude, target, vertical speed, runway distance."""
    sim = task.sim
    alt = float(sim.alt[i, 0])
    target = float(task.target_alt[i])
    vs = float(sim.vs[i, 0])
    return [
        ("ALT", f"{alt:.0f} m  FL{max(alt, 0) / FT / 100:03.0f}"),
        ("target", f"{target:.0f} m ({alt - target:+.0f})"),
        ("VS", f"{vs:+.1f} m/s ({vs / FT * 60:+.0f} fpm)"),
        ("GS", f"{float(sim.gs[i, 0]) * MPS2KT:.0f} kt"),
        ("to runway", f"{rd_km:.1f} km"),
    ]


def descent_scene(task: Any, i: int) -> SideScene:
    """Altitude against distance to the runway, with the target altitude."""
    rd = float(task.runway_distance()[i])
    return SideScene(
        x_max_km=float(task.config.runway_distance_km) + 5.0,
        x_min_km=-10.0,
        alt_max=5000.0,
        aircraft=side_ownship(task, i, rd),
        target_alt=float(task.target_alt[i]) if task.sim.active[i, 0] else None,
        runway_km=3.0,
        panel=vertical_lines(task, i, rd),
        legend=LEGEND,
    )
