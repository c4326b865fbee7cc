"""The CUDA target measured and checked: ``bluesky-gym bench gpu``.

Two parts:

* :func:`compile_all` (``--compile-only``): every kernel of ``bluesky_gym.core`` and
  ``bluesky_gym.tasks`` compiled to PTX by numba-cuda, without a GPU (NVVM from the CUDA
  toolkit's wheels), for every argument-type signature the package calls it with on the CPU.
  Those signatures are numba's own record of the CPU calls: :func:`exercise_kernels` first runs
  the simulator and every environment briefly on the CPU. A kernel that fails to compile, or
  that the exercise never reached, is a failure.
* :func:`device_check` (the default): on a machine with a CUDA GPU, the device simulator
  (:class:`bluesky_gym.core.DeviceSimulator`) against the CPU core of the same machine, in at
  most :data:`DEVICE_CHECK_BUDGET` seconds: agreement of the two over a sample of airspaces
  (against the project's tolerances) and aircraft-sub-steps per second side by side.
* :func:`device_envs` (``--envs``): on a machine with a CUDA GPU, every id's vector
  environment made with ``device="cuda"`` against its CPU one: the same seeded episodes compared,
  and environment steps per second side by side.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from bluesky_gym.benchmarks.core_bench import core_scenario, make_simulator, populate

#: Packages whose kernels the compile-only check covers (an environment folder's task may hold kernels too; of the
#: recorded traffic, the replay's: the cleaning of recordings runs on the host only).
KERNEL_PACKAGES = (
    "bluesky_gym.core.",
    "bluesky_gym.tasks.",
    "bluesky_gym.realtraffic.flights.",
    "bluesky_gym.realtraffic.scenario.",
    "bluesky_gym.environments.",
)
#: Wall-clock budget of the device check [s] (the issue's limit: 8 minutes).
DEVICE_CHECK_BUDGET = 480.0
#: Aircraft per airspace of the physics measurement (the benchmark traffic of ``bench core``).
PHYSICS_AIRCRAFT = 20
#: Airspaces of the physics measurement on the device: 2^10 .. 2^16 (20 aircraft each: 20k .. 1.3M aircraft).
DEVICE_BATCHES = tuple(2**k for k in (10, 12, 14, 16))
#: Airspaces of the CPU reference line (one core).
CPU_BATCH = 4096
#: Sub-steps per timed launch of the independent-aircraft run kernel.
SUBSTEPS = 30
#: Fidelity sample: airspaces, aircraft each, steps.
FIDELITY_SAMPLE = (1024, PHYSICS_AIRCRAFT, 300)
#: The project's fidelity tolerances: position [m], speeds [m/s], angles [deg].
TOLERANCE_M = 1e-6
TOLERANCE_MS = 1e-9
TOLERANCE_DEG = 1e-9
#: Metres per degree of latitude used to express latitude differences in metres.
M_PER_DEG_LAT = 111319.49
#: Targets of the issue on one H100 [aircraft-sub-steps/s].
TARGET_PHYSICS_RATE = 5e9
#: Rows (episodes) of the task-kernel measurement on the device: 2^10 .. 2^20, and on the CPU.
TASK_ROWS = tuple(2**k for k in (10, 14, 17, 20))
TASK_ROWS_CPU = 2**14
#: Intruders observed per row (SectorCR's and Merge's observation size).
TASK_INTRUDERS = 5

Say = Callable[[str], None] | None


# --- compile-only ----------------------------------------------------------------------------
def exercise_kernels(say: Say = None) -> list[str]:
    """Run the simulator and every environment briefly on the CPU, so that numba records the argument types of every kernel.

    Returns:
        What could not be run (``"id: reason"``); the kernels only they reach then stay without signatures.
    """
    problems: list[str] = []
    if say is not None:
        say("exercise: simulator")
    _exercise_core()
    import gymnasium as gym

    from bluesky_gym.envs.registry import entry
    from bluesky_gym.registration import available_envs, register_envs

    register_envs()
    for env_id in available_envs():
        status = entry(env_id).data_status()
        if status is not None:  # preparing recorded data is no part of a compile check
            problems.append(f"{env_id}: its data are not prepared ({status})")
            continue
        if say is not None:
            say(f"exercise: {env_id}")
        try:
            _exercise_env(gym, env_id)
        except Exception as exc:  # noqa: BLE001 - reported, and the kernels it alone reaches show as unexercised
            problems.append(f"{env_id}: {type(exc).__name__}: {exc}")
    try:
        from bluesky_gym.envs.registry import multiagent_entries
        from bluesky_gym.multiagent import parallel_env
    except ImportError as exc:
        problems.append(f"multi-agent environments: {exc}")
    else:
        for ma in multiagent_entries():
            if say is not None:
                say(f"exercise: {ma.name} (multi-agent)")
            try:
                env = parallel_env(ma.name)
                env.reset(seed=0)
                for _ in range(3):
                    env.step({agent: env.action_space(agent).sample() for agent in env.agents})
                env.close()
            except Exception as exc:  # noqa: BLE001
                problems.append(f"{ma.name}: {type(exc).__name__}: {exc}")
    return problems


def _exercise_env(gym: Any, env_id: str) -> None:
    env = gym.make(env_id)
    env.action_space.seed(0)
    env.reset(seed=0)
    for _ in range(3):
        env.step(env.action_space.sample())
    env.close()
    # Episodes of 2 steps: they end (the KPIs) and are reset within the 3 steps.
    venv = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point", max_episode_steps=2)
    venv.action_space.seed(0)
    venv.reset(seed=0)
    for _ in range(3):
        venv.step(venv.action_space.sample())
    venv.close()


def _exercise_core() -> None:
    """The simulator's own paths: creation (mixed types), routes and LNAV, wind, runs with traces and stops, creconfs, ASAS with MVP, geometry.

    ASAS runs with both pair searches (all pairs and the grid).
    """
    from bluesky_gym.core import Simulator, atmosphere, geo, lnav
    from bluesky_gym.core.conflicts import detect_pairs
    from bluesky_gym.core.resolution import AsasConfig, mvp_pairs

    sim = Simulator(3, 4, dt=1.0)
    sim.create([0, 1, 2], 0, [52.0, 52.1, 51.9], [4.0, 4.1, 3.9], [0.0, 90.0, 180.0], 3000.0, [140.0, 0.6, 150.0], actype=["A320", "B738", "A320"])
    sim.add_waypoint([0, 1], 0, [52.3, 52.2], [4.2, 4.3])
    sim.set_destination([0, 1], 0, [52.5, 52.4], [4.5, 4.6])
    sim.creconfs([0, 1], 0, 1, 20.0, 1.0, 200.0)
    sim.creconfs([2], 0, 1, 30.0, 0.5, 150.0, dh=300.0, spd=150.0)
    sim.wind.add_points(0, [52.0], [4.0], [5.0], [3.0])
    sim.step()
    sim.run(3)
    sim.run(3, trace=True)
    sim.run(4, stop=lambda track: np.full(sim.n_envs, 2))
    sim.wind.add_points(1, [52.0, 53.0], [4.0, 5.0], [5.0, -3.0], [3.0, 1.0])
    sim.run(2)
    sim.set_conflict_resolution([0, 1, 2], AsasConfig(detector="CSTATEBASED", resolution=True))
    sim.run(3)
    grid = Simulator(2, 4, dt=1.0, pair_search="grid")  # the grid's pair search (CPU only; its kernels must compile all the same)
    grid.create([0, 0, 1, 1], [0, 1, 0, 1], [52.0, 52.1, 52.0, 52.0], [4.0, 4.0, 4.0, 4.1], [0.0, 180.0, 90.0, 270.0], 3000.0, 140.0)
    grid.alt[1, 1] = np.nan  # an airspace searched exhaustively
    grid.set_conflict_resolution([0, 1], AsasConfig(detector="CSTATEBASED", resolution=True))
    grid.run(2)
    mvp_pairs(grid, detect_pairs(grid.lat, grid.lon, grid.alt, grid.gs, grid.trk, grid.vs, grid.active))  # MVP of listed pairs (API)
    grid.set_conflict_resolution([0, 1], AsasConfig(detector="CSTATEBASED", resolution=True, method="EBY"))  # a method's own grid path
    grid.run(2)
    ones = np.ones(3)
    geo.qdrdist(52.0 * ones, 4.0, 52.1, 4.1)
    geo.qdrdist_python(52.0 * ones, 4.0, 52.1, 4.1)
    geo.kwikqdrdist(52.0 * ones, 4.0, 52.1, 4.1)
    geo.kwikdist(52.0 * ones, 4.0, 52.1, 4.1)
    geo.kwikpos(52.0 * ones, 4.0, 45.0, 10.0)
    atmosphere.vcas2tas(150.0 * ones, 3000.0)
    atmosphere.tas2cas(150.0 * ones, 3000.0)
    atmosphere.casormach2tas(150.0 * ones, 3000.0)
    lnav.turn_distances(150.0 * ones, 10.0, 80.0)
    sim.cmd_altitude([0, 1], 0, [3000.0, 4000.0], [0.0, 5.0])
    _exercise_device_only()
    _exercise_real_traffic()


def _exercise_device_only() -> None:
    """The kernels only the device runs, on host arrays of the layouts the device gives them.

    The device steps' commands (:func:`bluesky_gym.tasks.compiled.command_heading_speed`,
    :func:`bluesky_gym.environments.descent.task.command_vertical_speed`,
    :func:`bluesky_gym.tasks.compiled.command_heading`),
    :meth:`bluesky_gym.core.DeviceSimulator.reset_on_host`'s scatters and
    :meth:`~bluesky_gym.core.DeviceSimulator.edit_on_host`'s gathers of each state dtype, ``delete_flagged``, and
    StaticObstacle's device step holding the state of the episodes stopped within a decision step
    (:func:`~bluesky_gym.environments.static_obstacle.task.hold_ended`, :func:`~bluesky_gym.environments.static_obstacle.task.restore_ended`).
    """
    from bluesky_gym.core import Simulator
    from bluesky_gym.core.state import clear_flagged, gather_columns, gather_rows, scatter_columns, scatter_rows
    from bluesky_gym.environments.descent import task as descent
    from bluesky_gym.environments.static_obstacle.task import hold_ended, restore_ended
    from bluesky_gym.tasks import compiled

    sim = Simulator(2, 3, dt=1.0)
    sim.create([0, 1], 0, 52.0, 4.0, 90.0, 3000.0, 150.0)
    flat = sim.n_envs * sim.max_aircraft
    field = {k: np.ascontiguousarray(getattr(sim, k)) for k in ("hdg", "cas", "ap_trk", "selspd", "swlnav", "swvnavspd", "alt", "selalt", "selvs")}
    envs, own = np.arange(2), np.zeros(2, np.int64)
    compiled.command_heading_speed(
        envs, own, np.zeros((2, 2)), field["hdg"], field["cas"], 22.5, 6.0, *(field[k] for k in ("ap_trk", "swlnav", "selspd", "swvnavspd"))
    )
    descent.command_vertical_speed(envs, own, np.zeros((2, 1)), field["alt"], True, field["selalt"], field["selvs"])
    for reference in (np.zeros(2), field["hdg"][:, 0]):  # HorizontalCR's headings at the last observation; PlanWaypoint's now (a column)
        compiled.command_heading(envs, own, reference, np.zeros((2, 1)), 45.0, field["ap_trk"], field["swlnav"])
    rows = np.arange(sim.max_aircraft)
    for flat_array in (np.ascontiguousarray(sim._float_flat), sim.phase.reshape(1, flat), sim.active.reshape(1, flat), sim.iactwp.reshape(1, flat)):
        scatter_columns(rows, np.ascontiguousarray(flat_array[:, rows]), flat_array.copy())
        gather_columns(rows, flat_array, np.empty((flat_array.shape[0], rows.size), flat_array.dtype))
    scatter_rows(rows, np.ascontiguousarray(sim._memo[rows]), sim._memo.copy())
    gather_rows(rows, sim._memo, np.empty((rows.size, sim._memo.shape[1])))
    clear_flagged(np.zeros(flat, np.bool_), sim.active.reshape(flat).copy())
    for routes in (sim.route_lat, sim.route_lon):
        flat_routes = routes.reshape(flat, -1)
        gather_rows(rows, flat_routes, np.empty((rows.size, flat_routes.shape[1])))
    state = np.ascontiguousarray(sim._float_block)  # (fields, n_envs, max_aircraft), as DeviceSimulator.device_state
    ended_at, held = np.array([1, 0]), np.empty_like(state)
    hold_ended(ended_at, 1, state, held)
    restore_ended(ended_at, 10, state, held)


def _exercise_real_traffic() -> None:
    """RealTrafficCR's kernels on a two-flight recording (its collections may not be prepared where the check runs).

    The recorded-flight interpolation, the profile guidance and the task's steering, measure and
    reward, each in the form the CPU task calls and, for the commands, the device step's.
    """
    from bluesky_gym.core import Simulator
    from bluesky_gym.environments.real_traffic import task as rt
    from bluesky_gym.realtraffic.flights import RecordedFlights
    from bluesky_gym.realtraffic.scenario import guide_airspaces, profile_command_rows
    from bluesky_gym.tasks import compiled

    k = np.arange(6, dtype=np.float64)
    text = np.array(["", ""])
    lat, lon, alt, gs, trk, vs = (
        np.tile(x, 2) for x in (47.0 + 0.01 * k, 8.0 + 0.01 * k, 3000.0 + 10.0 * k, np.full(6, 150.0), np.full(6, 45.0), np.ones(6))
    )
    flights = RecordedFlights(
        "exercise", "2024-01-01T00:00:00+00:00", 10.0, np.array([0.0, 5.0]), np.array([0, 6, 12]), lat, lon, alt, gs, trk, vs,
        np.array([0, 2, 4]), np.array([0, 5, 0, 5]), text, text, text, text,
    )  # fmt: skip
    sim = Simulator(2, 3, dt=1.0)
    sim.create([0, 0, 1], [0, 1, 0], 47.0, 8.0, 45.0, 3000.0, 150.0)
    t0, offset, period, lat, lon, alt, gs, _trk, _vs = flights.kernel_arrays()
    flights.at(np.array([0, 1]), np.array([12.0, 30.0]))
    flight, guided, vsmax = np.zeros((2, 3), np.int64), np.ones((2, 3), np.bool_), np.full((2, 3), 10.0)
    start, elapsed, envs, own, two = np.zeros(2), np.full(2, 10.0), np.arange(2), np.zeros(2, np.int64), np.zeros(2)
    field = {
        k: np.ascontiguousarray(getattr(sim, k))
        for k in ("lat", "lon", "alt", "hdg", "cas", "vs", "gseast", "gsnorth", "selalt", "selvs", "selspd", "ap_trk")
    }
    switches = {k: np.ascontiguousarray(getattr(sim, k)) for k in ("swlnav", "swvnav", "swvnavspd")}
    profile_command_rows(t0, offset, period, alt, gs, flight, envs, own, two, field["alt"], vsmax, two, two, np.empty(2), np.empty(2), np.empty(2))
    commands = (field["selalt"], switches["swvnav"], field["selvs"], field["selspd"], switches["swvnavspd"])
    guide_airspaces(t0, offset, period, alt, gs, flight, guided, start, elapsed, field["alt"], vsmax, *commands)
    recorded = (t0, offset, period, lat, lon, alt, gs)
    action = np.zeros((2, 3))
    rt.steering_rows(
        envs, own, action, start, elapsed, flight, vsmax, *recorded, field["lat"], field["lon"], field["alt"], *(np.empty(2) for _ in range(4))
    )
    position = (field["lat"], field["lon"], field["alt"])
    rt.steer_commands(envs, own, action, start, elapsed, flight, vsmax, *recorded, *position, field["ap_trk"], switches["swlnav"], *commands)
    sep, los = np.empty((2, 3)), np.empty((2, 3), np.bool_)
    compiled.kwik_separation(
        envs, own, field["lat"], field["lon"], field["alt"], np.ascontiguousarray(sim.active), rt.INTRUSION_NM, rt.INTRUSION_VERTICAL, sep, los
    )
    route, drift, cas_error, alt_error = (np.empty(2) for _ in range(4))
    state = (field["lat"], field["lon"], field["alt"], field["hdg"], field["cas"], field["vs"], field["gseast"], field["gsnorth"])
    rt.measure_rows(
        envs, own, start, elapsed, flight, *recorded, rt.route_offsets(10.0), *state,
        sep, route, drift, cas_error, alt_error, np.empty((2, rt.OWNSHIP_FEATURES)), np.empty((2, rt.NUM_INTRUDERS, rt.INTRUDER_FEATURES)),
    )  # fmt: skip
    rt.reward_rows(route, los, np.empty(2), np.empty(2), np.empty(2))
    rt.episode_sums(envs, route, los, np.zeros(2), np.zeros(2))


@dataclass(frozen=True)
class CompileResult:
    """One kernel compiled for one signature (or a kernel that could not be).

    Attributes:
        kernel: ``module.function``.
        signature: The argument types, as numba writes them ("" where there is none).
        kind: ``"kernel"`` (launchable), ``"device"`` (a device function compiled on its own), or
            ``"in callers"`` (a device function compiled inside the kernels that call it only:
            it has no CPU signature of its own).
        ptx_chars: Length of the PTX (0 where nothing was compiled).
        seconds: Compilation time [s].
        error: None, or why it failed.
    """

    kernel: str
    signature: str
    kind: str
    ptx_chars: int
    seconds: float
    error: str | None


def kernels_in_scope() -> list[Any]:
    """The kernels (:class:`bluesky_gym.core.jit.Kernel`) of :data:`KERNEL_PACKAGES`, in definition order."""
    import importlib
    import importlib.util
    import pkgutil

    import bluesky_gym.environments as environments
    from bluesky_gym.core.jit import KERNELS

    for module in ("bluesky_gym.core.simulator", "bluesky_gym.tasks.compiled"):
        importlib.import_module(module)
    for folder in pkgutil.iter_modules(environments.__path__):
        if folder.ispkg and importlib.util.find_spec(f"{environments.__name__}.{folder.name}.task") is not None:
            importlib.import_module(f"{environments.__name__}.{folder.name}.task")
    return [k for k in KERNELS.values() if k.name.startswith(KERNEL_PACKAGES)]


def launchable(kernel: Any) -> bool:
    """Whether a kernel is launched over a grid (its outer loop is a ``grid_range``); the others are device functions."""
    return "grid_range" in kernel.py_func.__code__.co_names


def callees(kernel: Any) -> list[Any]:
    """The kernels that ``kernel`` calls by name (its module globals that are kernels)."""
    from bluesky_gym.core.jit import KERNELS

    by_identity = {id(k.compiled): k for k in KERNELS.values()}
    g = kernel.py_func.__globals__
    return [by_identity[id(g[n])] for n in kernel.py_func.__code__.co_names if n in g and id(g[n]) in by_identity]


def compile_all(cc: tuple[int, int], say: Say = None, only: list[str] | None = None) -> list[CompileResult]:
    """Compile every kernel in scope to PTX for compute capability ``cc``, for every signature numba recorded on the CPU.

    Launchable kernels (:func:`launchable`) are called from Python, so numba records their
    argument types; each is compiled as a CUDA kernel for each of them, and a launchable kernel
    without any is a failure ("not exercised"). A device function is compiled for its own
    recorded signatures, if any, and in any case inside every kernel that calls it: one that no
    compiled kernel reaches and that has no signature of its own is a failure. Call
    :func:`exercise_kernels` first. Compilation needs no GPU (see
    :func:`bluesky_gym.core.cuda_target.offline_compilation`).

    Args:
        cc: Compute capability, e.g. (9, 0).
        say: Progress messages.
        only: Names (``module.function`` or ``function``) to compile; None: all.
    """
    from bluesky_gym.core import cuda_target

    results: list[CompileResult] = []
    compiled_ok: set[str] = set()
    scope = [k for k in kernels_in_scope() if only is None or k.name in only or k.name.rsplit(".", 1)[1] in only]
    with cuda_target.offline_compilation(cc):
        for k in scope:
            signatures = list(getattr(k.compiled, "signatures", []))
            for sig in signatures:
                restype = k.compiled.overloads[sig].signature.return_type
                device = str(restype) != "none"
                if say is not None:
                    say(f"compile: {k.name}{_sig_text(sig)}")
                t0 = time.perf_counter()
                try:
                    ptx = cuda_target.compile_ptx(k.compiled, sig, device=device, cc=cc)
                    error = None
                    compiled_ok.add(k.name)
                except Exception as exc:  # noqa: BLE001 - every failure is reported by kernel
                    ptx, error = "", _first_line(exc)
                results.append(CompileResult(k.name, _sig_text(sig), "device" if device else "kernel", len(ptx), time.perf_counter() - t0, error))
    reached: set[str] = set()
    todo = [k for k in scope if k.name in compiled_ok]
    while todo:
        for c in callees(todo.pop()):
            if c.name not in reached:
                reached.add(c.name)
                todo.append(c)
    for k in scope:
        if getattr(k.compiled, "signatures", []):
            continue
        if launchable(k):
            why = "not exercised: never called on the CPU, so no argument types to compile with"
            results.append(CompileResult(k.name, "", "kernel", 0, 0.0, why))
        elif k.name in reached:
            results.append(CompileResult(k.name, "", "in callers", 0, 0.0, None))
        else:
            results.append(CompileResult(k.name, "", "device", 0, 0.0, "reached by no compiled kernel and never called on the CPU: not compiled"))
    return results


def _sig_text(sig: tuple[Any, ...]) -> str:
    return "(" + ", ".join(str(t) for t in sig) + ")"


def _first_line(exc: BaseException) -> str:
    import re

    text = re.sub(r"\x1b\[[0-9;]*m", "", str(exc)).strip()
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    detail = next((line for line in lines if not line.startswith("Failed in")), lines[0] if lines else "")
    return f"{type(exc).__name__}: {detail}"[:300]


def format_compile(results: list[CompileResult], cc: tuple[int, int], problems: list[str]) -> str:
    """The compile-only table: one line per kernel (signatures, PTX size, time), then the failures."""
    by_kernel: dict[str, list[CompileResult]] = {}
    for r in results:
        by_kernel.setdefault(r.kernel, []).append(r)
    lines = [f"CUDA kernels compiled to PTX for compute capability {cc[0]}.{cc[1]} (numba-cuda, NVVM; no GPU used)", ""]
    lines.append(f"{'kernel':<50}  {'kind':<10}  {'signatures':>10}  {'PTX chars':>10}  {'seconds':>7}  status")
    lines.append("-" * 100)
    for name, rs in by_kernel.items():
        failed = [r for r in rs if r.error]
        ptx = sum(r.ptx_chars for r in rs)
        secs = sum(r.seconds for r in rs)
        status = "FAILED" if failed else ("ok (inside its callers)" if rs[0].kind == "in callers" else "ok")
        n = sum(1 for r in rs if r.signature)
        lines.append(f"{name:<50}  {rs[0].kind:<10}  {n:>10}  {ptx:>10}  {secs:>7.1f}  {status}")
    failures = [r for r in results if r.error]
    compiled = sum(1 for r in results if r.ptx_chars)
    lines.append("")
    lines.append(f"{len(by_kernel)} kernels, {compiled} compilations, {len(failures)} failed")
    for p in problems:
        lines.append(f"not exercised: {p}")
    for r in failures:
        lines.append(f"FAILED {r.kernel}{r.signature}: {r.error}")
    return "\n".join(lines)


def compile_summary(results: list[CompileResult]) -> list[dict[str, Any]]:
    """The results as JSON-ready dicts."""
    return [asdict(r) for r in results]


# --- the device check -------------------------------------------------------------------------
def device_check(budget: float = DEVICE_CHECK_BUDGET, say: Say = None) -> dict[str, Any]:
    """Fidelity and throughput of the device simulator against the CPU core of this machine.

    Raises:
        RuntimeError: No CUDA device (or numba-cuda's simulator instead of one).
    """
    from bluesky_gym.core import cuda_target

    require_device()
    start = time.perf_counter()
    device = _device_name()
    if say is not None:
        say(f"device check on {device}")
    fidelity = fidelity_sample(*FIDELITY_SAMPLE, say=say)
    physics: list[dict[str, Any]] = []
    cpu = _physics_rate_cpu(CPU_BATCH, PHYSICS_AIRCRAFT, say)
    physics.append(cpu)
    for n_envs in DEVICE_BATCHES:
        if time.perf_counter() - start > 0.8 * budget:
            physics.append({"target": "cuda", "airspaces": n_envs, "aircraft": n_envs * PHYSICS_AIRCRAFT, "skipped": "time budget"})
            continue
        physics.append(_physics_rate_device(n_envs, PHYSICS_AIRCRAFT, say))
    tasks: list[dict[str, Any]] = []
    for target, rows in (("cpu (1 core)", TASK_ROWS_CPU), *(("cuda", n) for n in TASK_ROWS)):
        if time.perf_counter() - start > 0.9 * budget:
            tasks.append({"target": target, "rows": rows, "skipped": "time budget"})
            continue
        tasks.append(_task_kernel_rates(target, rows, say))
    cuda_target.synchronize()
    return {"device": device, "seconds": time.perf_counter() - start, "fidelity": fidelity, "physics": physics, "tasks": tasks}


def _task_arrays(rows: int, m: int) -> dict[str, Any]:
    """Random airspaces of ``m`` aircraft around 52N 4E, one ownship row per airspace, and the outputs of the observation and statistics kernels."""
    rng = np.random.default_rng(0)
    k = TASK_INTRUDERS
    return {
        "envs": np.arange(rows),
        "own": np.zeros(rows, dtype=np.int64),
        "lat": 52 + rng.uniform(-0.5, 0.5, (rows, m)),
        "lon": 4 + rng.uniform(-0.5, 0.5, (rows, m)),
        "hdg": rng.uniform(0, 360, (rows, m)),
        "tas": rng.uniform(100, 200, (rows, m)),
        "active": rng.uniform(size=(rows, m)) < 0.9,
        "wpt_lat": 52 + rng.uniform(-0.5, 0.5, rows),
        "wpt_lon": 4 + rng.uniform(-0.5, 0.5, rows),
        "drift": np.empty(rows),
        "own_out": np.empty((rows, 3)),
        "merge_own": np.empty((rows, 4)),
        "intruders": np.empty((rows, 7, k)),
        "count": np.empty(rows, dtype=np.int64),
    }


def _task_kernel_rates(target: str, rows: int, say: Say) -> dict[str, Any]:
    """Rows per second of SectorCR's and Merge's observation kernels, on the CPU (one core) or launched on the device."""
    from bluesky_gym.core import cuda_target
    from bluesky_gym.tasks import compiled

    if PHYSICS_AIRCRAFT - 1 < TASK_INTRUDERS:  # the kernels read that many other slots (the tasks ensure it)
        raise ValueError(f"{TASK_INTRUDERS} intruders observed need at least {TASK_INTRUDERS + 1} aircraft per airspace, got {PHYSICS_AIRCRAFT}")
    if say is not None:
        say(f"task kernels: {target}, {rows} rows")
    a = _task_arrays(rows, PHYSICS_AIRCRAFT)
    if target == "cuda":
        a = {name: cuda_target.to_device(v) for name, v in a.items()}
    center = (52.0, 4.0, float(np.cos(np.radians(52.0))))
    scales = (150.0, 20.0, 5000.0, 50.0, 50.0, 10000.0, 5000.0)
    sector = (a["envs"], a["own"], a["lat"], a["lon"], a["hdg"], a["tas"], a["active"], a["wpt_lat"], a["wpt_lon"], center, scales,
              a["drift"], a["own_out"], a["intruders"], a["count"])  # fmt: skip
    merge = (a["envs"], a["own"], a["lat"], a["lon"], a["hdg"], a["tas"], a["active"], a["wpt_lat"], a["wpt_lon"], (5000.0, 50.0, 10.0),
             a["merge_own"], a["intruders"], a["count"])  # fmt: skip
    out: dict[str, Any] = {"target": target, "rows": rows}
    for name, kernel, args in (("sector_observe", compiled.sector_observe, sector), ("merge_observe", compiled.merge_observe, merge)):

        def call(kernel: Any = kernel, args: tuple[Any, ...] = args) -> None:
            if target == "cuda":
                cuda_target.launch(kernel, rows, *args)
            else:
                kernel(*args)

        call()  # compiles
        if target == "cuda":
            cuda_target.synchronize()
        reps = 10
        t0 = time.perf_counter()
        for _ in range(reps):
            call()
        if target == "cuda":
            cuda_target.synchronize()
        out[name] = rows * reps / (time.perf_counter() - t0)
    return out


def device_refusal() -> str | None:
    """Why the device check cannot run here (one line), or None."""
    from bluesky_gym.core import cuda_target
    from bluesky_gym.core.extras import install_hint

    if not cuda_target.AVAILABLE:
        return f"numba-cuda is not installed (the 'gpu' extra): {install_hint('gpu')}"
    if cuda_target.SIMULATOR:
        return "numba-cuda's simulator is on (NUMBA_ENABLE_CUDASIM=1): it measures nothing; unset it on a machine with a GPU"
    if not cuda_target.device_present():
        return "no CUDA device found (numba-cuda sees no GPU or no driver); run it on a machine with an NVIDIA GPU, or use --compile-only"
    return None


def require_device() -> None:
    """Refuse a device check where it cannot run.

    Raises:
        RuntimeError: :func:`device_refusal`'s reason.
    """
    refusal = device_refusal()
    if refusal is not None:
        raise RuntimeError(refusal)


def _device_name() -> str:
    from numba import cuda

    dev = cuda.get_current_device()
    name = dev.name.decode() if isinstance(dev.name, bytes) else str(dev.name)
    return f"{name} (compute capability {dev.compute_capability[0]}.{dev.compute_capability[1]})"


def _scenario_sim(cls: Any, n_envs: int, n_aircraft: int, routes: bool) -> Any:
    """The ``bench core`` traffic in a simulator of class ``cls``; with ``routes``, two waypoints each and a uniform wind in every third airspace."""
    sc = core_scenario(n_envs, n_aircraft)
    sim = cls(n_envs, n_aircraft, dt=1.0) if cls is not None else make_simulator(n_envs, n_aircraft)
    populate(sim, sc)
    if routes:
        env, slot = np.nonzero(sim.active)
        sim.add_waypoint(env, slot, sim.lat[env, slot] + 0.3, sim.lon[env, slot] + 0.2)
        sim.add_waypoint(env, slot, sim.lat[env, slot] + 0.5, sim.lon[env, slot] - 0.1)
        for e in range(0, n_envs, 3):
            sim.wind.add_points(e, [52.0], [4.0], [6.0], [-4.0])
    return sim


def fidelity_sample(n_envs: int, n_aircraft: int, steps: int, say: Say = None) -> dict[str, Any]:
    """The same traffic (routes, LNAV, uniform wind) stepped on the CPU and on the device; largest differences against the tolerances."""
    from bluesky_gym.core import DeviceSimulator, Simulator

    if say is not None:
        say(f"fidelity: {n_envs} airspaces x {n_aircraft} aircraft, {steps} steps, CPU and device")
    cpu = _scenario_sim(Simulator, n_envs, n_aircraft, True)
    dev = _scenario_sim(DeviceSimulator, n_envs, n_aircraft, True)
    for _ in range(steps):
        cpu.step()
        dev.step()
    return compare_states(cpu, dev)


def compare_states(a: Any, b: Any) -> dict[str, Any]:
    """Largest differences of two simulators' states (active slots), in the tolerances' units, and the fraction of bit-identical values."""
    act = np.asarray(a.active)
    out: dict[str, Any] = {}
    fields = {"lat": ("m", M_PER_DEG_LAT), "lon": ("m", M_PER_DEG_LAT), "alt": ("m", 1.0), "tas": ("m/s", 1.0), "gs": ("m/s", 1.0),
              "vs": ("m/s", 1.0), "hdg": ("deg", 1.0), "trk": ("deg", 1.0)}  # fmt: skip
    tolerance = {"m": TOLERANCE_M, "m/s": TOLERANCE_MS, "deg": TOLERANCE_DEG}
    within = True
    for name, (unit, scale) in fields.items():
        x, y = np.asarray(getattr(a, name))[act], np.asarray(getattr(b, name))[act]
        diff = np.abs(x - y)
        if name in ("hdg", "trk"):
            diff = np.minimum(diff, 360.0 - diff)
        worst = float(np.max(diff) * scale) if diff.size else 0.0
        ok = worst <= tolerance[unit]
        within &= ok
        out[name] = {"max_diff": worst, "unit": unit, "bit_identical": float(np.mean(x == y)) if x.size else 1.0, "within": ok}
    out["iactwp_equal"] = float(np.mean(np.asarray(a.iactwp)[act] == np.asarray(b.iactwp)[act])) if act.any() else 1.0
    out["within_tolerances"] = bool(within)
    return out


def _physics_rate_cpu(n_envs: int, n_aircraft: int, say: Say) -> dict[str, Any]:
    from bluesky_gym.core import Simulator

    if say is not None:
        say(f"physics: CPU, {n_envs} x {n_aircraft}")
    sim = _scenario_sim(Simulator, n_envs, n_aircraft, False)
    sim.run(2)
    n = int(sim.active.sum())
    t0 = time.perf_counter()
    sim.run(SUBSTEPS)
    run_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    for _ in range(5):
        sim.step()
    step_s = (time.perf_counter() - t0) / 5
    return {"target": "cpu (1 core)", "airspaces": n_envs, "aircraft": n, "run_rate": SUBSTEPS * n / run_s, "step_rate": n / step_s}


def _physics_rate_device(n_envs: int, n_aircraft: int, say: Say) -> dict[str, Any]:
    from bluesky_gym.core import DeviceSimulator, cuda_target

    if say is not None:
        say(f"physics: device, {n_envs} x {n_aircraft}")
    sim = _scenario_sim(DeviceSimulator, n_envs, n_aircraft, False)
    n = int(sim.active.sum())
    sim.run(2)  # compiles and uploads
    sim.step()
    cuda_target.synchronize()
    reps = 3
    t0 = time.perf_counter()
    for _ in range(reps):
        sim.run(SUBSTEPS)
    cuda_target.synchronize()
    run_s = (time.perf_counter() - t0) / reps
    steps = 50
    t0 = time.perf_counter()
    for _ in range(steps):
        sim.step()
    cuda_target.synchronize()
    step_s = (time.perf_counter() - t0) / steps
    return {"target": "cuda", "airspaces": n_envs, "aircraft": n, "run_rate": SUBSTEPS * n / run_s, "step_rate": n / step_s}


def format_device_check(result: dict[str, Any]) -> str:
    """The device check's table: fidelity, then physics throughput side by side with the CPU."""
    lines = [f"Device check on {result['device']} ({result['seconds']:.0f} s)", ""]
    fid = result["fidelity"]
    n, m, steps = FIDELITY_SAMPLE
    lines.append(f"Fidelity: {n} airspaces x {m} aircraft, LNAV routes, uniform wind in 1 of 3 airspaces, {steps} steps, device against CPU")
    lines.append(f"{'field':<6}  {'max |diff|':>12}  {'unit':<4}  {'bit-identical':>13}  within tolerance")
    for name, d in fid.items():
        if isinstance(d, dict):
            lines.append(f"{name:<6}  {d['max_diff']:>12.3g}  {d['unit']:<4}  {d['bit_identical']:>12.2%}  {'yes' if d['within'] else 'NO'}")
    lines.append(f"same active waypoint: {fid['iactwp_equal']:.2%}")
    lines.append("")
    lines.append("Physics: aircraft-sub-steps per second (bench core traffic, 20 aircraft per airspace)")
    lines.append(f"{'target':<14}  {'airspaces':>9}  {'aircraft':>9}  {'run (30 sub-steps/launch)':>26}  {'step (1 launch/step)':>21}")
    for p in result["physics"]:
        if "skipped" in p:
            lines.append(f"{p['target']:<14}  {p['airspaces']:>9}  {p['aircraft']:>9}  {'skipped: ' + p['skipped']:>26}")
            continue
        lines.append(f"{p['target']:<14}  {p['airspaces']:>9}  {p['aircraft']:>9}  {_rate(p['run_rate']):>26}  {_rate(p['step_rate']):>21}")
    best = max((p["run_rate"] for p in result["physics"] if p["target"] == "cuda" and "run_rate" in p), default=0.0)
    verdict = "met" if best >= TARGET_PHYSICS_RATE else "NOT MET"
    lines.append(f"target: physics >= {_rate(TARGET_PHYSICS_RATE)} aircraft-sub-steps/s on one H100: {verdict} (best {_rate(best)})")
    lines.append("")
    lines.append(f"Task kernels: observation rows per second ({PHYSICS_AIRCRAFT} aircraft per airspace, {TASK_INTRUDERS} intruders observed)")
    lines.append(f"{'target':<14}  {'rows':>9}  {'sector_observe':>15}  {'merge_observe':>15}")
    for t in result.get("tasks", []):
        if "skipped" in t:
            lines.append(f"{t['target']:<14}  {t['rows']:>9}  {'skipped: ' + t['skipped']:>15}")
            continue
        lines.append(f"{t['target']:<14}  {t['rows']:>9}  {_rate(t['sector_observe']):>15}  {_rate(t['merge_observe']):>15}")
    lines.append("Environment steps on the device: bluesky-gym bench gpu --envs; PPO end to end: bluesky-gym bench gpu --ppo.")
    return "\n".join(lines)


def _rate(x: float) -> str:
    if not math.isfinite(x):
        return "-"
    for div, suffix in ((1e9, " G"), (1e6, " M"), (1e3, " k")):
        if x >= div:
            return f"{x / div:.3g}{suffix}"
    return f"{x:.3g}"


# --- the vector environments on the device (``bench gpu --envs``) ------------------------------
#: Episodes and steps of the comparison of each id's device vector environment with its CPU one.
ENV_SAMPLE = (256, 30)
#: Batch sizes at which each id's device vector environment is timed, and the CPU one's.
ENV_BATCHES = (2**10, 2**14)
ENV_CPU_BATCH = 2**10
#: Timed steps per measurement.
ENV_STEPS = 5
#: Wall-clock budget of ``bench gpu --envs`` [s].
ENV_CHECK_BUDGET = 240.0


def env_check_ids() -> list[str]:
    """The ids the device vector environments are checked with: every single-agent id whose data are in place.

    Those whose step runs on the device (a registry row with a ``device_step``) come first, so
    that a tight budget measures them.
    """
    from bluesky_gym.envs.registry import entry, env_ids

    ids = [i for i in env_ids() if entry(i).data_status() is None]
    return sorted(ids, key=lambda i: entry(i).device_step is None)


def _max_diff(a: np.ndarray, b: np.ndarray) -> float:
    """Largest absolute difference of two arrays (NaN where both are NaN counts as equal; NaN against a number as inf)."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    both = np.isnan(a) & np.isnan(b)
    diff = np.where(both, 0.0, np.abs(a - b))
    return float(np.nanmax(np.where(np.isnan(diff), np.inf, diff))) if diff.size else 0.0


def _torch_device() -> tuple[Any, str]:
    """PyTorch and the device of the device vector environments' tensors (the CPU under numba-cuda's simulator)."""
    import torch

    from bluesky_gym.core import cuda_target

    return torch, "cpu" if cuda_target.SIMULATOR else "cuda"


def env_sample(env_id: str, n_envs: int, steps: int, say: Say = None) -> dict[str, Any]:
    """One id's device vector environment against its CPU one: same seeds, same actions (as device tensors), ``steps`` steps.

    Returns:
        The largest differences of the observations and rewards over every step and row, the
        fraction of bit-identical observation values, and the rows x steps whose end
        (``terminated | truncated``) differs (a threshold crossed on the last bit).
    """
    import gymnasium as gym

    from bluesky_gym.registration import register_envs

    register_envs()
    if say is not None:
        say(f"envs: {env_id}, {n_envs} episodes x {steps} steps, device against CPU")
    cpu = gym.make_vec(env_id, num_envs=n_envs, vectorization_mode="vector_entry_point")
    dev = gym.make_vec(env_id, num_envs=n_envs, vectorization_mode="vector_entry_point", device="cuda")
    torch, on = _torch_device()
    obs_c, _ = cpu.reset(seed=0)
    obs_d, _ = dev.reset(seed=0)
    cpu.action_space.seed(0)
    worst_obs, worst_reward, same, total, ended_differ = 0.0, 0.0, 0, 0, 0
    for step in range(steps + 1):
        if step > 0:
            a = cpu.action_space.sample()
            obs_c, r_c, t_c, u_c, _ = cpu.step(a)
            obs_d, r_d, t_d, u_d, _ = dev.step(torch.as_tensor(a, device=on))
            worst_reward = max(worst_reward, _max_diff(r_d.cpu().numpy(), r_c))
            ended_differ += int(((t_d | u_d).cpu().numpy() != (t_c | u_c)).sum())
        for k, v in obs_c.items():
            d = obs_d[k].cpu().numpy()
            worst_obs = max(worst_obs, _max_diff(d, v))
            same += int(np.sum((d == v) | (np.isnan(d) & np.isnan(v))))
            total += v.size
    cpu.close()
    dev.close()
    return {"id": env_id, "episodes": n_envs, "steps": steps, "obs_max_diff": worst_obs, "reward_max_diff": worst_reward,
            "obs_bit_identical": same / max(total, 1), "ended_differ": ended_differ}  # fmt: skip


def env_rate(env_id: str, device: str, n_envs: int, say: Say = None) -> dict[str, Any]:
    """Environment steps per second of one id's vector environment on ``device`` (``"cpu"``: one process; ``"cuda"``), resets included."""
    import gymnasium as gym

    from bluesky_gym.core import cuda_target
    from bluesky_gym.registration import register_envs

    register_envs()
    if say is not None:
        say(f"envs: {env_id} on {device}, {n_envs} episodes")
    env = gym.make_vec(env_id, num_envs=n_envs, vectorization_mode="vector_entry_point", device=device)
    env.action_space.seed(0)
    env.reset(seed=0)
    a = env.action_space.sample()
    if device == "cuda":
        torch, on = _torch_device()
        a = torch.as_tensor(a, device=on)
    env.step(a)
    t0 = time.perf_counter()
    for _ in range(ENV_STEPS):
        env.step(a)
    if device == "cuda":
        cuda_target.synchronize()
    rate = n_envs * ENV_STEPS / (time.perf_counter() - t0)
    env.close()
    return {"id": env_id, "target": "cpu (1 process)" if device == "cpu" else "cuda", "episodes": n_envs, "rate": rate}


