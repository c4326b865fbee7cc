"""Users' ADS-B tables: loaded and cleaned with the traffic library, bad input named with file and line."""

from __future__ import annotations

import numpy as np
import pytest

from bluesky_gym.core.units import FPM, FT, KTS

from .synthetic import fly

pytest.importorskip("traffic")
pd = pytest.importorskip("pandas")

from bluesky_gym.realtraffic.sources import load_table  # noqa: E402


def _table(tmp_path, **changes):
    rows = []
    for k, (callsign, t0, lat0) in enumerate((("ABC123", 0, 47.0), ("XYZ9", 60, 47.3), ("ABC123", 7200, 47.6))):
        f = fly(lat0, 7.0, [(90.0, 60.0), (150.0, 40.0)], gs=220.0, alt=[9000.0, 9000.0, 8000.0])
        t = pd.Timestamp("2024-05-01T10:00:00Z") + pd.to_timedelta(t0 + 10.0 * np.arange(len(f["lat"])), unit="s")
        for i in range(len(t)):
            rows.append(
                {
                    "time": t[i].isoformat(),
                    "callsign": callsign,
                    "lat": f["lat"][i],
                    "lon": f["lon"][i],
                    "altitude": f["alt"][i] / FT,
                    "groundspeed": f["gs"][i] / KTS,
                    "track": f["trk"][i],
                    "vertical_rate": f["vs"][i] / FPM,
                    "typecode": "B738" if k == 1 else "",
                    "icao24": f"{k:06x}",
                }
            )
    df = pd.DataFrame(rows)
    for key, value in changes.items():
        row, col = key.split("__")
        if isinstance(value, str):
            df[col] = df[col].astype(object)  # a bad text value in a numeric column, as a user's file may have
        df.loc[int(row), col] = value
    path = tmp_path / "adsb.csv"
    df.to_csv(path, index=False)
    return path


def test_table_is_cleaned_into_flights(tmp_path) -> None:
    flights = load_table(_table(tmp_path))
    # the reused callsign gives two flights (assign_id splits them), three in all
    assert flights.n_flights == 3
    assert sorted(flights.callsign.tolist()) == ["ABC123", "ABC123", "XYZ9"]
    assert len(set(flights.flight_id.tolist())) == 3
    assert dict(zip(flights.callsign.tolist(), flights.typecode.tolist()))["XYZ9"] == "B738"
    f = int(np.flatnonzero(flights.callsign == "XYZ9")[0])
    s = flights.samples(f)
    assert np.allclose(flights.gs[s], 220.0, atol=1.0) and np.allclose(flights.lat[s][0], 47.3, atol=1e-3)
    pts = flights.route_points(f)
    assert 3 <= len(pts) <= 5  # the dog-leg's corners survive the simplification


def test_bad_values_are_named_with_file_and_line(tmp_path) -> None:
    path = _table(tmp_path, **{"5__altitude": "high"})
    with pytest.raises(ValueError, match=r"adsb.csv:7: column 'altitude' is not a number: 'high'"):
        load_table(path)
    path = _table(tmp_path, **{"0__time": "yesterday"})
    with pytest.raises(ValueError, match=r"adsb.csv:2: column 'time' is not a time"):
        load_table(path)
    df = pd.read_csv(_table(tmp_path)).drop(columns=["track"])
    df.to_csv(tmp_path / "short.csv", index=False)
    with pytest.raises(ValueError, match=r"short.csv: missing column\(s\) \['track'\]"):
        load_table(tmp_path / "short.csv")
    (tmp_path / "short.txt").write_text("x")
    with pytest.raises(ValueError, match=r"short.txt: unsupported table format '.txt'"):
        load_table(tmp_path / "short.txt")


def test_consistency_filter_removes_an_altitude_glitch(tmp_path) -> None:
    # 40 samples (6.5 minutes) of ABC123's first flight at 5000 ft instead of 29,528 ft: too long for the default filter
    path = _table(tmp_path, **{f"{k}__altitude": 5000.0 for k in range(30, 70)})
    raw, fixed = load_table(path, consistency=False), load_table(path)
    f = int(np.flatnonzero(raw.flight_id == "ABC123_000")[0])
    g = int(np.flatnonzero(fixed.flight_id == "ABC123_000")[0])
    assert np.abs(np.diff(raw.alt[raw.samples(f)])).max() / FT > 20000.0  # left by the default filter
    assert np.abs(np.diff(fixed.alt[fixed.samples(g)])).max() / FT < 100.0
    assert np.allclose(fixed.alt[fixed.samples(g)][:60] / FT, 29527.6, atol=1.0)


@pytest.mark.parametrize("flag", [[], ["--no-consistency"]])
def test_prepare_command_writes_the_flights_of_a_table(tmp_path, flag) -> None:
    from bluesky_gym.cli import main
    from bluesky_gym.realtraffic.flights import RecordedFlights

    out = tmp_path / "mine.npz"
    assert main(["realtraffic", "prepare", "--table", str(_table(tmp_path)), "--out", str(out), *flag]) == 0
    assert RecordedFlights.load(out).n_flights == 3
