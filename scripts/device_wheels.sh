#!/usr/bin/env bash
# Download, on a machine with network, the wheels that scripts/device_check.sh installs on a GPU
# machine without network, into .device-wheels/ (git-ignored; about 5 MB, so they can travel with the
# working tree). The GPU machine is expected to bring Python 3.12 with numba, numpy, cuda-bindings,
# cuda-core, cuda-pathfinder and a CUDA toolkit of its own; these wheels add what it lacks:
# numba-cuda at the version of the gpu extra, the package's own requirements Gymnasium and OpenAP, and
# Stable-Baselines3 with cloudpickle for the PPO section (PyTorch and pandas must be on the machine).
#   PYTHON_VERSION=3.12 PLATFORM=manylinux_2_28_x86_64 bash scripts/device_wheels.sh
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3}
PYV=${PYTHON_VERSION:-3.12}
PLAT=${PLATFORM:-manylinux_2_28_x86_64}
NUMBA_CUDA=$(sed -n 's/^gpu = \["numba-cuda\[cu12\]==\([0-9.]*\)"\]$/\1/p' pyproject.toml)
OPENAP=$(sed -n 's/^    "openap==\([0-9.]*\)",.*/\1/p' pyproject.toml)
if [ -z "$NUMBA_CUDA" ] || [ -z "$OPENAP" ]; then echo "device_wheels.sh: could not read the numba-cuda and openap pins from pyproject.toml" >&2; exit 1; fi
rm -rf .device-wheels && mkdir -p .device-wheels
"$PY" -m pip download -q --no-deps --only-binary=:all: --python-version "$PYV" --platform "$PLAT" --platform any -d .device-wheels \
    "numba-cuda==$NUMBA_CUDA" "openap==$OPENAP" "gymnasium>=1.1" farama-notifications "stable-baselines3>=2.3" cloudpickle
ls -l .device-wheels
