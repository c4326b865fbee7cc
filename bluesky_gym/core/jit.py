"""Compilation of the scalar kernels with numba, and the uncompiled fallback.

Every piece of physics and geometry in the package is written once, as scalar Python functions
that numba compiles (``nopython``, no fast-math, so floating-point results are those of the
plain source). Where numba is not installed the same functions run as ordinary Python: correct,
but orders of magnitude slower, and a :class:`RuntimeWarning` says so once.

One source, two targets: every function given to :func:`jit` or :func:`jit_inline` is recorded
in :data:`KERNELS`, from which :mod:`bluesky_gym.core.cuda_target` builds the CUDA form of the
same function (numba-cuda). What differs between the targets is named once here, as a
*primitive* with one implementation per target (:data:`PRIMITIVES`): the float remainder
(:func:`fmod`), rounding to the nearest even integer (:func:`rint`), a scratch array
(:func:`scratch`) and the range of indices a kernel's outer loop visits (:func:`grid_range`).
A kernel calls the primitive by its name; on the CPU the call is numba's implementation
(``overload`` for the CPU target, inlined), in plain Python the function itself, and on CUDA the
form the CUDA target gives for that name. No kernel is written twice.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from fractions import Fraction
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
#: The folders whose modules define kernels (the environment folders' tasks too); a change to any
#: of their modules invalidates every cached kernel.
_KERNEL_DIRS = (_PACKAGE_DIR / "core", _PACKAGE_DIR / "tasks", _PACKAGE_DIR / "realtraffic", _PACKAGE_DIR / "environments")


def _kernel_sources_stamp() -> tuple[tuple[str, float, int], ...]:
    """Name, modification time and size of every kernel-defining module."""
    return tuple((str(p), p.stat().st_mtime, p.stat().st_size) for d in _KERNEL_DIRS for p in sorted(d.rglob("*.py")))


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


@dataclass(frozen=True)
class Kernel:
    """A function of the package compiled by :func:`jit` or :func:`jit_inline`.

    Attributes:
        name: ``module.function``.
        py_func: The plain-Python source, which every target compiles.
        compiled: What the decorator returned (numba's CPU dispatcher, or ``py_func`` without numba).
        inline: Inlined into its callers (:func:`jit_inline`).
    """

    name: str
    py_func: Callable[..., Any]
    compiled: Callable[..., Any]
    inline: bool


#: Every kernel of the package, by ``module.function``, in definition order.
KERNELS: dict[str, Kernel] = {}


def _register(fn: Callable[..., Any], compiled: Callable[..., Any], inline: bool) -> None:
    name = f"{fn.__module__}.{fn.__qualname__}"
    KERNELS[name] = Kernel(name, fn, compiled, inline)


def jit(fn: F) -> F:
    """Compile ``fn`` with numba (cached, no fast-math); without numba, return it unchanged."""
    if numba is None:  # pragma: no cover
        _warn_uncompiled()
        _register(fn, fn, False)
        return fn
    compiled = numba.njit(cache=True, nogil=True, error_model="numpy")(fn)
    _register(fn, compiled, False)
    return compiled  # type: ignore[return-value]


def jit_inline(fn: F) -> F:
    """:func:`jit`, inlined into its callers by numba (for small helpers of hot loops)."""
    if numba is None:  # pragma: no cover
        _warn_uncompiled()
        _register(fn, fn, True)
        return fn
    compiled = numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")(fn)
    _register(fn, compiled, True)
    return compiled  # type: ignore[return-value]


# --- Primitives: one name, one implementation per target ---------------------------------------
#: The primitives by name: their plain-Python form (which is also the CPU target's source).
PRIMITIVES: dict[str, Callable[..., Any]] = {}


def _primitive(fn: F) -> F:
    """Record ``fn`` as a primitive and give it numba's CPU implementation: ``fn`` itself, inlined."""
    PRIMITIVES[fn.__name__] = fn
    if numba is not None:
        from numba.core.extending import overload

        def typer(*args: Any) -> Callable[..., Any]:
            return fn  # numba compiles the primitive's own source for the CPU

        overload(fn, target="cpu", inline="always", strict=False)(typer)
    return fn


@_primitive
def fmod(a: float, b: float) -> float:
    """C's ``fmod``: the remainder of ``a / b`` with the sign of ``a`` (exact); NaN for ``b == 0``, as ``np.fmod``."""
    return np.fmod(a, b)  # type: ignore[no-any-return]


def fma(a: float, b: float, c: float) -> float:
    """``a * b + c`` rounded once (a fused multiply-add), as an x86-64 BLAS ``ddot`` with FMA accumulates numpy's ``np.dot``.

    The plain-Python form is exact rational arithmetic (slow; non-finite inputs give ``a * b + c``);
    the CPU target emits the hardware's ``fma`` instruction, CUDA libdevice's ``fma``.
    """
    if not (math.isfinite(a) and math.isfinite(b) and math.isfinite(c)):
        return a * b + c
    return float(Fraction(a) * Fraction(b) + Fraction(c))


PRIMITIVES["fma"] = fma
if numba is not None:
    from numba.core import types as _nb_types
    from numba.core.extending import intrinsic, overload

    @intrinsic
    def _fma_instruction(typingctx: Any, a: Any, b: Any, c: Any) -> Any:
        def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
            return builder.fma(*args)

        return _nb_types.float64(_nb_types.float64, _nb_types.float64, _nb_types.float64), codegen

    def _fma_typer(a: Any, b: Any, c: Any) -> Callable[..., Any]:
        def impl(a: float, b: float, c: float) -> float:
            return _fma_instruction(float(a), float(b), float(c))  # type: ignore[call-arg]  # numba passes the typing context itself

        return impl

    overload(fma, target="cpu", inline="always", strict=False)(_fma_typer)


@_primitive
def rint(x: float) -> float:
    """``x`` rounded to the nearest integer, halves to even (``np.rint``), as a float."""
    return np.rint(x)  # type: ignore[no-any-return]


@_primitive
def scratch(n: int, dtype: Any) -> np.ndarray:
    """A scratch array of ``n`` elements of ``dtype`` for a kernel's working values (contents undefined).

    On CUDA it is thread-local memory of a fixed capacity (``cuda_target.SCRATCH_CAPACITY``).
    """
    return np.empty(n, dtype)


@_primitive
def grid_range(n: int) -> range:
    """The indices ``0 .. n-1`` of a kernel's outer loop that this thread visits.

    On the CPU (and in plain Python) all of them, in order; on CUDA the grid-stride share of the
    calling thread, so that one launch covers any ``n``.
    """
    return range(n)


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
