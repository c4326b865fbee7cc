"""Run files as a release artifact: what run summaries drop, packed with a SHA-256 manifest.

The repository keeps run summaries (:mod:`bluesky_gym.training.summary`); the files a summary
removes (final models, checkpoints, TensorBoard logs, the raw episode logs) travel as a release
asset instead. :func:`pack_runs` (``bluesky-gym results pack``) writes them into one
``.tar.gz`` and writes a manifest beside it, the file that is committed: a JSON object with the
archive's name, and per file its path, size in bytes and SHA-256. The archive is deterministic
(members sorted, owner and times zeroed), so packing the same files again gives the same members
and checksums.

:class:`RunArtifact` reads an archive back: it checks the archive against its manifest (the same
paths, each member's size and SHA-256) and serves the files by path, e.g. the raw episode log of a
summarised run to :func:`~bluesky_gym.training.plotting.load_run`. Paths in the manifest are
relative to the directory ``pack`` ran in (the repository root), POSIX-style.
"""

from __future__ import annotations

import gzip
import hashlib
import io
import os
import tarfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from bluesky_gym.training.io import atomic_path, atomic_write_json, read_json
from bluesky_gym.training.plotting import find_runs
from bluesky_gym.training.summary import SUMMARY_DROPS

#: Manifest format version.
MANIFEST_FORMAT = 1
#: Suffix of a manifest's name beside its archive (``NAME.tar.gz`` -> ``NAME.manifest.json``).
MANIFEST_SUFFIX = ".manifest.json"
#: Suffix of an archive's name.
ARCHIVE_SUFFIX = ".tar.gz"


