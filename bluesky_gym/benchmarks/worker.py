"""Benchmark worker run in another Python interpreter (as a script, by file path).

The real BlueSky 1.1.1 does not run with every numpy version, has one global simulator per
process, and the reference implementation (bluesky-gym 0.2.0) is a package that is also called
``bluesky_gym``. So the figures of BlueSky, of this project's BlueSky backend and of the reference
are measured in a separate interpreter, one process per measurement, by this script::

    python worker.py MODE CONFIG_JSON OUT_JSON

Modes:

* ``bluesky-core``: ``bs.sim.step()`` of one airspace with the aircraft given in the config.
* ``bluesky-scale``: ``bs.sim.step()`` flying the aircraft of a file for a simulated time, with and
  without conflict detection and resolution.
* ``backend-env``: ``gym.make(env_id, backend="bluesky")`` of this project, single environment.
  The config's ``package_root`` is a folder holding only this project's ``bluesky_gym`` package;
  it is put first on ``sys.path``.
* ``reference-env``: ``gym.make(env_id)`` of the installed reference package (checked to be
  bluesky-gym 0.2.0).

The script imports only the standard library at module level, plus :mod:`timing` from its own
folder, so that it runs whatever the other interpreter has installed. The result (or the error)
is written to OUT_JSON.
"""

from __future__ import annotations

import json
import os
import platform
import sys
import traceback
import warnings
from typing import Any

if __package__:
    from bluesky_gym.benchmarks.timing import env_step_rate, measure
else:  # run as a script: timing.py is in this script's folder (sys.path[0])
    from timing import env_step_rate, measure  # type: ignore[no-redef,import-not-found]

REFERENCE_VERSION = "0.2.0"


def _versions(*dists: str) -> dict[str, str]:
    from importlib import metadata

    out = {"python": platform.python_version()}
    for name in dists:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = "not installed"
    return out


def _init_bluesky() -> Any:
    """Start BlueSky headless (once per process), as the reference environments do."""
    import bluesky as bs

    if bs.sim is None:
        bs.init(mode="sim", detached=True)
    return bs


def bluesky_core(config: dict[str, Any]) -> dict[str, Any]:
    """Time ``bs.sim.step()`` for each aircraft set of the config.

    Config keys: ``seconds`` (budget per set), ``dt`` [s], ``sets``: a list of aircraft lists,
    each aircraft ``[lat, lon, hdg, alt, cas, turn]`` (deg, deg, deg, m, m/s CAS, turn angle of
    the heading commands in deg; 0 = no turn). Turning aircraft get a new heading target
    ``hdg + turn`` before every timed block (untimed), so they keep turning.
    """
    import numpy as np

    bs = _init_bluesky()
    results = []
    for aircraft in config["sets"]:
        bs.traf.reset()
        bs.stack.stack(f"DT {config['dt']};FF")
        for i, (lat, lon, hdg, alt, cas, _turn) in enumerate(aircraft):
            ok = bs.traf.cre(f"AC{i:03d}", "A320", float(lat), float(lon), float(hdg), float(alt), float(cas))
            if ok is not True:
                raise RuntimeError(f"BlueSky refused to create aircraft {i}: {ok}")
        turning = np.array([i for i, ac in enumerate(aircraft) if ac[5] != 0.0], dtype=np.int64)
        turn = np.array([ac[5] for ac in aircraft if ac[5] != 0.0])

        def recommand(turning: Any = turning, turn: Any = turn) -> None:
            if turning.size:
                bs.traf.ap.selhdgcmd(turning, (bs.traf.hdg[turning] + turn) % 360.0)

        recommand()
        bs.sim.step()  # processes the DT command
        n = len(aircraft)
        res = measure(bs.sim.step, float(n), float(config["seconds"]), between=recommand)
        if bs.traf.ntraf != n:
            raise RuntimeError(f"expected {n} aircraft after the run, BlueSky has {bs.traf.ntraf}")
        res["aircraft"] = n
        results.append(res)
    return {"versions": _versions("bluesky-simulator", "numpy"), "results": results}


