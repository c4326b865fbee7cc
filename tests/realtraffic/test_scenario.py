"""Recorded flights to scenarios on the core: a known route is reproduced, windows and splits."""

from __future__ import annotations

import numpy as np
import pytest

from bluesky_gym.core.geo import qdrdist
from bluesky_gym.core.simulator import Simulator
from bluesky_gym.core.units import FT, NM
from bluesky_gym.realtraffic.fidelity import fidelity, pair_los
from bluesky_gym.realtraffic.flights import RecordedFlights
from bluesky_gym.realtraffic.scenario import MAX_ROUTE_POINTS, ScenarioPlayer, Window, split_windows, windows

from .synthetic import collection, fly, traffic_collection

# Stated tolerance of the replay of a recorded flight flown on its route points (dog-leg route,
# 30 deg turn, 230 m/s, a 1000 m descent): lateral within 0.5 NM and vertical within 200 ft of the
# recording at every 10 s sample over 23 minutes (measured: 0.27 NM and 105 ft; the recording's legs
# are rhumb lines, LNAV flies great circles and cuts the corner with a fly-by turn).
LATERAL_TOLERANCE_NM = 0.5
VERTICAL_TOLERANCE_FT = 200.0


def _dogleg() -> RecordedFlights:
    f = fly(47.0, 7.0, [(90.0, 60.0), (120.0, 60.0), (120.0, 60.0)], gs=230.0, alt=[10000.0, 10000.0, 9000.0, 9000.0])
    return collection([(0.0, f)])


def test_known_route_is_reproduced_within_tolerance() -> None:
    flights = _dogleg()
    assert flights.route_points(0).tolist() == [0, 48, 96, 144]
    sim = Simulator(1, 2, dt=1.0, max_waypoints=MAX_ROUTE_POINTS)
    player = ScenarioPlayer(sim, flights)
    player.load(np.array([0]), [Window(0.0, 1400.0, 0, ())])
    lateral, vertical = [], []
    for _ in range(140):
        sim.run(10)
        player.advance_clock(10.0)
        rec = flights.at(np.array([0]), player.now())
        _, d = qdrdist(sim.lat[0, 0], sim.lon[0, 0], rec["lat"][0], rec["lon"][0])
        lateral.append(float(d))
        vertical.append(abs(float(sim.alt[0, 0] - rec["alt"][0])) / FT)
        player.update()
    assert max(lateral) < LATERAL_TOLERANCE_NM, max(lateral)
    assert max(vertical) < VERTICAL_TOLERANCE_FT, max(vertical)
    # the turn happened: the aircraft ends on the last leg's course, south-east of its start
    assert abs(float(sim.hdg[0, 0]) - 120.0) < 1.0
    # a lazier replay (straight to the last point, no profile) would be far off: the check can fail
    straight = Simulator(1, 1, dt=1.0)
    straight.create(0, 0, lat=47.0, lon=7.0, hdg=90.0, alt=10000.0, spd=float(sim.cas[0, 0]))
    straight.run(1400)
    rec = flights.at(np.array([0]), np.array([1400.0]))
    assert float(qdrdist(straight.lat[0, 0], straight.lon[0, 0], rec["lat"][0], rec["lon"][0])[1]) > 10 * LATERAL_TOLERANCE_NM


def test_aircraft_appear_and_leave_with_their_recordings() -> None:
    a = fly(47.0, 7.0, [(90.0, 100.0)], gs=200.0, alt=9000.0)
    b = fly(47.2, 7.0, [(90.0, 20.0)], gs=200.0, alt=9000.0)  # about 3 minutes, appears at 120 s
    flights = collection([(0.0, a), (120.0, b)])
    sim = Simulator(1, 3, dt=1.0, max_waypoints=MAX_ROUTE_POINTS)
    player = ScenarioPlayer(sim, flights)
    player.load(np.array([0]), [Window(0.0, 600.0, 0, (1,))])
    seen = []
    for _ in range(60):
        seen.append(bool(sim.active[0, 1]))
        sim.run(10)
        player.advance_clock(10.0)
        player.update()
    first = seen.index(True)
    assert first * 10.0 == 120.0
    assert 120.0 + 170.0 <= (first + seen[first:].index(False)) * 10.0 <= 120.0 + 200.0
    rec = flights.at(np.array([1]), np.array([120.0]))
    assert sim.active[0, 0] and not sim.active[0, 1]
    assert rec["lat"][0] == pytest.approx(47.2)