def sha256_file(path: str | os.PathLike[str]) -> str:
    """Hex SHA-256 of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def default_manifest_path(archive: str | os.PathLike[str]) -> Path:
    """The manifest beside an archive: ``NAME.tar.gz`` -> ``NAME.manifest.json``."""
    archive = Path(archive)
    if not archive.name.endswith(ARCHIVE_SUFFIX):
        raise ValueError(f"{archive}: an artifact archive's name ends with {ARCHIVE_SUFFIX}")
    return archive.with_name(archive.name[: -len(ARCHIVE_SUFFIX)] + MANIFEST_SUFFIX)


def dropped_files(run_dir: Path) -> list[Path]:
    """The files of a run that its summary drops (:data:`~bluesky_gym.training.summary.SUMMARY_DROPS`), sorted."""
    out: list[Path] = []
    for name in SUMMARY_DROPS:
        p = run_dir / name
        if p.is_dir():
            out.extend(sorted(q for q in p.rglob("*") if q.is_file()))
        elif p.is_file():
            out.append(p)
    return sorted(out)


def _relative(path: Path, root: Path) -> str:
    try:
        return path.resolve().relative_to(root.resolve()).as_posix()
    except ValueError:
        raise ValueError(f"{path} is not below {root} (pack from a directory that holds the runs)") from None


def pack_runs(
    dirs: Sequence[str | os.PathLike[str]],
    archive: str | os.PathLike[str],
    manifest: str | os.PathLike[str] | None = None,
    root: str | os.PathLike[str] = ".",
    command: Sequence[str] | None = None,
) -> dict[str, Any]:
    """Pack what the summaries of the runs below ``dirs`` drop into ``archive``, and write its manifest.

    Args:
        dirs: Run or sweep directories.
        archive: The ``.tar.gz`` to write (a release asset; not committed).
        manifest: The manifest to write (committed); default beside the archive
            (:func:`default_manifest_path`).
        root: The directory the paths in the archive and manifest are relative to.
        command: The command line that made it, recorded in the manifest.

    Returns:
        The manifest.

    Raises:
        FileNotFoundError: A directory holds no run.
        ValueError: No run holds a file to pack, or a run is not below ``root``.

    """
    root = Path(root)
    archive = Path(archive)
    manifest_path = Path(manifest) if manifest is not None else default_manifest_path(archive)
    if not archive.name.endswith(ARCHIVE_SUFFIX):
        raise ValueError(f"{archive}: an artifact archive's name ends with {ARCHIVE_SUFFIX}")
    runs = find_runs([Path(d) for d in dirs])
    if not runs:
        raise FileNotFoundError(f"no run directories (with config.json) below {', '.join(map(str, dirs))}")
    files = sorted({_relative(p, root): p for run in runs for p in dropped_files(run)}.items())
    if not files:
        raise ValueError(f"nothing to pack: the runs below {', '.join(map(str, dirs))} hold only summaries")
    entries = []
    with atomic_path(archive) as tmp:
        with (
            open(tmp, "wb") as raw,
            gzip.GzipFile(filename="", mode="wb", fileobj=raw, mtime=0) as gz,
            tarfile.open(fileobj=gz, mode="w", format=tarfile.PAX_FORMAT) as tar,
        ):
            for rel, path in files:
                data = path.read_bytes()
                info = tarfile.TarInfo(rel)
                info.size = len(data)
                info.mode = 0o644
                tar.addfile(info, io.BytesIO(data))
                entries.append({"path": rel, "bytes": len(data), "sha256": hashlib.sha256(data).hexdigest()})
    record = {
        "format": MANIFEST_FORMAT,
        "archive": archive.name,
        "archive_bytes": archive.stat().st_size,
        "archive_sha256": sha256_file(archive),
        "command": list(command) if command is not None else None,
        "runs": [_relative(r, root) for r in runs],
        "files": entries,
    }
    atomic_write_json(manifest_path, record)
    return record


@dataclass
class RunArtifact:
    """An archive made by :func:`pack_runs`, checked against its manifest; its files by path."""

    manifest_path: Path
    archive_path: Path
    manifest: dict[str, Any]
    files: dict[str, bytes]
    root: Path

    @classmethod
    def open(cls, path: str | os.PathLike[str], root: str | os.PathLike[str] = ".") -> RunArtifact:
        """Open an artifact by its manifest (the archive beside it, by the name it records) or by its archive (the manifest beside it).

        Every member is read and checked: the archive must hold exactly the manifest's paths,
        each with the recorded size and SHA-256.

        Args:
            path: The manifest (``.json``) or the archive (``.tar.gz``).
            root: The directory the artifact's paths are relative to.

        Raises:
            FileNotFoundError: The manifest or the archive is missing.
            ValueError: The archive does not match its manifest (the message names the first mismatch).

        """
        path = Path(path)
        if path.suffix == ".json":
            manifest_path = path
            if not manifest_path.is_file():
                raise FileNotFoundError(f"{manifest_path}: no such artifact manifest")
            manifest = read_json(manifest_path)
            archive_path = manifest_path.parent / str(manifest.get("archive", ""))
        else:
            archive_path = path
            manifest_path = default_manifest_path(archive_path)
            if not manifest_path.is_file():
                raise FileNotFoundError(f"{manifest_path}: no manifest beside the artifact {archive_path}")
            manifest = read_json(manifest_path)
        if manifest.get("format") != MANIFEST_FORMAT or not isinstance(manifest.get("files"), list):
            raise ValueError(f"{manifest_path} is not an artifact manifest (format {MANIFEST_FORMAT})")
        if not archive_path.is_file():
            raise FileNotFoundError(
                f"{archive_path}: the artifact archive named by {manifest_path} is missing (download the release asset {manifest['archive']})"
            )
        expected = {e["path"]: e for e in manifest["files"]}
        for name in expected:
            if name.startswith("/") or ".." in name.split("/"):
                raise ValueError(f"{manifest_path}: {name} is not a path below the artifact's root")
        files: dict[str, bytes] = {}
        try:
            with tarfile.open(archive_path, mode="r:gz") as tar:
                for member in tar:
                    if not member.isfile():
                        continue
                    entry = expected.get(member.name)
                    if entry is None:
                        raise ValueError(f"{archive_path}: {member.name} is not in the manifest {manifest_path}")
                    f = tar.extractfile(member)
                    data = f.read() if f is not None else b""
                    if len(data) != entry["bytes"] or hashlib.sha256(data).hexdigest() != entry["sha256"]:
                        raise ValueError(f"{archive_path}: {member.name} does not match its SHA-256 in {manifest_path}")
                    files[member.name] = data
        except (tarfile.TarError, EOFError, OSError) as exc:
            raise ValueError(f"{archive_path} is not a readable .tar.gz ({exc})") from None
        missing = sorted(set(expected) - set(files))
        if missing:
            raise ValueError(f"{archive_path} lacks {len(missing)} file(s) of its manifest, first {missing[0]}")
        return cls(manifest_path, archive_path, manifest, files, Path(root))

    def key(self, path: str | os.PathLike[str]) -> str:
        """The artifact path of a file on disk (relative to the artifact's root)."""
        p = Path(path)
        try:
            return p.resolve().relative_to(self.root.resolve()).as_posix()
        except ValueError:
            return p.as_posix()

    def get(self, path: str | os.PathLike[str]) -> bytes | None:
        """The checked bytes of a file (a path on disk, as if the artifact were unpacked in its root); None if not in the artifact."""
        return self.files.get(self.key(path))

    def unpack(self) -> list[Path]:
        """Write every file of the artifact to its place below the root, as it was before the runs were summarised; return the paths written."""
        written = []
        for rel, data in sorted(self.files.items()):
            target = self.root / rel
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_bytes(data)
            written.append(target)
        return written
