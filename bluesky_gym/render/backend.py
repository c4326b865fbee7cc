"""Lazy access to pygame and the one on-screen window of a process.

pygame is an optional dependency (the ``render`` extra); it is imported only when a renderer is
created. The display of a pygame process is a single window, shared by every renderer in
``"human"`` mode: it is opened by the first renderer that shows a frame and closed when the last
renderer that used it is closed (or when the user closes it). The window also tracks the mouse
pointer, so that the renderer can label the aircraft under it.
"""

from __future__ import annotations

import os
from types import ModuleType
from typing import Any

from bluesky_gym.core.extras import missing_extra


def import_pygame() -> ModuleType:
    """Import pygame and initialise its font module.

    Returns:
        The ``pygame`` module.

    Raises:
        ImportError: If pygame is not installed, with the command that installs it.
    """
    os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")
    try:
        import pygame
    except ImportError as exc:
        raise missing_extra("rendering needs pygame", "render") from exc
    if not pygame.font.get_init():
        pygame.font.init()
    return pygame


class _Window:
    """The process-wide pygame window (pygame has one display per process)."""

    def __init__(self) -> None:
        self.users: set[int] = set()
        self.surface: Any = None
        self.clock: Any = None
        self.closed_for: set[int] = set()  # renderers whose window the user closed
        self.shown_by: int | None = None  # renderer whose frame the window shows
        self.mouse: tuple[int, int] | None = None  # pointer position [px], None when outside the window

    def show(self, owner: int, frame: Any, caption: str, fps: float) -> bool:
        """Draw ``frame`` (a pygame Surface) in the window, pump events and keep the frame rate.

        Args:
            owner: Identity of the renderer showing the frame.
            frame: The Surface to show; the window takes its size.
            caption: Window title.
            fps: Frame rate limit (0 for none).

        Returns:
            False if the user closed the window of this renderer (now or earlier), True otherwise.
        """
        pg = import_pygame()
        if owner in self.closed_for:
            return False
        self.users.add(owner)
        if not pg.display.get_init():
            pg.display.init()
        size = frame.get_size()
        if self.surface is None or pg.display.get_surface() is None or pg.display.get_surface().get_size() != size:
            self.surface = pg.display.set_mode(size)
            self.clock = pg.time.Clock()
        pg.display.set_caption(caption)
        for event in pg.event.get():
            if event.type == pg.QUIT:
                self._close_display(pg)
                self.closed_for |= self.users
                self.users.clear()
                return False
            self._track(pg, event)
        self.shown_by = owner
        self.surface.blit(frame, (0, 0))
        pg.display.flip()
        if fps > 0:
            self.clock.tick(fps)
        return True

    def pointer(self, owner: int) -> tuple[int, int] | None:
        """Where the mouse pointer is over the frame ``owner`` showed last.

        Reads the pending pointer events (leaving every other event for :meth:`show`).

        Args:
            owner: Identity of the renderer asking.

        Returns:
            The pointer's pixel position in that frame, or None when the pointer is outside the
            window, or the window is closed or shows another renderer's frame.
        """
        if self.surface is None or self.shown_by != owner or owner in self.closed_for:
            return None
        pg = import_pygame()
        if not pg.display.get_init():
            return None
        for event in pg.event.get((pg.MOUSEMOTION, pg.WINDOWLEAVE)):
            self._track(pg, event)
        if pg.mouse.get_focused():  # the pointer is over the window: its current position
            x, y = pg.mouse.get_pos()
            self.mouse = (int(x), int(y))
        return self.mouse

    def _track(self, pg: ModuleType, event: Any) -> None:
        """Follow the pointer: motion events give its position, leaving the window clears it."""
        if event.type == pg.MOUSEMOTION:
            self.mouse = (int(event.pos[0]), int(event.pos[1]))
        elif event.type == pg.WINDOWLEAVE:
            self.mouse = None

    def release(self, owner: int) -> None:
        """Forget ``owner``; close the window when no renderer uses it any more."""
        self.users.discard(owner)
        self.closed_for.discard(owner)
        if not self.users:
            self._close_display(import_pygame())

    def _close_display(self, pg: ModuleType) -> None:
        if pg.display.get_init():
            pg.display.quit()
        self.surface = None
        self.clock = None
        self.shown_by = None
        self.mouse = None


WINDOW = _Window()