def device_envs(budget: float = ENV_CHECK_BUDGET, say: Say = None) -> dict[str, Any]:
    """Every id's device vector environment (``make_vec(..., device="cuda")``) against its CPU one: episodes and env-steps/s.

    Raises:
        RuntimeError: No CUDA device (or numba-cuda's simulator instead of one).
    """
    require_device()
    start = time.perf_counter()
    device = _device_name()
    samples: list[dict[str, Any]] = []
    rates: list[dict[str, Any]] = []
    for env_id in env_check_ids():
        if time.perf_counter() - start > 0.9 * budget:
            samples.append({"id": env_id, "skipped": "time budget"})
            continue
        samples.append(env_sample(env_id, *ENV_SAMPLE, say=say))
        for device_kind, n in (("cpu", ENV_CPU_BATCH), *(("cuda", n) for n in ENV_BATCHES)):
            if time.perf_counter() - start > 0.9 * budget:
                rates.append({"id": env_id, "target": device_kind, "episodes": n, "skipped": "time budget"})
                continue
            rates.append(env_rate(env_id, device_kind, n, say))
    return {"device": device, "seconds": time.perf_counter() - start, "samples": samples, "rates": rates}


def format_device_envs(result: dict[str, Any]) -> str:
    """``bench gpu --envs``'s tables: the device vector environments against the CPU ones, then env-steps/s side by side."""
    n, steps = ENV_SAMPLE
    lines = [f"Vector environments on {result['device']} ({result['seconds']:.0f} s)", ""]
    lines.append(f"Episodes: {n} per id, {steps} steps of seeded random actions, device (make_vec(..., device='cuda')) against CPU")
    lines.append(f"{'id':<22}  {'obs max |diff|':>14}  {'obs bit-identical':>17}  {'reward max |diff|':>17}  {'ends differ (rows x steps)':>26}")
    for s in result["samples"]:
        if "skipped" in s:
            lines.append(f"{s['id']:<22}  skipped: {s['skipped']}")
            continue
        lines.append(
            f"{s['id']:<22}  {s['obs_max_diff']:>14.3g}  {s['obs_bit_identical']:>16.2%}  {s['reward_max_diff']:>17.3g}  {s['ended_differ']:>26}"
        )
    lines.append("")
    lines.append(f"Environment steps per second (random actions, resets included, {ENV_STEPS} timed steps)")
    lines.append(f"{'id':<22}  {'target':<16}  {'episodes':>9}  {'env-steps/s':>12}")
    for r in result["rates"]:
        rate = "skipped: " + r["skipped"] if "skipped" in r else _rate(r["rate"])
        lines.append(f"{r['id']:<22}  {r['target']:<16}  {r['episodes']:>9}  {rate:>12}")
    return "\n".join(lines)


