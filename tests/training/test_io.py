"""Crash-safe result files."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from bluesky_gym.training.io import AppendCSV, atomic_path, atomic_write_json, atomic_write_text, read_csv_rows, read_json


def test_atomic_write_replaces_or_leaves_untouched(tmp_path: Path) -> None:
    target = tmp_path / "result.json"
    atomic_write_json(target, {"a": 1, "nan": math.nan, "inf": math.inf})
    assert read_json(target) == {"a": 1, "nan": None, "inf": None}
    with pytest.raises(RuntimeError), atomic_path(target) as tmp:
        tmp.write_text("half a fi")
        raise RuntimeError("killed while writing")
    assert read_json(target) == {"a": 1, "nan": None, "inf": None}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["result.json"]  # no temporary file left
    atomic_write_text(target, "{}")
    assert read_json(target) == {}


def test_append_csv_and_cut_last_line(tmp_path: Path) -> None:
    path = tmp_path / "episodes.csv"
    log = AppendCSV(path, lambda rec: sorted(rec))
    log.append({"b": np.float64(2.5), "a": np.int64(1), "c": math.nan})
    log.append({"a": 3, "b": math.inf, "c": "x,y"})
    log.close()
    header, rows = read_csv_rows(path)
    assert header == ["a", "b", "c"] and rows == [["1", "2.5", ""], ["3", "inf", "x,y"]]
    with open(path, "a") as f:
        f.write("4,5")  # a row cut off by a crash
    assert read_csv_rows(path)[1] == rows
    again = AppendCSV(path, lambda rec: ["z"])
    assert again.header == ["a", "b", "c"] and again.rows_written == 2
    again.append({"a": 5, "b": 6, "c": 7})
    again.close()
    assert read_csv_rows(path)[1] == [*rows, ["5", "6", "7"]]
