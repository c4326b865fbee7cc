"""Hyperparameters: the paper's defaults, config files and their resolution for one run.

The paper (BlueSky-Gym, SESAR Innovation Days 2024) trained every algorithm with
Stable-Baselines3 2.2.1 defaults, a learning rate of 3e-4 (1e-4 for PPO on
StaticObstacleEnv-v0), one environment, and 2e6 steps. SB3 2.3 changed the TD3/DDPG defaults, so
the 2.2.1 values are written out here instead of relying on the installed SB3's defaults.

A config file (TOML or JSON) has the same layout as :data:`PAPER`, e.g.::

    [run]
    n_envs = 8
    checkpoint_freq = 20000

    [algos.PPO]
    n_steps = 256

    [algos.PPO.envs."DescentEnv-v0"]
    learning_rate = 1e-4

    [env_options."SectorCREnv-v0"]
    ac_density_mode = "uniform"

Values in a file override the paper's; command-line options override the file.
``configs/paper.toml`` holds exactly :data:`PAPER` (a test keeps the two identical).
"""

from __future__ import annotations

import copy
import difflib
import importlib.util
import inspect
import json
import re
from pathlib import Path
from typing import Any

from bluesky_gym.training import ALGORITHMS, OFF_POLICY, algorithm_class

#: The policy class of every run: observations are dicts.
POLICY = "MultiInputPolicy"

#: Everything a run needs besides env, algorithm, seed and steps.
PAPER: dict[str, Any] = {
    "run": {
        "n_envs": 1,
        "total_timesteps": 2_000_000,
        "checkpoint_freq": 50_000,
        "eval_episodes": 50,
        "device": "cpu",
        "torch_threads": 1,
        "trainer": "sb3",
        "compile": "auto",
        "env_device": "cpu",
    },
    "algos": {
        "PPO": {
            "learning_rate": 3e-4,
            "n_steps": 2048,
            "batch_size": 64,
            "n_epochs": 10,
            "gamma": 0.99,
            "gae_lambda": 0.95,
            "clip_range": 0.2,
            "ent_coef": 0.0,
            "vf_coef": 0.5,
            "max_grad_norm": 0.5,
            "envs": {"StaticObstacleEnv-v0": {"learning_rate": 1e-4}, "StaticObstacleEnv-v1": {"learning_rate": 1e-4}},
        },
        "SAC": {
            "learning_rate": 3e-4,
            "buffer_size": 1_000_000,
            "learning_starts": 100,
            "batch_size": 256,
            "tau": 0.005,
            "gamma": 0.99,
            "train_freq": 1,
            "gradient_steps": 1,
            "ent_coef": "auto",
            "target_entropy": "auto",
        },
        # SB3 2.2.1 defaults (before 2.3 aligned TD3/DDPG with SAC), learning rate from the paper.
        "TD3": {
            "learning_rate": 3e-4,
            "buffer_size": 1_000_000,
            "learning_starts": 100,
            "batch_size": 100,
            "tau": 0.005,
            "gamma": 0.99,
            "train_freq": [1, "episode"],
            "gradient_steps": -1,
            "policy_delay": 2,
            "target_policy_noise": 0.2,
            "target_noise_clip": 0.5,
        },
        "DDPG": {
            "learning_rate": 3e-4,
            "buffer_size": 1_000_000,
            "learning_starts": 100,
            "batch_size": 100,
            "tau": 0.005,
            "gamma": 0.99,
            "train_freq": [1, "episode"],
            "gradient_steps": -1,
        },
    },
    "env_options": {},
}

#: Settings of the ``demo`` command: PPO on 16 batched environments, short rollouts, the fast trainer.
DEMO: dict[str, Any] = {
    "run": {"n_envs": 16, "total_timesteps": 250_000, "checkpoint_freq": 50_000, "eval_episodes": 100, "trainer": "fast"},
    "algos": {"PPO": {"n_steps": 128, "batch_size": 256, "n_epochs": 10}},
}

