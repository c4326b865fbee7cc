#!/usr/bin/env bash
# Static checks, as CI runs them: ruff lint, ruff format check, mypy, no tracked file over 500 KiB.
# Uses $PYTHON (default: .venv/bin/python, else python3); runs every check and fails if any failed.
# The package's layering (no import cycles, no upward imports) is a test: tests/test_layering.py.
set -uo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-.venv/bin/python}
if [ ! -x "$PY" ]; then PY=python3; fi

status=0
run() {
    echo "+ $*"
    "$@" || status=1
}
run "$PY" -m ruff check .
run "$PY" -m ruff format --check .
run "$PY" -m mypy bluesky_gym
run "$PY" scripts/check_file_sizes.py
exit $status