def test_windows_have_an_ownship_recorded_throughout_and_traffic_around() -> None:
    flights = traffic_collection()
    found = windows(flights, 600.0, 60.0, 30.0, 1, 10)
    assert found
    for w in found:
        assert flights.t0[w.ownship] <= w.start and flights.t_end[w.ownship] >= w.start + w.duration
        assert 1 <= len(w.traffic) <= 10 and w.ownship not in w.traffic
        t = np.arange(w.start, w.start + w.duration + 1, 10.0)
        own = flights.at(np.full(len(t), w.ownship), t)
        for f in w.traffic:
            other = flights.at(np.full(len(t), f), t)
            present = (t >= flights.t0[f]) & (t <= flights.t_end[f])
            d = qdrdist(own["lat"], own["lon"], other["lat"], other["lon"])[1]
            assert np.min(np.where(present, d, np.inf)) < 30.5


def test_time_split_is_disjoint() -> None:
    flights = traffic_collection()
    found = windows(flights, 600.0, 60.0, 30.0, 1, 10)
    train, test = split_windows(found, 0.3, float(flights.t0.min()), float(flights.t_end.max()))
    assert train and test
    assert max(w.start + w.duration for w in train) <= min(w.start for w in test)
    assert len(train) + len(test) < len(found)  # windows across the split time are dropped


def test_fidelity_of_synthetic_traffic_and_pair_conflicts() -> None:
    flights = traffic_collection(n_flights=6)
    found = windows(flights, 1200.0, 300.0, 60.0, 1, 10)
    result = fidelity(flights, found[:4], 11, MAX_ROUTE_POINTS)
    rows = result.summary()
    assert [r["minutes"] for r in rows] == [5.0, 10.0, 20.0]
    assert rows[0]["aircraft"] > 0
    assert all(r["lateral_p95_nm"] < 1.0 and r["vertical_p95_ft"] < 300.0 for r in rows if r["aircraft"])
    assert result.aircraft_hours > 0
    lat = np.array([[47.0, 47.0, 47.0 + 6 / 60]])
    lon = np.array([[8.0, 8.0 + 4 / 60 / np.cos(np.radians(47.0)), 8.0]])
    alt = np.array([[10000.0, 10000.0 + 900 * FT, 10000.0]])
    los = pair_los(lat, lon, alt, np.ones((1, 3), bool))
    assert los[0, 0, 1] and los[0, 1, 0] and not los[0, 0, 2] and not los[0, 1, 2]
    alt[0, 1] += 200 * FT
    assert not pair_los(lat, lon, alt, np.ones((1, 3), bool))[0, 0, 1]


def test_save_load_round_trip_and_bad_file(tmp_path) -> None:
    flights = traffic_collection(n_flights=3)
    path = flights.save(tmp_path / "c.npz")
    back = RecordedFlights.load(path)
    assert back.n_flights == 3 and np.array_equal(back.lat, flights.lat) and back.typecode.tolist() == ["A320"] * 3
    (tmp_path / "bad.npz").write_text("nope")
    with pytest.raises(ValueError, match="bad.npz: not a recorded-flights file"):
        RecordedFlights.load(tmp_path / "bad.npz")
    assert NM == 1852.0


