"""The device tests: the CUDA forms of the kernels launched, on a GPU or under numba-cuda's simulator.

They run where numba-cuda (the ``gpu`` extra) can launch kernels: on a machine with a CUDA GPU,
or anywhere under the simulator (``NUMBA_ENABLE_CUDASIM=1``, as ``scripts/test.sh`` runs them),
which executes the same kernels as Python, thread by thread: small sizes only. Elsewhere they skip.

Under the simulator the kernels compute with numpy's and Python's scalar functions, so results
must equal the CPU kernels' bit for bit; on a GPU they must agree within the project's tolerances.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import bluesky_gym
from bluesky_gym.core import DeviceSimulator, cuda_target

#: Every test module here carries it: skip where kernels cannot be launched.
needs_device = pytest.mark.skipif(
    not (cuda_target.AVAILABLE and (cuda_target.SIMULATOR or cuda_target.device_present())),
    reason="no CUDA device and numba-cuda's simulator is off (NUMBA_ENABLE_CUDASIM=1 runs these tests)",
)

#: Largest differences allowed on a GPU (the project's fidelity tolerances, per unit).
TOLERANCE = {"deg": 1e-9, "m": 1e-6, "m/s": 1e-9}


def assert_agree(device: np.ndarray, cpu: np.ndarray, atol: float) -> None:
    """Bit for bit under the simulator; within ``atol`` on a GPU (NaN where the CPU has NaN)."""
    device, cpu = np.asarray(device), np.asarray(cpu)
    if cuda_target.SIMULATOR:
        np.testing.assert_array_equal(device, cpu)
    else:
        np.testing.assert_allclose(device, cpu, rtol=0.0, atol=atol, equal_nan=True)


#: The torch device of the device environments' tensors (the CPU under numba-cuda's simulator).
ON = "cpu" if cuda_target.SIMULATOR else "cuda"


def same_tensor(device: Any, cpu: np.ndarray, what: str) -> None:
    """A device output (a tensor on :data:`ON`) equals the CPU's: bit for bit under the simulator, within the rounding on a GPU."""
    import torch

    assert isinstance(device, torch.Tensor), (what, type(device))
    assert device.device.type == ON, (what, device.device)
    got = device.cpu().numpy()
    assert got.dtype == cpu.dtype and got.shape == cpu.shape, (what, got.dtype, cpu.dtype, got.shape, cpu.shape)
    if cuda_target.SIMULATOR or cpu.dtype == np.bool_:
        np.testing.assert_array_equal(got, cpu, err_msg=what)
    else:  # on a GPU: within the physics' rounding (float32 observations: their last bit)
        np.testing.assert_allclose(got, cpu, rtol=max(1e-7, 4 * float(np.finfo(cpu.dtype).eps)), atol=1e-9, err_msg=what)


def compare_device_step(
    env_id: str,
    options: dict[str, Any],
    step_class: type,
    monkeypatch: pytest.MonkeyPatch,
    *,
    steps: int = 9,
    num_envs: int = 3,
    seed: int = 11,
    cpu_infos: list[dict[str, Any]] | None = None,
) -> tuple[int, int, Any, Any]:
    """Step the device and the CPU vector environments of ``env_id`` with the same seeds and actions, comparing every output.

    Observations, reward, terminated, truncated, every info entry and the final observations and
    infos of ended episodes, at the reset and at each step (random actions beyond the bounds:
    clipped); the aircraft state must never come back to the host whole during a step.

    Args:
        cpu_infos: Where given, the CPU environment's info of each step is appended to it (for the
            caller to check which events happened).

    Returns:
        The episodes that ended and those terminated over the steps, and both environments (still open).
    """
    import torch

    bluesky_gym.register_envs()
    cpu = gym.make_vec(env_id, num_envs=num_envs, **options)
    dev = gym.make_vec(env_id, num_envs=num_envs, device="cuda", **options)
    assert isinstance(dev.unwrapped._device_step, step_class), type(dev.unwrapped._device_step)
    assert isinstance(dev.unwrapped.task.sim, DeviceSimulator)
    obs_c, info_c = cpu.reset(seed=seed)
    obs_d, info_d = dev.reset(seed=seed)
    assert set(obs_d) == set(obs_c) and set(info_d) == set(info_c)
    for k in obs_c:
        same_tensor(obs_d[k], obs_c[k], f"reset {k}")
    for k in info_c:
        same_tensor(info_d[k], info_c[k], f"reset info {k}")
    pulls: list[int] = []
    original = DeviceSimulator._to_host
    monkeypatch.setattr(DeviceSimulator, "_to_host", lambda self: (pulls.append(1), original(self))[1])
    rng = np.random.default_rng(2)
    ended = terminated = 0
    for step in range(steps):
        a = rng.uniform(-1.5, 1.5, cpu.action_space.shape).astype(cpu.action_space.dtype)
        oc, rc, tc, uc, ic = cpu.step(a)
        od, rd, td, ud, idev = dev.step(torch.as_tensor(a, device=ON))
        assert set(od) == set(oc)
        for k in oc:
            same_tensor(od[k], oc[k], f"step {step} obs {k}")
        same_tensor(rd, rc, f"step {step} reward")
        same_tensor(td, tc, f"step {step} terminated")
        same_tensor(ud, uc, f"step {step} truncated")
        assert set(idev) == set(ic), set(idev) ^ set(ic)
        for k, v in ic.items():
            if k in ("final_obs", "final_info"):
                assert set(idev[k]) == set(v)
                for key in v:
                    same_tensor(idev[k][key], v[key], f"step {step} {k} {key}")
            else:
                same_tensor(idev[k], v, f"step {step} info {k}")
        ended += int((tc | uc).sum())
        terminated += int(tc.sum())
        if cpu_infos is not None:
            cpu_infos.append(ic)
    assert not pulls, "the aircraft state came back to the host whole during a step"
    monkeypatch.setattr(DeviceSimulator, "_to_host", original)
    return ended, terminated, cpu, dev


def launches_of_step(env_id: str, num_envs: int, ends: bool, **options: Any) -> int:
    """The kernel launches of one device step of ``env_id`` (zero actions), in which every episode ends (``ends``: a time limit of 1) or none does."""
    import torch

    env = gym.make_vec(env_id, num_envs=num_envs, max_episode_steps=1 if ends else 50, device="cuda", **options)
    assert env.unwrapped._device_step is not None, f"{env_id} has no device step"
    env.reset(seed=0)
    before = cuda_target.launches()
    _, _, terminated, truncated, _ = env.step(torch.zeros(env.action_space.shape, device=ON))
    assert bool((terminated | truncated).all()) == ends
    env.close()
    return cuda_target.launches() - before
