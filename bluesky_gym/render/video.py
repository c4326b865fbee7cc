"""Writing frames to an animated GIF (pillow) or an MP4 video (imageio with imageio-ffmpeg)."""

from __future__ import annotations

import importlib.util
from collections.abc import Iterable
from pathlib import Path
from types import TracebackType
from typing import Any

import numpy as np

from bluesky_gym.core.extras import missing_extra

FORMATS = (".gif", ".mp4")


def _check_frame(frame: Any) -> np.ndarray:
    a = np.asarray(frame)
    if a.ndim != 3 or a.shape[2] != 3 or a.dtype != np.uint8:
        raise ValueError(f"a frame must be an (H, W, 3) uint8 array, got shape {a.shape} and dtype {a.dtype}")
    return a


def _gif_palette(first: np.ndarray, colors: int) -> Any:
    """A palette image for a GIF: the named colours exactly, the rest chosen from the first frame.

    The named colours of :mod:`bluesky_gym.render.palette` and their blends into the background
    (trails, rings) keep their exact values, so that an aircraft is the same colour in every
    frame, whatever else the first frame shows.
    """
    from PIL import Image

    from bluesky_gym.render import palette as pal

    named = [v for k, v in vars(pal).items() if k.isupper() and isinstance(v, tuple) and len(v) == 3]
    fixed = list(dict.fromkeys([*named, *(pal.mix(bg, c, t) for c in named for bg, t in ((pal.BACKGROUND, 0.35), (pal.BACKGROUND, 0.6)))]))
    fixed = fixed[:colors]
    free = colors - len(fixed)
    extra: list[int] = []
    if free > 0:
        q = Image.fromarray(first).quantize(colors=free, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)
        extra = (q.getpalette() or [])[: 3 * free]
    flat = [v for c in fixed for v in c] + extra
    flat += flat[:3] * (256 - len(flat) // 3)  # pad with a used colour
    img = Image.new("P", (1, 1))
    img.putpalette(flat[: 3 * 256])
    return img


class VideoWriter:
    """Streams RGB frames to ``path``; the format follows the suffix (``.gif`` or ``.mp4``).

    GIF frames share one palette of ``colors`` colours, chosen from the first frame and the
    colours of :mod:`bluesky_gym.render.palette` (so that colours appearing later, such as the
    red of a loss of separation, are exact); a shared palette lets the encoder store only what
    changed between frames. Frames are reduced to it as they arrive (so long videos stay small
    in memory) and written on :meth:`close`. MP4 frames are encoded as they arrive (H.264).

    Args:
        path: Output file; its folder is created if needed.
        fps: Frames per second.
        scale: Resize factor applied to every frame (e.g. 0.5 halves width and height).
        colors: Palette size of GIF frames (2..256).

    Raises:
        ValueError: For an unsupported suffix.
        ImportError: If the encoder's package is missing (pillow for GIF, imageio-ffmpeg for MP4).
    """

    def __init__(self, path: str | Path, fps: float = 15.0, scale: float = 1.0, colors: int = 192) -> None:
        self.path = Path(path)
        self.suffix = self.path.suffix.lower()
        if self.suffix not in FORMATS:
            raise ValueError(f"unsupported video format {self.path.suffix!r}; use one of {', '.join(FORMATS)}")
        if not fps > 0:
            raise ValueError(f"fps must be > 0, got {fps}")
        if not 0 < scale <= 4:
            raise ValueError(f"scale must be in (0, 4], got {scale}")
        if not 2 <= colors <= 256:
            raise ValueError(f"colors must be in [2, 256], got {colors}")
        self.fps = float(fps)
        self.scale = float(scale)
        self.colors = int(colors)
        self.n_frames = 0
        self._gif: list[Any] = []
        self._palette: Any = None
        self._mp4: Any = None
        self._size: tuple[int, int] | None = None
        if self.suffix == ".gif":
            if importlib.util.find_spec("PIL") is None:
                raise missing_extra("writing GIF files needs pillow", "render")
        elif importlib.util.find_spec("imageio") is None or importlib.util.find_spec("imageio_ffmpeg") is None:
            raise missing_extra("writing MP4 files needs imageio and imageio-ffmpeg (an ffmpeg binary; or write a .gif instead)", "render")
        self.path.parent.mkdir(parents=True, exist_ok=True)

    def append(self, frame: Any) -> None:
        """Add one (H, W, 3) uint8 frame; every frame must have the size of the first."""
        from PIL import Image

        a = _check_frame(frame)
        img = Image.fromarray(a)
        if self.scale != 1.0:
            size = (max(2, round(img.width * self.scale) // 2 * 2), max(2, round(img.height * self.scale) // 2 * 2))
            img = img.resize(size, Image.Resampling.BOX)
        elif self.suffix == ".mp4" and (img.width % 2 or img.height % 2):
            img = img.crop((0, 0, img.width // 2 * 2, img.height // 2 * 2))
        if self._size is None:
            self._size = img.size
        elif img.size != self._size:
            raise ValueError(f"frame size {img.size} differs from the first frame's {self._size}")
        if self.suffix == ".gif":
            if self._palette is None:
                self._palette = _gif_palette(np.asarray(img), self.colors)
            self._gif.append(img.quantize(palette=self._palette, dither=Image.Dither.NONE))
        else:
            if self._mp4 is None:
                import imageio.v2 as imageio

                self._mp4 = imageio.get_writer(self.path, fps=self.fps, codec="libx264", quality=7, macro_block_size=2, pixelformat="yuv420p")
            self._mp4.append_data(np.asarray(img))
        self.n_frames += 1

    def close(self) -> Path:
        """Finish the file and return its path.

        Raises:
            ValueError: If no frame was added.
        """
        if self.n_frames == 0:
            raise ValueError(f"no frames to write to {self.path}")
        if self.suffix == ".gif" and self._gif:
            first, rest = self._gif[0], self._gif[1:]
            duration = round(1000.0 / self.fps)
            first.save(self.path, save_all=True, append_images=rest, duration=duration, loop=0, optimize=True, disposal=1)
            self._gif = []
        if self._mp4 is not None:
            self._mp4.close()
            self._mp4 = None
        return self.path

    def __enter__(self) -> VideoWriter:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None) -> None:
        if exc_type is None:
            self.close()
        elif self._mp4 is not None:
            self._mp4.close()
            self._mp4 = None


def write_video(path: str | Path, frames: Iterable[Any], fps: float = 15.0, scale: float = 1.0) -> Path:
    """Write RGB frames (e.g. collected from ``env.render()``) to a ``.gif`` or ``.mp4`` file.

    Args:
        path: Output file.
        frames: (H, W, 3) uint8 frames.
        fps: Frames per second.
        scale: Resize factor.

    Returns:
        The path written.
    """
    writer = VideoWriter(path, fps=fps, scale=scale)
    for f in frames:
        writer.append(f)
    return writer.close()
