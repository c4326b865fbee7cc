"""One training run in its own directory: resumable, crash-safe, fully recorded.

A run is ``(environment, algorithm, seed, steps, hyperparameters)``. Its directory holds:

* ``config.json`` - the exact configuration (resolved hyperparameters as passed to SB3, scenario
  options, seeds and the train/eval seed split), written once. Rerunning in the same directory
  with a different configuration is refused.
* ``run.json`` - one entry per process that trained the run (start, end, host, package
  versions, command, timesteps at start).
* ``episodes.csv`` - one row per finished training episode: episode number, timesteps and wall
  time when it ended, environment index, return, length, whether it terminated, the reference
  info values, summed reward components (``reward_*``) and the KPIs (``kpi_*``).
* ``checkpoints/step_<N>/`` - the two latest checkpoints: ``model.zip`` and, for off-policy
  algorithms, ``replay_buffer.pkl``; ``checkpoint.json`` names the latest (and the one before,
  as ``previous``) and records the timesteps, the number of episode rows and the training wall
  time it includes, and the size and SHA-256 of each of its files.
* ``tensorboard/`` - Stable-Baselines3's TensorBoard log (``tensorboard --logdir <run dir>``).
* ``model.zip`` - the final model; ``eval.json`` / ``eval_episodes.csv`` - its deterministic
  evaluation on held-out scenarios; ``result.json`` - written last, marks the run finished.

Every file except the episode log is replaced atomically, and ``checkpoint.json`` is written only
after the files it names, so a run killed at any moment (even ``SIGKILL``) resumes from its last
complete checkpoint: model weights, optimiser state, replay buffer and timesteps are restored,
episode-log rows written after that checkpoint are dropped (they are played again) and episodes
in flight at the checkpoint are abandoned. Checkpoints are taken at the start of a rollout, where
the model has been trained on every transition counted so far (for PPO: between rollouts), so
no transition is lost or counted twice. A resumed run continues with fresh training scenario
streams derived from the run seed and the timesteps done (see :mod:`bluesky_gym.envs.seeds`).

Everything that can be checked before training (environment id and options, hyperparameter
names) is checked before the run directory is created, and a run that fails before it trained
leaves no directory behind. A damaged run directory (a checkpoint file missing, truncated or
changed, a step count in ``checkpoint.json`` that its model does not hold, an episode log shorter
than its checkpoint, a JSON file that does not parse) is never resumed silently:
:func:`inspect_run` names the damage and :func:`run_training` refuses to go on unless told to
resume from the last intact checkpoint (``on_damage="resume"``) or to start over
(``on_damage="restart"``). Where ``checkpoint.json`` itself is unreadable or missing, the
checkpoints in ``checkpoints/step_*`` are checked by their own files and the episode log (see
:func:`_checkpoints_on_disk`) and can still be resumed from.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import pickletools
import platform
import shutil
import socket
import subprocess
import sys
import time
import zipfile
import zlib
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from bluesky_gym.core.extras import MissingDependencyError, missing_extra, require_sb3
from bluesky_gym.envs.seeds import EVAL_SEED_BASE, TRAIN_SEED_LIMIT, train_env_seeds
from bluesky_gym.training import TRAINERS, algorithm_class
from bluesky_gym.training.hyperparams import POLICY, adapt_to_n_envs, check_hyperparameter_names, resolve, sb3_kwargs
from bluesky_gym.training.io import (
    AppendCSV,
    DamagedFileError,
    atomic_path,
    atomic_write_csv,
    atomic_write_json,
    file_damage,
    file_record,
    latest_checkpoint,
    read_csv_rows,
    read_json,
)

EPISODE_LOG = "episodes.csv"
LEADING_COLUMNS = ["episode", "timesteps", "wall_time_s", "env_index", "return", "length", "terminated"]
#: Subdirectory of a run directory with Stable-Baselines3's TensorBoard log.
TENSORBOARD_DIR = "tensorboard"
#: What :func:`run_training` does with a damaged run directory: refuse, resume from the last intact checkpoint, start over.
ON_DAMAGE = ("error", "resume", "restart")
#: Files of a run directory that training produces (removed when a damaged run starts over).
TRAINING_OUTPUTS = ("checkpoint.json", EPISODE_LOG, "model.zip", "eval.json", "eval_episodes.csv", "result.json")


class RunConfigMismatch(RuntimeError):
    """The run directory belongs to a run with a different configuration."""


class RunLocked(RuntimeError):
    """Another live process is training in this run directory."""


class RunDamaged(RuntimeError):
    """The run directory is damaged; the message names the damage and the ways on."""


@dataclass(frozen=True)
class RunSpec:
    """Everything that defines one training run.

    Attributes:
        env_id: Environment id.
        algo: ``PPO``, ``SAC``, ``TD3`` or ``DDPG``.
        seed: Run seed (model initialisation, exploration and training scenarios).
        total_timesteps: Environment steps to train for (PPO stops at the end of a rollout).
        n_envs: Batched environments.
        hyperparams: Constructor arguments of the SB3 algorithm (after :func:`adapt_to_n_envs`).
        env_options: Scenario options of the environment.
        notes: How the hyperparameters were adapted, if at all.
        checkpoint_freq: Steps between checkpoints (rounded up to rollouts).
        eval_episodes: Held-out episodes evaluated at the end (0: none).
        device: Torch device.
        torch_threads: Torch intra-op threads (0: leave PyTorch's default).
        trainer: ``"sb3"`` (Stable-Baselines3's own loops) or ``"fast"`` (:mod:`bluesky_gym.training.fast`).
        compile: Compile the fast trainer's update with ``torch.compile``.
        env_device: Where the fast trainer's environments run: ``"cpu"``, or ``"cuda"``
            (``gym.make_vec(..., device="cuda")``: tensors on the GPU, read by the trainer where
            they are). Not part of the identity: the episodes are the CPU's (docs/backends.md).

    """

    env_id: str
    algo: str
    seed: int
    total_timesteps: int
    n_envs: int
    hyperparams: dict[str, Any]
    env_options: dict[str, Any] = field(default_factory=dict)
    notes: tuple[str, ...] = ()
    checkpoint_freq: int = 50_000
    eval_episodes: int = 50
    device: str = "cpu"
    torch_threads: int = 1
    trainer: str = "sb3"
    compile: bool = False
    env_device: str = "cpu"

    def identity(self) -> dict[str, Any]:
        """Return the parts that determine what is learned (a resumed run must match them).

        The trainer is part of it when it is not SB3 (so the identities of SB3 runs made before
        there was a choice stay the same).
        """
        identity = {
            "env_id": self.env_id,
            "algo": self.algo,
            "seed": self.seed,
            "total_timesteps": self.total_timesteps,
            "n_envs": self.n_envs,
            "policy": POLICY,
            "hyperparams": self.hyperparams,
            "env_options": self.env_options,
        }
        if self.trainer != "sb3":
            identity["trainer"] = self.trainer
        return json.loads(json.dumps(identity, sort_keys=True))

    def digest(self) -> str:
        """Return a short hash of :meth:`identity`."""
        return hashlib.sha256(json.dumps(self.identity(), sort_keys=True).encode()).hexdigest()[:16]


#: Where the fast trainer's environments may run (``env_device``).
ENV_DEVICES = ("cpu", "cuda")


def make_run_spec(config: dict[str, Any], env_id: str, algo: str, seed: int, **run_overrides: Any) -> RunSpec:
    """Resolve a full config (see :mod:`bluesky_gym.training.hyperparams`) into a :class:`RunSpec`.

    Args:
        config: The merged config (paper defaults, config file).
        env_id: Environment id.
        algo: Algorithm name.
        seed: Run seed (non-negative, below ``2**31``).
        **run_overrides: Values of the ``run`` section given on the command line (None = unset).

    """
    algo = algo.upper()
    algorithm_class(algo)  # validates the name (and that SB3 is installed)
    if not 0 <= int(seed) < TRAIN_SEED_LIMIT:
        raise ValueError(f"seed must be in [0, 2**31), got {seed}")
    run, hp, env_options = resolve(config, env_id, algo)
    run.update({k: v for k, v in run_overrides.items() if v is not None})
    n_envs = int(run["n_envs"])
    if n_envs < 1 or int(run["total_timesteps"]) < 1:
        raise ValueError("n_envs and total_timesteps must be positive")
    trainer = str(run["trainer"])
    if trainer not in TRAINERS:
        raise ValueError(f"unknown trainer {trainer!r}; choose one of {', '.join(TRAINERS)}")
    env_device = str(run["env_device"])
    if env_device not in ENV_DEVICES:
        raise ValueError(f"env_device must be one of {', '.join(ENV_DEVICES)}, got {env_device!r}")
    if env_device != "cpu" and trainer != "fast":
        raise ValueError(f"env_device {env_device!r} needs the fast trainer (--trainer fast): Stable-Baselines3's loops step numpy arrays")
    hp, notes = adapt_to_n_envs(algo, hp, n_envs)
    check_hyperparameter_names(algo, hp, source=f"{algo} hyperparameters", trainer=trainer)
    return RunSpec(
        env_id=env_id,
        algo=algo,
        seed=int(seed),
        total_timesteps=int(run["total_timesteps"]),
        n_envs=n_envs,
        hyperparams=hp,
        env_options=env_options,
        notes=tuple(notes),
        checkpoint_freq=max(1, int(run["checkpoint_freq"])),
        eval_episodes=max(0, int(run["eval_episodes"])),
        device=str(run["device"]),
        torch_threads=int(run["torch_threads"]),
        trainer=trainer,
        compile=resolve_compile(run["compile"], trainer, algo, hp, n_envs, int(run["total_timesteps"])),
        env_device=env_device,
    )


#: ``compile = "auto"`` compiles the fast PPO update from this many minibatch updates on (compiling takes tens of seconds once).
AUTO_COMPILE_UPDATES = 20_000
#: ... and only for minibatches up to this size, where the per-minibatch overhead is what compiling removes.
AUTO_COMPILE_MAX_BATCH = 1024


def resolve_compile(value: Any, trainer: str, algo: str, hyperparams: dict[str, Any], n_envs: int, total_timesteps: int) -> bool:
    """Whether a run compiles its update: ``True``/``False`` as given; ``"auto"``: the fast trainer's PPO with small minibatches in a long run.

    Raises:
        ValueError: ``value`` is neither a bool nor ``"auto"``.

    """
    if isinstance(value, bool):
        return value
    if value != "auto":
        raise ValueError(f"compile must be true, false or 'auto', got {value!r}")
    if trainer != "fast" or algo != "PPO":
        return False
    rollout = int(hyperparams.get("n_steps", 2048)) * n_envs
    batch = int(hyperparams.get("batch_size", 64))
    updates = -(-total_timesteps // rollout) * int(hyperparams.get("n_epochs", 10)) * -(-rollout // batch)
    return batch <= AUTO_COMPILE_MAX_BATCH and updates >= AUTO_COMPILE_UPDATES


def run_dir_for(out: str | Path, env_id: str, algo: str, seed: int) -> Path:
    """Return the run directory of ``(env, algo, seed)`` under ``out``: ``out/<env>/<ALGO>/seed_<S>``."""
    return Path(out) / env_id / algo.upper() / f"seed_{seed}"


# --- versions and metadata --------------------------------------------------------------------
def package_versions() -> dict[str, str]:
    """Versions of Python, the platform and every package a run depends on."""
    import importlib.metadata as md

    import bluesky_gym

    out = {"python": sys.version.split()[0], "platform": platform.platform(), "bluesky_gym": bluesky_gym.__version__}
    for dist in ("numpy", "gymnasium", "stable_baselines3", "torch"):
        try:
            out[dist] = md.version(dist.replace("_", "-"))
        except md.PackageNotFoundError:
            out[dist] = "not installed"
    commit = _git_commit(Path(bluesky_gym.__file__).resolve().parent)
    if commit:
        out["bluesky_gym_git"] = commit
    return out


def _git_commit(directory: Path) -> str | None:
    try:
        res = subprocess.run(["git", "-C", str(directory), "rev-parse", "HEAD"], capture_output=True, text=True, timeout=5, check=False)
        if res.returncode != 0:
            return None
        status = ["git", "-C", str(directory), "status", "--porcelain", "--untracked-files=no"]
        dirty = subprocess.run(status, capture_output=True, text=True, timeout=5, check=False)
        return res.stdout.strip() + ("+dirty" if dirty.stdout.strip() else "")
    except (OSError, subprocess.SubprocessError):
        return None


def _now() -> str:
    return datetime.now(UTC).isoformat(timespec="seconds")


# --- lock ------------------------------------------------------------------------------------------
class RunLock:
    """An exclusive lock file in a run directory, taken over when its owner process is gone.

    Args:
        run_dir: The run directory.

    """

    def __init__(self, run_dir: Path) -> None:
        self.path = run_dir / ".lock"
        self.owner = f"{socket.gethostname()} {os.getpid()}"

    def __enter__(self) -> RunLock:
        for _ in range(2):
            try:
                fd = os.open(self.path, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
            except FileExistsError:
                if self._stale():
                    self.path.unlink(missing_ok=True)
                    continue
                owner = self.path.read_text().strip()
                raise RunLocked(f"{self.path.parent} is being trained by {owner} (delete {self.path} if not)") from None
            with os.fdopen(fd, "w") as f:
                f.write(self.owner + "\n")
            return self
        raise RunLocked(f"could not lock {self.path.parent}")

    def __exit__(self, *exc: object) -> None:
        try:
            if self.path.read_text().strip() == self.owner:
                self.path.unlink()
        except OSError:
            pass

    def is_held(self) -> bool:
        """True if a live process holds the lock (a lock left by a dead process does not count)."""
        return self.path.exists() and not self._stale()

    def _stale(self) -> bool:
        try:
            host, pid = self.path.read_text().split()
        except (OSError, ValueError):
            return True  # unreadable or half-written: its writer died before finishing
        if host != socket.gethostname():
            return False
        try:
            os.kill(int(pid), 0)
        except ProcessLookupError:
            return True
        except PermissionError:
            return False
        return int(pid) == os.getpid()


# --- checkpoints -------------------------------------------------------------------------------------
def save_checkpoint(model: Any, run_dir: Path, episodes_logged: int, wall_time_s: float) -> dict[str, Any]:
    """Save model (and replay buffer) into a new step directory, then commit ``checkpoint.json``.

    Each file is written under a temporary name and renamed; ``checkpoint.json`` (written last,
    atomically) records their sizes and SHA-256, so later damage is detected. The checkpoint
    before is kept (``previous``) as a fallback; older ones are deleted.
    """
    step = int(model.num_timesteps)
    rel = Path("checkpoints") / f"step_{step:012d}"
    d = run_dir / rel
    d.mkdir(parents=True, exist_ok=True)
    files = {}
    for name, write in checkpoint_writers(model).items():
        with atomic_path(d / name) as tmp:
            write(tmp)
        files[name] = file_record(d / name)
    buffer = next((name for name in files if name.startswith("replay_buffer")), None)
    try:
        current = latest_checkpoint(run_dir)
    except DamagedFileError:
        current = None
    previous = None
    if current is not None and current[0]["dir"] != rel.as_posix():
        previous = {k: v for k, v in current[0].items() if k != "previous"}
    record = {
        "timesteps": step,
        "dir": rel.as_posix(),
        "episodes_logged": int(episodes_logged),
        "wall_time_s": float(wall_time_s),
        "replay_buffer": buffer is not None,
        "files": files,
        "saved_at": _now(),
        "previous": previous,
    }
    atomic_write_json(run_dir / "checkpoint.json", record)
    keep = {d.name} | ({Path(previous["dir"]).name} if previous else set())
    for old in (run_dir / "checkpoints").glob("step_*"):
        if old.name not in keep:
            shutil.rmtree(old, ignore_errors=True)
    return record


def checkpoint_writers(model: Any) -> dict[str, Any]:
    """The files of a checkpoint of ``model``, each with the function that writes it to a given path.

    A fast trainer names its own (:meth:`~bluesky_gym.training.fast.base.FastTrainer.checkpoint_writers`);
    an SB3 model writes ``model.zip`` and, for off-policy algorithms, ``replay_buffer.pkl``.
    """
    own = getattr(model, "checkpoint_writers", None)
    if own is not None:
        writers: dict[str, Any] = own()
        return writers
    writers = {"model.zip": model.save}
    if getattr(model, "replay_buffer", None) is not None:
        writers["replay_buffer.pkl"] = model.save_replay_buffer
    return writers


@dataclass
class RunHealth:
    """What :func:`inspect_run` found in a run directory.

    Attributes:
        problems: The damage, one sentence each naming the file (empty: intact).
        intact: Committed checkpoints whose files are intact and whose episodes are all in the
            log, newest first (the ones a run can resume from).
        log_rows: Complete rows of the episode log (None: there is none).

    """

    problems: list[str]
    intact: list[dict[str, Any]]
    log_rows: int | None


def _checkpoint_damage(run_dir: Path, record: dict[str, Any], log_rows: int | None, deep: bool = True) -> list[str]:
    where = run_dir / str(record.get("dir", "?"))
    step = record.get("timesteps", "?")
    if not where.is_dir():
        return [f"checkpoint.json names {where}, which is missing"]
    names = list(record.get("files") or {}) or ["model.zip"] + (["replay_buffer.pkl"] if record.get("replay_buffer") else [])
    out = [f"checkpoint at {step} steps: {bad}" for n in names if (bad := file_damage(where / n, record.get("files", {}).get(n), deep))]
    if not out:  # the record must agree with the model it names (an edited step count would be trusted on resume)
        held = _model_data(where / "model.zip").get("num_timesteps")
        if held is None:
            out.append(f"checkpoint at {step} steps: {where / 'model.zip'} cannot be read as a model")
        elif held != step:
            out.append(f"checkpoint.json says {step} steps, but {where / 'model.zip'} holds {held} (edited or replaced)")
    n = int(record.get("episodes_logged", 0))
    log = run_dir / EPISODE_LOG
    if n > 0 and log_rows is None:
        out.append(f"{log} is missing; the checkpoint at {step} steps includes {n} logged episodes")
    elif log_rows is not None and log_rows < n:
        out.append(f"{log} has {log_rows} complete rows; the checkpoint at {step} steps includes {n} (truncated)")
    return out


def inspect_run(run_dir: str | Path, deep: bool = True) -> RunHealth:
    """Check a run directory for damage: JSON files, checkpoint files against their checksums and step counts, the episode log.

    Where ``checkpoint.json`` is unreadable or missing, the intact checkpoints are those of
    ``checkpoints/step_*`` that pass the checks of :func:`_checkpoints_on_disk`.

    Args:
        run_dir: The run directory.
        deep: Compare checksums (else only the sizes of the files).

    """
    d = Path(run_dir)
    problems: list[str] = []
    result = config = None
    for name in ("config.json", "run.json", "result.json"):
        if (d / name).exists():
            try:
                data = read_json(d / name)
            except DamagedFileError as exc:
                problems.append(str(exc))
                continue
            if name == "result.json":
                result = data
            elif name == "config.json":
                config = data
    log = d / EPISODE_LOG
    log_rows = len(read_csv_rows(log)[1]) if log.exists() else None
    records: list[dict[str, Any]] = []
    unrecorded = False  # checkpoint.json is unreadable or missing: the checkpoints on disk are checked by their own files
    if (d / "checkpoint.json").exists():
        try:
            latest = read_json(d / "checkpoint.json")
            records = [latest] + ([latest["previous"]] if latest.get("previous") else [])
        except DamagedFileError as exc:
            problems.append(str(exc))
            unrecorded = True
    elif any((d / "checkpoints").glob("step_*")):
        problems.append(f"{d / 'checkpoint.json'} is missing but {d / 'checkpoints'} holds checkpoints")
        unrecorded = True
    intact = _checkpoints_on_disk(d, config, result, deep) if unrecorded else []
    for k, record in enumerate(records):
        damage = _checkpoint_damage(d, record, log_rows, deep)
        if not damage:
            intact.append(record)
        elif k == 0:
            problems.extend(damage)
    if result is not None:
        removed = set((result.get("summarised") or {}).get("removed", ()))  # a run summary (bluesky_gym.training.summary)
        bad = None if "model.zip" in removed else file_damage(d / "model.zip", result.get("files", {}).get("model.zip"), deep)
        if bad:
            problems.append(f"final model: {bad}")
        if EPISODE_LOG not in removed:
            if log_rows is not None and log_rows < int(result.get("episodes", 0)):
                problems.append(f"{log} has {log_rows} complete rows; result.json counts {result.get('episodes')} (truncated)")
            elif log_rows is None and int(result.get("episodes", 0)) > 0:
                problems.append(f"{log} is missing; result.json counts {result.get('episodes')} episodes")
    return RunHealth(problems, intact, log_rows)


def _model_data(path: Path) -> dict[str, Any]:
    """The attributes an SB3 model file stores as JSON (its ``data`` member), or ``{}`` if it cannot be read."""
    try:
        with zipfile.ZipFile(path) as z:
            data = json.loads(z.read("data"))
    except (OSError, KeyError, ValueError, zipfile.BadZipFile):
        return {}
    return data if isinstance(data, dict) else {}


def _zip_intact(path: Path) -> bool:
    """True if every member of a zip file matches the CRC stored with it."""
    try:
        with zipfile.ZipFile(path) as z:
            return z.testzip() is None
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, zlib.error):
        return False


def _whole_pickle(path: Path) -> bool:
    """True if a pickle file parses to its end (a truncated file does not); nothing in it is loaded."""
    try:
        with open(path, "rb") as f:
            for _ in pickletools.genops(f):
                pass
    except (OSError, ValueError, EOFError):
        return False
    return True


def _checkpoint_files(trainer: str, off_policy: bool) -> list[str] | None:
    """The files :func:`checkpoint_writers` writes for a trainer (None: the fast trainer cannot be imported here)."""
    if trainer != "fast":
        return ["model.zip"] + (["replay_buffer.pkl"] if off_policy else [])
    try:
        from bluesky_gym.training.fast.base import FastTrainer
        from bluesky_gym.training.fast.offpolicy import REPLAY_FILE
    except ImportError:
        return None
    return ["model.zip", FastTrainer.STATE_FILE] + ([REPLAY_FILE] if off_policy else [])


def _checkpoints_on_disk(run_dir: Path, config: dict[str, Any] | None, result: dict[str, Any] | None, deep: bool = True) -> list[dict[str, Any]]:
    """The checkpoints in ``checkpoints/step_*`` that can be resumed without ``checkpoint.json``, newest first.

    Without the sizes and checksums of ``checkpoint.json`` a checkpoint counts as intact when its
    ``model.zip`` holds the step count of its directory's name, every other file its trainer
    writes (the replay buffer of an off-policy algorithm; the fast trainer's state) is there, and,
    with ``deep``, its zip files (``.zip``, ``.pt``) pass the CRCs of their members and a pickled
    replay buffer parses to its end; and when the episode log shows that it reaches past the
    checkpoint: a row logged after it, or, at the final checkpoint, as many rows as
    ``result.json`` counts. Its record (episodes logged, wall time, file checksums) is rebuilt
    from these files.

    Args:
        run_dir: The run directory.
        config: The content of ``config.json`` (None: unreadable; the trainer is then told by the files).
        result: The content of ``result.json`` (None: none, or unreadable).
        deep: Read the files whole (else only their structure).

    """
    log = run_dir / EPISODE_LOG
    header, rows = read_csv_rows(log) if log.exists() else ([], [])
    if "timesteps" not in header:
        rows = []
    column = header.index("timesteps") if rows else 0
    try:
        steps = [int(r[column]) for r in rows]
    except ValueError:  # an edited log: nothing can be matched to it
        return []
    walls = [r[header.index("wall_time_s")] if "wall_time_s" in header else "" for r in rows]
    found = []
    for where in sorted((run_dir / "checkpoints").glob("step_*"), reverse=True):
        try:
            step = int(where.name.removeprefix("step_"))
        except ValueError:
            continue
        data = _model_data(where / "model.zip")
        if data.get("num_timesteps") != step:
            continue
        if config is not None:
            trainer = str(config.get("trainer", "sb3"))
        else:  # told by the fast trainer's own state file
            trainer = "fast" if any((where / n).exists() for n in (_checkpoint_files("fast", False) or [])[1:]) else "sb3"
        names = _checkpoint_files(trainer, "replay_buffer_class" in data)  # an off-policy model: its replay buffer is part of it
        if names is None or not all((where / n).is_file() for n in names):
            continue
        if deep and not all(_whole_pickle(where / n) if n.endswith(".pkl") else _zip_intact(where / n) for n in names):
            continue
        logged = next((k for k, t in enumerate(steps) if t > step), None)
        wall = walls[logged - 1] if logged else ""
        if logged is None:  # nothing logged after it: the log may have lost rows of the checkpoint, unless result.json counts them
            if result is None or result.get("timesteps") != step or len(rows) != result.get("episodes"):
                continue
            logged, wall = len(rows), result.get("wall_time_s", "")
        found.append(
            {
                "timesteps": step,
                "dir": where.relative_to(run_dir).as_posix(),
                "episodes_logged": logged,
                "wall_time_s": _float(wall),  # of the last episode logged before it: the wall time it includes, nearly
                "replay_buffer": any(n.startswith("replay_buffer") for n in names),
                "files": {n: file_record(where / n) for n in names} if deep else {},
                "saved_at": None,
                "recovered": "without checkpoint.json, from the files of the checkpoint and the episode log",
                "previous": None,
            }
        )
    return found


def _float(value: Any) -> float:
    try:
        return float(value)
    except (TypeError, ValueError):
        return 0.0


def _damage_message(d: Path, health: RunHealth) -> str:
    if health.intact:
        resume = f"--resume-from-last-intact (on_damage='resume') continues from the intact checkpoint at {health.intact[0]['timesteps']} steps"
    else:
        resume = "no intact checkpoint is left to resume from"
    return f"{d} is damaged: {'; '.join(health.problems)}. {resume}; --restart (on_damage='restart') starts the run over"


def _repair(d: Path, health: RunHealth, on_damage: str, verbose: int) -> tuple[dict[str, Any] | None, dict[str, Any] | None]:
    """Decide where training starts; return ``(checkpoint record or None, repair note or None)``."""
    if not health.problems:
        latest = latest_checkpoint(d)
        return (latest[0] if latest else None), None
    if on_damage == "error":
        raise RunDamaged(_damage_message(d, health))
    for name in ("config.json", "run.json"):  # unreadable metadata: rewritten from the run's spec
        if any(p.startswith(str(d / name)) for p in health.problems):
            (d / name).unlink()
    if on_damage == "resume":
        if not health.intact:
            raise RunDamaged(_damage_message(d, health))
        record = health.intact[0]
        for name in ("model.zip", "eval.json", "eval_episodes.csv", "result.json"):
            (d / name).unlink(missing_ok=True)
        atomic_write_json(d / "checkpoint.json", {**record, "previous": None})
        for old in (d / "checkpoints").glob("step_*"):
            if old.name != Path(record["dir"]).name:
                shutil.rmtree(old, ignore_errors=True)
        action = f"resumed from the last intact checkpoint at {record['timesteps']} steps"
    else:
        for name in TRAINING_OUTPUTS:
            (d / name).unlink(missing_ok=True)
        for sub in ("checkpoints", TENSORBOARD_DIR):
            shutil.rmtree(d / sub, ignore_errors=True)
        record = None
        action = "started over"
    if verbose:
        print(f"{d} was damaged ({'; '.join(health.problems)}); {action}", flush=True)
    return record, {"damage": health.problems, "action": action}


# --- the bookkeeping during training ----------------------------------------------------------------
class RunBook:
    """The episode log and the checkpoints of a run while it trains, for either trainer.

    The SB3 callback (:func:`_make_callback`) and the fast trainer's hooks both report to it: a
    rollout start (where a checkpoint is taken when one is due) and each finished episode.

    Args:
        run_dir: The run directory.
        spec: The run.
        log: The episode log.
        start_timesteps: Steps done when this process started.
        wall_offset: Training wall time of earlier processes.
        verbose: 1 prints a line per checkpoint.

    """

    def __init__(self, run_dir: Path, spec: RunSpec, log: AppendCSV, start_timesteps: int, wall_offset: float, verbose: int) -> None:
        self.run_dir, self.spec, self.log, self.verbose = run_dir, spec, log, verbose
        self.start_timesteps = start_timesteps
        self.last_checkpoint = start_timesteps
        self.wall_offset = wall_offset
        self.t0 = time.time()
        self.recent: list[float] = []

    def wall_time(self) -> float:
        """Training wall time of the run so far, earlier processes included."""
        return self.wall_offset + time.time() - self.t0

    def rollout_start(self, model: Any) -> None:
        """Take a checkpoint if ``checkpoint_freq`` steps were done since the last one."""
        if model.num_timesteps - self.last_checkpoint >= self.spec.checkpoint_freq:
            self.checkpoint(model)

    def checkpoint(self, model: Any) -> None:
        """Commit a checkpoint of ``model`` (the episode log is flushed first)."""
        self.log.flush()
        save_checkpoint(model, self.run_dir, self.log.rows_written, self.wall_time())
        self.last_checkpoint = model.num_timesteps
        if self.verbose:
            mean = sum(self.recent) / len(self.recent) if self.recent else float("nan")
            rate = (model.num_timesteps - self.start_timesteps) / max(time.time() - self.t0, 1e-9)
            print(
                f"[{self.spec.env_id} {self.spec.algo} seed {self.spec.seed}] checkpoint at {model.num_timesteps} steps, "
                f"{rate:.0f} steps/s, mean return of the last {len(self.recent)} episodes {mean:.2f}",
                flush=True,
            )
            self.recent.clear()

    def episode(self, timesteps: int, record: dict[str, Any]) -> None:
        """Append a finished episode (``env_index``, ``return``, ``length``, ``terminated``, components, info values) to the log."""
        self.log.append({"episode": self.log.rows_written, "timesteps": timesteps, "wall_time_s": round(self.wall_time(), 3), **record})
        self.recent.append(float(record["return"]))

    # the fast trainer's hooks (bluesky_gym.training.fast.base.Hooks)
    def on_rollout_start(self, trainer: Any) -> None:
        """A fast trainer's rollout starts."""
        self.rollout_start(trainer)

    def on_episodes(self, trainer: Any, records: list[dict[str, Any]]) -> None:
        """A fast trainer's episodes ended."""
        for record in records:
            self.episode(trainer.num_timesteps, record)


class _AllHooks:
    """The run's bookkeeping, then any extra hooks (tests use them to stop a run)."""

    def __init__(self, hooks: list[Any]) -> None:
        self.hooks = hooks

    def on_rollout_start(self, trainer: Any) -> None:
        for hook in self.hooks:
            hook.on_rollout_start(trainer)

    def on_episodes(self, trainer: Any, records: list[dict[str, Any]]) -> None:
        for hook in self.hooks:
            hook.on_episodes(trainer, records)


def _make_callback(book: RunBook) -> Any:
    """Build the SB3 callback that reports episodes and rollout starts to ``book`` (lazily: it needs SB3)."""
    from stable_baselines3.common.callbacks import BaseCallback

    class RunCallback(BaseCallback):
        """Episode log rows and checkpoints at rollout starts."""

        def __init__(self) -> None:
            super().__init__(verbose=0)

        def _on_rollout_start(self) -> None:
            book.rollout_start(self.model)

        def _on_step(self) -> bool:
            for i, info in enumerate(self.locals["infos"]):
                ep = info.get("episode")
                if ep is None:
                    continue
                record = {"env_index": i, "return": ep["r"], "length": ep["l"], "terminated": not info.get("TimeLimit.truncated", False)}
                record.update(info.get("episode_reward_components", {}))
                record.update(
                    {k: v for k, v in info.items() if isinstance(v, (int, float)) and k != "TimeLimit.truncated" and not k.startswith("reward_")}
                )
                book.episode(self.model.num_timesteps, record)
            return True

    return RunCallback()


def _episode_header(record: dict[str, Any]) -> list[str]:
    rest = sorted(k for k in record if k not in LEADING_COLUMNS)
    ordered = [k for k in rest if not k.startswith(("reward_", "kpi_"))]
    ordered += [k for k in rest if k.startswith("reward_")] + [k for k in rest if k.startswith("kpi_")]
    return LEADING_COLUMNS + ordered


def _truncate_log(path: Path, rows: int) -> None:
    """Keep the header and the first ``rows`` complete rows of the episode log (atomically)."""
    if not path.exists():
        return
    header, data = read_csv_rows(path)
    if rows == 0 or not header:
        path.unlink()
        return
    atomic_write_csv(path, header, data[:rows])


# --- the run -----------------------------------------------------------------------------------------
def run_status(run_dir: str | Path) -> str:
    """``finished``, ``checkpointed`` (resumable), ``started``, ``new`` or ``damaged`` (an unreadable ``checkpoint.json``)."""
    d = Path(run_dir)
    if (d / "result.json").exists():
        return "finished"
    try:
        if latest_checkpoint(d) is not None:
            return "checkpointed"
    except DamagedFileError:
        return "damaged"
    return "started" if (d / "config.json").exists() else "new"


def run_training(
    spec: RunSpec,
    run_dir: str | Path,
    *,
    progress_bar: bool = False,
    verbose: int = 1,
    callbacks: list[Any] | None = None,
    on_damage: str = "error",
    tensorboard: bool = True,
) -> dict[str, Any]:
    """Train (or resume, or skip if finished) one run and return its ``result.json`` content.

    The environment, its options and the hyperparameter names are checked before the run
    directory is created; if the run fails before training started, the directory it created is
    removed again.

    Args:
        spec: The run.
        run_dir: Its directory (created if needed).
        progress_bar: Show SB3's progress bar (needs tqdm and rich).
        verbose: 1 prints a line per checkpoint and at the end.
        callbacks: Extra SB3 callbacks (e.g. to stop early).
        on_damage: What to do with a damaged run directory (see :func:`inspect_run`): ``"error"``
            raises :class:`RunDamaged` naming the damage, ``"resume"`` resumes from the last intact
            checkpoint (the episode log cut to it), ``"restart"`` deletes the training outputs
            and starts over.
        tensorboard: Write SB3's TensorBoard log to ``<run_dir>/tensorboard`` (needs the
            ``tensorboard`` package of the ``train`` extra).

    Raises:
        RunConfigMismatch: ``run_dir`` holds a run with another configuration.
        RunLocked: another live process trains in ``run_dir``.
        RunDamaged: ``run_dir`` is damaged and ``on_damage`` is ``"error"`` (or nothing intact is left to resume).

    """
    require_sb3()
    if on_damage not in ON_DAMAGE:
        raise ValueError(f"on_damage must be one of {', '.join(ON_DAMAGE)}, got {on_damage!r}")
    if tensorboard:
        _require_tensorboard()
    check_hyperparameter_names(spec.algo, spec.hyperparams, trainer=spec.trainer)
    d = Path(run_dir)
    venv = _make_venv(spec)  # checks the id and the scenario options before anything is written
    created = [p for p in [d, *d.parents] if not p.exists()]
    try:
        d.mkdir(parents=True, exist_ok=True)
        with RunLock(d):
            for stale in d.rglob(".*.tmp"):  # temporary files of a writer killed mid-write
                stale.unlink(missing_ok=True)
            record, note = _repair(d, inspect_run(d), on_damage, verbose)
            _check_or_write_config(spec, d, verbose)
            if (d / "result.json").exists():
                result = read_json(d / "result.json")
                result["skipped"] = True
                return result
            return _train(spec, d, venv, record, note, progress_bar, verbose, callbacks or [], tensorboard)
    except BaseException:
        if created and not (d / "run.json").exists():  # failed before training: leave nothing behind
            shutil.rmtree(d, ignore_errors=True)
            for p in created[1:]:
                with contextlib.suppress(OSError):
                    p.rmdir()  # only if empty
        raise
    finally:
        venv.close()


def _require_tensorboard() -> None:
    import importlib.util

    if importlib.util.find_spec("tensorboard") is None:
        error = missing_extra("TensorBoard logging needs the tensorboard package", "train")
        raise MissingDependencyError(f"{error} (or train without it: --no-tensorboard)")


def _make_venv(spec: RunSpec) -> Any:
    from bluesky_gym.training.sb3_vec_env import SB3VecEnv

    device = {"device": spec.env_device} if spec.env_device != "cpu" else {}
    try:
        return SB3VecEnv(spec.env_id, num_envs=spec.n_envs, **spec.env_options, **device)
    except TypeError as exc:  # unknown scenario option names
        raise ValueError(f"env_options of {spec.env_id}: {exc}") from None


def _nothing_trained(d: Path) -> bool:
    """True if a run directory holds no trace of training (only a configuration, from a failed start)."""
    return not any((d / name).exists() for name in ("run.json", "checkpoints", *TRAINING_OUTPUTS))


def _check_or_write_config(spec: RunSpec, d: Path, verbose: int = 0) -> None:
    path = d / "config.json"
    if path.exists():
        stored = read_json(path)
        if stored.get("identity") != spec.identity() and _nothing_trained(d):
            if verbose:
                print(f"{d} holds only the configuration of a start that failed; replacing it", flush=True)
        elif stored.get("identity") != spec.identity():
            old, new = stored.get("identity", {}), spec.identity()
            diff = sorted(k for k in set(old) | set(new) if old.get(k) != new.get(k))
            raise RunConfigMismatch(f"{d} holds a run with another configuration (differs in: {', '.join(diff)}); use another output directory")
        return
    atomic_write_json(
        path,
        {
            **asdict(spec),
            "identity": spec.identity(),
            "digest": spec.digest(),
            "policy": POLICY,
            "seeds": {
                "train": f"training scenario seeds derived from seed {spec.seed}, all below 2**31",
                "train_env_seeds_at_start": train_env_seeds(spec.seed, spec.n_envs),
                "eval_seed_base": EVAL_SEED_BASE,
            },
            "created_at": _now(),
        },
    )


def set_torch_threads(n: int) -> None:
    """Limit PyTorch to ``n`` intra-op threads (0 leaves its default).

    Small MLPs gain nothing from several threads, and on a loaded machine threads that wait for
    each other slow training down by an order of magnitude.
    """
    if n > 0:
        import torch

        torch.set_num_threads(n)


def new_model(spec: RunSpec, venv: Any, tensorboard_log: str | None = None) -> Any:
    """Create the untrained SB3 model of a run on ``venv`` (seeded with the run seed; TensorBoard log directory optional)."""
    cls = algorithm_class(spec.algo)
    return cls(POLICY, venv, seed=spec.seed, device=spec.device, verbose=0, tensorboard_log=tensorboard_log, **sb3_kwargs(spec.hyperparams))


def _train(
    spec: RunSpec,
    d: Path,
    venv: Any,
    record: dict[str, Any] | None,
    note: dict[str, Any] | None,
    progress_bar: bool,
    verbose: int,
    extra_callbacks: list[Any],
    tensorboard: bool,
) -> dict[str, Any]:
    set_torch_threads(spec.torch_threads)
    log_path = d / EPISODE_LOG
    tb_dir = str(d / TENSORBOARD_DIR) if tensorboard else None
    fast = spec.trainer == "fast"
    if record is not None:
        ckpt_dir = d / record["dir"]
        model = _load_checkpoint(spec, ckpt_dir, venv, None if fast else tb_dir)
        if int(model.num_timesteps) != int(record["timesteps"]):  # inspect_run checks it; a resume must never count other steps
            raise RunDamaged(f"{ckpt_dir / 'model.zip'} holds {model.num_timesteps} steps, checkpoint.json says {record['timesteps']}")
        stream = train_env_seeds(spec.seed, 1, stream=int(record["timesteps"]))[0]
        _truncate_log(log_path, int(record["episodes_logged"]))
        wall_offset = float(record["wall_time_s"])
        resumed_from: int | None = int(record["timesteps"])
    else:
        model = new_model(spec, venv, tensorboard_log=None if fast else tb_dir)
        stream = spec.seed
        if verbose and log_path.exists() and read_csv_rows(log_path)[1]:
            print(f"{d}: no checkpoint was taken; starting over (the logged episodes are played again)", flush=True)
        _truncate_log(log_path, 0)
        wall_offset = 0.0
        resumed_from = None
    trainer = None
    if fast:
        trainer = _fast_trainer(spec, model, venv, tb_dir, None if record is None else d / record["dir"])
        trainer.start(train_env_seeds(stream, spec.n_envs))
    elif record is not None:
        model.set_random_seed(stream)
    if not fast and tb_dir is None:  # SB3's own logger would make an empty SB3-<date> folder in the temporary directory
        from stable_baselines3.common.logger import Logger

        model.set_logger(Logger(folder=None, output_formats=[]))
    start = int(model.num_timesteps)
    process = _start_process(d, start, resumed_from, note)

    log = AppendCSV(log_path, _episode_header)
    book = RunBook(d, spec, log, start, wall_offset, verbose)
    learner = trainer if trainer is not None else model
    if verbose:
        what = f"resuming from {start} steps" if resumed_from is not None else "starting"
        tag = f"[{spec.env_id} {spec.algo} seed {spec.seed}]"
        print(f"{tag} {what}; {spec.total_timesteps} steps, {spec.n_envs} environments, {spec.trainer} trainer -> {d}", flush=True)
    try:
        if trainer is not None:
            try:
                trainer.learn(spec.total_timesteps, _AllHooks([book, *extra_callbacks]), progress_bar=progress_bar)
            finally:
                trainer.close()
        elif spec.total_timesteps > start:
            model.learn(
                total_timesteps=spec.total_timesteps - start,
                callback=[_make_callback(book), *extra_callbacks],
                reset_num_timesteps=resumed_from is None,
                progress_bar=progress_bar,
                tb_log_name=spec.algo,
            )
        wall = book.wall_time()
        if int(learner.num_timesteps) != book.last_checkpoint:
            book.checkpoint(learner)
    except BaseException as exc:
        _end_process(d, process, int(learner.num_timesteps), error=f"{type(exc).__name__}: {exc}")
        raise
    finally:
        log.close()

    with atomic_path(d / "model.zip") as tmp:
        learner.save(tmp)
    eval_summary = None
    if spec.eval_episodes > 0:
        from bluesky_gym.training.evaluation import evaluate, save_result
        from bluesky_gym.training.policies import SB3Policy

        res = evaluate(spec.env_id, SB3Policy(model, name=spec.algo), spec.eval_episodes, env_options=spec.env_options)
        save_result(res, d, stem="eval")
        eval_summary = res.summary
    timesteps = int(learner.num_timesteps)
    trained = timesteps - start
    result = {
        "status": "finished",
        "env_id": spec.env_id,
        "algo": spec.algo,
        "seed": spec.seed,
        "digest": spec.digest(),
        "trainer": spec.trainer,
        "timesteps": timesteps,
        "episodes": log.rows_written,
        "wall_time_s": wall,
        "steps_per_second_last_process": trained / max(wall - wall_offset, 1e-9) if trained else None,
        "resumed_from": resumed_from,
        "eval_episodes": spec.eval_episodes,
        "eval": eval_summary,
        "files": {"model.zip": file_record(d / "model.zip")},
        "finished_at": _now(),
    }
    _end_process(d, process, timesteps)
    atomic_write_json(d / "result.json", result)
    if verbose:
        ret = f", held-out return {eval_summary['return']['mean']:.2f}" if eval_summary else ""
        print(f"[{spec.env_id} {spec.algo} seed {spec.seed}] finished: {timesteps} steps in {wall:.0f} s{ret}", flush=True)
    return result


def _load_checkpoint(spec: RunSpec, ckpt_dir: Path, venv: Any, tensorboard_log: str | None) -> Any:
    """Load the SB3 model of a checkpoint (and, for the SB3 trainer, its replay buffer)."""
    cls = algorithm_class(spec.algo)
    try:
        model = cls.load(ckpt_dir / "model.zip", env=venv, device=spec.device, tensorboard_log=tensorboard_log)
        if spec.trainer == "sb3" and (ckpt_dir / "replay_buffer.pkl").exists():
            model.load_replay_buffer(ckpt_dir / "replay_buffer.pkl")
    except Exception as exc:  # damage that no checksum recorded (a checkpoint of an older version)
        raise RunDamaged(f"{ckpt_dir} cannot be loaded ({type(exc).__name__}: {exc}); rerun with --restart (on_damage='restart')") from exc
    return model


def _fast_trainer(spec: RunSpec, model: Any, venv: Any, tensorboard_log: str | None, ckpt_dir: Path | None) -> Any:
    """The fast trainer of a run on its SB3 model (restored from ``ckpt_dir`` if given)."""
    from bluesky_gym.training.fast import trainer_class

    trainer = trainer_class(spec.algo)(model, venv.venv, seed=spec.seed, tensorboard_log=tensorboard_log, compile=spec.compile)
    if ckpt_dir is not None:
        try:
            trainer.restore(ckpt_dir)
        except Exception as exc:
            raise RunDamaged(f"{ckpt_dir} cannot be loaded ({type(exc).__name__}: {exc}); rerun with --restart (on_damage='restart')") from exc
    return trainer


def recorded_command(argv: Sequence[str]) -> list[str]:
    """The command line as a user types it: the program by its name, not by the path it was run from.

    ``python -m bluesky_gym`` (whose ``argv[0]`` is the path of ``__main__.py``) and the
    ``bluesky-gym`` script both read ``bluesky-gym``, so ``run.json`` names no directory of the
    machine that made the run.
    """
    if not argv:
        return []
    program = Path(argv[0]).name
    if program in ("__main__.py", "bluesky-gym"):
        program = "bluesky-gym"
    return [program, *argv[1:]]


def _start_process(d: Path, timesteps: int, resumed_from: int | None, note: dict[str, Any] | None = None) -> int:
    path = d / "run.json"
    data = read_json(path) if path.exists() else {"processes": []}
    entry: dict[str, Any] = {
        "started_at": _now(),
        "host": socket.gethostname(),
        "pid": os.getpid(),
        "start_timesteps": timesteps,
        "resumed_from_checkpoint": resumed_from,
        "versions": package_versions(),
        "command": recorded_command(sys.argv),
    }
    if note:
        entry["repair"] = note
    data["processes"].append(entry)
    atomic_write_json(path, data)
    return len(data["processes"]) - 1


def _end_process(d: Path, index: int, timesteps: int, error: str | None = None) -> None:
    """Record the end of a training process (with the error that ended it, if any)."""
    path = d / "run.json"
    data = read_json(path)
    data["processes"][index].update({"ended_at": _now(), "end_timesteps": timesteps})
    if error is not None:
        data["processes"][index]["error"] = error
    atomic_write_json(path, data)
