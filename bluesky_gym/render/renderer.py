"""The renderer behind ``env.render()``: scenes to pixels, trails, text panel, window, grid.

One :class:`Renderer` draws the episodes of one batched task. It only reads the task (it never
calls methods that change the simulation or the MDP), so rendering does not change what the
environment does.
"""

from __future__ import annotations

import itertools
import math
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pygame

from bluesky_gym.core.units import FT, MPS2KT, NM2KM
from bluesky_gym.render import draw
from bluesky_gym.render import palette as pal
from bluesky_gym.render.backend import WINDOW
from bluesky_gym.render.scene import MapAircraft, MapScene, Scene, SideScene
from bluesky_gym.render.scenes import SceneBuilder
from bluesky_gym.render.views import MapView, SideView, nice_step, scale_bar_nm

PANEL_WIDTH = 224
MAP_SIZE = (608, 608)  # plan view (pixels); with the panel the frame is 832 x 608
SIDE_SIZE = (608, 608)  # side view (same frame size as the plan view)
GRID_MAX = (1664, 1216)  # largest size of a grid of episodes
MAP_TRAIL = 12  # history dots per aircraft
TRAIL_DOT_S = 30.0  # simulated seconds between history dots (at least one decision step)
SIDE_TRAIL = 600  # points of the ownship's altitude profile
INSET_SIZE = 184  # plan-view inset of a side view
SPEED_VECTOR_S = 120.0  # the speed vector shows the position this many seconds ahead
FOLLOW_MARGIN = 0.9  # zoom out when the followed aircraft leaves this fraction of the view ...
ZOOM_OUT_MARGIN = 0.7  # ... so that it is back within this fraction
MAX_ZOOM_OUT = 3.0  # beyond this factor of the scene's width the view pans instead
HOVER_PX = 12.0  # the pointer labels an aircraft when within this distance of the symbol's centre [px]

_tokens = itertools.count(1)


@dataclass
class _EpisodeMemory:
    """What the renderer remembers about the episode shown in one slot of the batch."""

    steps: int = -1
    trail_step: int = -1
    distflown: float = -1.0
    trails: dict[int, deque[tuple[float, float]]] = field(default_factory=dict)
    center: tuple[float, float] | None = None
    half_width: float = 0.0
    alt_max: float = 0.0


