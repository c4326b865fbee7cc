"""``make_vec(..., device=...)`` where no device runs: the refusals, each in one line naming what is wrong.

The device vector environments themselves are tested in ``tests/device`` (under numba-cuda's
simulator, or on a GPU).
"""

from __future__ import annotations

import gymnasium as gym
import pytest

import bluesky_gym
from bluesky_gym.core import cuda_target
from bluesky_gym.core.extras import MissingDependencyError

bluesky_gym.register_envs()


def test_bad_device_arguments_are_refused_in_one_line() -> None:
    with pytest.raises(ValueError, match=r"device must be one of \('cpu', 'cuda'\), got 'gpu'"):
        gym.make_vec("DescentEnv-v0", num_envs=2, device="gpu")
    with pytest.raises(ValueError, match="backend must be 'native', got 'bluesky'"):
        gym.make_vec("DescentEnv-v0", num_envs=1, device="cuda", backend="bluesky")
    with pytest.raises(TypeError, match=r"unknown option\(s\) \['device'\]"):  # the multi-agent ids run on the CPU
        gym.make_vec("SectorCRCentralised-v0", num_envs=1, device="cuda")


def test_without_numba_cuda_device_cuda_names_the_gpu_extra(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(cuda_target, "AVAILABLE", False)
    with pytest.raises(MissingDependencyError, match=r"the 'gpu' extra"):
        gym.make_vec("DescentEnv-v0", num_envs=2, device="cuda")


def test_without_a_gpu_device_cuda_says_what_is_missing() -> None:
    if not cuda_target.AVAILABLE:
        pytest.skip("numba-cuda is not installed (the previous test covers that case)")
    if cuda_target.SIMULATOR or cuda_target.device_present():
        pytest.skip("a device (or numba-cuda's simulator) is there: tests/device runs the environments")
    pytest.importorskip("torch")
    with pytest.raises(RuntimeError, match="needs a CUDA GPU seen by both numba-cuda and PyTorch"):
        gym.make_vec("DescentEnv-v0", num_envs=2, device="cuda")


def test_bench_gpu_envs_does_not_go_with_compile_only() -> None:
    if not cuda_target.AVAILABLE:
        pytest.skip("numba-cuda is not installed")
    from bluesky_gym.cli import main

    for given in (["--envs"], ["--ppo"], ["--budget", "60"]):
        with pytest.raises(SystemExit, match="--envs, --ppo and --budget run on a GPU; they do not go with --compile-only"):
            main(["bench", "gpu", "--compile-only", *given])
    with pytest.raises(SystemExit, match="--envs and --ppo are two checks"):
        main(["bench", "gpu", "--envs", "--ppo"])
    with pytest.raises(SystemExit, match="--budget must be a positive number of seconds, got 0.0"):
        main(["bench", "gpu", "--ppo", "--budget", "0"])
