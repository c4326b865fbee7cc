"""numba's cache of a kernel is invalidated by a change to any kernel module, not just its own file."""

from __future__ import annotations

import inspect
from pathlib import Path

import pytest

numba = pytest.importorskip("numba")

from bluesky_gym.core import jit as jit_module  # noqa: E402
from bluesky_gym.core import step  # noqa: E402


def test_cached_kernels_are_stamped_with_every_kernel_module(tmp_path: Path) -> None:
    locator_class = jit_module._KernelCacheLocator
    kernel = step.step_kernel.py_func
    locator = locator_class.from_function(kernel, inspect.getsourcefile(kernel))
    assert locator is not None
    stamped = {Path(name).name for name, _mtime, _size in locator.get_source_stamp()}
    assert {"atmosphere.py", "geo.py", "performance.py", "step.py", "units.py", "compiled.py"} <= stamped

    # An environment folder's kernels (its task module) are stamped the same way, and stamp it.
    from bluesky_gym.environments.horizontal_cr import task as horizontal_cr

    env_kernel = horizontal_cr.row_reward.py_func
    env_locator = locator_class.from_function(env_kernel, inspect.getsourcefile(env_kernel))
    assert env_locator is not None
    stamped_paths = {Path(name) for name, _mtime, _size in env_locator.get_source_stamp()}
    assert Path(horizontal_cr.__file__).resolve() in {p.resolve() for p in stamped_paths}
    assert "compiled.py" in {p.name for p in stamped_paths}

    # A function outside the package keeps numba's own locator.
    outside = tmp_path / "mod.py"
    outside.write_text("def f():\n    return 1\n")
    namespace: dict = {}
    exec(compile(outside.read_text(), str(outside), "exec"), namespace)  # noqa: S102 - a function defined outside the package
    assert locator_class.from_function(namespace["f"], str(outside)) is None


def test_editing_another_kernel_module_changes_the_stamp(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    core, tasks = tmp_path / "core", tmp_path / "tasks"
    for d in (core, tasks):
        d.mkdir()
    (core / "atmosphere.py").write_text("X = 1\n")
    (tasks / "compiled.py").write_text("Y = 2\n")
    monkeypatch.setattr(jit_module, "_KERNEL_DIRS", (core, tasks))
    before = jit_module._kernel_sources_stamp()
    assert [Path(name).name for name, _, _ in before] == ["atmosphere.py", "compiled.py"]
    (core / "atmosphere.py").write_text("X = 10\n")
    assert jit_module._kernel_sources_stamp() != before
