"""The CUDA target of the kernels: the functions of :data:`bluesky_gym.core.jit.KERNELS`, compiled by numba-cuda.

Every kernel is written once (see :mod:`bluesky_gym.core.jit`). Its CUDA form is built here
from the same Python function: a copy of the function whose module globals name the CUDA forms
of the kernels it calls and the CUDA implementations of the primitives (libdevice's ``fmod`` and
``rint``, thread-local scratch arrays, grid-stride loops). A kernel with
a ``grid_range`` outer loop is launched with one thread per index (:func:`launch`); any other
kernel is a device function of its callers.

Under numba-cuda's simulator (``NUMBA_ENABLE_CUDASIM=1``) the same forms are plain Python run
thread by thread, so the device logic is tested without a GPU.

Without a GPU, :func:`compile_ptx` compiles a kernel to PTX with the CUDA toolkit's NVVM alone
(:func:`offline_compilation`). Needs the ``gpu`` extra.

The CUDA kernels are compiled without fast-math, but NVVM fuses multiplications and additions
into fused multiply-adds by default and libdevice's transcendental functions may differ from
the C library's in the last bit: device results agree with the CPU kernels to within rounding,
not bit for bit (``bluesky-gym bench gpu`` measures by how much).
"""

from __future__ import annotations

import importlib
import importlib.util
import math
import types
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np

from bluesky_gym.core.extras import missing_extra
from bluesky_gym.core.jit import KERNELS, PRIMITIVES, Kernel

#: What needs the ``gpu`` extra, for the error that names it.
NEEDS = "the CUDA target needs numba-cuda and the CUDA toolkit"

cuda: Any = None  # numba.cuda (its simulator under NUMBA_ENABLE_CUDASIM=1)
libdevice: Any = None  # numba.cuda.libdevice (compiled targets only)
#: Whether numba-cuda is installed. (numba itself may still bring an older, deprecated ``numba.cuda``,
#: which this target does not use.)
AVAILABLE = importlib.util.find_spec("numba_cuda") is not None
if AVAILABLE:
    try:
        cuda = importlib.import_module("numba.cuda")
    except ImportError:  # pragma: no cover - a broken installation (missing CUDA bindings) counts as none
        AVAILABLE = False

#: Whether numba-cuda runs its simulator (``NUMBA_ENABLE_CUDASIM=1``) instead of compiling.
SIMULATOR = bool(AVAILABLE and importlib.import_module("numba.cuda.core.config").ENABLE_CUDASIM)
if AVAILABLE and not SIMULATOR:
    libdevice = importlib.import_module("numba.cuda.libdevice")
#: Elements of one :func:`~bluesky_gym.core.jit.scratch` array on CUDA (thread-local memory; aircraft per airspace - 1 at most).
#: 160 holds DenseSectorCR's default traffic (157 aircraft beside the ownship); the task kernels that
#: use the most keep eight such arrays, about 10 KB of local memory per thread.
SCRATCH_CAPACITY = 160
#: Compute capability the offline compilation targets by default: Hopper (H100, H200).
DEFAULT_CC = (9, 0)
#: Threads per block of a launch.
THREADS_PER_BLOCK = 128


def require() -> None:
    """Raise :class:`~bluesky_gym.core.extras.MissingDependencyError` (with the install command) without numba-cuda."""
    if not AVAILABLE:
        raise missing_extra(NEEDS, "gpu")


# --- CUDA implementations of the primitives ------------------------------------------------------
def _cuda_fmod(a: float, b: float) -> float:
    return libdevice.fmod(a, b)  # type: ignore[no-any-return]


def _cuda_fma(a: float, b: float, c: float) -> float:
    return libdevice.fma(a, b, c)  # type: ignore[no-any-return]


def _cuda_rint(x: float) -> float:
    return libdevice.rint(x)  # type: ignore[no-any-return]


def _cuda_scratch(n: int, dtype: Any) -> Any:
    return cuda.local.array(SCRATCH_CAPACITY, dtype)[:n]


def _sim_scratch(n: int, dtype: Any) -> Any:
    if n > SCRATCH_CAPACITY:  # a compiled kernel would read past its thread-local array
        raise IndexError(f"scratch array of {n} elements: CUDA kernels have room for {SCRATCH_CAPACITY}")
    return cuda.local.array(n, dtype)


