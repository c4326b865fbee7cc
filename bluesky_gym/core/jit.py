"""Compilation of the scalar kernels with numba, and the uncompiled fallback.

Every piece of physics and geometry in the package is written once, as scalar Python functions
that numba compiles (``nopython``, no fast-math, so floating-point results are those of the
plain source). Where numba is not installed the same functions run as ordinary Python: correct,
but orders of magnitude slower, and a :class:`RuntimeWarning` says so once.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

F = TypeVar("F", bound=Callable[..., Any])

try:
    import numba

    AVAILABLE = True
except ImportError:  # pragma: no cover - exercised only without numba
    numba = None  # type: ignore[assignment]
    AVAILABLE = False

#: How to get the compiled kernels.
INSTALL_HINT = "pip install numba"
_warned = False

_PACKAGE_DIR = Path(__file__).resolve().parent.parent
#: The folders whose modules define kernels; a change to any of them invalidates every cached kernel.
_KERNEL_DIRS = (_PACKAGE_DIR / "core", _PACKAGE_DIR / "tasks")


def _kernel_sources_stamp() -> tuple[tuple[str, float, int], ...]:
    """Name, modification time and size of every kernel-defining module."""
    return tuple((str(p), p.stat().st_mtime, p.stat().st_size) for d in _KERNEL_DIRS for p in sorted(d.glob("*.py")))


if numba is not None:
    from numba.core.caching import CacheImpl, InTreeCacheLocator

    class _KernelCacheLocator(InTreeCacheLocator):
        """numba's in-tree cache, invalidated by a change to ANY kernel module.

        numba stamps a cached function with its own file only, but kernels inline and call
        kernels of other modules: after an edit of, say, the atmosphere, a cached step kernel
        would otherwise keep the old atmosphere.
        """

        @classmethod
        def from_function(cls, py_func: Any, py_file: str) -> Any:
            if not any(Path(py_file).resolve().is_relative_to(d) for d in _KERNEL_DIRS):
                return None
            return super().from_function(py_func, py_file)

        def get_source_stamp(self) -> Any:
            return _kernel_sources_stamp()

    if _KernelCacheLocator not in CacheImpl._locator_classes:
        # After numba's NUMBA_CACHE_DIR locator, before its default in-tree one.
        CacheImpl._locator_classes.insert(1, _KernelCacheLocator)


def _warn_uncompiled() -> None:
    global _warned
    if not _warned:
        _warned = True
        warnings.warn(
            f"numba is not installed: BlueSky-Gym's kernels run as plain Python, about 1000x slower ({INSTALL_HINT})",
            RuntimeWarning,
            stacklevel=3,
        )


def jit(fn: F) -> F:
    """Compile ``fn`` with numba (cached, no fast-math); without numba, return it unchanged."""
    if numba is None:  # pragma: no cover
        _warn_uncompiled()
        return fn
    return numba.njit(cache=True, nogil=True, error_model="numpy")(fn)  # type: ignore[return-value]


def jit_inline(fn: F) -> F:
    """:func:`jit`, inlined into its callers by numba (for small helpers of hot loops)."""
    if numba is None:  # pragma: no cover
        _warn_uncompiled()
        return fn
    return numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")(fn)  # type: ignore[return-value]


def python_form(fn: F) -> F:
    """The plain-Python source of a kernel (numba's ``py_func``; the function itself without numba).

    Used to evaluate constants at import time without compiling, and by the tests that run the
    kernels uncompiled.
    """
    plain: F = getattr(fn, "py_func", fn)
    return plain


def flat_float_args(*args: Any) -> tuple[tuple[int, ...], list[np.ndarray]]:
    """Broadcast array-likes to one shape and give each as a flat, contiguous float64 array.

    The array-facing functions of the core are thin wrappers: a jitted loop over these flat
    arrays calling a scalar kernel.

    Returns:
        The broadcast shape and the flattened arrays (views where no copy is needed).
    """
    arrays = [np.asarray(a, dtype=np.float64) for a in args]
    shape = np.broadcast_shapes(*(a.shape for a in arrays))
    return shape, [np.ascontiguousarray(np.broadcast_to(a, shape)).reshape(-1) for a in arrays]


def shaped(out: np.ndarray, shape: tuple[int, ...]) -> Any:
    """A flat result in the broadcast ``shape``; a numpy scalar for scalar inputs, as numpy gives."""
    return out.reshape(shape) if shape else out[0]
