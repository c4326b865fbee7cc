"""Settings of the whole test suite: nothing is written to the home directory.

BlueSky keeps its working directory (settings, navigation cache) in ``~/bluesky`` unless told
otherwise, Ray its session files in the temporary directory and its usage-statistics settings and
cluster token in ``~/.ray``, Matplotlib its font cache in ``~/.config``, the ``traffic`` library
its settings and cache in ``~/.config/traffic`` and ``~/.cache/traffic`` (the XDG directories), and
recorded-traffic episode data goes to ``$BLUESKY_GYM_CACHE``. The tests point all of them to one scratch
directory in the system's temporary directory (kept between runs, so BlueSky's navigation cache is
built once). Subprocesses started by the tests inherit the settings.

The recorded-traffic cache is the exception: every test process starts with an empty cache
directory of its own (whatever ``BLUESKY_GYM_CACHE`` says outside, and removed at the end), as on a
fresh machine, so no test depends on data prepared by an earlier run, and none reads or writes a
user's cache. Cleaning the ``traffic`` library's sample collections takes minutes; the tests that
make ``RealTrafficCREnv`` with its default collections (the contract, render and CLI tests) play
small synthetic stand-ins that :func:`recorded_traffic_stand_ins` saves under the sample names
there, once per test process. The cleaning itself is tested on tables and excerpts of a few flights.
"""

from __future__ import annotations

import atexit
import os
import shutil
import tempfile
from pathlib import Path

import pytest

SCRATCH = Path(tempfile.gettempdir()) / f"bluesky-gym-tests-{os.getuid() if hasattr(os, 'getuid') else 'user'}"

os.environ.setdefault("BLUESKY_GYM_BLUESKY_WORKDIR", str(SCRATCH / "bluesky"))
os.environ.setdefault("RAY_TMPDIR", str(SCRATCH / "ray"))
os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
os.environ.setdefault("RAY_USAGE_STATS_CONFIG_PATH", str(SCRATCH / "ray-usage.json"))
# Ray >= 2.5x protects a new local cluster with a token that it saves in ~/.ray; the tests' local
# clusters live only as long as one test, on this machine, so they run without one.
os.environ.setdefault("RAY_AUTH_MODE", "disabled")
os.environ.setdefault("MPLCONFIGDIR", str(SCRATCH / "matplotlib"))
os.environ.setdefault("XDG_CONFIG_HOME", str(SCRATCH / "config"))
os.environ.setdefault("XDG_CACHE_HOME", str(SCRATCH / "cache"))
SCRATCH.mkdir(parents=True, exist_ok=True)
RECORDED_TRAFFIC_CACHE = Path(tempfile.mkdtemp(prefix="bluesky-gym-cache-", dir=SCRATCH))
os.environ["BLUESKY_GYM_CACHE"] = str(RECORDED_TRAFFIC_CACHE)
atexit.register(shutil.rmtree, RECORDED_TRAFFIC_CACHE, ignore_errors=True)
# One intra-op thread for PyTorch (read when torch is imported): the tests' networks are small, and
# on a loaded 2-core machine threads that wait for each other made one training test 10x slower.
os.environ.setdefault("OMP_NUM_THREADS", "1")


def pytest_ignore_collect(collection_path: Path, config: pytest.Config) -> bool | None:
    """Leave out test modules that the run's marker expression deselects entirely.

    ``scripts/test.sh`` runs ``-m "not bluesky"`` in the main environment and ``-m bluesky`` in the
    BlueSky one. A module is imported before its tests are deselected, and a module that needs a
    package the environment lacks (BlueSky in the one, Stable-Baselines3 in the other) would be
    reported as skipped although none of its tests was meant to run there.
    """
    if collection_path.suffix != ".py" or not collection_path.name.startswith("test_"):
        return None
    expression = " ".join(str(config.getoption("markexpr") or "").split())
    if expression not in ("bluesky", "not bluesky"):
        return None
    text = collection_path.read_text(encoding="utf-8")
    if expression == "not bluesky" and "pytestmark = pytest.mark.bluesky" in text:
        return True
    if expression == "bluesky" and "mark.bluesky" not in text:
        return True
    return None


@pytest.fixture(scope="session", autouse=True)
def recorded_traffic_stand_ins() -> None:
    """Small synthetic collections under the names of the sample collections, in this process's empty cache directory.

    ``RealTrafficCREnv`` made with its defaults then plays them instead of cleaning the samples
    (minutes); what the environments do with a collection does not depend on where it came from.
    """
    from bluesky_gym.realtraffic.cache import collection_path
    from bluesky_gym.realtraffic.sources import SAMPLE_COLLECTIONS

    from .realtraffic.synthetic import traffic_collection

    for k, name in enumerate(SAMPLE_COLLECTIONS):
        path = collection_path(name)
        assert path.is_relative_to(RECORDED_TRAFFIC_CACHE), f"{path}: the tests' recorded-traffic cache moved"
        if not path.exists():
            traffic_collection(n_flights=40 - 16 * k, spacing_s=90.0 + 60.0 * k, seed=1 + k).save(path)


def same_values(a: object, b: object) -> bool:
    """Whether two nested results (dicts, lists, tuples of arrays and scalars) hold the same values, NaN equal to NaN."""
    import numpy as np

    if isinstance(a, dict):
        return isinstance(b, dict) and a.keys() == b.keys() and all(same_values(a[k], b[k]) for k in a)
    if isinstance(a, (list, tuple)):
        return isinstance(b, (list, tuple)) and len(a) == len(b) and all(same_values(x, y) for x, y in zip(a, b, strict=True))
    x, y = np.asarray(a), np.asarray(b)
    return bool(np.array_equal(x, y, equal_nan=x.dtype.kind in "fc" and y.dtype.kind in "fc"))
