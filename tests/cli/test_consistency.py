"""One spelling for every option, errors that show the subcommand's usage, and models that must fit their environment.

Every test runs the installed ``bluesky-gym`` console script in a temporary directory.
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path

import pytest

import bluesky_gym
from bluesky_gym.cli import build_parser, main
from bluesky_gym.cli.train import check_device, ppo_rounding
from bluesky_gym.core.extras import DISTRIBUTION

from .conftest import TINY_CONFIG, needs_sb3, run_cli

#: Every subcommand (with its nested ones), as typed before ``--help``.
SUBCOMMANDS = [
    ["list"],
    ["info"],
    ["train"],
    ["train-ma"],
    ["demo"],
    ["eval"],
    ["plot"],
    ["sweep"],
    ["render"],
    ["bench"],
    ["bench", "core"],
    ["bench", "envs"],
    ["bench", "all"],
    ["bench", "profile"],
    ["results"],
    ["results", "pack"],
    ["results", "unpack"],
]


def _one_error_line(stderr: str, prog: str) -> str:
    errors = [line for line in stderr.splitlines() if line.startswith(f"{prog}: error: ")]
    assert len(errors) == 1, stderr
    assert "Traceback" not in stderr, stderr
    return errors[0]


def test_version(tmp_path: Path) -> None:
    run = run_cli("--version", cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    assert run.stdout.strip() == f"bluesky-gym {bluesky_gym.__version__} ({DISTRIBUTION})"


def test_help_is_at_most_100_columns_on_a_wide_terminal(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    run = run_cli("train", "--help", cwd=tmp_path, columns=273)
    assert run.returncode == 0, run.stderr
    assert 80 < max(len(line) for line in run.stdout.splitlines()) <= 100  # wrapped near 100, not at 273 (nor 80)
    monkeypatch.setenv("COLUMNS", "273")
    for words in SUBCOMMANDS:
        with pytest.raises(SystemExit) as exc:
            build_parser().parse_known_args([*words, "--help"])
        assert exc.value.code == 0
        long = [line for line in capsys.readouterr().out.splitlines() if len(line) > 100]
        assert not long, (words, long)
    monkeypatch.setenv("COLUMNS", "60")
    with pytest.raises(SystemExit):
        build_parser().parse_known_args(["train", "--help"])
    options = capsys.readouterr().out.split("options:")[1]
    assert max(len(line) for line in options.splitlines()) <= 60


@pytest.mark.parametrize(
    ("words", "typo", "meant"),
    [
        (["train", "--env", "DescentEnv-v0"], "--step", "--steps"),
        (["train", "--env", "DescentEnv-v0"], "--num-env", "--num-envs"),
        (["eval", "--env", "DescentEnv-v0", "--model", "random"], "--episode", "--episodes"),
        (["sweep", "--env", "all"], "--seed", "--seeds"),
        (["bench", "envs"], "--num-env", "--num-envs"),
    ],
)
def test_a_misspelled_or_abbreviated_option_shows_the_subcommands_usage(
    tmp_path: Path, words: list[str], typo: str, meant: str, capsys: pytest.CaptureFixture[str]
) -> None:
    prog = "bluesky-gym " + " ".join(w for w in words if not w.startswith("-") and w[0].islower() and w not in ("random", "all"))
    if typo == "--step" or words[0] == "eval":  # through the installed script
        run = run_cli(*words, typo, "3", cwd=tmp_path)
        code, stderr = run.returncode, run.stderr
    else:
        with pytest.raises(SystemExit) as exc:
            main([*words, typo, "3"])
        code, stderr = int(exc.value.code or 0), capsys.readouterr().err
    assert code == 2
    assert stderr.startswith(f"usage: {prog} "), stderr
    line = _one_error_line(stderr, prog)
    assert f"did you mean {meant}?" in line, line
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize(
    ("words", "option"),
    [
        (["train", "--env", "DescentEnv-v0"], "--steps"),
        (["train", "--env", "DescentEnv-v0"], "--num-envs"),
        (["train", "--env", "DescentEnv-v0"], "--checkpoint-freq"),
        (["eval", "--env", "DescentEnv-v0", "--model", "random"], "--episodes"),
        (["eval", "--env", "DescentEnv-v0", "--model", "random"], "--num-envs"),
        (["demo"], "--episodes"),
        (["sweep", "--env", "all"], "--seeds"),
        (["render", "--env", "DescentEnv-v0"], "--episodes"),
        (["render", "--env", "DescentEnv-v0"], "--seed"),
        (["train-ma"], "--num-envs"),
        (["train-ma"], "--steps"),
        (["bench", "envs"], "--num-envs"),
        (["bench", "profile"], "--num-envs"),
    ],
)
def test_counts_accept_whole_numbers_in_any_notation_and_refuse_the_rest(words: list[str], option: str, capsys: pytest.CaptureFixture[str]) -> None:
    parser = build_parser()
    dest = "env_num_envs" if words == ["bench", "envs"] else option.lstrip("-").replace("-", "_")
    for text, value in (("2e6", 2_000_000), ("2_000_000", 2_000_000), ("2000000", 2_000_000)):
        args, extras = parser.parse_known_args([*words, option, text])
        assert not extras
        got = getattr(args, dest)
        assert (got[0] if isinstance(got, list) else got) == value
    refused = ["2.5e0", "-1", "abc", "1e400"] + ([] if option == "--seed" or option == "--seeds" else ["0"])
    for text in refused:
        with pytest.raises(SystemExit) as exc:
            parser.parse_known_args([*words, option, text])
        assert exc.value.code == 2
        err = capsys.readouterr().err
        assert re.search(rf"argument {option}.*(whole number|must be >= [01]|below 2\*\*63).*{re.escape(text)}", err), err


def test_the_readme_sweep_estimate_command_parses(tmp_path: Path) -> None:
    args, extras = build_parser().parse_known_args(["sweep", "--env", "all", "--algos", "all", "--steps", "2e6", "--estimate"])
    assert not extras and args.env == ["all"] and args.steps == 2_000_000 and args.estimate


def test_env_lists_and_deprecated_spellings(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    parser = build_parser()
    args, _ = parser.parse_known_args(["sweep", "--env", "DescentEnv-v0,MergeEnv-v0", "--env", "SectorCREnv-v0"])
    assert args.env == ["DescentEnv-v0", "MergeEnv-v0", "SectorCREnv-v0"]
    assert capsys.readouterr().err == ""
    cases = [
        (["sweep", "--envs", "DescentEnv-v0", "MergeEnv-v0"], "env", ["DescentEnv-v0", "MergeEnv-v0"], "--envs is deprecated; use --env"),
        (["bench", "envs", "--ids", "DescentEnv-v0"], "env", ["DescentEnv-v0"], "--ids is deprecated; use --env"),
        (["bench", "envs", "--batch", "2", "5"], "env_num_envs", [2, 5], "--batch is deprecated; use --num-envs"),
        (["bench", "core", "--envs", "4"], "core_num_envs", [4], "--envs is deprecated; use --num-envs"),
        (["bench", "profile", "--envs", "8"], "num_envs", 8, "--envs is deprecated; use --num-envs"),
        (["eval", "--env", "DescentEnv-v0", "--model", "random", "--batch", "8"], "num_envs", 8, "--batch is deprecated; use --num-envs"),
        (["train", "--env", "DescentEnv-v0", "--n-envs", "8"], "num_envs", 8, "--n-envs is deprecated; use --num-envs"),
        (["demo", "--n-envs", "8"], "num_envs", 8, "--n-envs is deprecated; use --num-envs"),
    ]
    for argv, dest, value, warning in cases:
        args, extras = parser.parse_known_args(argv)
        assert not extras and getattr(args, dest) == value, argv
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "warning: " + warning in err[0], (argv, err)
    # The hidden aliases are not in the help.
    run = run_cli("sweep", "--help", cwd=tmp_path, columns=100)
    assert "--envs" not in run.stdout and "--env ID" in run.stdout


def test_the_positional_id_still_works_with_a_deprecation_warning(tmp_path: Path) -> None:
    old = run_cli("info", "DescentEnv-v0", "--json", cwd=tmp_path)
    new = run_cli("info", "--env", "DescentEnv-v0", "--json", cwd=tmp_path)
    assert old.returncode == new.returncode == 0
    assert json.loads(old.stdout) == json.loads(new.stdout)
    assert new.stderr == ""
    assert old.stderr.strip() == "bluesky-gym info: warning: the positional environment id is deprecated; use --env DescentEnv-v0"


def test_the_environment_is_required(capsys: pytest.CaptureFixture[str]) -> None:
    for words in (["info"], ["train"], ["eval", "--model", "random"], ["render"], ["sweep"]):
        with pytest.raises(SystemExit) as exc:
            main(words)
        assert exc.value.code == 2
        assert "the following arguments are required: --env" in _one_error_line(capsys.readouterr().err, "bluesky-gym " + words[0])


def test_a_bad_config_file_is_named_with_its_line(tmp_path: Path) -> None:
    (tmp_path / "bad.toml").write_text("[run]\nn_envs = 2\n[algos.PPO\nn_steps = 3\n")
    (tmp_path / "bad.json").write_text('{"run": {"n_envs": 2,\n  "oops"}}\n')
    for name, line in (("bad.toml", "line 3"), ("bad.json", "line 2")):
        run = run_cli("train", "--env", "DescentEnv-v0", "--config", name, "--out", "runs", cwd=tmp_path)
        assert run.returncode == 2
        error = _one_error_line(run.stderr, "bluesky-gym train")
        assert name in error and line in error, error
    missing = run_cli("train", "--env", "DescentEnv-v0", "--config", "nothing.toml", cwd=tmp_path)
    assert missing.returncode == 2 and "nothing.toml not found" in _one_error_line(missing.stderr, "bluesky-gym train")
    assert not (tmp_path / "runs").exists()


@needs_sb3
def test_a_device_that_is_not_here_is_refused(tmp_path: Path) -> None:
    import torch

    if torch.cuda.is_available():
        pytest.skip("this machine has CUDA")
    run = run_cli("train", "--env", "DescentEnv-v0", "--device", "cuda", "--steps", "10", "--out", "runs", cwd=tmp_path)
    assert run.returncode == 2
    assert "no CUDA device" in _one_error_line(run.stderr, "bluesky-gym train")
    assert not (tmp_path / "runs").exists()
    with pytest.raises(ValueError, match="'gpu0' is not a torch device"):
        check_device("gpu0")
    check_device("cpu")


def test_ppo_rounding_is_stated() -> None:
    assert ppo_rounding("PPO", {"n_steps": 2048}, 1, 100) is not None
    assert "--steps 100 becomes 2048" in str(ppo_rounding("PPO", {"n_steps": 2048}, 1, 100))
    assert "--steps 5000 becomes 6144" in str(ppo_rounding("PPO", {"n_steps": 1024}, 2, 5000))
    assert ppo_rounding("PPO", {"n_steps": 32}, 2, 128) is None
    assert ppo_rounding("SAC", {}, 1, 100) is None


def test_centralised_ids_in_list_and_info(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    listing = run_cli("list", cwd=tmp_path)
    assert listing.returncode == 0, listing.stderr
    head, _, section = listing.stdout.partition("Centralised multi-agent environments")
    assert section, listing.stdout
    for m in ("SectorCRCentralised-v0", "MergeCentralised-v0", "HorizontalCRCentralised-v0"):
        assert m in section and m not in head
    info = run_cli("info", "--env", "SectorCRCentralised-v0", cwd=tmp_path)
    assert info.returncode == 0 and info.stderr == "", info.stderr
    assert "kind: centralised multi-agent" in info.stdout and "ac_density_mode" in info.stdout
    for m in ("MergeCentralised-v0", "HorizontalCRCentralised-v0"):
        assert main(["info", "--env", m, "--json"]) == 0
        d = json.loads(capsys.readouterr().out)
        assert d["id"] == m and d["kind"] == "centralised multi-agent" and d["options"]


@pytest.fixture(scope="module")
def descent_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, subprocess.CompletedProcess[str]]:
    pytest.importorskip("stable_baselines3")
    cwd = tmp_path_factory.mktemp("descent_run")
    (cwd / "tiny.json").write_text(json.dumps(TINY_CONFIG))
    run = run_cli("train", "--env", "DescentEnv-v0", "--steps", "100", "--num-envs", "2", "--config", "tiny.json", "--no-progress", cwd=cwd)
    assert run.returncode == 0, run.stderr
    return cwd, run


@needs_sb3
def test_ppo_states_the_rounding_of_its_step_budget(descent_run: tuple[Path, subprocess.CompletedProcess[str]]) -> None:
    _, run = descent_run
    assert "PPO trains whole rollouts of n_steps x num_envs = 32 x 2 = 64 steps: --steps 100 becomes 128" in run.stderr


@needs_sb3
def test_a_model_of_another_environment_or_algorithm_is_refused(descent_run: tuple[Path, subprocess.CompletedProcess[str]], tmp_path: Path) -> None:
    cwd, _ = descent_run
    run_dir = cwd / "runs" / "DescentEnv-v0" / "PPO" / "seed_0"
    other = run_cli("eval", "--env", "SectorCREnv-v0", "--model", str(run_dir), "--episodes", "2", cwd=tmp_path)
    assert other.returncode == 2
    error = _one_error_line(other.stderr, "bluesky-gym eval")
    assert "trained on DescentEnv-v0" in error and "config.json" in error and "--env DescentEnv-v0" in error
    algo = run_cli("eval", "--env", "DescentEnv-v0", "--model", str(run_dir / "model.zip"), "--algo", "SAC", "--episodes", "2", cwd=tmp_path)
    assert algo.returncode == 2
    assert "is a PPO model; --algo SAC does not match it" in _one_error_line(algo.stderr, "bluesky-gym eval")
    # Without its run folder, the model's observation space tells.
    shutil.copy(run_dir / "model.zip", tmp_path / "descent.zip")
    bare = run_cli("eval", "--env", "SectorCREnv-v0", "--model", "descent.zip", "--episodes", "2", cwd=tmp_path)
    assert bare.returncode == 2
    assert "trained on other observations than SectorCREnv-v0" in _one_error_line(bare.stderr, "bluesky-gym eval")
    film = run_cli("render", "--env", "SectorCREnv-v0", "--policy", "descent.zip", "--out", "x.gif", cwd=tmp_path)
    assert film.returncode == 2 and "other observations" in _one_error_line(film.stderr, "bluesky-gym render")


@needs_sb3
@pytest.mark.slow
def test_centralised_ids_train_and_evaluate(tmp_path: Path) -> None:
    (tmp_path / "tiny.json").write_text(json.dumps({**TINY_CONFIG, "run": {"checkpoint_freq": 100, "eval_episodes": 1}}))
    env = "MergeCentralised-v0"
    run = run_cli("train", "--env", env, "--steps", "64", "--num-envs", "2", "--config", "tiny.json", "--no-progress", cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    run_dir = tmp_path / "runs" / env / "PPO" / "seed_0"
    assert (run_dir / "model.zip").exists()
    ev = run_cli("eval", "--env", env, "--model", "random", "--model", str(run_dir), "--episodes", "2", cwd=tmp_path)
    assert ev.returncode == 0, ev.stderr
    assert "random" in ev.stdout and "PPO:seed_0" in ev.stdout


@needs_sb3
@pytest.mark.slow
def test_the_multi_agent_trainer_is_a_subcommand(tmp_path: Path) -> None:
    pytest.importorskip("pettingzoo")
    run = run_cli(
        "train-ma", "--env", "merge_v0", "--steps", "640", "--num-envs", "1", "--n-steps", "32", "--batch-size", "64", "--eval-episodes", "1",
        cwd=tmp_path,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr
    assert "trained merge_v0" in run.stdout and "shared PPO" in run.stdout
    bad = run_cli("train-ma", "--env", "DescentEnv-v0", cwd=tmp_path)
    assert bad.returncode == 2 and "must be one of horizontal_cr_v0, sector_cr_v0, merge_v0" in _one_error_line(bad.stderr, "bluesky-gym train-ma")


def _documented_commands() -> list[tuple[str, str]]:
    """Every concrete ``bluesky-gym`` command of the README, the docs and the subcommands' examples."""
    from .conftest import ROOT

    found: list[tuple[str, str]] = []
    for path in [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]:
        in_code = False
        for line in path.read_text(encoding="utf-8").splitlines():
            if line.startswith("```"):
                in_code = not in_code
                continue
            m = re.match(r"^\s*(?:\$ )?(?:\S*/)?bluesky-gym (.*)$", line) if in_code else None
            if m:
                found.append((str(path.relative_to(ROOT)), m.group(1)))
    for module in sorted((ROOT / "bluesky_gym" / "cli").glob("*.py")):
        text = module.read_text(encoding="utf-8").replace("\\\n", " ")
        for m in re.finditer(r"^    bluesky-gym (.*)$", text, flags=re.MULTILINE):
            found.append((module.name, m.group(1)))
    return found


def test_every_documented_command_uses_the_current_spellings(capsys: pytest.CaptureFixture[str]) -> None:
    import shlex

    from bluesky_gym.cli.arguments import chosen_env

    commands = _documented_commands()
    assert len(commands) > 20
    for source, command in commands:
        words = shlex.split(command, comments=True)
        if words and words[0] == "&&":
            continue
        words = words[: words.index("&&")] if "&&" in words else words
        args, extras = build_parser().parse_known_args(words)
        assert not extras, (source, command, extras)
        if hasattr(args, "env_required"):
            chosen_env(args.cli_parser, args)
        assert capsys.readouterr().err == "", (source, command)
