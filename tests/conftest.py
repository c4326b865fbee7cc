"""Settings of the whole test suite: nothing is written to the home directory.

BlueSky keeps its working directory (settings, navigation cache) in ``~/bluesky`` unless told
otherwise, Ray its session files in the temporary directory and its usage-statistics settings in
``~/.ray``, Matplotlib its font cache in ``~/.config``. The tests point all of them to one scratch
directory in the system's temporary directory (kept between runs, so BlueSky's navigation cache is
built once). Subprocesses started by the tests inherit the settings.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

SCRATCH = Path(tempfile.gettempdir()) / f"bluesky-gym-tests-{os.getuid() if hasattr(os, 'getuid') else 'user'}"

os.environ.setdefault("BLUESKY_GYM_BLUESKY_WORKDIR", str(SCRATCH / "bluesky"))
os.environ.setdefault("RAY_TMPDIR", str(SCRATCH / "ray"))
os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
os.environ.setdefault("RAY_USAGE_STATS_CONFIG_PATH", str(SCRATCH / "ray-usage.json"))
os.environ.setdefault("MPLCONFIGDIR", str(SCRATCH / "matplotlib"))
