#!/usr/bin/env bash
# The device check, as one script, on a machine with a CUDA GPU (docs/backends.md, "On a GPU"):
#   tests: the device tests (tests/device) on the GPU: the device simulator, task kernels and the
#          device vector environments against the CPU;
#   gpu:   `bluesky-gym bench gpu`: fidelity over a sample and physics throughput, device and CPU side by side;
#   envs:  `bluesky-gym bench gpu --envs`: every id's gym.make_vec(..., device="cuda") against its CPU
#          vector environment (the same seeded episodes) and env-steps/s side by side (needs PyTorch
#          with CUDA on the machine; without it the section says so and is skipped).
# SECTIONS (default: tests,gpu,envs) picks the sections, e.g. SECTIONS=envs bash scripts/device_check.sh.
# Outputs go to $OUT (default: device-check/): versions.txt, device-tests.txt, gpu.txt, gpu.json,
# gpu-envs.txt, gpu-envs.json.
# Without network on the GPU machine, bring .device-wheels/ (scripts/device_wheels.sh) with the tree:
# they are installed into a virtual environment over the machine's own Python packages.
set -uo pipefail
cd "$(dirname "$0")/.."
OUT=${OUT:-device-check}
SECTIONS=${SECTIONS:-tests,gpu,envs}
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
"$V" -c 'import torch; print("torch", torch.__version__, "cuda", torch.cuda.is_available())' >>"$OUT/versions.txt" 2>&1
has() { [[ ",$SECTIONS," == *",$1,"* ]]; }
status=0
if has tests; then
    timeout 240 "$V" -m pytest -p no:cacheprovider -q tests/device >"$OUT/device-tests.txt" 2>&1 || status=1
    tail -n 3 "$OUT/device-tests.txt"
fi
if has gpu; then
    timeout 480 "$V" -m bluesky_gym bench gpu --json "$OUT/gpu.json" >"$OUT/gpu.txt" 2>&1 || status=1
    cat "$OUT/gpu.txt"
fi
if has envs; then
    if "$V" -c 'import sys, torch; sys.exit(0 if torch.cuda.is_available() else 1)' >/dev/null 2>&1; then
        timeout 300 "$V" -m bluesky_gym bench gpu --envs --json "$OUT/gpu-envs.json" >"$OUT/gpu-envs.txt" 2>&1 || status=1
    else
        echo "bench gpu --envs skipped: PyTorch with CUDA is not installed on this machine" >"$OUT/gpu-envs.txt"
    fi
    cat "$OUT/gpu-envs.txt"
fi
exit $status
