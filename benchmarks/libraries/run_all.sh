#!/usr/bin/env bash
# Runs every harness one after another (SB3 first and last) and writes results/results.{jsonl,json,md}.
# Usage: bash run_all.sh [--quick] [results-dir]
set -u
HERE="$(cd "$(dirname "$0")" && pwd)"
QUICK=""
if [ "${1:-}" = "--quick" ]; then QUICK="--quick"; shift; fi
OUT="${1:-$HERE/results}"
mkdir -p "$OUT"
J="$OUT/results.jsonl"
: > "$J"
LOG="$OUT/run_all.log"
: > "$LOG"

# Same conditions for all: one BLAS/OpenMP thread, torch.set_num_threads(1) in the harnesses,
# XLA (SBX) single-threaded, CPU only.
export OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1
export XLA_FLAGS="--xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1"
export JAX_PLATFORMS=cpu CUDA_VISIBLE_DEVICES=""
export PYTHONUNBUFFERED=1 PYTHONWARNINGS="ignore::DeprecationWarning"

V="$HERE/venv/bin/python"          # torchrl, skrl, rl_games, sbx, sb3
VP="$HERE/venv-puffer/bin/python"  # pufferlib (needs gym 0.23 and a source build)
H="$HERE"

run() {  # run LABEL PYTHON SCRIPT SETTING
  local label=$1 py=$2 script=$3 s=$4
  echo "=== $(date +%T) $label $s  load: $(cut -d' ' -f1-3 /proc/loadavg)" | tee -a "$LOG"
  ( cd "$H" && timeout 900 "$py" "$H/$script" --setting "$s" --out "$J" $QUICK ) >> "$LOG" 2>&1
  local rc=$?
  if [ $rc -ne 0 ]; then
    echo "    exit code $rc" | tee -a "$LOG"
    printf '{"candidate": "%s", "setting": "%s", "status": "error", "error": "harness exited with code %s (see run_all.log)"}\n' "$label" "$s" "$rc" >> "$J"
  fi
  tail -n 1 "$J" | cut -c1-300
}

echo "start $(date -Is) on $(nproc --all) cores; $(uptime)" | tee -a "$LOG"
for s in A B C; do run env-only "$V" env_only.py $s; done
for s in A B C; do run sb3 "$V" sb3_harness.py $s; done
for s in A B C; do run torchrl "$V" torchrl_harness.py $s; done
for s in A B C; do run skrl "$V" skrl_harness.py $s; done
for s in A B C; do run rl_games "$V" rl_games_harness.py $s; done
for s in A B C; do run pufferlib "$VP" pufferlib_harness.py $s; done
for s in A B C; do run sbx "$V" sbx_harness.py $s; done
for s in A B C; do run fast "$V" fast_harness.py $s; done
for s in A B C; do run sb3 "$V" sb3_harness.py $s; done
for s in A B C; do run env-only "$V" env_only.py $s; done
echo "end $(date -Is); $(uptime)" | tee -a "$LOG"

python3 "$H/aggregate.py" "$J" "$OUT"
