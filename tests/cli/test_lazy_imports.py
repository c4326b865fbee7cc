"""Commands import what they use: ``list`` builds every environment without OpenAP, training or plotting, and ``import bluesky_gym`` is light."""

from __future__ import annotations

import json
import os
import subprocess
import sys

from .conftest import ROOT

#: Modules ``bluesky-gym list`` has no use for: aircraft performance data (read when an aircraft
#: is created), the multi-agent training, evaluation and policies, training and plotting libraries.
NOT_FOR_LISTING = (
    "openap",
    "pandas",
    "scipy.signal",
    "bluesky_gym.multiagent.evaluation",
    "bluesky_gym.multiagent.policies",
    "bluesky_gym.training.evaluation",
    "torch",
    "stable_baselines3",
    "matplotlib",
    "pygame",
)


def _modules_after(code: str) -> set[str]:
    """The modules a fresh interpreter has imported after running ``code`` (with this checkout first on the path)."""
    script = f"import json, sys\n{code}\nprint(json.dumps(sorted(sys.modules)), file=sys.stderr)"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300, env=env, cwd=ROOT, check=True)
    return set(json.loads(out.stderr.strip().splitlines()[-1]))


def test_list_imports_only_what_listing_needs() -> None:
    modules = _modules_after(
        "import contextlib, io\nfrom bluesky_gym.cli import main\nwith contextlib.redirect_stdout(io.StringIO()):\n    main(['list'])"
    )
    assert "bluesky_gym.environments.merge.env" in modules  # it did build the environments
    assert not {m for m in NOT_FOR_LISTING if m in modules}


def test_importing_the_package_does_not_import_the_physics() -> None:
    modules = _modules_after("import bluesky_gym")
    assert not {m for m in ("numba", "bluesky_gym.core.simulator", "openap", "scipy") if m in modules}


def test_the_default_type_is_read_when_an_aircraft_needs_it() -> None:
    """A simulator reads the A320's data at its first aircraft, with the same values as before."""
    modules = _modules_after(
        "from bluesky_gym.core import Simulator\n"
        "sim = Simulator(1, 2)\n"
        "assert 'openap' not in sys.modules\n"
        "sim.create(0, 0, lat=52.0, lon=4.0, hdg=0.0, alt=3000.0, spd=150.0)\n"
        "from bluesky_gym.core.aircraft import aircraft_performance\n"
        "assert sim.perf == aircraft_performance('A320') and sim.aircraft_types == ('A320',)\n"
        "assert sim.vmin[0, 0] == sim.perf.vmin_enroute"
    )
    assert "openap" in modules
