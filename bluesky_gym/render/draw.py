"""Drawing primitives on pygame surfaces: anti-aliased shapes, aircraft symbols, text.

Imported only after :func:`bluesky_gym.render.backend.import_pygame` has succeeded.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import pygame
import pygame.gfxdraw

from bluesky_gym.render import palette as pal
from bluesky_gym.render.palette import Color

Point = tuple[float, float]

_GFX_LIMIT = 30000  # gfxdraw takes 16-bit coordinates
_FONTS: dict[int, pygame.font.Font] = {}
_GRADIENTS: dict[tuple[int, int, Color, Color], pygame.Surface] = {}

# Plan-view aircraft silhouette, nose along +y, right wing along +x (unit: half length).
_PLAN_SHAPE: tuple[Point, ...] = (
    (0.0, 1.0),
    (0.10, 0.82),
    (0.10, 0.28),
    (0.95, -0.12),
    (0.95, -0.30),
    (0.10, -0.10),
    (0.09, -0.62),
    (0.40, -0.86),
    (0.40, -1.0),
    (0.0, -0.92),
)
_PLAN_POLY: tuple[Point, ...] = _PLAN_SHAPE + tuple((-x, y) for x, y in reversed(_PLAN_SHAPE[1:-1]))

# Side-view silhouette, nose along +x, up along +y (unit: half length).
_SIDE_POLY: tuple[Point, ...] = (
    (1.0, 0.0),
    (0.86, 0.12),
    (-0.62, 0.14),
    (-0.90, 0.55),
    (-1.0, 0.55),
    (-0.94, 0.06),
    (-1.0, -0.06),
    (0.80, -0.12),
)


def font(size: int) -> pygame.font.Font:
    """The default pygame font at ``size`` (cached)."""
    if not pygame.font.get_init():
        pygame.font.init()
        _FONTS.clear()
    f = _FONTS.get(size)
    if f is None:
        f = pygame.font.Font(None, size)
        _FONTS[size] = f
    return f


def text(surf: pygame.Surface, s: str, pos: Point, size: int = 18, color: Color = pal.TEXT, anchor: str = "topleft") -> pygame.Rect:
    """Draw anti-aliased text; ``anchor`` is a pygame Rect attribute (``"midleft"``, ...)."""
    img = font(size).render(s, True, color)
    r = img.get_rect(**{anchor: (round(pos[0]), round(pos[1]))})
    surf.blit(img, r)
    return r


def text_with_halo(surf: pygame.Surface, s: str, pos: Point, size: int, color: Color, anchor: str = "topleft") -> pygame.Rect:
    """Text on a dark outline so that it stays legible over lines and areas."""
    img = font(size).render(s, True, color)
    halo = font(size).render(s, True, pal.BACKGROUND)
    r = img.get_rect(**{anchor: (round(pos[0]), round(pos[1]))})
    for dx, dy in ((-1, 0), (1, 0), (0, -1), (0, 1)):
        surf.blit(halo, r.move(dx, dy))
    surf.blit(img, r)
    return r


def _fits(points: Sequence[Point]) -> bool:
    return all(abs(x) < _GFX_LIMIT and abs(y) < _GFX_LIMIT for x, y in points)


def _visible(surf: pygame.Surface, points: Sequence[Point], margin: float = 0.0) -> bool:
    w, h = surf.get_size()
    xs = [p[0] for p in points]
    ys = [p[1] for p in points]
    return max(xs) >= -margin and min(xs) <= w + margin and max(ys) >= -margin and min(ys) <= h + margin


def polygon(surf: pygame.Surface, color: Color, points: Sequence[Point], fill: Color | None = None, width: int = 1) -> None:
    """A polygon with an anti-aliased outline and an optional fill."""
    if len(points) < 3 or not _visible(surf, points):
        return
    ipts = [(round(x), round(y)) for x, y in points]
    if fill is not None:
        if _fits(points):
            pygame.gfxdraw.filled_polygon(surf, ipts, fill)
        else:
            pygame.draw.polygon(surf, fill, ipts)
    if width <= 1 and _fits(points):
        pygame.gfxdraw.aapolygon(surf, ipts, color)
    else:
        pygame.draw.polygon(surf, color, ipts, max(width, 1))


def circle(surf: pygame.Surface, color: Color, center: Point, radius: float, width: int = 1, fill: Color | None = None) -> None:
    """An anti-aliased circle (``width`` rings of one pixel), optionally filled."""
    cx, cy = round(center[0]), round(center[1])
    r = round(radius)
    if r < 1 or not _visible(surf, [(cx - r, cy - r), (cx + r, cy + r)]) or not _fits([(cx, cy), (r, r)]):
        return
    if fill is not None:
        pygame.gfxdraw.filled_circle(surf, cx, cy, r, fill)
    for k in range(max(width, 1)):
        if r - k >= 1:
            pygame.gfxdraw.aacircle(surf, cx, cy, r - k, color)


def dashed_circle(surf: pygame.Surface, color: Color, center: Point, radius: float, dash_px: float = 6.0) -> None:
    """A dashed circle."""
    if radius < 2 or not _visible(surf, [(center[0] - radius, center[1] - radius), (center[0] + radius, center[1] + radius)]):
        return
    n = max(8, int(2 * math.pi * radius / dash_px) // 2 * 2)
    for k in range(0, n, 2):
        a0, a1 = 2 * math.pi * k / n, 2 * math.pi * (k + 1) / n
        p0 = (center[0] + radius * math.cos(a0), center[1] + radius * math.sin(a0))
        p1 = (center[0] + radius * math.cos(a1), center[1] + radius * math.sin(a1))
        line(surf, color, p0, p1)


def line(surf: pygame.Surface, color: Color, p0: Point, p1: Point, width: int = 1) -> None:
    """A straight line, anti-aliased when one pixel wide."""
    if not _visible(surf, [p0, p1]):
        return
    if width <= 1:
        pygame.draw.aaline(surf, color, p0, p1)
    else:
        pygame.draw.line(surf, color, (round(p0[0]), round(p0[1])), (round(p1[0]), round(p1[1])), width)


def dashed_line(surf: pygame.Surface, color: Color, p0: Point, p1: Point, dash_px: float = 7.0, gap_px: float = 5.0, width: int = 1) -> None:
    """A dashed straight line."""
    dx, dy = p1[0] - p0[0], p1[1] - p0[1]
    length = math.hypot(dx, dy)
    if length < 1e-6 or not _visible(surf, [p0, p1]):
        return
    ux, uy = dx / length, dy / length
    s = 0.0
    while s < length:
        e = min(s + dash_px, length)
        line(surf, color, (p0[0] + ux * s, p0[1] + uy * s), (p0[0] + ux * e, p0[1] + uy * e), width)
        s = e + gap_px


def polyline(surf: pygame.Surface, color: Color, points: Sequence[Point], dashed: bool = False, width: int = 1) -> None:
    """Consecutive (optionally dashed) segments."""
    for a, b in zip(points[:-1], points[1:]):
        if dashed:
            dashed_line(surf, color, a, b, width=width)
        else:
            line(surf, color, a, b, width)


def _transform(shape: Sequence[Point], center: Point, fx: float, fy: float, rx: float, ry: float, scale: float) -> list[Point]:
    """Place a shape given in (right, forward) units at ``center`` with screen axes f and r."""
    return [(center[0] + (x * rx + y * fx) * scale, center[1] + (x * ry + y * fy) * scale) for x, y in shape]


def plan_aircraft(surf: pygame.Surface, color: Color, center: Point, hdg_deg: float, size: float = 9.0, outline: Color | None = None) -> None:
    """An aircraft silhouette seen from above, nose along the true heading (north-up map)."""
    h = math.radians(hdg_deg)
    fx, fy = math.sin(h), -math.cos(h)  # forward on screen
    rx, ry = math.cos(h), math.sin(h)  # right wing on screen
    pts = _transform(_PLAN_POLY, center, fx, fy, rx, ry, size)
    polygon(surf, outline or color, pts, fill=color)


def side_aircraft(surf: pygame.Surface, color: Color, center: Point, direction: int, pitch_deg: float, size: float = 10.0) -> None:
    """An aircraft silhouette seen from the side, nose right (``direction`` 1) or left (-1).

    ``pitch_deg`` tilts the nose up (positive) in screen terms.
    """
    p = math.radians(pitch_deg)
    d = 1 if direction >= 0 else -1
    fx, fy = d * math.cos(p), -math.sin(p)  # forward on screen
    ux, uy = -d * math.sin(p), -math.cos(p)  # up on screen
    pts = [(center[0] + (x * fx + y * ux) * size, center[1] + (x * fy + y * uy) * size) for x, y in _SIDE_POLY]
    polygon(surf, color, pts, fill=color)


def triangle(surf: pygame.Surface, color: Color, center: Point, size: float, filled: bool = False) -> None:
    """An upward triangle (the chart symbol of a waypoint)."""
    cx, cy = center
    pts = [(cx, cy - size), (cx + size * 0.87, cy + size * 0.5), (cx - size * 0.87, cy + size * 0.5)]
    polygon(surf, color, pts, fill=color if filled else None)


def diamond(surf: pygame.Surface, color: Color, center: Point, size: float, filled: bool = False) -> None:
    """A diamond (used for the final approach fix)."""
    cx, cy = center
    pts = [(cx, cy - size), (cx + size, cy), (cx, cy + size), (cx - size, cy)]
    polygon(surf, color, pts, fill=color if filled else None)


def swatch(surf: pygame.Surface, color: Color, rect: pygame.Rect) -> None:
    """A small filled square for legends."""
    pygame.draw.rect(surf, color, rect)


def vertical_gradient(surf: pygame.Surface, rect: pygame.Rect, top: Color, bottom: Color) -> None:
    """Fill ``rect`` with a top-to-bottom colour gradient (cached per size and colours)."""
    key = (rect.width, rect.height, top, bottom)
    grad = _GRADIENTS.get(key)
    if grad is None:
        grad = pygame.Surface((rect.width, rect.height))
        for k in range(rect.height):
            c = pal.mix(top, bottom, k / max(rect.height - 1, 1))
            pygame.draw.line(grad, c, (0, k), (rect.width - 1, k))
        _GRADIENTS[key] = grad
    surf.blit(grad, rect.topleft)