RUN_KEYS = frozenset(PAPER["run"])


def load_config_file(path: str | Path) -> dict[str, Any]:
    """Read a config file (``.toml`` or ``.json``) and check its layout.

    Raises:
        ValueError: The file is missing, unreadable, not valid TOML/JSON (the message names the
            file and the line) or does not have the layout of :data:`PAPER`.

    """
    p = Path(path)
    if p.suffix.lower() not in (".toml", ".json"):
        raise ValueError(f"config file {p} must end in .toml or .json")
    if not p.is_file():
        raise ValueError(f"config file {p} not found")
    if p.suffix.lower() == ".toml":
        import tomllib

        text = p.read_text(encoding="utf-8")
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:  # its message ends with "(at line L, column C)"
            raise ValueError(f"{p}: not valid TOML: {exc}") from None
    else:  # .json
        text = p.read_text(encoding="utf-8")
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            raise ValueError(f"{p}, line {exc.lineno}, column {exc.colno}: not valid JSON: {exc.msg}") from None
        if not isinstance(data, dict):
            raise ValueError(f"{p}: expected a JSON object with the sections run, algos, env_options")
    check_config(data, source=str(p), text=text)
    return data


#: Constructor arguments that the runner sets itself (a config file may not).
RUNNER_ARGUMENTS = frozenset({"self", "policy", "env", "seed", "device", "verbose", "tensorboard_log", "_init_setup_model"})


def hyperparameter_names(algo: str, trainer: str = "sb3") -> frozenset[str] | None:
    """Return the hyperparameters a config may set for ``algo`` with ``trainer``; None if SB3 is not installed.

    For SB3 they are the arguments of its constructor; the fast trainer implements a subset of
    them (:data:`bluesky_gym.training.fast.HYPERPARAMETERS`).
    """
    if trainer == "fast":
        from bluesky_gym.training.fast import HYPERPARAMETERS

        return HYPERPARAMETERS[algo.upper()]
    if importlib.util.find_spec("stable_baselines3") is None:
        return None
    return frozenset(inspect.signature(algorithm_class(algo).__init__).parameters) - RUNNER_ARGUMENTS


def check_hyperparameter_names(
    algo: str, hp: dict[str, Any], source: str = "hyperparameters", table: str = "", text: str = "", trainer: str = "sb3"
) -> None:
    """Raise ``ValueError`` naming the first key of ``hp`` that the algorithm does not take, and the valid keys.

    Args:
        algo: Algorithm name.
        hp: Hyperparameters (an ``envs`` sub-table is allowed).
        source: Where they come from (a file name), for the message.
        table: The table they sit in, for the message (default ``algos.<ALGO>``).
        text: The source's text, to find the line of the key.
        trainer: ``"sb3"`` or ``"fast"``: a name SB3 takes but the fast trainer does not implement is refused too.

    """
    valid = hyperparameter_names(algo, trainer)
    if valid is None:
        return
    unknown = sorted(set(hp) - valid - {"envs"})
    if not unknown:
        return
    key = unknown[0]
    if trainer != "sb3" and key in (hyperparameter_names(algo) or ()):
        raise ValueError(f"{source}: {key!r} is not supported by the {trainer} trainer; it implements: {', '.join(sorted(valid))}")
    close = difflib.get_close_matches(key, sorted(valid), n=1)
    hint = f" (did you mean {close[0]!r}?)" if close else ""
    found = re.search(rf'^\s*"?{re.escape(key)}"?\s*[=:]', text, flags=re.MULTILINE) if text else None
    where = f"{source}:{text.count(chr(10), 0, found.start()) + 1}" if found else source
    raise ValueError(f"{where}: unknown key {key!r} in [{table or 'algos.' + algo.upper()}]{hint}; valid keys: {', '.join(sorted(valid))}")