def _cuda_grid_range(n: int) -> range:
    return range(cuda.grid(1), n, cuda.gridsize(1))


def _primitive_forms() -> dict[str, Callable[..., Any]]:
    """The CUDA form of every primitive, by name (plain Python where the simulator runs)."""
    if SIMULATOR:
        # libdevice does not exist in the simulator: numpy's scalar functions are the same operations.
        return {
            "fmod": PRIMITIVES["fmod"],
            "rint": PRIMITIVES["rint"],
            "fma": PRIMITIVES["fma"],
            "scratch": cuda.jit(device=True)(_sim_scratch),
            "grid_range": cuda.jit(device=True)(_cuda_grid_range),
        }
    return {
        "fmod": cuda.jit(device=True, inline="always")(_cuda_fmod),
        "rint": cuda.jit(device=True, inline="always")(_cuda_rint),
        "fma": cuda.jit(device=True, inline="always")(_cuda_fma),
        # A local array can only leave a device function that is inlined into its caller.
        "scratch": cuda.jit(device=True, inline="always")(_cuda_scratch),
        "grid_range": cuda.jit(device=True, inline="always")(_cuda_grid_range),
    }


_primitives: dict[str, Callable[..., Any]] = {}
_module_globals: dict[str, dict[str, Any]] = {}
_devices: dict[str, Any] = {}
_kernels: dict[str, Any] = {}
_by_identity: dict[int, Kernel] = {}


def _kernel_of(fn: Any) -> Kernel:
    """The :class:`~bluesky_gym.core.jit.Kernel` of a kernel given as its compiled form, its source, or its name."""
    if isinstance(fn, str):
        return KERNELS[fn]
    k = _by_identity.get(id(fn))
    if k is None or (fn is not k.compiled and fn is not k.py_func):
        _by_identity.clear()
        for known in KERNELS.values():
            _by_identity[id(known.compiled)] = _by_identity[id(known.py_func)] = known
        k = _by_identity.get(id(fn))
        if k is None or (fn is not k.compiled and fn is not k.py_func):
            raise KeyError(f"{getattr(fn, '__name__', fn)!r} is not a kernel of the package (bluesky_gym.core.jit.jit / jit_inline)")
    return k


def _cuda_globals(module: str) -> dict[str, Any]:
    """A copy of ``module``'s globals naming the CUDA forms of the kernels and primitives it uses."""
    g = _module_globals.get(module)
    if g is not None:
        return g
    if not _primitives:
        _primitives.update(_primitive_forms())
    source = vars(importlib.import_module(module))
    g = dict(source)
    _module_globals[module] = g  # before filling: kernels of this module call each other
    by_identity = {id(k.compiled): k for k in KERNELS.values()}
    primitive_names = {id(fn): name for name, fn in PRIMITIVES.items()}
    for name, value in source.items():
        if id(value) in primitive_names:
            g[name] = _primitives[primitive_names[id(value)]]
        elif id(value) in by_identity and by_identity[id(value)].compiled is value:
            g[name] = device_function(by_identity[id(value)].compiled)
    return g


def _rebuilt(kernel: Kernel) -> types.FunctionType:
    """``kernel``'s Python function with the CUDA globals of its module."""
    f = kernel.py_func
    new = types.FunctionType(f.__code__, _cuda_globals(f.__module__), f.__name__, f.__defaults__, f.__closure__)
    new.__qualname__ = f.__qualname__
    new.__doc__ = f.__doc__
    return new


def device_function(fn: Any) -> Any:
    """The CUDA device function of a kernel (given as its compiled form, its source or its name)."""
    require()
    k = _kernel_of(fn)
    d = _devices.get(k.name)
    if d is None:
        options = {"inline": "always"} if (k.inline and not SIMULATOR) else {}
        d = cuda.jit(device=True, **options)(_rebuilt(k))
        _devices[k.name] = d
    return d


