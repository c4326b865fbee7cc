"""Optional dependencies: import them on demand, or fail with the extra that installs them.

This module imports nothing else from the package, so every layer may use it.
"""

from __future__ import annotations

from types import ModuleType

TRAIN_EXTRA_HINT = 'pip install "bluesky-gym[train]"'
DISTRIBUTED_EXTRA_HINT = 'pip install "bluesky-gym[distributed]"'


class MissingDependencyError(ImportError):
    """An optional dependency is not installed; the message says which extra provides it."""


def require_sb3() -> ModuleType:
    """Import Stable-Baselines3, or raise :class:`MissingDependencyError` naming the extra."""
    try:
        import stable_baselines3
    except ImportError as exc:
        raise MissingDependencyError(f"training needs Stable-Baselines3 and PyTorch, which are not installed: {TRAIN_EXTRA_HINT}") from exc
    return stable_baselines3


def require_ray() -> ModuleType:
    """Import Ray, or raise :class:`MissingDependencyError` naming the extra."""
    try:
        import ray
    except ImportError as exc:
        raise MissingDependencyError(
            f"distributed sweeps need Ray, which is not installed: {DISTRIBUTED_EXTRA_HINT} (or run the sweep with --local)"
        ) from exc
    return ray


def require_rliable() -> tuple[ModuleType, ModuleType]:
    """Import ``rliable.library`` and ``rliable.metrics``, or raise :class:`MissingDependencyError` naming the extra."""
    try:
        from rliable import library, metrics
    except ImportError as exc:
        raise MissingDependencyError(f"aggregate scores need rliable, which is not installed: {TRAIN_EXTRA_HINT}") from exc
    return library, metrics