def check_config(data: dict[str, Any], source: str = "config", text: str = "") -> None:
    """Raise ``ValueError`` if ``data`` does not have the layout of :data:`PAPER` or names unknown hyperparameters.

    Args:
        data: The parsed config.
        source: Its file name, for the messages.
        text: Its text, to give the line of an unknown key.

    """
    unknown = set(data) - {"run", "algos", "env_options"}
    if unknown:
        raise ValueError(f"{source}: unknown section(s) {sorted(unknown)}; expected run, algos, env_options")
    bad_run = set(data.get("run", {})) - RUN_KEYS
    if bad_run:
        raise ValueError(f"{source}: unknown [run] key(s) {sorted(bad_run)}; valid: {', '.join(sorted(RUN_KEYS))}")
    for algo, table in data.get("algos", {}).items():
        if algo not in ALGORITHMS:
            raise ValueError(f"{source}: unknown algorithm [algos.{algo}]; choose from {', '.join(ALGORITHMS)}")
        if not isinstance(table, dict) or not isinstance(table.get("envs", {}), dict):
            raise ValueError(f"{source}: [algos.{algo}] must be a table (with an optional 'envs' sub-table)")
        check_hyperparameter_names(algo, table, source, f"algos.{algo}", text)
        for env_id, per_env in table.get("envs", {}).items():
            check_hyperparameter_names(algo, per_env, source, f'algos.{algo}.envs."{env_id}"', text)
    for env_id, opts in data.get("env_options", {}).items():
        if not isinstance(opts, dict):
            raise ValueError(f'{source}: [env_options."{env_id}"] must be a table')
    check_value_types(data, source, text)


#: Keys of the ``run`` table that take a whole number (``2e6`` is one).
RUN_INTEGERS = frozenset({"n_envs", "total_timesteps", "checkpoint_freq", "eval_episodes", "torch_threads"})
#: Keys of the ``run`` table that take a string (``compile`` takes ``true``, ``false`` or ``"auto"``).
RUN_STRINGS = frozenset({"device", "trainer", "env_device"})


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _line_of(text: str, path: list[str], key: str) -> int | None:
    """The line of ``key`` in a config text, found after the names of its enclosing tables (None: not found)."""
    pos = 0
    for name in [*path, key]:
        found = re.compile(rf'(?<![\w-])"?{re.escape(name)}"?(?![\w-])').search(text, pos)
        if found is None:
            return None
        pos = found.end()
    return text.count("\n", 0, pos) + 1


def check_value_types(data: dict[str, Any], source: str = "config", text: str = "") -> None:
    """Raise ``ValueError`` naming the file, line and key of the first value of a wrong type.

    The ``run`` counts are whole numbers, ``device`` and ``trainer`` strings, ``compile`` is
    ``true``, ``false`` or ``"auto"``; a hyperparameter whose paper default is a number must be a
    number (``train_freq`` may also be ``[N, "step" | "episode"]``).

    Args:
        data: The parsed config (its layout already checked by :func:`check_config`).
        source: Its file name, for the message.
        text: Its text, to give the line of the key.

    """

    def fail(path: list[str], key: str, what: str, value: Any) -> None:
        line = _line_of(text, path, key) if text else None
        table = ".".join(f'"{p}"' if "-" in p else p for p in path)
        raise ValueError(f"{source}{f':{line}' if line else ''}: [{table}] {key} must be {what}, got {value!r}")

    for key, value in data.get("run", {}).items():
        if key in RUN_INTEGERS and not (_is_number(value) and float(value).is_integer()):
            fail(["run"], key, "an integer", value)
        if key in RUN_STRINGS and not isinstance(value, str):
            fail(["run"], key, "a string", value)
        if key == "compile" and not (isinstance(value, bool) or value == "auto"):
            fail(["run"], key, 'true, false or "auto"', value)
    for algo, table in data.get("algos", {}).items():
        defaults = PAPER["algos"].get(algo, {})
        tables = [(["algos", algo], table)] + [(["algos", algo, "envs", env_id], t) for env_id, t in table.get("envs", {}).items()]
        for path, hp in tables:
            for key, value in hp.items():
                if key == "envs" or not _is_number(defaults.get(key)) or _is_number(value):
                    continue
                if key == "train_freq" and isinstance(value, list):
                    continue
                fail(path, key, "a number", value)


