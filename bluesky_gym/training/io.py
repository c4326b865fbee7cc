"""Crash-safe file writing and CSV/JSON utilities shared by the benchmark modules.

Result files are written atomically: the content goes to a temporary file in the same directory,
is flushed to disk, and replaces the target with :func:`os.replace`. A process killed at any
moment therefore leaves either the old file or the new one, never a half-written one.
"""

from __future__ import annotations

import contextlib
import csv
import hashlib
import json
import math
import os
import uuid
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; on success it replaces ``path`` atomically.

    Use it for writers that want a file name (e.g. ``model.save(tmp)``). If the body raises, the
    temporary file is removed and ``path`` is untouched.
    """
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp_path = target.parent / f".{target.name}.{os.getpid()}.{uuid.uuid4().hex[:12]}.tmp"
    os.close(os.open(tmp_path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o666))  # permissions follow the umask
    try:
        yield tmp_path
        _fsync(tmp_path)
        os.replace(tmp_path, target)
        _fsync(target.parent)
    finally:
        if tmp_path.exists():
            tmp_path.unlink()


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes) -> None:
    """Write ``data`` to ``path`` atomically."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)


def atomic_write_text(path: str | os.PathLike[str], text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    atomic_write_bytes(path, text.encode("utf-8"))


def atomic_write_json(path: str | os.PathLike[str], obj: Any) -> None:
    """Write ``obj`` as indented JSON to ``path`` atomically (NaN and infinities become null)."""
    atomic_write_text(path, json.dumps(json_safe(obj), indent=2, sort_keys=False) + "\n")


def atomic_write_csv(path: str | os.PathLike[str], header: Sequence[str], rows: Sequence[Sequence[Any]]) -> None:
    """Write a CSV file atomically."""
    with atomic_path(path) as tmp, open(tmp, "w", newline="", encoding="utf-8") as f:
        writer = csv.writer(f)
        writer.writerow(header)
        writer.writerows([[format_cell(v) for v in row] for row in rows])


class DamagedFileError(ValueError):
    """A file of a run or cache cannot be read as what it should be; the message names the file."""


def read_json(path: str | os.PathLike[str]) -> Any:
    """Read a JSON file.

    Raises:
        DamagedFileError: The file is not valid JSON (the message names the file and the place).

    """
    with open(path, encoding="utf-8") as f:
        text = f.read()
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise DamagedFileError(f"{path} is not valid JSON ({exc.msg} at line {exc.lineno} column {exc.colno})") from None


def file_record(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Return the size and SHA-256 of a file, as recorded in ``checkpoint.json`` and ``result.json``."""
    digest = hashlib.sha256()
    size = 0
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
            size += len(block)
    return {"bytes": size, "sha256": digest.hexdigest()}


def file_damage(path: str | os.PathLike[str], record: dict[str, Any] | None, deep: bool = True) -> str | None:
    """Compare a file with its :func:`file_record`; return what is wrong with it, or None if intact.

    Without a record (written by an older version) only the file's existence is checked; without
    ``deep`` only its size.
    """
    p = Path(path)
    if not p.is_file():
        return f"{p} is missing"
    if not record:
        return None
    size = p.stat().st_size
    if size != record.get("bytes"):
        return f"{p} has {size} bytes, {record.get('bytes')} were written (truncated or replaced)"
    if deep and file_record(p)["sha256"] != record.get("sha256"):
        return f"{p} does not match the checksum written with it (corrupted or replaced)"
    return None


def latest_checkpoint(run_dir: str | Path) -> tuple[dict[str, Any], Path] | None:
    """Return the committed checkpoint of a run directory: its record and directory (None if there is none).

    ``checkpoint.json`` is written last, atomically, so it only ever names a complete checkpoint.
    Whether its files are intact is checked by :func:`bluesky_gym.training.runner.inspect_run`.
    """
    p = Path(run_dir) / "checkpoint.json"
    if not p.exists():
        return None
    info = read_json(p)
    d = Path(run_dir) / info["dir"]
    if not (d / "model.zip").exists():
        return None
    return info, d


def json_safe(obj: Any) -> Any:
    """Return a copy of ``obj`` that :func:`json.dumps` accepts.

    Numpy scalars become Python numbers, tuples and arrays lists, non-finite floats ``None``.
    """
    if isinstance(obj, dict):
        return {str(k): json_safe(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [json_safe(v) for v in obj]
    if hasattr(obj, "item") and callable(obj.item) and getattr(obj, "ndim", 1) == 0:
        obj = obj.item()
    elif hasattr(obj, "tolist"):
        return json_safe(obj.tolist())
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


def format_cell(v: Any) -> str:
    """Format a CSV cell: floats with full precision, NaN as empty, infinities as ``inf``/``-inf``."""
    if isinstance(v, bool):
        return str(int(v))
    if isinstance(v, float):  # also numpy floats, whose repr() is not a plain number
        if math.isnan(v):
            return ""
        return repr(float(v))
    if hasattr(v, "item") and getattr(v, "ndim", None) == 0:
        return format_cell(v.item())
    return str(v)


def read_csv_rows(path: str | os.PathLike[str]) -> tuple[list[str], list[list[str]]]:
    """Header and complete rows of a CSV file (a trailing line cut off by a crash is dropped)."""
    return read_csv_text(Path(path).read_text(encoding="utf-8"))


def read_csv_text(text: str) -> tuple[list[str], list[list[str]]]:
    """Header and complete rows of CSV text (a trailing line cut off by a crash is dropped)."""
    if not text:
        return [], []
    complete = text if text.endswith("\n") else text[: text.rfind("\n") + 1]
    lines = list(csv.reader(complete.splitlines()))
    if not lines:
        return [], []
    header, rows = lines[0], lines[1:]
    return header, [r for r in rows if len(r) == len(header)]


class AppendCSV:
    """A CSV file that grows by one flushed row at a time (the episode log of a run).

    The header is written with the first row. Rows are flushed (not fsynced) so readers see
    them; a crash may leave a partial last line, which :func:`read_csv_rows` ignores and the
    run's resume rewrites away.
    """

    def __init__(self, path: str | os.PathLike[str], header_fn: Callable[[dict[str, Any]], list[str]]) -> None:
        self.path = Path(path)
        self._header_fn = header_fn
        self.header: list[str] | None = None
        self.rows_written = 0
        self._file: Any = None
        if self.path.exists():
            _cut_partial_line(self.path)
            header, rows = read_csv_rows(self.path)
            self.header = header or None
            self.rows_written = len(rows)

    def append(self, record: dict[str, Any]) -> None:
        """Append one row (keys outside the header are ignored, missing ones left empty)."""
        if self._file is None:
            new = not self.path.exists() or self.path.stat().st_size == 0
            self._file = open(self.path, "a", newline="", encoding="utf-8")  # noqa: SIM115 - held open across rows, closed by close()
            if new or self.header is None:
                self.header = self._header_fn(record)
                self._file.write(",".join(self.header) + "\n")
        assert self.header is not None
        self._file.write(",".join(_csv_escape(format_cell(record.get(k, float("nan")))) for k in self.header) + "\n")
        self._file.flush()
        self.rows_written += 1

    def flush(self) -> None:
        """Flush and fsync the file."""
        if self._file is not None:
            self._file.flush()
            os.fsync(self._file.fileno())

    def close(self) -> None:
        """Close the file."""
        if self._file is not None:
            self._file.close()
            self._file = None


def _cut_partial_line(path: Path) -> None:
    """Drop a last line without its newline (cut off by a crash), so appends start a new row."""
    data = path.read_bytes()
    if data and not data.endswith(b"\n"):
        os.truncate(path, data.rfind(b"\n") + 1)


def _csv_escape(cell: str) -> str:
    if any(c in cell for c in ',"\n'):
        return '"' + cell.replace('"', '""') + '"'
    return cell


def _fsync(path: Path) -> None:
    """Flush a file's or a directory's entries to disk (best effort)."""
    with contextlib.suppress(OSError):
        fd = os.open(path, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
