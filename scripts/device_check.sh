#!/usr/bin/env bash
# The device check, as one script, on a machine with a CUDA GPU (docs/backends.md, "On a GPU").
# Sections (SECTIONS, comma-separated; default gpu,envs,ppo: at most about 8 minutes together, each
# section capped by its --budget and a hard timeout):
#   gpu:   `bluesky-gym bench gpu --budget 140`: fidelity over a sample and physics throughput, device
#          and CPU side by side (hard cap 170 s);
#   envs:  `bluesky-gym bench gpu --envs --budget 110`: the ids whose step runs on the device first
#          (SectorCR), every id's gym.make_vec(..., device="cuda") against its CPU vector environment
#          (the same seeded episodes) and env-steps/s side by side (hard cap 140 s);
#   ppo:   `bluesky-gym bench gpu --ppo --budget 130`: the fast PPO trainer end to end on
#          SectorCREnv-v1, environments on the CPU and on the device, learner on the GPU, env-steps/s
#          (hard cap 160 s);
#   tests: (not in the default) the device tests (tests/device) on the GPU (hard cap 240 s).
# envs needs PyTorch with CUDA on the machine, ppo also Stable-Baselines3 (its wheel comes with
# .device-wheels/) and pandas; without them the section says so and is skipped.
# E.g. SECTIONS=ppo bash scripts/device_check.sh, or SECTIONS=gpu,envs,ppo,tests.
# Outputs go to $OUT (default: device-check/): versions.txt, device-tests.txt, gpu.txt, gpu.json,
# gpu-envs.txt, gpu-envs.json, gpu-ppo.txt, gpu-ppo.json.
# Without network on the GPU machine, bring .device-wheels/ (scripts/device_wheels.sh) with the tree:
# they are installed into a virtual environment over the machine's own Python packages.
set -uo pipefail
cd "$(dirname "$0")/.."
OUT=${OUT:-device-check}
SECTIONS=${SECTIONS:-gpu,envs,ppo}
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
    timeout 170 "$V" -m bluesky_gym bench gpu --budget 140 --json "$OUT/gpu.json" >"$OUT/gpu.txt" 2>&1 || status=1
    cat "$OUT/gpu.txt"
fi
if has envs; then
    if "$V" -c 'import sys, torch; sys.exit(0 if torch.cuda.is_available() else 1)' >/dev/null 2>&1; then
        timeout 140 "$V" -m bluesky_gym bench gpu --envs --budget 110 --json "$OUT/gpu-envs.json" >"$OUT/gpu-envs.txt" 2>&1 || status=1
    else
        echo "bench gpu --envs skipped: PyTorch with CUDA is not installed on this machine" >"$OUT/gpu-envs.txt"
    fi
    cat "$OUT/gpu-envs.txt"
fi
if has ppo; then
    if "$V" -c 'import sys, torch, stable_baselines3, pandas; sys.exit(0 if torch.cuda.is_available() else 1)' >/dev/null 2>&1; then
        timeout 160 "$V" -m bluesky_gym bench gpu --ppo --budget 130 --json "$OUT/gpu-ppo.json" >"$OUT/gpu-ppo.txt" 2>&1 || status=1
    else
        echo "bench gpu --ppo skipped: PyTorch with CUDA, Stable-Baselines3 or pandas is not installed on this machine" >"$OUT/gpu-ppo.txt"
    fi
    cat "$OUT/gpu-ppo.txt"
fi
exit $status
