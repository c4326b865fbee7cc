"""Packed run files: what summaries drop, in a .tar.gz checked against a committed SHA-256 manifest and read back."""

from __future__ import annotations

import hashlib
import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest

from bluesky_gym.cli import build_parser, main
from bluesky_gym.training.pack import RunArtifact, default_manifest_path, pack_runs
from bluesky_gym.training.plotting import load_run

EPISODES = "episode,timesteps,wall_time_s,env_index,return,length\n" + "".join(
    f"{i},{10 * (i + 1)},{0.1 * i:.1f},0,{-i * 0.5},10\n" for i in range(40)
)


def _run(d: Path, seed: int) -> Path:
    """A run directory as a finished run leaves it (the files a summary keeps and those it drops)."""
    d.mkdir(parents=True)
    (d / "config.json").write_text(json.dumps({"env_id": "DescentEnv-v0", "algo": "PPO", "seed": seed, "total_timesteps": 400}))
    (d / "result.json").write_text("{}")
    (d / "episodes.csv").write_text(EPISODES)
    (d / "curve.csv").write_text("timesteps,episodes,wall_time_s,return,length\n200,20,1.9,-4.75,10\n400,20,3.9,-14.75,10\n")
    (d / "model.zip").write_bytes(os.urandom(1000))
    (d / "checkpoints" / "step_000000000200").mkdir(parents=True)
    (d / "checkpoints" / "step_000000000200" / "model.zip").write_bytes(os.urandom(500))
    (d / "eval.json").write_text(json.dumps({"summary": {"return": {"mean": -1.0}}}))
    return d


