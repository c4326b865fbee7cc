#!/usr/bin/env bash
# Set up the test environments (idempotent) and run the whole test suite.
#   .venv          everything but the BlueSky backend (numpy >= 2.4 allowed)
#   .venv-bluesky  the real BlueSky 1.1.1 backend (needs numpy < 2.4) for the parity tests
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3}

if [ ! -x .venv/bin/python ]; then "$PY" -m venv .venv; fi
.venv/bin/python -m pip install -q --upgrade pip
.venv/bin/python -m pip install -q -e ".[all]"

if [ ! -x .venv-bluesky/bin/python ]; then "$PY" -m venv .venv-bluesky; fi
.venv-bluesky/bin/python -m pip install -q --upgrade pip
.venv-bluesky/bin/python -m pip install -q -e ".[bluesky,fast,test]"

export SDL_VIDEODRIVER=dummy SDL_AUDIODRIVER=dummy MPLBACKEND=Agg

# Native suite (slow tests included), on both cores.
.venv/bin/python -m pytest -n 2 -p no:cacheprovider -m "not bluesky" "$@"
# BlueSky backend: parity with the native core, episode by episode.
.venv-bluesky/bin/python -m pytest -n 2 -p no:cacheprovider -m bluesky "$@"
