"""One source, two targets: the kernel registry, the per-target primitives, and the CUDA forms built from the same functions.

The CUDA parts compile to PTX without a GPU (numba-cuda with the CUDA toolkit's wheels, the
``gpu`` extra); they skip without numba-cuda and under its simulator (tests/device runs there).
"""

from __future__ import annotations

import importlib
import inspect
import math
import os
import subprocess
import sys

import numpy as np
import pytest

from bluesky_gym.core import jit as jit_module
from bluesky_gym.core.jit import KERNELS, PRIMITIVES, fmod, grid_range, jit, rint, scratch

KERNEL_MODULES = [
    "bluesky_gym.core.scalar",
    "bluesky_gym.core.geo",
    "bluesky_gym.core.atmosphere",
    "bluesky_gym.core.performance",
    "bluesky_gym.core.conflicts",
    "bluesky_gym.core.lnav",
    "bluesky_gym.core.resolution",
    "bluesky_gym.core.step",
    "bluesky_gym.tasks.compiled",
]


def _cuda_target():  # type: ignore[no-untyped-def]
    pytest.importorskip("numba_cuda")
    from bluesky_gym.core import cuda_target

    if cuda_target.SIMULATOR:
        pytest.skip("numba-cuda's simulator is on: offline compilation needs NVVM (tests/device covers the simulator)")
    return cuda_target


@jit
def _primitives_kernel(x, out, rounded):  # type: ignore[no-untyped-def]
    s = scratch(x.shape[0], np.float64)
    for i in grid_range(x.shape[0]):
        s[i] = fmod(x[i], 3.0)
        out[i] = s[i]
        rounded[i] = rint(x[i])


def test_primitives_are_numpys_operations_compiled_and_in_python() -> None:
    x = np.array([-7.5, -2.5, -0.5, -0.0, 0.0, 0.5, 1.5, 2.5, 3.0, 7.25, 1e300, np.inf, np.nan])
    with np.errstate(invalid="ignore"):
        want_mod, want_rint = np.fmod(x, 3.0), np.rint(x)
    for run in (_primitives_kernel, jit_module.python_form(_primitives_kernel)):
        out, rounded = np.empty_like(x), np.empty_like(x)
        with np.errstate(invalid="ignore"):
            run(x, out, rounded)
        np.testing.assert_array_equal(out, want_mod)
        np.testing.assert_array_equal(rounded, want_rint)
        assert np.array_equal(np.signbit(rounded), np.signbit(want_rint))  # rint(-0.5) is -0.0, as numpy's
    with np.errstate(invalid="ignore"):
        assert math.isnan(fmod(1.0, 0.0))  # numpy's, where Python's math.fmod raises
    assert list(grid_range(4)) == [0, 1, 2, 3]
    assert set(PRIMITIVES) == {"fmod", "rint", "fma", "scratch", "grid_range"}


def test_every_kernel_of_core_and_tasks_is_registered_once() -> None:
    numba = pytest.importorskip("numba")
    found = set()
    for name in KERNEL_MODULES:
        module = importlib.import_module(name)
        for value in vars(module).values():
            if isinstance(value, numba.core.registry.CPUDispatcher) and value.py_func.__module__ == name:
                found.add(f"{name}.{value.py_func.__qualname__}")
    registered = {k for k in KERNELS if k.startswith(("bluesky_gym.core.", "bluesky_gym.tasks."))}
    assert found and found <= registered
    assert len({id(k.py_func) for k in KERNELS.values()}) == len(KERNELS)


def test_kernels_name_the_per_target_operations_by_their_one_name() -> None:
    """No kernel calls numpy's fmod, rint or array allocation directly: each target gives its own."""
    for k in KERNELS.values():
        if not k.name.startswith(("bluesky_gym.core.", "bluesky_gym.tasks.")):
            continue
        source = inspect.getsource(k.py_func)
        for direct in ("np.fmod(", "np.rint(", "np.empty(", "np.zeros(", "np.ones(", "np.full("):
            assert direct not in source, f"{k.name} calls {direct}...) instead of the jit layer's primitive"


def test_cuda_forms_are_built_from_the_same_functions() -> None:
    cuda_target = _cuda_target()
    from bluesky_gym.core import scalar, step

    for k in KERNELS.values():
        if k.name.startswith(("bluesky_gym.core.", "bluesky_gym.tasks.")):
            assert cuda_target.device_function(k.compiled).py_func.__code__ is k.py_func.__code__, k.name
    form = cuda_target.device_function(step.step_kernel).py_func.__globals__
    assert form["_mod"] is cuda_target.device_function(scalar.mod)
    assert form["rint"] is not rint and form["grid_range"] is not grid_range
    assert step.step_kernel.py_func.__globals__["rint"] is rint  # the CPU module is untouched


def test_offline_compilation_gives_ptx_and_restores_numba_cuda() -> None:
    cuda_target = _cuda_target()
    import numba.cuda.dispatcher as dispatcher
    from numba import types

    from bluesky_gym.core import atmosphere

    original = dispatcher.get_current_device
    array = types.float64[::1]
    with cuda_target.offline_compilation((9, 0)):
        ptx = cuda_target.compile_ptx(atmosphere._vcas2tas_loop, (array, array, array), cc=(9, 0))
        device = cuda_target.compile_ptx(atmosphere.isa, (types.float64,), device=True, cc=(9, 0))
    assert dispatcher.get_current_device is original
    assert ".entry" in ptx and ".target sm_90" in ptx
    assert ".entry" not in device and ".func" in device


