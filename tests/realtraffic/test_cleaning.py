"""The cleaning on arrays gives the library's results bit for bit, several times faster, and says what it does."""

from __future__ import annotations

import io
import time

import numpy as np
import pytest

from bluesky_gym.realtraffic import cleaning
from bluesky_gym.realtraffic.flights import _ARRAYS, RecordedFlights

from .test_sources import _table

pytest.importorskip("traffic")


def _same(a: RecordedFlights, b: RecordedFlights) -> list[str]:
    """The fields in which two collections differ (none: identical, bit for bit)."""
    out = []
    for name in ("name", "epoch", "period", *_ARRAYS):
        x, y = getattr(a, name), getattr(b, name)
        if not (np.array_equal(x, y) if isinstance(x, np.ndarray) else x == y):
            out.append(name)
    return out


@pytest.fixture(scope="module")
def excerpt():
    """Every 25th flight of the switzerland sample (50 flights), identified as the cleaning does."""
    import traffic.data.samples as samples
    from traffic.core import Traffic

    data = samples.switzerland.clean_invalid().assign_id().eval().data
    ids = sorted(data["flight_id"].unique())[::25]
    return Traffic(data[data["flight_id"].isin(ids)])


def _cpu(fn):
    start = time.process_time()
    result = fn()
    return result, time.process_time() - start


def test_the_arrays_give_the_library_cleaning_bit_for_bit_and_three_times_faster(excerpt, monkeypatch) -> None:
    from bluesky_gym.realtraffic import sources

    sources.clean(excerpt.__class__(excerpt.data[excerpt.data["flight_id"] == excerpt.data["flight_id"].iloc[0]]), "warm-up")
    taken = {"arrays": 0, "consistency": 0}
    real_arrays, real_consistency = sources._clean_arrays, cleaning.consistency_filter

    def arrays(*args, **kwargs):
        taken["arrays"] += 1
        return real_arrays(*args, **kwargs)

    def consistency(*args, **kwargs):
        taken["consistency"] += 1
        return real_consistency(*args, **kwargs)

    monkeypatch.setattr(sources, "_clean_arrays", arrays)
    monkeypatch.setattr(cleaning, "consistency_filter", consistency)
    fast, fast_s = _cpu(lambda: sources.clean(excerpt, "switzerland"))
    reference, reference_s = _cpu(lambda: sources.clean(excerpt, "switzerland", reference=True))
    assert taken["arrays"] == 50 and taken["consistency"] >= 1  # every flight on arrays, a glitch included
    assert fast.n_flights >= 50 and _same(fast, reference) == []
    assert reference_s > 3.0 * fast_s, f"arrays {fast_s:.2f} s, library {reference_s:.2f} s of CPU time"


def test_a_users_table_is_cleaned_on_arrays_as_by_the_library(tmp_path, monkeypatch) -> None:
    """A table read with numpy types (the default filter then takes latitude and longitude too), with and without an altitude glitch."""
    from bluesky_gym.realtraffic import sources

    raws = {}
    real = sources.clean

    def capture(raw, name, *args, **kwargs):
        raws[name] = raw
        return real(raw, name, *args, **kwargs)

    monkeypatch.setattr(sources, "clean", capture)
    (tmp_path / "plain").mkdir()
    (tmp_path / "glitch").mkdir()
    for path in (_table(tmp_path / "plain"), _table(tmp_path / "glitch", **{f"{k}__altitude": 5000.0 for k in range(30, 70)})):
        fast = sources.load_table(path)
        assert _same(fast, real(raws["adsb"], "adsb", reference=True)) == []


def test_no_projection_database_search_and_no_networkx_per_flight(excerpt, monkeypatch) -> None:
    """What made the cleaning slow is gone: a PROJ database search per flight, NetworkX's graph in Python."""
    import pyproj
    from traffic.algorithms.filters import consistency

    from bluesky_gym.realtraffic import sources

    def refuse(*args, **kwargs):
        raise AssertionError("searched the PROJ database")

    def no_networkx(*args, **kwargs):
        raise AssertionError("NetworkX's longest path")

    monkeypatch.setattr(pyproj.Transformer, "from_proj", refuse)
    monkeypatch.setattr(pyproj.Transformer, "from_crs", refuse)
    monkeypatch.setattr(consistency, "get_nxlongest", no_networkx)
    flights = sources.clean(excerpt, "switzerland")
    assert flights.n_flights >= 50