@pytest.fixture
def sweep(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.chdir(tmp_path)
    for seed in (0, 1):
        _run(Path("sweep") / "DescentEnv-v0" / "PPO" / f"seed_{seed}", seed)
    return Path("sweep")


def _summarise(sweep: Path) -> None:
    """What a summary does to the files that are packed."""
    for d in sorted(sweep.glob("*/*/seed_*")):
        for name in ("episodes.csv", "model.zip"):
            (d / name).unlink()
        (d / "checkpoints" / "step_000000000200" / "model.zip").unlink()


def test_pack_writes_the_dropped_files_and_a_manifest_of_their_sha256(sweep: Path) -> None:
    record = pack_runs([sweep], "out/files.tar.gz")
    assert record == json.loads(Path("out/files.manifest.json").read_text())
    run0 = "sweep/DescentEnv-v0/PPO/seed_0"
    paths = [e["path"] for e in record["files"]]
    assert paths == sorted(paths)
    assert set(paths) == {
        f"sweep/DescentEnv-v0/PPO/seed_{s}/{n}" for s in (0, 1) for n in ("episodes.csv", "model.zip", "checkpoints/step_000000000200/model.zip")
    }
    assert record["runs"] == [run0, "sweep/DescentEnv-v0/PPO/seed_1"]
    for e in record["files"]:
        data = Path(e["path"]).read_bytes()
        assert e["bytes"] == len(data) and e["sha256"] == hashlib.sha256(data).hexdigest()
    archive = Path("out/files.tar.gz").read_bytes()
    assert record["archive_sha256"] == hashlib.sha256(archive).hexdigest() and record["archive_bytes"] == len(archive)
    pack_runs([sweep], "again/files.tar.gz")  # deterministic: the same files give the same archive
    assert Path("again/files.tar.gz").read_bytes() == archive


def test_load_run_reads_the_raw_log_back_from_the_artifact(sweep: Path) -> None:
    d = sweep / "DescentEnv-v0" / "PPO" / "seed_0"
    raw = load_run(d)
    pack_runs([sweep], "files.tar.gz", "manifests/files.manifest.json")
    _summarise(sweep)
    assert load_run(d).columns["return"].tolist() == [-4.75, -14.75]  # the summary's binned curve
    with pytest.raises(FileNotFoundError, match="is missing"):
        RunArtifact.open("manifests/files.manifest.json")
    Path("manifests/files.tar.gz").write_bytes(Path("files.tar.gz").read_bytes())  # the asset downloaded beside its manifest
    artifact = RunArtifact.open("manifests/files.manifest.json")
    back = load_run(d, artifact)
    assert set(back.columns) == set(raw.columns)
    for k, v in raw.columns.items():
        np.testing.assert_array_equal(back.columns[k], v)
    assert artifact.get(d / "model.zip") is not None and artifact.get(d / "eval.json") is None


def test_unpack_restores_the_files_as_they_were(sweep: Path) -> None:
    before = {p: p.read_bytes() for p in sweep.rglob("*") if p.is_file()}
    pack_runs([sweep], "files.tar.gz")
    _summarise(sweep)
    assert main(["results", "unpack", "files.tar.gz"]) == 0
    assert {p: p.read_bytes() for p in sweep.rglob("*") if p.is_file()} == before


def test_an_archive_that_differs_from_its_manifest_is_refused_by_name(sweep: Path) -> None:
    record = pack_runs([sweep], "files.tar.gz")
    manifest = Path("files.manifest.json")
    record["files"][1]["sha256"] = "0" * 64
    manifest.write_text(json.dumps(record))
    with pytest.raises(ValueError, match=f"{record['files'][1]['path']} does not match its SHA-256"):
        RunArtifact.open("files.tar.gz")
    del record["files"][1]
    manifest.write_text(json.dumps(record))
    with pytest.raises(ValueError, match="is not in the manifest"):
        RunArtifact.open(manifest)
    record["files"].append({"path": "sweep/gone.csv", "bytes": 1, "sha256": "0" * 64})
    manifest.write_text(json.dumps(record))
    with pytest.raises(ValueError, match="is not in the manifest"):
        RunArtifact.open(manifest)
    Path("files.tar.gz").unlink()
    with pytest.raises(FileNotFoundError, match="download the release asset files.tar.gz"):
        RunArtifact.open(manifest)


def test_pack_refuses_runs_with_nothing_to_pack_and_bad_names(sweep: Path) -> None:
    with pytest.raises(ValueError, match=r"ends with \.tar\.gz"):
        default_manifest_path("files.zip")
    _summarise(sweep)
    for d in sweep.glob("*/*/seed_*"):
        shutil.rmtree(d / "checkpoints")
    with pytest.raises(ValueError, match="nothing to pack"):
        pack_runs([sweep], "files.tar.gz")


def test_results_pack_is_a_subcommand_beside_the_page_command(sweep: Path, capsys: pytest.CaptureFixture[str]) -> None:
    parser = build_parser()
    page = parser.parse_args(["results", "a", "b", "--out", "page.md"])
    assert page.sweeps == [Path("a"), Path("b")] and page.out == Path("page.md") and page.artifact is None
    assert parser.parse_args(["results", "./pack", "--out", "page.md"]).sweeps == [Path("pack")]
    pack = parser.parse_args(["results", "pack", "a", "--out", "files.tar.gz"])
    assert pack.dirs == [Path("a")] and pack.out == Path("files.tar.gz") and pack.manifest is None
    assert pack.func is not page.func
    with pytest.raises(SystemExit):
        parser.parse_args(["results", "pack", "a"])  # --out is required
    assert "bluesky-gym results pack: error: the following arguments are required: --out" in capsys.readouterr().err
    assert main(["results", "pack", str(sweep), "--out", "dist/files.tar.gz", "--manifest", "files.manifest.json"]) == 0
    assert "packed 6 files of 2 runs" in capsys.readouterr().out
    assert json.loads(Path("files.manifest.json").read_text())["command"] == [
        "bluesky-gym",
        "results",
        "pack",
        "sweep",
        "--out",
        "dist/files.tar.gz",
        "--manifest",
        "files.manifest.json",
    ]
    assert main(["results", "pack", "nowhere", "--out", "x.tar.gz"]) == 2
    assert capsys.readouterr().err.startswith("bluesky-gym results pack: error: nowhere is not a run or sweep directory")


def test_the_page_command_refuses_a_missing_or_damaged_artifact_in_one_line(sweep: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["results", str(sweep), "--artifact", "nowhere.manifest.json", "--out", "page.md"]) == 2
    assert capsys.readouterr().err == "bluesky-gym results: error: nowhere.manifest.json: no such artifact manifest\n"
    pack_runs([sweep], "files.tar.gz")
    Path("files.tar.gz").write_bytes(b"not a tar.gz")
    assert main(["results", str(sweep), "--artifact", "files.tar.gz", "--out", "page.md"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("bluesky-gym results: error: files.tar.gz is not a readable .tar.gz") and err.count("\n") == 1
    assert not Path("page.md").exists()


def test_a_summarised_run_names_where_its_model_went(sweep: Path) -> None:
    from bluesky_gym.training.evaluation import find_model

    d = sweep / "DescentEnv-v0" / "PPO" / "seed_0"
    _summarise(sweep)
    shutil.rmtree(d / "checkpoints")
    with pytest.raises(FileNotFoundError, match="holds neither model.zip nor a checkpoint"):
        find_model(d)
    (d / "result.json").write_text(json.dumps({"summarised": {"removed": ["checkpoints", "episodes.csv", "model.zip"]}}))
    with pytest.raises(FileNotFoundError, match=r"is a run summary: its model.zip went to the run files' release asset \(bluesky-gym results unpack"):
        find_model(d)