class Renderer:
    """Draws the episodes of a batched task, as RGB arrays or in a window.

    Args:
        task: The batched task to draw (read only).
        render_mode: ``"rgb_array"`` or ``"human"``.
        fps: Frame-rate limit of the window in ``"human"`` mode.
        scene: The scene builder ``(task, env_index) -> Scene`` that says what to draw (see
            :mod:`bluesky_gym.render.scenes`).
        title: The id shown in the panel and the window title (default: the task's ``env_id``).
    """

    def __init__(self, task: Any, render_mode: str, fps: float, scene: SceneBuilder, title: str | None = None) -> None:
        if render_mode not in ("rgb_array", "human"):
            raise ValueError(f"render_mode must be 'rgb_array' or 'human', got {render_mode!r}")
        if not callable(scene):
            raise TypeError(f"scene must be a scene builder (task, env_index) -> Scene, got {scene!r}")
        self.task = task
        self.render_mode = render_mode
        self.fps = float(fps)
        self.scene = scene
        self.title = str(task.env_id) if title is None else title
        self._memory: dict[int, _EpisodeMemory] = {}
        self._dot_steps = max(1, round(TRAIL_DOT_S / (float(task.dt) * int(task.action_frequency))))
        self._token = next(_tokens)
        self._closed = False

    # --- public API (used by the Gymnasium shells) ---------------------------------------------
    def render(self, env_index: int = 0, reward: float | None = None, info: Mapping[str, Any] | None = None) -> np.ndarray | None:
        """Draw episode ``env_index``.

        Args:
            env_index: Episode of the batch to draw.
            reward: Reward of the last step (shown in the panel).
            info: Info dict of the last step for this episode (scalars).

        Returns:
            An (H, W, 3) uint8 frame in ``"rgb_array"`` mode; None in ``"human"`` mode.
        """
        self._check_index(env_index)
        frame = self.draw_frame(env_index, reward, info, hover=self._pointer())
        return self._output(frame)

    def render_grid(self, n: int, rewards: Any = None, info: Mapping[str, Any] | None = None) -> np.ndarray | None:
        """Draw the first ``n`` episodes side by side in a grid.

        Args:
            n: Number of episodes (the first ``n`` of the batch).
            rewards: Rewards of the last step, one per episode of the batch (or None).
            info: Batched info dict (arrays over the batch) of the last step.

        Returns:
            An (H, W, 3) uint8 frame in ``"rgb_array"`` mode; None in ``"human"`` mode.
        """
        n = int(n)
        if not 1 <= n <= self.task.n_envs:
            raise ValueError(f"n must be in [1, {self.task.n_envs}], got {n}")
        r = None if rewards is None else np.asarray(rewards, dtype=np.float64).reshape(-1)
        tiles = [self.draw_frame(i, None if r is None else float(r[i]), _pick(info, i)) for i in range(n)]
        pointer = self._pointer()
        hit = None if pointer is None else _tile_point(pointer, n, tiles[0].get_size())
        if hit is not None:  # the tile under the pointer again, with the pointer
            k, point = hit
            tiles[k] = self.draw_frame(k, None if r is None else float(r[k]), _pick(info, k), hover=point)
        return self._output(_tile(tiles))

    def close(self) -> None:
        """Close the window (if this renderer opened one) and forget the trails."""
        if self.render_mode == "human" and not self._closed:
            WINDOW.release(self._token)
        self._closed = True
        self._memory.clear()

    # --- drawing -------------------------------------------------------------------------------
    def draw_frame(
        self, env_index: int, reward: float | None = None, info: Mapping[str, Any] | None = None, hover: draw.Point | None = None
    ) -> pygame.Surface:
        """The picture of episode ``env_index`` as a pygame Surface.

        Args:
            env_index: Episode of the batch to draw.
            reward: Reward of the last step (shown in the panel).
            info: Info dict of the last step for this episode (scalars).
            hover: Mouse pointer [px of the frame], or None: on a plan view the aircraft under it is
                labelled (see :func:`draw_map`).
        """
        scene = self.scene(self.task, env_index)
        mem = self._remember(env_index, scene)
        if isinstance(scene, MapScene):
            plot = pygame.Surface(MAP_SIZE)
            view = self._map_view(scene, mem, (0, 0, *MAP_SIZE))
            draw_map(plot, view, scene, mem.trails, hover=hover)
        else:
            plot = pygame.Surface(SIDE_SIZE)
            draw_side(plot, scene, mem)
        w, h = plot.get_size()
        frame = pygame.Surface((w + PANEL_WIDTH, h))
        frame.blit(plot, (0, 0))
        self._draw_panel(frame, pygame.Rect(w, 0, PANEL_WIDTH, h), env_index, scene, reward, info)
        return frame

    def _check_index(self, env_index: int) -> None:
        if not 0 <= int(env_index) < self.task.n_envs:
            raise ValueError(f"env_index must be in [0, {self.task.n_envs}), got {env_index}")

    def _pointer(self) -> tuple[int, int] | None:
        """The mouse pointer over this renderer's window frame ("human" mode), else None."""
        return WINDOW.pointer(self._token) if self.render_mode == "human" and not self._closed else None

    def _output(self, frame: pygame.Surface) -> np.ndarray | None:
        if self.render_mode == "rgb_array":
            return surface_to_array(frame)
        self._closed = False
        WINDOW.show(self._token, frame, f"BlueSky-Gym - {self.title}", self.fps)
        return None

    def _remember(self, i: int, scene: Scene) -> _EpisodeMemory:
        """Update the trails of episode slot ``i``; start afresh when a new episode began."""
        sim = self.task.sim
        steps = int(self.task.stats.steps[i])
        flown = float(sim.distflown[i, 0])
        mem = self._memory.get(i)
        if mem is None or steps == 0 or steps < mem.steps or flown < mem.distflown - 1e-6:
            mem = _EpisodeMemory()
            self._memory[i] = mem
        elif steps == mem.steps:
            return mem  # same state drawn again: nothing new for the trails
        mem.steps, mem.distflown = steps, flown
        if mem.trail_step >= 0 and steps - mem.trail_step < self._dot_steps:
            if isinstance(scene, SideScene):  # the ownship's profile takes every step
                for ac in scene.aircraft:
                    if ac.role == "own":
                        mem.trails.setdefault(ac.key, deque(maxlen=SIDE_TRAIL)).append((ac.x_km, ac.alt))
            return mem
        mem.trail_step = steps
        if isinstance(scene, MapScene):
            for mac in scene.aircraft:
                mem.trails.setdefault(mac.key, deque(maxlen=MAP_TRAIL)).append((mac.lat, mac.lon))
        else:
            for ac in scene.aircraft:
                n = SIDE_TRAIL if ac.role == "own" else MAP_TRAIL
                mem.trails.setdefault(ac.key, deque(maxlen=n)).append((ac.x_km, ac.alt))
            if scene.inset is not None:
                for mac in scene.inset.aircraft:
                    mem.trails.setdefault(-1 - mac.key, deque(maxlen=MAP_TRAIL)).append((mac.lat, mac.lon))
        return mem

    def _map_view(self, scene: MapScene, mem: _EpisodeMemory, rect: tuple[int, int, int, int]) -> MapView:
        """The episode's fixed view; it zooms out (then pans) to keep the followed aircraft in sight."""
        if mem.center is None:
            mem.center = (scene.center_lat, scene.center_lon)
            mem.half_width = scene.half_width_nm
        view = MapView.fit(mem.center[0], mem.center[1], mem.half_width, rect)
        follow = next((a for a in scene.aircraft if a.key == scene.follow), None) if scene.follow is not None else None
        if follow is not None:
            east, north = view.to_nm(follow.lat, follow.lon)
            hw, hh = view.half_extent_nm()
            if abs(float(east)) > FOLLOW_MARGIN * hw or abs(float(north)) > FOLLOW_MARGIN * hh:
                need = max(abs(float(east)) / hw, abs(float(north)) / hh) * mem.half_width / ZOOM_OUT_MARGIN
                if need <= MAX_ZOOM_OUT * scene.half_width_nm:
                    mem.half_width = need
                else:  # far away: keep the scale, centre on the aircraft
                    mem.center = (follow.lat, follow.lon)
                view = MapView.fit(mem.center[0], mem.center[1], mem.half_width, rect)
        return view

    def _draw_panel(
        self, frame: pygame.Surface, rect: pygame.Rect, i: int, scene: Scene, reward: float | None, info: Mapping[str, Any] | None
    ) -> None:
        task = self.task
        st = task.stats
        pygame.draw.rect(frame, pal.PANEL, rect)
        pygame.draw.line(frame, pal.PANEL_EDGE, rect.topleft, rect.bottomleft)
        x0, x1 = rect.left + 12, rect.right - 12
        y = rect.top + 10
        draw.text(frame, self.title, (x0, y), 22, pal.TEXT)
        y += 20
        if task.n_envs > 1:
            draw.text(frame, f"episode slot {i} of {task.n_envs}", (x0, y), 16, pal.TEXT_DIM)
            y += 15
        y += 6
        steps = int(st.steps[i])
        t = steps * task.dt * task.action_frequency
        in_los = int(np.count_nonzero(task.ownship_separation()[1][i]))
        min_sep = float(st.min_separation[i])
        lines: list[tuple[str, str]] = [
            ("time", _clock(t)),
            ("step", f"{steps} / {task.time_limit}"),
            ("reward", "-" if reward is None else f"{reward:+.3f}"),
            ("return", f"{float(st.total_reward[i]):+.2f}"),
            ("fuel", _fuel(float(task.sim.fuelburn[i, 0]), float(task.sim.fuelflow[i, 0]))),
        ]
        has_traffic = task.sim.max_aircraft > 1
        if has_traffic:
            lines += [
                ("LoS now", str(in_los)),
                ("LoS events", str(int(st.los_count[i]))),
                ("min sep", "-" if not math.isfinite(min_sep) else f"{min_sep:.1f} NM"),
            ]
        y = _panel_lines(frame, lines, x0, x1, y, los_row=1 if in_los else 0)
        if scene.panel:
            y = _separator(frame, rect, y)
            y = _panel_lines(frame, scene.panel, x0, x1, y)
        shown = [info_line(k, info[k]) for k in getattr(task, "info_keys", ()) if info and k in info and k != "total_reward"]
        if shown:
            y = _separator(frame, rect, y)
            y = _panel_lines(frame, shown, x0, x1, y)
        if scene.legend:
            ly = rect.bottom - 10 - 16 * len(scene.legend)
            if ly > y + 8:
                _separator(frame, rect, ly - 10)
                for color, label in scene.legend:
                    draw.swatch(frame, color, pygame.Rect(x0, ly + 3, 10, 10))
                    draw.text(frame, label, (x0 + 16, ly), 16, pal.TEXT_DIM)
                    ly += 16