def bluesky_scale(config: dict[str, Any]) -> dict[str, Any]:
    """Wall-clock time of ``bs.sim.step()`` flying the given aircraft for a simulated time, per CD&R setting.

    Config keys: ``aircraft_file`` (a JSON list of ``[lat, lon, hdg, alt, cas]``: deg, deg, deg,
    m, m/s CAS), ``sim_time`` [s], ``dt`` [s], ``cdr``: a list of booleans, one flight each (with
    CD&R: ``ASAS CSTATEBASED`` and ``RESO MVP``). Only the steps are timed.
    """
    import time

    bs = _init_bluesky()
    with open(config["aircraft_file"], encoding="utf-8") as fh:
        aircraft = json.load(fh)
    steps = round(float(config["sim_time"]) / float(config["dt"]))
    results = []
    for cdr in config["cdr"]:
        bs.traf.reset()
        setup = f"DT {config['dt']};FF" + (";ASAS CSTATEBASED;RESO MVP" if cdr else ";ASAS OFF;RESO OFF")
        bs.stack.stack(setup)
        bs.sim.step()  # processes the commands
        for i, (lat, lon, hdg, alt, cas) in enumerate(aircraft):
            ok = bs.traf.cre(f"AC{i:06d}", "A320", float(lat), float(lon), float(hdg), float(alt), float(cas))
            if ok is not True:
                raise RuntimeError(f"BlueSky refused to create aircraft {i}: {ok}")
        t0 = bs.sim.simt
        start = time.perf_counter()
        for _ in range(steps):
            bs.sim.step()
        wall = time.perf_counter() - start
        if bs.traf.ntraf != len(aircraft):
            raise RuntimeError(f"expected {len(aircraft)} aircraft after the flight, BlueSky has {bs.traf.ntraf}")
        if abs(bs.sim.simt - t0 - steps * float(config["dt"])) > 1e-6:
            raise RuntimeError(f"BlueSky flew {bs.sim.simt - t0} s instead of {steps * float(config['dt'])} s")
        methods = (bs.traf.cd.selected().__name__, bs.traf.cr.selected().__name__)
        results.append({"cdr": bool(cdr), "wall_s": wall, "steps": steps, "detection": methods[0], "resolution": methods[1]})
    return {"versions": _versions("bluesky-simulator", "numpy"), "results": results}


def backend_env(config: dict[str, Any]) -> dict[str, Any]:
    """Single-environment steps per second of this project's BlueSky backend.

    Config keys: ``env_id``, ``seconds``, ``seed``, ``package_root``.
    """
    sys.path.insert(0, config["package_root"])
    import gymnasium as gym

    import bluesky_gym

    bluesky_gym.register_envs()
    env = gym.make(config["env_id"], backend="bluesky")
    try:
        res = env_step_rate(env, float(config["seconds"]), seed=int(config["seed"]))
    finally:
        env.close()
    versions = _versions("bluesky-simulator", "numpy", "gymnasium")
    versions["bluesky_gym"] = getattr(bluesky_gym, "__version__", "?")
    return {"versions": versions, "result": res}


def reference_env(config: dict[str, Any]) -> dict[str, Any]:
    """Single-environment steps per second of the reference package (bluesky-gym 0.2.0).

    Config keys: ``env_id``, ``seconds``, ``seed``. The reference draws its scenarios from the
    global numpy generator, which is seeded with ``seed``.
    """
    versions = _versions("bluesky-gym", "bluesky-simulator", "numpy", "gymnasium")
    if versions["bluesky-gym"] != REFERENCE_VERSION:
        found = versions["bluesky-gym"]
        raise RuntimeError(f"the reference interpreter must have bluesky-gym=={REFERENCE_VERSION} installed, found {found}")
    import gymnasium as gym
    import numpy as np

    import bluesky_gym

    if hasattr(bluesky_gym, "available_envs"):  # this project's package, not the reference
        raise RuntimeError(f"'import bluesky_gym' found this project ({bluesky_gym.__file__}), not the reference package")
    bluesky_gym.register_envs()
    np.random.seed(int(config["seed"]))
    env = gym.make(config["env_id"])
    try:
        res = env_step_rate(env, float(config["seconds"]), seed=int(config["seed"]))
    finally:
        env.close()
    return {"versions": versions, "result": res}


MODES = {"bluesky-core": bluesky_core, "bluesky-scale": bluesky_scale, "backend-env": backend_env, "reference-env": reference_env}


def main(argv: list[str]) -> int:
    """Run one measurement; returns the exit code (the result or the error is in OUT_JSON)."""
    if len(argv) != 3 or argv[0] not in MODES:
        print(f"usage: worker.py {{{','.join(MODES)}}} CONFIG_JSON OUT_JSON", file=sys.stderr)
        return 2
    mode, config, out_path = argv[0], json.loads(argv[1]), argv[2]
    warnings.simplefilter("ignore")
    try:
        # BlueSky and the reference print progress; keep stdout for them, results go to the file.
        out: dict[str, Any] = MODES[mode](config)
        code = 0
    except Exception as exc:  # noqa: BLE001 - reported to the parent, which shows it in the table
        out = {"error": f"{type(exc).__name__}: {exc}", "traceback": traceback.format_exc()}
        code = 1
    out["pid"] = os.getpid()
    with open(out_path, "w", encoding="utf-8") as fh:
        json.dump(out, fh)
    return code


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
