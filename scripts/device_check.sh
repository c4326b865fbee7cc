#!/usr/bin/env bash
# The device check, as one script, on a machine with a CUDA GPU (docs/backends.md, "On a GPU"):
#   1. the device tests (tests/device) on the GPU: the device simulator and task kernels against the CPU;
#   2. `bluesky-gym bench gpu`: fidelity over a sample and physics throughput, device and CPU side by side.
# Outputs go to $OUT (default: device-check/): versions.txt, device-tests.txt, gpu.txt, gpu.json.
# Without network on the GPU machine, bring .device-wheels/ (scripts/device_wheels.sh) with the tree:
# they are installed into a virtual environment over the machine's own Python packages.
set -uo pipefail
cd "$(dirname "$0")/.."
OUT=${OUT:-device-check}
mkdir -p "$OUT"
PY=${PYTHON:-python3}
VENV=${DEVICE_VENV:-/tmp/bluesky-gym-device-venv}
if [ ! -x "$VENV/bin/python" ]; then "$PY" -m venv --system-site-packages "$VENV"; fi
if [ -d .device-wheels ]; then
    "$VENV/bin/python" -m pip install -q --no-index --no-deps --force-reinstall .device-wheels/*.whl
fi
export PYTHONPATH="$PWD${PYTHONPATH:+:$PYTHONPATH}"
V="$VENV/bin/python"
"$V" -c 'import sys, numpy, numba, numba_cuda; from numba import cuda; print(sys.version); print("numpy", numpy.__version__, "numba", numba.__version__, "numba-cuda", numba_cuda.__version__); cuda.detect()' >"$OUT/versions.txt" 2>&1
status=0
timeout 240 "$V" -m pytest -p no:cacheprovider -q tests/device >"$OUT/device-tests.txt" 2>&1 || status=1
timeout 480 "$V" -m bluesky_gym bench gpu --json "$OUT/gpu.json" >"$OUT/gpu.txt" 2>&1 || status=1
tail -n 3 "$OUT/device-tests.txt"
cat "$OUT/gpu.txt"
exit $status
