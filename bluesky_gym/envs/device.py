"""Vector environments on a CUDA GPU: ``gym.make_vec(id, num_envs=N, device="cuda")``.

With ``device="cuda"`` a native vector environment runs its physics on the device
(:class:`~bluesky_gym.core.DeviceSimulator`, the ``"cuda"`` backend) and speaks torch tensors:
observations, rewards, ``terminated`` and ``truncated`` (and the final observations of the
episodes that ended) are tensors on the GPU, and actions may be given as tensors on the GPU
(or as anything array-like).

How the batches travel (:class:`TensorIO`):

* **Out**: each output array goes to the device once per step, into a numba-cuda device array
  (:func:`bluesky_gym.core.cuda_target.to_device`), which torch then wraps without a copy through
  the CUDA Array Interface (``__cuda_array_interface__``): the tensor owns the device array's
  memory. The same zero-copy wrap gives the simulator's own device state as tensors
  (:meth:`TensorIO.tensor`, used by ``state_tensors`` of the vector environment).
* **In**: actions on the device (a torch tensor, or any object with ``__cuda_array_interface__``
  or ``__dlpack__``) are copied to the host once per step: the actions become autopilot
  commands, which the task gives on the host.

Where the task's whole step runs on the device (:mod:`bluesky_gym.environments.sector_cr.device_step`: SectorCR),
neither copy happens: the actions stay on the device, the kernels write into tensors
(:meth:`TensorIO.kernel_array`), and only which episodes ended comes to the host.

Under numba-cuda's simulator (``NUMBA_ENABLE_CUDASIM=1``) the device arrays are numpy arrays in
disguise and torch has no GPU to put tensors on: the tensors are then CPU tensors, made by the
same code path, so that the environment's logic is tested without a GPU.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from bluesky_gym.core import cuda_target
from bluesky_gym.core.extras import missing_extra

#: The values of the vector environments' ``device`` argument.
DEVICES = ("cpu", "cuda")


def check_device(device: Any) -> str:
    """Validate a vector environment's ``device`` argument.

    Raises:
        ValueError: ``device`` is not one of :data:`DEVICES`.
    """
    if not isinstance(device, str) or device not in DEVICES:
        raise ValueError(f"device must be one of {DEVICES}, got {device!r}")
    return device


def _torch() -> Any:
    try:
        import torch
    except ImportError as exc:
        raise missing_extra("device='cuda' gives torch tensors and needs PyTorch", "train") from exc
    return torch


class TensorIO:
    """Moves a vector environment's batches between numpy on the host and torch tensors on the device.

    Raises:
        MissingDependencyError: Without numba-cuda (the ``gpu`` extra) or PyTorch (the ``train`` extra).
        RuntimeError: Neither a CUDA GPU nor numba-cuda's simulator is there to run on.
    """

    def __init__(self) -> None:
        cuda_target.require()
        self.torch = _torch()
        if cuda_target.SIMULATOR:
            self.device = self.torch.device("cpu")
        elif cuda_target.device_present() and self.torch.cuda.is_available():
            self.device = self.torch.device("cuda", self.torch.cuda.current_device())
        else:
            raise RuntimeError(
                "device='cuda' needs a CUDA GPU seen by both numba-cuda and PyTorch (none found); "
                "numba-cuda's simulator (NUMBA_ENABLE_CUDASIM=1) runs the same code on the CPU"
            )

    def tensor(self, device_array: Any) -> Any:
        """A torch tensor sharing the memory of a numba-cuda device array (no copy; a CPU copy under the simulator)."""
        if cuda_target.SIMULATOR:
            return self.torch.from_numpy(device_array.copy_to_host())
        return self.torch.as_tensor(device_array, device=self.device)

    def kernel_array(self, tensor: Any) -> Any:
        """A contiguous tensor as a kernel argument sharing its memory (numba-cuda's view of it; its numpy view under the simulator)."""
        if cuda_target.SIMULATOR:
            return tensor.numpy()
        return cuda_target.cuda.as_cuda_array(tensor)

    def upload(self, host: np.ndarray) -> Any:
        """A host array as a tensor on the device: one copy into a numba-cuda device array, wrapped by :meth:`tensor`."""
        return self.tensor(cuda_target.to_device(np.ascontiguousarray(host)))

    def upload_all(self, arrays: dict[str, np.ndarray]) -> dict[str, Any]:
        """:meth:`upload` of every array of a dict."""
        return {k: self.upload(v) for k, v in arrays.items()}

    def to_host(self, value: Any) -> Any:
        """Actions as the task takes them: a tensor or device array copied to the host; anything else as it is.

        Accepts torch tensors on any device, objects with ``__cuda_array_interface__`` (CuPy,
        numba-cuda, ...) or ``__dlpack__`` (JAX, ...), and array-likes (numpy, lists).
        """
        torch = self.torch
        if isinstance(value, torch.Tensor):
            return value.detach().cpu().numpy()
        if hasattr(value, "copy_to_host"):  # numba-cuda's device arrays (and the simulator's)
            return value.copy_to_host()
        if hasattr(value, "__cuda_array_interface__"):
            return cuda_target.cuda.as_cuda_array(value).copy_to_host()
        if hasattr(value, "__dlpack__") and not isinstance(value, np.ndarray):
            return torch.from_dlpack(value).cpu().numpy()
        return value