def _clock(seconds: float) -> str:
    """Episode time as m:ss, or h:mm:ss from one hour on."""
    s = int(seconds)
    if s >= 3600:
        return f"{s // 3600}:{s % 3600 // 60:02d}:{s % 60:02d}"
    return f"{s // 60}:{s % 60:02d}"


def _fuel(burned: float, flow: float) -> str:
    """The ownship's fuel burned so far [kg] and its fuel flow now [kg/s], as the panel shows them."""
    if not (math.isfinite(burned) and math.isfinite(flow)):
        return "-"
    return f"{burned:.0f} kg, {flow:.2f} kg/s"


def _panel_lines(frame: pygame.Surface, lines: list[tuple[str, str]], x0: int, x1: int, y: int, los_row: int = 0) -> int:
    for label, value in lines:
        color = pal.LOS if los_row and label == "LoS now" else pal.TEXT
        draw.text(frame, label, (x0, y), 18, pal.TEXT_DIM)
        draw.text(frame, value, (x1, y), 18, color, anchor="topright")
        y += 18
    return y


def _separator(frame: pygame.Surface, rect: pygame.Rect, y: int) -> int:
    pygame.draw.line(frame, pal.PANEL_EDGE, (rect.left + 12, y + 4), (rect.right - 12, y + 4))
    return y + 10