@jit
def _uncompilable_kernel(x, out):  # type: ignore[no-untyped-def]
    for i in grid_range(x.shape[0]):
        out[i] = np.linalg.norm(x)  # BLAS: no CUDA implementation


@jit
def _never_called_kernel(x, out):  # type: ignore[no-untyped-def]
    for i in grid_range(x.shape[0]):
        out[i] = x[i]


def _fake_scope(monkeypatch: pytest.MonkeyPatch) -> None:
    from bluesky_gym.benchmarks import gpu_bench

    x = np.ones(3)
    _uncompilable_kernel(x, np.empty(3))
    _primitives_kernel(x, np.empty(3), np.empty(3))
    scope = [KERNELS[f"{__name__}.{n}"] for n in ("_primitives_kernel", "_uncompilable_kernel", "_never_called_kernel")]
    monkeypatch.setattr(gpu_bench, "kernels_in_scope", lambda: scope)
    monkeypatch.setattr(gpu_bench, "exercise_kernels", lambda say=None: [])


def test_compile_all_names_every_kernel_that_fails(monkeypatch: pytest.MonkeyPatch) -> None:
    _cuda_target()
    from bluesky_gym.benchmarks import gpu_bench

    _fake_scope(monkeypatch)
    results = gpu_bench.compile_all((9, 0))
    by_name = {r.kernel.rsplit(".", 1)[1]: r for r in results}
    assert by_name["_primitives_kernel"].error is None and by_name["_primitives_kernel"].ptx_chars > 0
    assert by_name["_uncompilable_kernel"].error is not None
    assert "not exercised" in (by_name["_never_called_kernel"].error or "")
    text = gpu_bench.format_compile(results, (9, 0), [])
    assert "FAILED tests.core.test_jit_targets._uncompilable_kernel" in text
    assert "FAILED tests.core.test_jit_targets._never_called_kernel" in text
    assert "3 kernels, 1 compilations, 2 failed" in text


def test_bench_gpu_compile_only_exits_non_zero_on_a_failure(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    _cuda_target()
    from bluesky_gym.cli import main

    _fake_scope(monkeypatch)
    assert main(["bench", "gpu", "--compile-only", "--quiet"]) == 1
    assert "FAILED tests.core.test_jit_targets._uncompilable_kernel" in capsys.readouterr().out
    assert main(["bench", "gpu", "--compile-only", "--quiet", "--kernel", "_primitives_kernel"]) == 0


def test_bench_gpu_without_a_device_refuses_in_one_line() -> None:
    cuda_target = _cuda_target()
    if cuda_target.device_present():
        pytest.skip("a CUDA device is present: the device check would run")
    env = {**os.environ, "NUMBA_ENABLE_CUDASIM": "0"}
    done = subprocess.run([sys.executable, "-m", "bluesky_gym", "bench", "gpu", "--quiet"], capture_output=True, text=True, env=env, timeout=300)
    assert done.returncode != 0
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("bluesky-gym bench gpu: no CUDA device found"), done.stderr


def test_none_arguments_are_passed_as_a_null_pointer() -> None:
    """numba-cuda lays out a None argument as one 64-bit parameter but does not convert it: the kernels' extension does."""
    cuda_target = _cuda_target()
    from numba import types

    from bluesky_gym.core import step

    array = types.float64[::1]
    ext = cuda_target.NoneArgument()
    assert ext.prepare_args(types.none, None) == (types.uint64, 0)
    assert ext.prepare_args(array, "unchanged") == (array, "unchanged")
    assert any(isinstance(e, cuda_target.NoneArgument) for e in cuda_target.kernel(step.run_kernel).targetoptions["extensions"])
    with cuda_target.offline_compilation((9, 0)):
        ptx = cuda_target.compile_ptx(_never_called_kernel, (array, array), cc=(9, 0))
        with_none = cuda_target.compile_ptx(_optional_kernel, (array, types.none, array), cc=(9, 0))
    params = ptx.count(".param .u64")
    assert with_none.count(".param .u64") == params + 1  # the None: one 64-bit parameter


@jit
def _optional_kernel(x, extra, out):  # type: ignore[no-untyped-def]
    for i in grid_range(x.shape[0]):
        out[i] = x[i] if extra is None else x[i] + extra[i]


def test_without_numba_cuda_the_device_parts_name_the_gpu_extra(monkeypatch: pytest.MonkeyPatch) -> None:
    from bluesky_gym.cli import main
    from bluesky_gym.core import DeviceSimulator, cuda_target
    from bluesky_gym.core.extras import MissingDependencyError

    monkeypatch.setattr(cuda_target, "AVAILABLE", False)
    with pytest.raises(MissingDependencyError, match=r"numba-cuda.*the 'gpu' extra"):
        DeviceSimulator(1, 2)
    for argv in (["bench", "gpu"], ["bench", "gpu", "--compile-only"]):
        with pytest.raises(SystemExit, match=r"^bluesky-gym bench gpu: numba-cuda is not installed \(the 'gpu' extra\)"):
            main(argv)