def test_scn_file_of_a_window(tmp_path) -> None:
    from bluesky_gym.realtraffic.scn import write_scn

    a = fly(47.0, 7.0, [(90.0, 60.0), (120.0, 60.0)], gs=230.0, alt=[10000.0, 10000.0, 9000.0])
    b = fly(47.2, 7.0, [(90.0, 20.0)], gs=200.0, alt=9000.0)
    flights = collection([(0.0, a), (120.0, b)])
    path = write_scn(flights, Window(0.0, 900.0, 0, (1,)), tmp_path / "w.scn")
    lines = path.read_text().splitlines()
    assert lines[0].startswith("# synthetic: 2 recorded aircraft")
    assert lines[1] == "00:00:00.00>CRE SYN000,A320,47.000000,7.000000,90.0,32808,273"
    assert [line for line in lines if "ADDWPT SYN000" in line] == [line for line in lines if line.startswith("00:00:00.00>ADDWPT SYN000")] and len(
        [line for line in lines if "ADDWPT SYN000" in line]
    ) == 2
    assert any(line.startswith("00:02:00.00>CRE SYN001,A320,47.200000,7.000000,90.0,29528,") for line in lines)
    dels = [line for line in lines if "DEL" in line]
    assert len(dels) == 1 and dels[0].endswith("DEL SYN001")
    stamps = [line.split(">")[0] for line in lines[1:]]
    assert stamps == sorted(stamps)


def test_a_climb_steeper_than_the_type_can_fly_is_commanded_at_its_vsmax() -> None:
    """A recorded departure that climbs at 4500 ft/min while accelerating, flown as the B744 (vsmax 2705 ft/min).

    Asking for more than vsmax makes BlueSky's limit trade climb for acceleration
    (``w = (1 - ax/axmax) vsmax``), so the aircraft levels off while it accelerates; the player
    asks for at most the type's vsmax, and the aircraft climbs at it throughout.
    """
    from bluesky_gym.core.aircraft import aircraft_performance
    from bluesky_gym.realtraffic.flights import SAMPLE_PERIOD

    f = fly(48.7, 2.4, [(90.0, 40.0)], gs=150.0, alt=[600.0, 600.0 + 22.86 * 40.0 * NM / 150.0])
    f["gs"] = np.minimum(70.0 + 1.0 * SAMPLE_PERIOD * np.arange(len(f["gs"])), 230.0)  # accelerating at 1 m/s2 through the climb
    flights = collection([(0.0, f)])
    flights.typecode[:] = "B744"
    vsmax = aircraft_performance("B744").vsmax
    sim = Simulator(1, 2, dt=1.0, max_waypoints=MAX_ROUTE_POINTS)
    player = ScenarioPlayer(sim, flights)
    player.load(np.array([0]), [Window(0.0, 600.0, 0, ())])
    rates = []
    for _ in range(40):
        assert abs(float(sim.selvs[0, 0])) <= vsmax + 1e-9, float(sim.selvs[0, 0])
        sim.run(10)
        player.advance_clock(10.0)
        rates.append(float(sim.vs[0, 0]))
        player.update()
    assert sim.aircraft_type(0, 0) == ["B744"]
    assert min(rates[1:]) > 0.9 * vsmax, min(rates[1:])


def test_large_vertical_deviations_are_classified_by_what_the_recording_asks_of_the_type() -> None:
    from bluesky_gym.realtraffic.fidelity import large_vertical_deviations

    high = fly(47.0, 7.0, [(90.0, 150.0)], gs=230.0, alt=12500.0)  # FL410: above the B744's ceiling (11290 m)
    steep = fly(47.3, 7.0, [(90.0, 150.0)], gs=230.0, alt=[3000.0, 3000.0 + 25.0 * 150.0 * NM / 230.0])  # climbs at 25 m/s
    flights = collection([(0.0, high), (0.0, steep), (0.0, fly(47.6, 7.0, [(90.0, 150.0)], gs=230.0, alt=9000.0))])
    flights.typecode[:] = ""  # no recorded type: the B744
    result = fidelity(flights, [Window(0.0, 1200.0, 0, (1, 2))], 3, MAX_ROUTE_POINTS)
    rows = large_vertical_deviations(flights, result)
    assert [r["minutes"] for r in rows] == [5.0, 10.0, 20.0]
    five = rows[0]
    assert five["aircraft"] == 3 and five["large"] == 2 and five["above_ceiling"] == 1 and five["steeper_than_vsmax"] == 1 and five["other"] == 0
    level = result.vertical_m[300.0][result.flight[300.0] == 2]
    assert level.size == 1 and float(level[0]) < 1000.0 * FT
