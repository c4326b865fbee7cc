#!/usr/bin/env bash
# Set up the test environments (idempotent), run the static checks and the whole test suite.
#   .venv          everything but the BlueSky backend (numpy >= 2.4 allowed), with the gpu extra
#   .venv-bluesky  the real BlueSky 1.1.1 backend (needs numpy < 2.4) for the parity tests, with pyclipper
#                  (the ssd extra) for BlueSky's SSD plugin
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3}

if [ ! -x .venv/bin/python ]; then "$PY" -m venv .venv; fi
.venv/bin/python -m pip install -q --upgrade pip
.venv/bin/python -m pip install -q -e ".[all,gpu]"

if [ ! -x .venv-bluesky/bin/python ]; then "$PY" -m venv .venv-bluesky; fi
.venv-bluesky/bin/python -m pip install -q --upgrade pip
.venv-bluesky/bin/python -m pip install -q -e ".[bluesky,ssd,test]"

# Lint, format check and type check (scripts/lint.sh).
PYTHON=.venv/bin/python bash scripts/lint.sh

# An empty recorded-traffic cache, as on a fresh machine: the site and the tests must not depend on
# data prepared earlier (the tests play small stand-ins of the sample collections, tests/conftest.py).
BLUESKY_GYM_CACHE="$(mktemp -d)"
export BLUESKY_GYM_CACHE
trap 'rm -rf "$BLUESKY_GYM_CACHE"' EXIT

# The documentation site (mkdocs.yml), warnings as errors, into the ignored site/ folder;
# tests/docs/test_site.py then opens every page of this build in a headless browser.
export BLUESKY_GYM_SITE_DIR="$PWD/site"
# (Not --quiet: it hides the warnings from --strict, which then passes a build that warns.)
NO_MKDOCS_2_WARNING=1 .venv/bin/python -m mkdocs build --strict --site-dir "$BLUESKY_GYM_SITE_DIR"

export SDL_VIDEODRIVER=dummy SDL_AUDIODRIVER=dummy MPLBACKEND=Agg
# On CPUs with AVX-512, numpy >= 2 computes sin, cos, exp, pow... with its own SIMD loops, which
# differ from the C library in the last bit. BlueSky itself computes with numpy, and the bit-exact
# tests (numpy oracles against the kernels, BlueSky parity and recordings) compare with numpy's
# portable loops, so numpy's AVX-512 dispatch is turned off for both test runs. The package's own
# kernels call the C library and do not depend on this setting.
export NPY_DISABLE_CPU_FEATURES="X86_V4 AVX512_ICL AVX512_SPR AVX512F AVX512CD AVX512_SKX AVX512_CLX AVX512_CNL"

# Native suite (slow tests included), on both cores, then the CUDA target without a GPU: every
# kernel of core/, tasks/ and the environment folders compiled to PTX (NVVM from the gpu extra's
# toolkit wheels), then the device logic under numba-cuda's simulator at small sizes. The line
# coverage of the package is measured over both test runs (the device logic runs only in the second)
# with a floor at the figure measured when it was set (numba-compiled kernel bodies cannot be traced
# and are left out: [tool.coverage.report] in pyproject.toml). The floor holds for the whole suite
# only: a run narrowed by arguments (-k, paths) reports coverage.
COVERAGE_FLOOR=91  # measured 91.1% over both runs (18078 statements, 1613 missed), 2026-11-27
.venv/bin/python -m pytest -n 2 -p no:cacheprovider -m "not bluesky" --cov=bluesky_gym --cov-report= "$@"
.venv/bin/python -m bluesky_gym bench gpu --compile-only --quiet
DEVICE_COVERAGE=(--cov=bluesky_gym --cov-append --cov-report=term:skip-covered)
if [ $# -eq 0 ]; then DEVICE_COVERAGE+=(--cov-fail-under="$COVERAGE_FLOOR"); fi
NUMBA_ENABLE_CUDASIM=1 .venv/bin/python -m pytest -n 2 -p no:cacheprovider "${DEVICE_COVERAGE[@]}" tests/device
# BlueSky backend: parity with the native core, episode by episode.
.venv-bluesky/bin/python -m pytest -n 2 -p no:cacheprovider -m bluesky "$@"
