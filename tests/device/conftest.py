"""The device tests: the CUDA forms of the kernels launched, on a GPU or under numba-cuda's simulator.

They run where numba-cuda (the ``gpu`` extra) can launch kernels: on a machine with a CUDA GPU,
or anywhere under the simulator (``NUMBA_ENABLE_CUDASIM=1``, as ``scripts/test.sh`` runs them),
which executes the same kernels as Python, thread by thread: small sizes only. Elsewhere they skip.

Under the simulator the kernels compute with numpy's and Python's scalar functions, so results
must equal the CPU kernels' bit for bit; on a GPU they must agree within the project's tolerances.
"""

from __future__ import annotations

import numpy as np
import pytest

from bluesky_gym.core import cuda_target

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
