"""``gym.make_vec(id, num_envs=N, device="cuda")`` against the CPU vector environment, episode by episode.

Under numba-cuda's simulator the tensors are CPU tensors and every output must equal the CPU
environment's bit for bit; on a GPU they are CUDA tensors and must agree within the tolerances
(the physics differs by the GPU's rounding, docs/backends.md).
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import bluesky_gym
from bluesky_gym.core import DeviceSimulator, cuda_target
from bluesky_gym.envs.registry import env_ids

from .conftest import needs_device

torch = pytest.importorskip("torch")
pytestmark = needs_device
bluesky_gym.register_envs()

#: Outputs of the environments (observations are normalised: no unit) compared on a GPU.
RTOL, ATOL = 1e-7, 1e-9
#: Every single-agent id (the recorded-traffic ones play the tests' stand-in collections, tests/conftest.py).
IDS = env_ids()
#: DenseSectorCR with entries at once (5 per step on average) into few slots (the default 120 are slow under the simulator).
_DENSE = {"max_spawned": 12, "spawn_rate_start": 3600.0, "spawn_rate_end": 3600.0}
DEVICE_OPTIONS: dict[str, dict[str, Any]] = {"DenseSectorCREnv-v0": _DENSE, "DenseSectorCREnv-v1": _DENSE}


def _host(value: Any) -> np.ndarray:
    assert isinstance(value, torch.Tensor), type(value)
    assert value.device.type == ("cpu" if cuda_target.SIMULATOR else "cuda")
    return value.cpu().numpy()


def _agree(device: Any, cpu: np.ndarray, what: str) -> None:
    got = _host(device)
    assert got.dtype == cpu.dtype and got.shape == cpu.shape, what
    if cuda_target.SIMULATOR or cpu.dtype == np.bool_:
        np.testing.assert_array_equal(got, cpu, err_msg=what)
    else:  # a -v1 observation is float32: the GPU's last-bit differences may move its last float32 bit
        rtol = max(RTOL, 4 * float(np.finfo(cpu.dtype).eps))
        np.testing.assert_allclose(got, cpu, rtol=rtol, atol=ATOL, err_msg=what)


def _same_host(device: Any, cpu: np.ndarray, what: str, on_device: bool = False) -> None:
    """An info entry: a numpy array on the host, or a tensor on the device where the task's step runs there (``on_device``)."""
    if on_device:
        device = _host(device)
        assert device.dtype == cpu.dtype, what
    assert isinstance(device, np.ndarray), what
    if cuda_target.SIMULATOR or cpu.dtype == np.bool_:
        np.testing.assert_array_equal(device, cpu, err_msg=what)
    else:
        np.testing.assert_allclose(device, cpu, rtol=RTOL, atol=ATOL, err_msg=what)


@pytest.mark.parametrize("env_id", IDS)
def test_device_episodes_equal_the_cpu_vector_envs_with_autoreset(env_id: str) -> None:
    """Same seeds, same actions (given to the device as tensors): the same episodes, through a truncation and its autoreset."""
    options = DEVICE_OPTIONS.get(env_id, {})
    cpu = gym.make_vec(env_id, num_envs=2, max_episode_steps=2, **options)
    dev = gym.make_vec(env_id, num_envs=2, max_episode_steps=2, device="cuda", **options)
    assert isinstance(dev.unwrapped.task.sim, DeviceSimulator)
    on_device = dev.unwrapped._device_step is not None  # the task's step on the device: its info entries are tensors too
    obs_c, _ = cpu.reset(seed=7)
    obs_d, _ = dev.reset(seed=7)
    for k in obs_c:
        _agree(obs_d[k], obs_c[k], f"reset {k}")
    rng = np.random.default_rng(5)
    ended = 0
    for step in range(3):
        a = rng.uniform(-1.0, 1.0, cpu.action_space.shape).astype(cpu.action_space.dtype)
        oc, rc, tc, uc, ic = cpu.step(a)
        od, rd, td, ud, idev = dev.step(torch.as_tensor(a, device="cpu" if cuda_target.SIMULATOR else "cuda"))
        for k in oc:
            _agree(od[k], oc[k], f"step {step} {k}")
        _agree(rd, rc, f"step {step} reward")
        _agree(td, tc, f"step {step} terminated")
        _agree(ud, uc, f"step {step} truncated")
        assert set(idev) == set(ic)
        for k, v in ic.items():
            if k == "final_obs":
                for key in v:
                    _agree(idev[k][key], v[key], f"step {step} final_obs {key}")
            elif k == "final_info":
                for key in v:
                    _same_host(idev[k][key], v[key], f"step {step} final_info {key}", on_device)
            else:
                _same_host(idev[k], v, f"step {step} info {k}", on_device)
        ended += int((tc | uc).sum())
    assert ended >= 2, "the episodes must end (max_episode_steps=2) and be reset on the way"
    cpu.close()
    dev.close()


class _DLPackOnly:
    """An array that only speaks DLPack (as JAX's do)."""

    def __init__(self, tensor: Any) -> None:
        self.tensor = tensor

    def __dlpack__(self, **kwargs: Any) -> Any:
        return self.tensor.__dlpack__(**kwargs)

    def __dlpack_device__(self) -> Any:
        return self.tensor.__dlpack_device__()


def test_actions_as_device_arrays_dlpack_numpy_or_lists_give_the_same_step() -> None:
    envs = [gym.make_vec("HorizontalCREnv-v0", num_envs=2, device="cuda") for _ in range(4)]
    a = np.array([[0.3], [-0.8]])
    given = [cuda_target.to_device(a), _DLPackOnly(torch.as_tensor(a)), a, a.tolist()]
    results = []
    for env, action in zip(envs, given):
        env.reset(seed=1)
        results.append(env.step(action))
    for other in results[1:]:
        for k in results[0][0]:
            assert torch.equal(other[0][k], results[0][0][k])
        assert torch.equal(other[1], results[0][1])


def test_state_tensors_are_the_device_state() -> None:
    env = gym.make_vec("HorizontalCREnv-v0", num_envs=3, device="cuda")
    env.reset(seed=2)
    env.step(np.zeros((3, 1)))
    sim = env.unwrapped.task.sim
    lat, active = env.unwrapped.state_tensors("lat", "active")
    assert sim.on_device
    if not cuda_target.SIMULATOR:  # on a GPU: the tensors are the simulator's device memory, not copies (before any host read)
        lat_d, active_d = sim.device_arrays("lat", "active")
        assert lat.data_ptr() == lat_d.device_ctypes_pointer.value
        assert active.data_ptr() == active_d.device_ctypes_pointer.value
    np.testing.assert_array_equal(_host(active), sim.active)
    assert np.array_equal(_host(lat)[sim.active], sim.lat[sim.active])
    cpu = gym.make_vec("HorizontalCREnv-v0", num_envs=3)
    with pytest.raises(RuntimeError, match="device='cuda'"):
        cpu.unwrapped.state_tensors("lat")