class NoneArgument:
    """Passes ``None`` to a kernel, as a null pointer (a numba-cuda kernel-argument extension).

    Kernels take ``None`` for an absent optional argument (``run_kernel``'s ``lnav`` and
    ``trace``), which numba compiles as a specialisation; numba-cuda lays a ``None`` argument out
    as one pointer-sized parameter but has no conversion for its value. This extension, given
    to every launchable kernel, converts it to a 64-bit zero.
    """

    def prepare_args(self, ty: Any, val: Any, stream: Any = 0, retr: Any = None) -> tuple[Any, Any]:
        """numba-cuda's extension interface: ``(type, value)`` of an argument, converted where it is ``None``."""
        if isinstance(ty, cuda.types.NoneType):
            return cuda.types.uint64, 0
        return ty, val


def kernel(fn: Any) -> Any:
    """The launchable CUDA kernel of a kernel of the package (one whose outer loop is a ``grid_range``)."""
    require()
    k = _kernel_of(fn)
    c = _kernels.get(k.name)
    if c is None:
        # (The simulator runs Python and passes None as it is.)
        c = cuda.jit(_rebuilt(k)) if SIMULATOR else cuda.jit(extensions=[NoneArgument()])(_rebuilt(k))
        _kernels[k.name] = c
    return c


_launches = 0


def launches() -> int:
    """How many kernels :func:`launch` has launched in this process (to check that a step's launches do not grow with the batch)."""
    return _launches


def launch(fn: Any, n: int, *args: Any) -> None:
    """Launch kernel ``fn`` over ``n`` indices of its ``grid_range`` loop (nothing for ``n == 0``)."""
    global _launches
    if n <= 0:
        return
    _launches += 1
    blocks = math.ceil(n / THREADS_PER_BLOCK)
    kernel(fn)[blocks, THREADS_PER_BLOCK](*args)


def device_present() -> bool:
    """Whether a CUDA GPU and its driver are usable (always False without numba-cuda; True under the simulator)."""
    if not AVAILABLE:
        return False
    try:
        return bool(cuda.is_available())
    except Exception:  # noqa: BLE001 - a broken driver installation counts as no device
        return False


class _OfflineDevice:
    """What numba-cuda reads of the current device while compiling: its compute capability."""

    def __init__(self, cc: tuple[int, int]) -> None:
        self.compute_capability = cc


@contextmanager
def offline_compilation(cc: tuple[int, int] = DEFAULT_CC) -> Iterator[None]:
    """Compile for compute capability ``cc`` without a GPU or a CUDA driver (NVVM from the toolkit's wheels).

    numba-cuda (0.30) compiles a device function called from a kernel through
    ``numba.cuda.dispatcher``'s ``compile_device``, which asks the CUDA driver for the current
    device's compute capability even when the kernel's compilation names one. This is the one
    place where the package stands in for that query: within this context, and only where no
    CUDA device is present, ``numba.cuda.dispatcher.get_current_device`` reports a device of
    capability ``cc``. With a device present nothing is replaced; nothing is launched either way.
    """
    require()
    if SIMULATOR:
        raise RuntimeError("offline compilation compiles with NVVM; numba-cuda's simulator (NUMBA_ENABLE_CUDASIM=1) compiles nothing")
    if device_present():
        yield
        return
    import numba.cuda.dispatcher as dispatcher

    original = dispatcher.get_current_device
    dispatcher.get_current_device = lambda: _OfflineDevice(cc)
    try:
        yield
    finally:
        dispatcher.get_current_device = original


def compile_ptx(fn: Any, signature: tuple[Any, ...], *, device: bool = False, cc: tuple[int, int] = DEFAULT_CC) -> str:
    """PTX of a kernel for argument types ``signature`` (numba types).

    Args:
        fn: The kernel (its compiled form, its source or its name).
        signature: Its argument types.
        device: Compile it as a device function (a kernel that returns a value must be one);
            otherwise as a launchable kernel.
        cc: Compute capability.

    Where no GPU is present, call it within :func:`offline_compilation`.
    """
    require()
    ptx, _restype = cuda.compile_ptx(_rebuilt(_kernel_of(fn)), tuple(signature), device=device, cc=cc)
    return ptx  # type: ignore[no-any-return]


def to_device(array: np.ndarray) -> Any:
    """A device copy of a host array (contiguous)."""
    require()
    return cuda.to_device(np.ascontiguousarray(array))


def device_empty(shape: tuple[int, ...], dtype: Any) -> Any:
    """An uninitialised device array."""
    require()
    return cuda.device_array(shape, dtype)


def synchronize() -> None:
    """Wait for every launch to finish."""
    require()
    cuda.synchronize()