def test_the_compiled_longest_path_is_networkx_one() -> None:
    """The same path as NetworkX's Bellman-Ford among equally long ones, on random consistency matrices."""
    from traffic.algorithms.filters.consistency import get_nxlongest

    rng = np.random.default_rng(0)
    for _ in range(200):
        n = int(rng.integers(1, 80))
        horizon = int(rng.integers(1, min(n, 25) + 1))
        dd = rng.uniform(size=(horizon, n)) < rng.uniform(0.05, 0.95)
        for h in range(horizon):
            dd[h, n - h :] = False
        assert cleaning.longest_consistent_path(dd).tolist() == get_nxlongest(dd)[1:-1]


def test_the_compiled_longest_path_on_a_recorded_glitch() -> None:
    """A quickstart flight the consistency filter takes: its matrices give NetworkX's path."""
    import pandas as pd
    import traffic.data.samples as samples
    from traffic.algorithms.filters.consistency import FilterConsistency, get_nxlongest

    data = samples.quickstart.clean_invalid().assign_id().eval().data
    flight = data[data["flight_id"] == sorted(data["flight_id"].unique())[0]].reset_index(drop=True).iloc[:400]
    filt = FilterConsistency()
    frame = pd.DataFrame({c: flight[c] for c in ("timestamp", "latitude", "longitude", "altitude", "groundspeed", "track", "vertical_rate")})
    dt = filt.compute_dt(frame, 200)
    for compute in (filt.compute_ddspeed, filt.compute_ddtrack, filt.compute_ddverti):
        dd = compute(frame, dt, 200)
        assert cleaning.longest_consistent_path(dd).tolist() == get_nxlongest(dd)[1:-1]


class _Clock:
    """A clock that advances 2 s at every reading."""

    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        self.now += 2.0
        return self.now


def test_progress_says_the_steps_the_expected_time_and_the_flights_cleaned(tmp_path) -> None:
    from bluesky_gym.realtraffic.sources import Progress, load_table

    out = io.StringIO()
    load_table(_table(tmp_path), progress=Progress("adsb", out=out, every_s=1.0, clock=_Clock()))
    lines = out.getvalue().splitlines()
    assert all(line.startswith("bluesky-gym: adsb: ") for line in lines)
    said = "\n".join(lines)
    assert "reading the table..." in said and "identifying the flights" in said
    expected = [line for line in lines if "expected to take about" in line]
    assert len(expected) == 1 and "cleaning 3 flights" in expected[0]
    progress = [line for line in lines if "flights cleaned (" in line]
    assert progress and all("flights/s" in line and "left" in line for line in progress)
    assert "1/3 flights cleaned (33%)" in said
    assert lines[-1].startswith("bluesky-gym: adsb: 3 flights cleaned in ")
    assert lines.index(expected[0]) < lines.index(progress[0])


def test_prepare_says_what_it_does(tmp_path, capsys) -> None:
    from bluesky_gym.cli import main

    assert main(["realtraffic", "prepare", "--table", str(_table(tmp_path)), "--out", str(tmp_path / "mine.npz")]) == 0
    said = capsys.readouterr().out
    assert "reading the table..." in said and "expected to take about" in said and "3 flights cleaned in" in said


def test_the_first_use_of_a_sample_says_what_it_does(tmp_path, monkeypatch, capsys) -> None:
    """Cleaning a sample into the cache (the first reset of an environment) reports through a Progress."""
    from bluesky_gym.realtraffic import cache, sources

    from .synthetic import traffic_collection

    seen = []

    def fake(name, consistency=True, progress=None):
        seen.append(progress)
        progress.start(12, 3456)
        return traffic_collection(n_flights=3)

    monkeypatch.setenv("BLUESKY_GYM_CACHE", str(tmp_path))
    monkeypatch.setattr(sources, "load_sample", fake)
    cache.load_collection("switzerland")
    said = capsys.readouterr().out
    assert isinstance(seen[0], sources.Progress) and not isinstance(seen[0], sources.Quiet)
    assert "switzerland" in said and "cleaning 12 flights (3,456 positions), expected to take about" in said


def test_the_rows_of_the_flights_share_one_array() -> None:
    """Each flight's rows are a view of one ordering of the table (a copy per flight held 1.3 GB for switzerland)."""
    import pandas as pd

    frame = pd.DataFrame(
        {
            "timestamp": pd.date_range("2024-01-01", periods=12, freq="10s", tz="UTC"),
            "flight_id": ["b", "a", "c", None] * 3,
            **{name: np.arange(12.0) for name in cleaning.REQUIRED},
        }
    )
    groups = cleaning.flight_rows(cleaning.Columns.of(frame))
    assert [g.tolist() for g in groups] == [[1, 5, 9], [0, 4, 8], [2, 6, 10]]
    assert len({id(g.base) for g in groups}) == 1