# --- PPO end to end -----------------------------------------------------------------------------
#: The id PPO trains on end to end: its vector step runs on the device (bluesky_gym.environments.sector_cr.device_step).
PPO_ID = "SectorCREnv-v1"
#: (environment device, episodes) of the PPO measurement: the CPU vector environment (one process)
#: next to the device environment at growing batches; the learner is on the GPU in every row.
PPO_BATCHES: tuple[tuple[str, int], ...] = (("cpu", 2**10), ("cuda", 2**12), ("cuda", 2**14), ("cuda", 2**16))
#: Rollout steps per environment, epochs and minibatches per update (large-batch PPO, as GPU trainers run it).
PPO_SETTINGS = (16, 2, 4)
#: Timed rollouts of each measurement, after one untimed rollout (which compiles the kernels).
PPO_ROLLOUTS = 2
#: Wall-clock budget of ``bench gpu --ppo`` [s].
PPO_CHECK_BUDGET = 150.0
#: The issue's target on one H100: PPO end to end [env-steps/s].
TARGET_PPO_RATE = 1e6


def ppo_rate(env_device: str, n_envs: int, say: Say = None) -> dict[str, Any]:
    """Env-steps per second of the fast PPO trainer on :data:`PPO_ID`, collection and updates included.

    The environment runs on ``env_device`` (``"cuda"``: ``make_vec(..., device="cuda")``, the
    trainer reading its tensors where they are); the learner on the GPU (on the CPU under
    numba-cuda's simulator). One untimed rollout first, then :data:`PPO_ROLLOUTS` timed ones.
    """
    import torch
    from stable_baselines3.common.logger import configure

    from bluesky_gym.core import cuda_target
    from bluesky_gym.training.fast import trainer_class
    from bluesky_gym.training.hyperparams import PAPER, merge
    from bluesky_gym.training.runner import make_run_spec, new_model
    from bluesky_gym.training.sb3_vec_env import SB3VecEnv

    if say is not None:
        say(f"ppo: {PPO_ID}, environments on {env_device}, {n_envs} episodes")
    learner = "cpu" if cuda_target.SIMULATOR else "cuda"
    n_steps, epochs, minibatches = PPO_SETTINGS
    hp = {"n_steps": n_steps, "batch_size": max(1, n_envs * n_steps // minibatches), "n_epochs": epochs}
    config = merge(PAPER, {"run": {"trainer": "fast", "compile": False}, "algos": {"PPO": hp}})
    spec = make_run_spec(config, PPO_ID, "PPO", 0, n_envs=n_envs, total_timesteps=1, device=learner, env_device=env_device)
    venv = SB3VecEnv(PPO_ID, num_envs=n_envs, **({"device": env_device} if env_device != "cpu" else {}))
    try:
        model = new_model(spec, venv)
        model.set_logger(configure(None, []))
        trainer = trainer_class("PPO")(model, venv.venv, seed=0)
        trainer.start(list(range(n_envs)))

        def synchronize() -> None:
            if env_device == "cuda":
                cuda_target.synchronize()
            if learner == "cuda":
                torch.cuda.synchronize()

        rollout = n_envs * n_steps
        trainer.learn(rollout)
        synchronize()
        t0, steps0 = time.perf_counter(), trainer.num_timesteps
        trainer.learn(steps0 + PPO_ROLLOUTS * rollout)
        synchronize()
        rate = (trainer.num_timesteps - steps0) / (time.perf_counter() - t0)
        trainer.close()
    finally:
        venv.close()
    target = "cpu env (1 process)" if env_device == "cpu" else "cuda env"
    return {"env": target, "learner": learner, "episodes": n_envs, "rate": rate, "hyperparams": dict(spec.hyperparams)}


def device_ppo(budget: float = PPO_CHECK_BUDGET, say: Say = None) -> dict[str, Any]:
    """PPO end to end (:func:`ppo_rate`) at the sizes of :data:`PPO_BATCHES`, within ``budget`` seconds.

    Raises:
        RuntimeError: No CUDA device (or numba-cuda's simulator instead of one).
    """
    require_device()
    start = time.perf_counter()
    device = _device_name()
    rates: list[dict[str, Any]] = []
    for env_device, n in PPO_BATCHES:
        if time.perf_counter() - start > 0.7 * budget:  # a measurement takes a while: start one only with room left
            rates.append({"env": f"{env_device} env", "episodes": n, "skipped": "time budget"})
            continue
        rates.append(ppo_rate(env_device, n, say))
    return {"device": device, "id": PPO_ID, "seconds": time.perf_counter() - start, "rates": rates}


def format_device_ppo(result: dict[str, Any]) -> str:
    """``bench gpu --ppo``'s table: PPO end-to-end env-steps/s, CPU and device environments side by side."""
    n_steps, epochs, minibatches = PPO_SETTINGS
    lines = [f"PPO end to end on {result['device']}: {result['id']} ({result['seconds']:.0f} s)", ""]
    lines.append(
        f"fast PPO, rollouts of {n_steps} steps per environment, {epochs} epochs of {minibatches} minibatches; {PPO_ROLLOUTS} rollouts timed"
    )
    lines.append(f"{'environments':<20}  {'learner':<8}  {'episodes':>9}  {'env-steps/s':>12}")
    for r in result["rates"]:
        rate = "skipped: " + r["skipped"] if "skipped" in r else _rate(r["rate"])
        lines.append(f"{r['env']:<20}  {r.get('learner', ''):<8}  {r['episodes']:>9}  {rate:>12}")
    best = max((r["rate"] for r in result["rates"] if "rate" in r and r["env"] == "cuda env"), default=0.0)
    verdict = "met" if best >= TARGET_PPO_RATE else "NOT MET"
    lines.append(f"target: PPO end to end >= {_rate(TARGET_PPO_RATE)} env-steps/s on one H100: {verdict} (best {_rate(best)})")
    return "\n".join(lines)
