"""``bluesky-gym bench``: throughput of the simulation core and of the environments.

Examples::

    bluesky-gym bench core                          # native core; BlueSky if importable here
    bluesky-gym bench core --bluesky-python /path/to/python   # BlueSky in that interpreter
    bluesky-gym bench envs --env DescentEnv-v0 --num-envs 1 64 --reference-python /path/to/python
    bluesky-gym bench all --bluesky-python P --reference-python P --json results.json
    bluesky-gym bench profile                       # where the core's step time goes
    bluesky-gym bench scale --aircraft 1000 10000 --sim-time 600 --bluesky-python P --json scale.json
    bluesky-gym bench train --repeat 3              # training throughput: SB3 and the fast trainer
    bluesky-gym bench gpu --compile-only            # every CUDA kernel to PTX, no GPU needed (the gpu extra)
    bluesky-gym bench gpu                           # the device check, on a machine with a CUDA GPU
    bluesky-gym bench gpu --envs                    # the device vector environments against the CPU ones (a CUDA GPU)
    bluesky-gym bench gpu --ppo                     # PPO end to end on device environments (a CUDA GPU)

The interpreters can also be given by the environment variables ``BLUESKY_PYTHON`` and
``BLUESKY_GYM_REFERENCE_PYTHON``.

Speed targets are printed next to the figures; they are reported, never enforced. The exit code
is 1 when a measurement failed (the table still shows the others).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path
from typing import Any

from bluesky_gym.cli.arguments import deprecated_alias, env_list, positive_float, positive_int

#: Environment variables giving the default of ``--bluesky-python`` and ``--reference-python``.
BLUESKY_PYTHON_VAR = "BLUESKY_PYTHON"
REFERENCE_PYTHON_VAR = "BLUESKY_GYM_REFERENCE_PYTHON"


def _add_repeat(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--repeat",
        type=positive_int,
        default=1,
        metavar="N",
        help="measure everything N times; report per-cell medians and the medians of same-run ratios",
    )


def _add_common(p: argparse.ArgumentParser) -> None:
    p.add_argument("--json", metavar="PATH", type=Path, help="also save the results (with versions and settings) as JSON")
    p.add_argument("--quiet", action="store_true", help="no progress messages on stderr")


def _add_bluesky(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--bluesky-python",
        metavar="PATH",
        default=os.environ.get(BLUESKY_PYTHON_VAR) or None,
        help=f"Python interpreter with bluesky-simulator 1.1.1 installed (default: ${BLUESKY_PYTHON_VAR}, else this one if BlueSky is "
        "importable here)",
    )
    p.add_argument("--no-bluesky", action="store_true", help="do not measure BlueSky")


def _add_core(p: argparse.ArgumentParser, seconds_flag: str = "--seconds", num_envs_flag: str = "--num-envs") -> None:
    from bluesky_gym.benchmarks.core_bench import AIRCRAFT_COUNTS, BATCH_SIZES, DEFAULT_SECONDS

    p.add_argument(
        num_envs_flag, dest="core_num_envs", nargs="+", type=positive_int, default=list(BATCH_SIZES), metavar="N", help="batch sizes (airspaces)"
    )
    deprecated_alias(p, "--envs", num_envs_flag, "core_num_envs", nargs="+", type=positive_int, metavar="N")
    p.add_argument("--aircraft", nargs="+", type=positive_int, default=list(AIRCRAFT_COUNTS), metavar="N", help="aircraft per airspace")
    p.add_argument("--kernel", action="append", metavar="NAME", help="core step kernel to measure (repeatable; default: every available one)")
    p.add_argument(seconds_flag, dest="core_seconds", type=positive_float, default=DEFAULT_SECONDS, metavar="S", help="time budget per core cell [s]")


def _add_envs(p: argparse.ArgumentParser, seconds_flag: str = "--seconds", num_envs_flag: str = "--num-envs") -> None:
    from bluesky_gym.benchmarks.env_bench import BATCH_SIZES, DEFAULT_SECONDS

    p.add_argument("--env", action="extend", type=env_list, metavar="ID", help="environment ids (repeatable, comma-separated; default: all)")
    deprecated_alias(p, "--ids", "--env", "env", extend=True, nargs="+", metavar="ID")
    p.add_argument(num_envs_flag, dest="env_num_envs", nargs="+", type=positive_int, default=list(BATCH_SIZES), metavar="N", help="batch sizes")
    deprecated_alias(p, "--batch", num_envs_flag, "env_num_envs", nargs="+", type=positive_int, metavar="N")
    p.add_argument(
        "--reference-python",
        metavar="PATH",
        default=os.environ.get(REFERENCE_PYTHON_VAR) or None,
        help=f"Python interpreter with the reference bluesky-gym==0.2.0 installed (default: ${REFERENCE_PYTHON_VAR}; measured when given)",
    )
    p.add_argument(
        seconds_flag, dest="env_seconds", type=positive_float, default=DEFAULT_SECONDS, metavar="S", help="time budget per environment cell [s]"
    )


def add_parser(subparsers: Any) -> None:
    """Register ``bench`` and its ``core``, ``envs``, ``all``, ``train``, ``gpu``, ``profile`` and ``scale`` subcommands."""
    bench = subparsers.add_parser(
        "bench",
        help="measure simulation and environment throughput",
        description="Throughput of the native core and of the environments,\ncompared with BlueSky and the reference bluesky-gym 0.2.0.",
    )
    sub = bench.add_subparsers(dest="bench_command", metavar="WHAT")
    sub.required = True

    core = sub.add_parser("core", help="aircraft-sub-steps per second of the core (and of BlueSky)")
    _add_core(core)
    _add_bluesky(core)
    _add_repeat(core)
    _add_common(core)
    core.set_defaults(func=run_core_command)

    envs = sub.add_parser("envs", help="environment steps per second (single, batched, BlueSky backend, reference)")
    _add_envs(envs)
    _add_bluesky(envs)
    _add_repeat(envs)
    _add_common(envs)
    envs.set_defaults(func=run_envs_command)

    both = sub.add_parser("all", help="core and envs")
    _add_core(both, "--core-seconds", "--core-num-envs")
    _add_envs(both, "--env-seconds", "--env-num-envs")
    _add_bluesky(both)
    _add_repeat(both)
    _add_common(both)
    both.set_defaults(func=run_all_command)

    train = sub.add_parser(
        "train",
        help="training throughput: SB3 and the fast trainer side by side, against the environment alone",
        description="End-to-end training throughput (env-steps/s of collection and updates) of each trainer,\n"
        "for each setting, with ratios against the environment alone and SB3 measured in the same run\n"
        "(docs/training-fast.md).",
    )
    train.add_argument("--env", default="SectorCREnv-v0", metavar="ID", help="environment id (default: SectorCREnv-v0)")
    train.add_argument("--setting", action="extend", nargs="+", metavar="NAME", help="settings to measure (default: all; see docs/training-fast.md)")
    train.add_argument("--trainer", action="extend", nargs="+", metavar="NAME", help="trainers: sb3, fast, fast+compile (default: all)")
    train.add_argument("--device", default="cpu", help="torch device of the learners (default: cpu)")
    train.add_argument("--threads", type=int, default=1, metavar="N", help="torch threads (0: PyTorch's default; default: 1)")
    _add_repeat(train)
    _add_common(train)
    train.set_defaults(func=run_train_command)

    gpu = sub.add_parser(
        "gpu",
        help="CUDA: every kernel to PTX (--compile-only, no GPU) or the device check",
        description="--compile-only: every kernel of bluesky_gym.core and bluesky_gym.tasks compiled to PTX (numba-cuda),\n"
        "without a GPU, for every signature the package calls it with on the CPU; exit 1 naming each failure.\n"
        "Without it, on a CUDA GPU: the device simulator against the CPU core (fidelity, throughput).",
    )
    gpu.add_argument("--compile-only", action="store_true", help="compile to PTX only (no GPU needed; the gpu extra)")
    gpu.add_argument("--cc", type=_compute_capability, default=None, metavar="M.N", help="compute capability (default: 9.0, Hopper)")
    gpu.add_argument("--kernel", action="append", metavar="NAME", help="with --compile-only: only this kernel (repeatable)")
    gpu.add_argument("--envs", action="store_true", help="on a CUDA GPU: every id's make_vec(..., device='cuda') against the CPU (episodes, steps/s)")
    gpu.add_argument("--ppo", action="store_true", help="on a CUDA GPU: PPO end to end (fast trainer) on device environments, env-steps/s")
    gpu.add_argument(
        "--budget",
        type=float,
        default=None,
        metavar="S",
        help="wall-clock budget of the device check in seconds (default: 480; --envs 240; --ppo 150)",
    )
    _add_common(gpu)
    gpu.set_defaults(func=run_gpu_command)

    scale = sub.add_parser(
        "scale",
        help="N aircraft for a simulated time, with and without CD&R, on the core and BlueSky side by side",
        description="Flies the same seeded random traffic of N aircraft (one airspace) for a simulated time, without and with\n"
        "conflict detection (CSTATEBASED) and MVP resolution, on the native core and, up to --bluesky-max-aircraft, on\n"
        "BlueSky 1.1.1 in its own interpreter; prints the wall-clock times (docs/backends.md).",
    )
    from bluesky_gym.benchmarks.scale_bench import AIRCRAFT_COUNTS, BLUESKY_MAX_AIRCRAFT, DEFAULT_SIM_TIME

    scale.add_argument("--aircraft", nargs="+", type=positive_int, default=list(AIRCRAFT_COUNTS), metavar="N", help="aircraft counts")
    scale.add_argument("--sim-time", type=positive_float, default=DEFAULT_SIM_TIME, metavar="S", help="simulated seconds of each flight")
    scale.add_argument(
        "--bluesky-max-aircraft",
        type=positive_int,
        default=BLUESKY_MAX_AIRCRAFT,
        metavar="N",
        help=f"largest aircraft count flown on BlueSky (default: {BLUESKY_MAX_AIRCRAFT})",
    )
    _add_bluesky(scale)
    _add_common(scale)
    scale.set_defaults(func=run_scale_command)

    prof = sub.add_parser("profile", help="cProfile of the core step: where the time goes")
    prof.add_argument("--num-envs", type=positive_int, default=4096, metavar="N", help="airspaces (batch size)")
    deprecated_alias(prof, "--envs", "--num-envs", "num_envs", type=positive_int, metavar="N")
    prof.add_argument("--aircraft", type=positive_int, default=20, metavar="N", help="aircraft per airspace")
    prof.add_argument("--kernel", action="append", metavar="NAME", help="kernel to profile (repeatable; default: every available one)")
    prof.add_argument("--steps", type=positive_int, default=30, help="profiled steps")
    prof.add_argument("--top", type=positive_int, default=15, help="functions listed")
    prof.add_argument(
        "--env",
        action="extend",
        type=env_list,
        metavar="ID",
        help="profile a batched environment step instead (physics against task layer; repeatable, comma-separated)",
    )
    _add_common(prof)
    prof.set_defaults(func=run_profile_command)


def _compute_capability(text: str) -> tuple[int, int]:
    major, sep, minor = text.partition(".")
    if not (sep and major.isdigit() and minor.isdigit()):
        raise argparse.ArgumentTypeError(f"expected a compute capability MAJOR.MINOR such as 9.0, got {text!r}")
    return int(major), int(minor)


def _progress(args: argparse.Namespace) -> Any:
    """Return a callable printing a status line with the seconds elapsed since the start (None if quiet)."""
    if args.quiet:
        return None
    start = time.perf_counter()
    return lambda msg: print(f"[bench {time.perf_counter() - start:6.1f} s] {msg}", file=sys.stderr, flush=True)


def _bluesky_python(args: argparse.Namespace) -> str | None:
    from bluesky_gym.benchmarks.external import bluesky_python

    return bluesky_python(args.bluesky_python, args.no_bluesky)


def _check_kernels(kernels: list[str] | None) -> None:
    from bluesky_gym.benchmarks.core_bench import available_kernels

    if kernels:
        unknown = sorted(set(kernels) - set(available_kernels()))
        if unknown:
            raise SystemExit(f"bluesky-gym bench: kernel(s) {unknown} not available here; available: {available_kernels()}")


def _core(args: argparse.Namespace) -> dict[str, Any]:
    from bluesky_gym.benchmarks.core_bench import run_core

    _check_kernels(args.kernel)
    return run_core(args.core_num_envs, args.aircraft, args.kernel, args.core_seconds, _bluesky_python(args), _progress(args), args.repeat)


def _envs(args: argparse.Namespace) -> dict[str, Any]:
    from bluesky_gym.benchmarks.env_bench import run_envs
    from bluesky_gym.registration import available_envs

    ids = None if not args.env or [e.lower() for e in args.env] == ["all"] else list(dict.fromkeys(args.env))
    if ids:
        unknown = [i for i in ids if i not in available_envs()]
        if unknown:
            raise SystemExit(f"bluesky-gym bench: unknown or unavailable id(s) {unknown}; available: {', '.join(available_envs())}")
    return run_envs(ids, args.env_num_envs, args.env_seconds, _bluesky_python(args), args.reference_python, _progress(args), args.repeat)


def _failed_core(core: dict[str, Any]) -> bool:
    return bool(core.get("bluesky") and "error" in core["bluesky"])


def _failed_envs(envs: dict[str, Any]) -> bool:
    for row in envs["rows"]:
        cells = [row["single"], *row["batched"].values(), row["bluesky"], row["reference"]]
        if any(c is not None and "error" in c for c in cells):
            return True
    return False


def _finish(args: argparse.Namespace, results: dict[str, Any], failed: bool) -> int:
    from bluesky_gym.benchmarks.report import metadata

    if args.json is not None:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps({"meta": metadata(), **results}, indent=2) + "\n", encoding="utf-8")
        print(f"\nresults saved to {args.json}")
    return 1 if failed else 0


def run_core_command(args: argparse.Namespace) -> int:
    """``bench core``."""
    from bluesky_gym.benchmarks.report import format_core

    core = _core(args)
    print(format_core(core))
    return _finish(args, {"core": core}, _failed_core(core))


def run_envs_command(args: argparse.Namespace) -> int:
    """``bench envs``."""
    from bluesky_gym.benchmarks.report import format_envs

    envs = _envs(args)
    print(format_envs(envs))
    return _finish(args, {"envs": envs}, _failed_envs(envs))


def run_all_command(args: argparse.Namespace) -> int:
    """``bench all``: the core table, then the environment table."""
    from bluesky_gym.benchmarks.report import format_core, format_envs

    core = _core(args)
    print(format_core(core), flush=True)
    envs = _envs(args)
    print()
    print(format_envs(envs))
    return _finish(args, {"core": core, "envs": envs}, _failed_core(core) or _failed_envs(envs))


def run_train_command(args: argparse.Namespace) -> int:
    """``bench train``."""
    from bluesky_gym.benchmarks.train_bench import SETTINGS, TRAINERS, format_table, run
    from bluesky_gym.cli.catalog import known_env
    from bluesky_gym.cli.train import check_device

    try:
        known_env(args.env)
        check_device(args.device)
        for given, valid, what in ((args.setting, SETTINGS, "setting"), (args.trainer, TRAINERS, "trainer")):
            unknown = sorted(set(given or ()) - set(valid))
            if unknown:
                raise ValueError(f"unknown {what}(s) {', '.join(unknown)}; choose from {', '.join(valid)}")
    except ValueError as exc:
        raise SystemExit(f"bluesky-gym bench train: {exc}") from None
    result = run(args.env, args.setting or list(SETTINGS), args.trainer or list(TRAINERS), args.repeat, args.device, args.threads, _progress(args))
    print(format_table(result))
    return _finish(args, {"train": result}, False)


def run_scale_command(args: argparse.Namespace) -> int:
    """``bench scale``."""
    from bluesky_gym.benchmarks.scale_bench import format_scale, run_scale

    result = run_scale(args.aircraft, args.sim_time, _bluesky_python(args), args.bluesky_max_aircraft, _progress(args))
    print(format_scale(result))
    return _finish(args, result, any(r["bluesky_error"] for r in result["rows"]))


def run_profile_command(args: argparse.Namespace) -> int:
    """``bench profile``."""
    from bluesky_gym.benchmarks.core_bench import available_kernels
    from bluesky_gym.benchmarks.profiling import profile_core
    from bluesky_gym.benchmarks.report import format_profile

    if args.env:
        return _run_env_profiles(args)
    _check_kernels(args.kernel)
    profiles = []
    say = _progress(args)
    for kernel in args.kernel or available_kernels():
        if say is not None:
            say(f"profile: {kernel} kernel, {args.num_envs} x {args.aircraft}")
        prof = profile_core(args.num_envs, args.aircraft, kernel, args.steps, args.top)
        profiles.append(prof)
        print(format_profile(prof), end="\n\n", flush=True)
    return _finish(args, {"profile": profiles}, False)


def _run_env_profiles(args: argparse.Namespace) -> int:
    """``bench profile --env ID``: physics against task layer in a batched step."""
    from bluesky_gym.benchmarks.env_profile import profile_env
    from bluesky_gym.benchmarks.report import format_env_profile
    from bluesky_gym.registration import available_envs

    unknown = [i for i in args.env if i not in available_envs()]
    if unknown:
        raise SystemExit(f"bluesky-gym bench: unknown or unavailable id(s) {unknown}; available: {', '.join(available_envs())}")
    say = _progress(args)
    profiles = []
    for env_id in args.env:
        if say is not None:
            say(f"profile: {env_id} x {args.num_envs}")
        prof = profile_env(env_id, args.num_envs, args.steps, args.top)
        profiles.append(prof)
        print(format_env_profile(prof), end="\n\n", flush=True)
    return _finish(args, {"env_profile": profiles}, False)


def _budget(args: argparse.Namespace) -> dict[str, float]:
    """The ``budget`` argument of a device check: ``--budget`` where given (else the check's own default)."""
    return {} if args.budget is None else {"budget": float(args.budget)}


def run_gpu_command(args: argparse.Namespace) -> int:
    """``bench gpu``: the compile-only check, or the device check."""
    from bluesky_gym.benchmarks import gpu_bench
    from bluesky_gym.core import cuda_target

    if not cuda_target.AVAILABLE:
        raise SystemExit(f"bluesky-gym bench gpu: {gpu_bench.device_refusal()}")
    say = _progress(args)
    if args.compile_only:
        if args.envs or args.ppo or args.budget is not None:
            raise SystemExit("bluesky-gym bench gpu: --envs, --ppo and --budget run on a GPU; they do not go with --compile-only")
        if cuda_target.SIMULATOR:
            raise SystemExit("bluesky-gym bench gpu: --compile-only compiles with NVVM; unset NUMBA_ENABLE_CUDASIM (the simulator compiles nothing)")
        cc = args.cc or cuda_target.DEFAULT_CC
        if args.kernel:
            known = {k.name for k in gpu_bench.kernels_in_scope()} | {k.name.rsplit(".", 1)[1] for k in gpu_bench.kernels_in_scope()}
            unknown = [k for k in args.kernel if k not in known]
            if unknown:
                raise SystemExit(f"bluesky-gym bench gpu: unknown kernel(s) {', '.join(unknown)}")
        problems = gpu_bench.exercise_kernels(say)
        results = gpu_bench.compile_all(cc, say, args.kernel)
        print(gpu_bench.format_compile(results, cc, problems))
        failed = any(r.error for r in results)
        return _finish(args, {"gpu_compile": {"cc": list(cc), "problems": problems, "results": gpu_bench.compile_summary(results)}}, failed)
    if args.kernel or args.cc:
        raise SystemExit("bluesky-gym bench gpu: --kernel and --cc go with --compile-only")
    if args.envs and args.ppo:
        raise SystemExit("bluesky-gym bench gpu: --envs and --ppo are two checks; run them one at a time")
    if args.budget is not None and not args.budget > 0:
        raise SystemExit(f"bluesky-gym bench gpu: --budget must be a positive number of seconds, got {args.budget}")
    refusal = gpu_bench.device_refusal()
    if refusal is not None:
        raise SystemExit(f"bluesky-gym bench gpu: {refusal}")
    if args.envs:
        envs = gpu_bench.device_envs(**_budget(args), say=say)
        print(gpu_bench.format_device_envs(envs))
        return _finish(args, {"gpu_envs": envs}, False)
    if args.ppo:
        ppo = gpu_bench.device_ppo(**_budget(args), say=say)
        print(gpu_bench.format_device_ppo(ppo))
        return _finish(args, {"gpu_ppo": ppo}, False)
    result = gpu_bench.device_check(**_budget(args), say=say)
    print(gpu_bench.format_device_check(result))
    return _finish(args, {"gpu": result}, not result["fidelity"]["within_tolerances"])