#: How the panel shows the tasks' info values: label and formatter (with the unit; values are SI inside).
INFO_DISPLAY: dict[str, tuple[str, Any]] = {
    "average_drift": ("mean |drift|", lambda v: f"{math.degrees(float(v)):.1f} deg"),
    "final_altitude": ("final altitude", lambda v: f"{float(v):.0f} m ({float(v) / FT:.0f} ft)"),
    "total_intrusions": ("intrusions", lambda v: str(int(v))),
    "waypoints_completed": ("waypoints done", lambda v: str(int(v))),
    "faf_reach": ("reached FAF", lambda v: "yes" if v else "no"),
    "waypoint_reached": ("reached goal", lambda v: "yes" if v else "no"),
    "crashed": ("restricted area", lambda v: "entered" if v else "clear"),
    "average_route_deviation_nm": ("mean route dev.", lambda v: f"{float(v):.2f} NM"),
    "traffic": ("traffic now", lambda v: str(int(v))),
    "spawned": ("entered", lambda v: str(int(v))),
    "spawns_dropped": ("entries dropped", lambda v: str(int(v))),
}


def info_line(key: str, value: Any) -> tuple[str, str]:
    """Label and value (with its unit) of one info entry on the panel; unknown keys are shown as they are."""
    label, fmt = INFO_DISPLAY.get(key, (key, _format))
    if isinstance(value, (float, np.floating)) and math.isnan(float(value)):
        return label, "-"
    return label, fmt(value)


def _format(v: Any) -> str:
    if isinstance(v, (bool, np.bool_)):
        return "yes" if v else "no"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        f = float(v)
        if math.isnan(f):
            return "-"
        return str(int(f)) if f.is_integer() and abs(f) < 1e6 else f"{f:.3f}"
    return str(v)


def _pick(info: Mapping[str, Any] | None, i: int) -> dict[str, Any]:
    if not info:
        return {}
    out: dict[str, Any] = {}
    for k, v in info.items():
        if isinstance(v, np.ndarray) and v.ndim == 1 and i < v.shape[0]:
            out[k] = v[i].item()
    return out


def surface_to_array(surf: pygame.Surface) -> np.ndarray:
    """An (H, W, 3) uint8 copy of a Surface's pixels."""
    w, h = surf.get_size()
    return np.frombuffer(pygame.image.tobytes(surf, "RGB"), dtype=np.uint8).reshape(h, w, 3).copy()


GRID_GAP = 4  # pixels between the tiles of a grid (before scaling)