def merge(base: dict[str, Any], override: dict[str, Any]) -> dict[str, Any]:
    """Return a deep copy of ``base`` with ``override`` merged in (tables recursively, values replaced)."""
    out = copy.deepcopy(base)
    for k, v in override.items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = merge(out[k], v)
        else:
            out[k] = copy.deepcopy(v)
    return out


def resolve(config: dict[str, Any], env_id: str, algo: str) -> tuple[dict[str, Any], dict[str, Any], dict[str, Any]]:
    """Return the run settings, algorithm hyperparameters and scenario options of one (env, algorithm).

    Args:
        config: A full config (:data:`PAPER` merged with files and command-line values).
        env_id: Environment id.
        algo: Algorithm name.

    Returns:
        ``(run, hyperparameters, env_options)``; per-environment algorithm overrides are applied.

    """
    algo = algo.upper()
    table = dict(config["algos"].get(algo, {}))
    per_env = table.pop("envs", {})
    hp = merge(table, per_env.get(env_id, {}))
    return dict(config["run"]), hp, dict(config.get("env_options", {}).get(env_id, {}))


def adapt_to_n_envs(algo: str, hp: dict[str, Any], n_envs: int) -> tuple[dict[str, Any], list[str]]:
    """Adjust off-policy settings to several batched environments, keeping the update ratio.

    With one environment the paper's off-policy settings make one gradient step per collected
    transition. SB3 counts ``train_freq`` and ``gradient_steps`` per *vector* step, and refuses
    episodic ``train_freq`` with several environments. So, when ``n_envs > 1``:

    * ``train_freq`` in episodes (TD3/DDPG, SB3 2.2.1) becomes 1 step with ``gradient_steps=-1``
      (one gradient step per transition, as per episode with ``-1``);
    * ``train_freq=1`` step with ``gradient_steps=1`` (SAC) becomes ``gradient_steps=-1``.

    Returns:
        The adjusted hyperparameters and a note per change (recorded in the run directory).

    """
    out = dict(hp)
    notes: list[str] = []
    if algo.upper() not in OFF_POLICY or n_envs <= 1:
        return out, notes
    tf = out.get("train_freq", 1)
    episodic = isinstance(tf, (list, tuple)) and len(tf) == 2 and str(tf[1]).startswith("episode")
    steps = tf if isinstance(tf, int) else (int(tf[0]) if isinstance(tf, (list, tuple)) and not episodic else None)
    if episodic:
        if out.get("gradient_steps", 1) != -1:
            raise ValueError(
                f"{algo}: train_freq {tf} in episodes with gradient_steps={out.get('gradient_steps')} cannot run on "
                f"{n_envs} batched environments; give train_freq in steps"
            )
        out["train_freq"] = 1
        notes.append(f"train_freq {list(tf)} -> 1 step with gradient_steps -1 ({n_envs} environments; SB3 trains per vector step)")
    elif steps == 1 and out.get("gradient_steps", 1) == 1:
        out["gradient_steps"] = -1
        notes.append(f"gradient_steps 1 -> -1: one gradient step per transition with {n_envs} environments, as with one")
    return out, notes


def sb3_kwargs(hp: dict[str, Any]) -> dict[str, Any]:
    """Hyperparameters in the form SB3's constructors take (``train_freq`` lists become tuples)."""
    out = dict(hp)
    tf = out.get("train_freq")
    if isinstance(tf, list):
        out["train_freq"] = (int(tf[0]), str(tf[1]))
    return out
