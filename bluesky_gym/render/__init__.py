"""Pictures of the environments: ``render_mode="rgb_array"`` frames, a ``"human"`` window, videos.

Horizontal environments are drawn as a north-up map (north up, east right, with a scale bar);
vertical ones (Descent, VerticalCR) as a side view of altitude against distance to the runway.
Aircraft point along their heading and leave short trails; protected zones turn red during a loss
of separation; a text panel shows time, step, reward, intrusions, the ownship's fuel and key numbers.

pygame (and, for videos, imageio/pillow) come with the ``render`` extra:
``pip install -e ".[render]"``. Nothing here imports pygame until a renderer is created.

Example::

    env = gym.make("DescentEnv-v0", render_mode="rgb_array")
    env.reset(seed=0)
    frame = env.render()  # (H, W, 3) uint8
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from bluesky_gym.render.backend import import_pygame
from bluesky_gym.render.video import VideoWriter, write_video

if TYPE_CHECKING:
    from bluesky_gym.render.renderer import Renderer
    from bluesky_gym.render.scenes import SceneBuilder

__all__ = ["VideoWriter", "import_pygame", "make_renderer", "write_video"]


def make_renderer(task: Any, render_mode: str, fps: float = 30.0, scene: SceneBuilder | None = None, title: str | None = None) -> Renderer:
    """The renderer of a batched task.

    Args:
        task: The batched task (a :class:`bluesky_gym.tasks.base.Task`); it is only read.
        render_mode: ``"rgb_array"`` or ``"human"``.
        fps: Frame-rate limit of the window in ``"human"`` mode.
        scene: What to draw, a scene builder ``(task, env_index) -> Scene`` (the environment
            table's scene of the task's id; default: every aircraft on a plan view around the
            ownship, :func:`~bluesky_gym.render.scenes.generic.generic_scene`).
        title: The id shown in the panel and the window title (default: the task's ``env_id``).

    Returns:
        An object with ``render(env_index, reward=..., info=...)``, ``render_grid(n, rewards=...,
        info=...)`` and ``close()``.

    Raises:
        ImportError: If pygame is not installed.
        ValueError: For an unknown render mode.
    """
    import_pygame()
    from bluesky_gym.render.renderer import Renderer

    if scene is None:
        from bluesky_gym.render.scenes.generic import generic_scene

        scene = generic_scene
    return Renderer(task, render_mode, fps, scene=scene, title=title)