def _grid_layout(n: int, tile: tuple[int, int]) -> tuple[int, tuple[int, int], tuple[int, int]]:
    """Columns, unscaled size and final size (even, within :data:`GRID_MAX`) of a grid of ``n`` tiles of size ``tile``."""
    cols = math.ceil(math.sqrt(n))
    rows = math.ceil(n / cols)
    w, h = tile
    bw, bh = cols * w + (cols - 1) * GRID_GAP, rows * h + (rows - 1) * GRID_GAP
    s = min(1.0, GRID_MAX[0] / bw, GRID_MAX[1] / bh)
    return cols, (bw, bh), (max(2, int(bw * s) // 2 * 2), max(2, int(bh * s) // 2 * 2))


def _tile(tiles: list[pygame.Surface]) -> pygame.Surface:
    """Tiles in a near-square grid, scaled down to fit :data:`GRID_MAX` (even dimensions)."""
    w, h = tiles[0].get_size()
    cols, full, size = _grid_layout(len(tiles), (w, h))
    big = pygame.Surface(full)
    big.fill(pal.PANEL_EDGE)
    for k, t in enumerate(tiles):
        big.blit(t, ((k % cols) * (w + GRID_GAP), (k // cols) * (h + GRID_GAP)))
    if size != full:
        big = pygame.transform.smoothscale(big, size)
    return big


def _tile_point(point: tuple[int, int], n: int, tile: tuple[int, int]) -> tuple[int, draw.Point] | None:
    """Which tile of a grid of ``n`` (see :func:`_tile`) a pixel of the grid falls in, and where in it.

    Returns:
        (tile index, pixel position in that tile), or None for a point in a gap or outside the tiles.
    """
    cols, full, size = _grid_layout(n, tile)
    x, y = point[0] * full[0] / size[0], point[1] * full[1] / size[1]
    w, h = tile
    col, row = int(x // (w + GRID_GAP)), int(y // (h + GRID_GAP))
    tx, ty = x - col * (w + GRID_GAP), y - row * (h + GRID_GAP)
    k = row * cols + col
    if not (0 <= col < cols and 0 <= tx < w and 0 <= ty < h and 0 <= k < n):
        return None
    return k, (tx, ty)


# --- plan view ------------------------------------------------------------------------------------
def draw_map(
    surf: pygame.Surface,
    view: MapView,
    scene: MapScene,
    trails: Mapping[int, Any],
    inset: bool = False,
    trail_offset: int = 0,
    hover: draw.Point | None = None,
) -> None:
    """Draw a plan view filling ``surf``.

    Args:
        surf: Target surface (the view's rectangle is in its pixels).
        view: The projection.
        scene: What to draw.
        trails: Per-aircraft (lat, lon) histories, keyed by ``trail_offset`` of the aircraft key.
        inset: Small variant (no labels, scale bar only).
        trail_offset: Trails are looked up as ``key`` (0) or ``-1 - key`` (-1).
        hover: Mouse pointer [px of ``surf``], or None; the aircraft whose symbol is nearest to it,
            within :data:`HOVER_PX`, gets its full label (callsign, flight level, ground speed) on
            top, whether or not the scene labels it.
    """
    surf.fill(pal.BACKGROUND)
    _graticule(surf, view)
    for area in scene.areas:
        x, y = view.to_px(area.lat, area.lon)
        pts = list(zip(x.tolist(), y.tolist()))
        if area.kind == "sector":
            draw.polygon(surf, pal.AIRSPACE_EDGE, pts, fill=pal.AIRSPACE_FILL, width=2)
        else:
            fill = pal.mix(pal.OBSTACLE_FILL, pal.LOS, 0.45) if area.violated else pal.OBSTACLE_FILL
            draw.polygon(surf, pal.LOS if area.violated else pal.OBSTACLE_EDGE, pts, fill=fill, width=2 if area.violated else 1)
    for area in scene.areas:
        if area.label and not inset:
            x, y = view.to_px(area.lat, area.lon)
            color = pal.OBSTACLE_EDGE if area.kind == "obstacle" else pal.AIRSPACE_EDGE
            draw.text_with_halo(surf, area.label, (float(np.mean(x)), float(np.mean(y))), 15, color, "center")
    for ln in scene.lines:
        x, y = view.to_px(ln.lat, ln.lon)
        draw.polyline(surf, ln.color, list(zip(x.tolist(), y.tolist())), dashed=ln.dashed, width=ln.width)
    for rw in scene.runways:
        _runway(surf, view, rw, inset)
    for fx in scene.fixes:
        p = view.point(fx.lat, fx.lon)
        color = pal.GOAL_DONE if fx.done else pal.GOAL
        if fx.capture_nm:
            draw.dashed_circle(surf, color, p, fx.capture_nm * view.px_per_nm)
        if fx.kind == "faf":
            draw.diamond(surf, color, p, 7, filled=not fx.done)
        elif fx.kind == "waypoint":
            draw.triangle(surf, color, p, 6, filled=not fx.done)
        if fx.label and not inset:
            draw.text_with_halo(surf, fx.label, (p[0] + 9, p[1] - 4), 16, color, "midleft")
    # Symbols shrink on small-scale maps so that they stay inside their protected zones.
    size = 6.0 if inset else min(9.0, max(6.0, 2.5 * view.px_per_nm))
    for ac in scene.aircraft:  # history dots below everything that moves
        trail = trails.get(ac.key if trail_offset == 0 else -1 - ac.key)
        if trail:
            pts = list(trail)
            lat = np.array([p[0] for p in pts])
            lon = np.array([p[1] for p in pts])
            xs, ys = view.to_px(lat, lon)
            base = _aircraft_color(ac.role, ac.los, ac.dim)
            for k, (x, y) in enumerate(zip(xs.tolist(), ys.tolist())):
                c = pal.mix(pal.BACKGROUND, base, 0.25 + 0.6 * (k + 1) / len(pts))
                draw.circle(surf, c, (x, y), 1.6, fill=c)
    own = next((a for a in scene.aircraft if a.role == "own"), None)
    hovered = None if inset or hover is None else _under_pointer(view, scene, hover)
    for ac in sorted(scene.aircraft, key=lambda a: (a.role == "own", a.los)):
        p = view.point(ac.lat, ac.lon)
        color = _aircraft_color(ac.role, ac.los, ac.dim)
        labelled = (
            not inset
            and scene.labels
            and (ac.role == "own" or ac.los or own is None or scene.label_range_nm is None or _nm_apart(own, ac) <= scene.label_range_nm)
        )
        if ac.ring_nm:
            ring = pal.LOS if ac.los else pal.mix(pal.BACKGROUND, color, 0.55 if ac.role == "own" else 0.35)
            draw.circle(surf, ring, p, ac.ring_nm * view.px_per_nm, width=2 if ac.los else 1)
        vx, vy = math.sin(math.radians(ac.trk)), -math.cos(math.radians(ac.trk))
        vec = ac.gs * SPEED_VECTOR_S / 1852.0 * view.px_per_nm
        draw.line(surf, color, p, (p[0] + vx * vec, p[1] + vy * vec))
        draw.plan_aircraft(surf, color, p, ac.hdg, size)
        if labelled and ac is not hovered:
            _aircraft_label(surf, ac, p, color, details=ac.role == "own" or scene.traffic_details)
    if hovered is not None:  # last, so that no other symbol covers it
        _aircraft_label(surf, hovered, view.point(hovered.lat, hovered.lon), _aircraft_color(hovered.role, hovered.los, hovered.dim), details=True)
    _scale_bar(surf, view, small=inset)
    if not inset:
        _north_arrow(surf, (surf.get_width() - 26, 30))
    pygame.draw.rect(surf, pal.PANEL_EDGE, surf.get_rect(), 1)


def _aircraft_label(surf: pygame.Surface, ac: MapAircraft, p: draw.Point, color: pal.Color, details: bool) -> None:
    """The label beside an aircraft symbol at ``p``: its callsign and, with ``details``, flight level and ground speed."""
    draw.text_with_halo(surf, ac.callsign, (p[0] + 10, p[1] + 6), 15, color)
    if details:
        fl = max(ac.alt, 0.0) / FT / 100.0
        draw.text_with_halo(surf, f"FL{fl:03.0f} {ac.gs * MPS2KT:.0f}kt", (p[0] + 10, p[1] + 17), 14, pal.mix(color, pal.TEXT_DIM, 0.4))


def _under_pointer(view: MapView, scene: MapScene, hover: draw.Point) -> MapAircraft | None:
    """The aircraft whose symbol centre is nearest to ``hover`` [px], if within :data:`HOVER_PX`."""
    best, best_d = None, HOVER_PX
    for ac in scene.aircraft:
        x, y = view.point(ac.lat, ac.lon)
        d = math.hypot(x - hover[0], y - hover[1])
        if d <= best_d:
            best, best_d = ac, d
    return best


def _nm_apart(a: Any, b: Any) -> float:
    """Flat-earth distance [NM] between two plan-view aircraft."""
    east = (b.lon - a.lon) * 60.0 * math.cos(math.radians(0.5 * (a.lat + b.lat)))
    return math.hypot(east, (b.lat - a.lat) * 60.0)


def _aircraft_color(role: str, los: bool, dim: bool) -> pal.Color:
    """Symbol colour: the ownship stays green (its ring turns red), traffic in a LoS turns red."""
    if role == "own":
        return pal.OWNSHIP
    if los:
        return pal.LOS
    return pal.INTRUDER_FAR if dim else pal.INTRUDER


def _graticule(surf: pygame.Surface, view: MapView) -> None:
    """Faint square grid aligned with north, one line per scale-bar step."""
    hw, hh = view.half_extent_nm()
    step = scale_bar_nm(hw * 0.5)
    x0, y0, w, h = view.rect
    cx, cy = x0 + w / 2.0, y0 + h / 2.0
    k = math.ceil(max(hw, hh) / step) + 1
    for j in range(-k, k + 1):
        x = cx + j * step * view.px_per_nm
        y = cy + j * step * view.px_per_nm
        pygame.draw.line(surf, pal.GRID, (round(x), y0), (round(x), y0 + h))
        pygame.draw.line(surf, pal.GRID, (x0, round(y)), (x0 + w, round(y)))


def _runway(surf: pygame.Surface, view: MapView, rw: Any, inset: bool) -> None:
    h = math.radians(rw.hdg)
    ux, uy = math.sin(h), -math.cos(h)
    a = view.point(rw.lat, rw.lon)
    length = max(rw.length_km / NM2KM * view.px_per_nm, 6.0)
    b = (a[0] + ux * length, a[1] + uy * length)
    ext = 15.0 * view.px_per_nm  # extended centre line, 15 NM before the threshold
    draw.dashed_line(surf, pal.mix(pal.BACKGROUND, pal.RUNWAY, 0.45), (a[0] - ux * ext, a[1] - uy * ext), a)
    draw.line(surf, pal.RUNWAY, a, b, width=4)
    if not inset and rw.label:
        draw.text_with_halo(surf, rw.label, (b[0] + 8, b[1]), 16, pal.RUNWAY, "midleft")


def _scale_bar(surf: pygame.Surface, view: MapView, small: bool = False) -> None:
    """A scale bar of a round length in NM (with its km) in the lower-left corner."""
    w, h = surf.get_size()
    nm = scale_bar_nm(0.28 * w / view.px_per_nm)
    length = nm * view.px_per_nm
    x0, y0 = 14, h - (14 if small else 22)
    color = pal.TEXT
    pygame.draw.line(surf, color, (x0, y0), (round(x0 + length), y0), 2)
    for x in (x0, x0 + length / 2.0, x0 + length):
        tick = 6 if x in (x0, x0 + length) else 4
        pygame.draw.line(surf, color, (round(x), y0 - tick), (round(x), y0))
    label = f"{nm:g} NM" if small else f"{nm:g} NM ({nm * NM2KM:.0f} km)"
    draw.text_with_halo(surf, label, (x0, y0 - 8), 14 if small else 16, color, "bottomleft")


def _north_arrow(surf: pygame.Surface, center: tuple[float, float]) -> None:
    cx, cy = center
    draw.polygon(surf, pal.TEXT, [(cx, cy - 14), (cx + 6, cy + 6), (cx, cy + 2), (cx - 6, cy + 6)], fill=pal.TEXT)
    draw.text_with_halo(surf, "N", (cx, cy - 16), 18, pal.TEXT, "midbottom")


# --- side view ------------------------------------------------------------------------------------
def draw_side(surf: pygame.Surface, scene: SideScene, mem: _EpisodeMemory) -> None:
    """Draw a vertical profile filling ``surf``; ``mem`` holds trails and the altitude scale."""
    w, h = surf.get_size()
    left, right, top, ground = 58, 14, 28, 40
    rect = (left, top, w - left - right, h - top - ground)
    alts = [ac.alt for ac in scene.aircraft] + ([scene.target_alt] if scene.target_alt is not None else [])
    need = max([scene.alt_max, *[a * 1.15 for a in alts]])
    mem.alt_max = max(mem.alt_max, math.ceil(need / 1000.0) * 1000.0)
    view = SideView(scene.x_max_km, scene.x_min_km, mem.alt_max, rect)
    draw.vertical_gradient(surf, pygame.Rect(0, 0, w, h - ground), pal.SKY_TOP, pal.SKY_BOTTOM)
    gy = round(float(view.y(0.0)))
    pygame.draw.rect(surf, pal.GROUND, pygame.Rect(0, gy, w, h - gy))
    pygame.draw.line(surf, pal.GROUND_EDGE, (0, gy), (w, gy), 2)
    # axes
    astep = nice_step(mem.alt_max, 5)
    a = astep
    while a < mem.alt_max + 1e-6:
        y = round(float(view.y(a)))
        pygame.draw.line(surf, pal.GRID, (left, y), (w - right, y))
        draw.text(surf, f"{a:.0f}", (left - 6, y), 15, pal.TEXT_DIM, "midright")
        a += astep
    draw.text(surf, "alt [m]", (6, 4), 15, pal.TEXT_DIM)
    xstep = nice_step(scene.x_max_km - scene.x_min_km, 6)
    d = math.floor(scene.x_max_km / xstep) * xstep
    while d >= scene.x_min_km:
        x = round(float(view.x(d)))
        if left <= x <= w - right:
            pygame.draw.line(surf, pal.GRID, (x, top), (x, gy))
            pygame.draw.line(surf, pal.GROUND_EDGE, (x, gy), (x, gy + 5))
            draw.text(surf, f"{d:.0f}", (x, gy + 7), 15, pal.TEXT_DIM, "midtop")
        d -= xstep
    draw.text(surf, "distance to runway [km]", (w - right, h - 4), 15, pal.TEXT_DIM, "bottomright")
    # runway and target altitude
    if scene.runway_km is not None:
        x0, x1 = float(view.x(0.0)), float(view.x(-scene.runway_km))
        pygame.draw.line(surf, pal.RUNWAY, (round(x0), gy - 1), (round(max(x1, x0 + 4)), gy - 1), 5)
        draw.text_with_halo(surf, "RWY", (x0, gy - 6), 16, pal.RUNWAY, "midbottom")
    if scene.target_alt is not None:
        ty = float(view.y(scene.target_alt))
        draw.dashed_line(surf, pal.GOAL, (left, ty), (w - right, ty), width=2)
        draw.text_with_halo(surf, f"target {scene.target_alt:.0f} m", (left + 6, ty - 3), 16, pal.GOAL, "bottomleft")
    # trails
    for ac in scene.aircraft:
        trail = mem.trails.get(ac.key)
        if not trail:
            continue
        xs = view.x([p[0] for p in trail]).tolist()
        ys = view.y([p[1] for p in trail]).tolist()
        base = _aircraft_color(ac.role, ac.los, ac.dim)
        if ac.role == "own":
            draw.polyline(surf, pal.mix(pal.SKY_BOTTOM, base, 0.6), [*zip(xs, ys), view.point(ac.x_km, ac.alt)], width=2)
        else:
            for k, (x, y) in enumerate(zip(xs, ys)):
                c = pal.mix(pal.SKY_BOTTOM, base, 0.25 + 0.5 * (k + 1) / len(xs))
                draw.circle(surf, c, (x, y), 1.6, fill=c)
    # separation boxes and aircraft
    for ac in sorted(scene.aircraft, key=lambda a: (a.role == "own", a.los)):
        p = view.point(ac.x_km, ac.alt)
        color = _aircraft_color(ac.role, ac.los, ac.dim)
        if ac.box is not None:
            bw, bh = ac.box[0] * view.px_per_km, ac.box[1] * view.px_per_m
            corners = [(p[0] - bw, p[1] - bh), (p[0] + bw, p[1] - bh), (p[0] + bw, p[1] + bh), (p[0] - bw, p[1] + bh)]
            box_color = pal.LOS if ac.los else pal.mix(pal.SKY_BOTTOM, color, 0.6)
            if ac.dim and not ac.los:
                draw.polyline(surf, box_color, [*corners, corners[0]], dashed=True)
            else:
                draw.polyline(surf, box_color, [*corners, corners[0]], width=2 if ac.los else 1)
        direction = 1 if ac.vx >= 0 else -1
        slope = (ac.vs * view.px_per_m) / max(abs(ac.vx) * view.px_per_km / 1000.0, 1e-6)
        pitch = max(-40.0, min(40.0, math.degrees(math.atan(slope))))
        draw.side_aircraft(surf, color, p, direction, pitch, 14.0 if ac.role == "own" else 11.0)
        label = ac.callsign + (f"  {ac.note}" if ac.note else "")
        draw.text_with_halo(surf, label, (p[0], p[1] - 12), 15, color, "midbottom")
    if scene.inset is not None:  # lower left: the descent profile rarely passes there
        size = INSET_SIZE
        inset = pygame.Surface((size, size))
        iv = MapView.fit(scene.inset.center_lat, scene.inset.center_lon, scene.inset.half_width_nm, (0, 0, size, size))
        draw_map(inset, iv, scene.inset, mem.trails, inset=True, trail_offset=-1)
        draw.text_with_halo(inset, "plan view", (size - 6, size - 4), 14, pal.TEXT_DIM, "bottomright")
        _north_arrow(inset, (size - 14, 34))
        inset.set_alpha(225)
        surf.blit(inset, (left + 6, gy - size - 6))
