"""Recorded flights to scenarios on the core: a known route is reproduced, windows and splits, windows written as .scn files."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from bluesky_gym.core.atmosphere import tas2cas
from bluesky_gym.core.command_text import time_stamp
from bluesky_gym.core.geo import qdrdist
from bluesky_gym.core.simulator import Simulator
from bluesky_gym.core.units import FT, KTS, NM
from bluesky_gym.realtraffic.fidelity import DT as fidelity_dt
from bluesky_gym.realtraffic.fidelity import fidelity, pair_los, window_scenario
from bluesky_gym.realtraffic.fidelity import fly as fly_window
from bluesky_gym.realtraffic.flights import RecordedFlights
from bluesky_gym.realtraffic.scenario import MAX_ROUTE_POINTS, Window, WindowPlayer, split_windows, windows
from bluesky_gym.scenarios import ScenarioPlayer, parse_scenario
from bluesky_gym.scenarios.player import slots_needed, waypoints_needed

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
    player = WindowPlayer(sim, flights)
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
    player = WindowPlayer(sim, flights)
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


def _scn_window() -> tuple[RecordedFlights, Window]:
    """A 600 s window of synthetic traffic: an aircraft that appears and leaves in it, one created in
    the middle of its recording, one that climbs, a repeated callsign, a missing, an unknown and two known types."""
    a = fly(47.0, 7.0, [(90.0, 60.0), (120.0, 60.0)], gs=230.0, alt=[10000.0, 10000.0, 9000.0])
    b = fly(47.2, 7.0, [(90.0, 20.0)], gs=200.0, alt=9000.0)
    c = fly(46.8, 7.3, [(60.0, 30.0), (20.0, 20.0)], gs=210.0, alt=[9500.0, 8000.0, 8000.0])
    d = fly(46.9, 6.8, [(45.0, 40.0)], gs=220.0, alt=[8500.0, 9500.0])
    flights = collection([(0.0, a), (400.0, b), (100.0, c), (450.0, d)])
    flights = dataclasses.replace(flights, callsign=np.array(["SWR123", "ezy 4U", "", "EZY4U"]), typecode=np.array(["A320", "B738", "ZZZZ", ""]))
    return flights, Window(300.0, 600.0, 0, (1, 2, 3))


def _fly_window(flights: RecordedFlights, window: Window) -> list[tuple[float, np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
    """(time in the window, lat, lon, alt, active) of the slots after every decision step of the replay with nobody acting."""
    sim = Simulator(1, len(window.flights), dt=fidelity_dt, max_waypoints=MAX_ROUTE_POINTS)
    player = WindowPlayer(sim, flights)
    player.load(np.array([0]), [window])
    return [
        (float(player.elapsed[0]), sim.lat[0].copy(), sim.lon[0].copy(), sim.alt[0].copy(), sim.active[0].copy())
        for _ in fly_window(sim, player, window.duration)
    ]


SCN_ACIDS = ["SWR123", "EZY4U", "AC002", "EZY4U_2"]  # the slots' callsigns in the file: recorded, cleaned, made unique


def test_scn_file_of_a_window() -> None:
    flights, window = _scn_window()
    lines = window_scenario(flights, window).splitlines()
    assert (
        lines[0]
        == "# synthetic: 600 s from 2024-01-01T00:05:00+00:00, 4 recorded aircraft (ownship SWR123), each guided along its recording, nobody acting"
    )
    body = [ln for ln in lines if ">" in ln]
    stamps = [ln.split(">")[0] for ln in body]
    assert stamps == sorted(stamps) and body[0] == "00:00:00.00>DT 1.0"
    cre = {ln.split()[1]: ln for ln in body if ">CRE " in ln}
    assert sorted(cre) == sorted(SCN_ACIDS) and sum(">CRE " in ln for ln in body) == 4  # each created once
    rec_a = flights.at(np.array([0]), np.array([300.0]))
    state = f"{float(rec_a['lat'][0])!r} {float(rec_a['lon'][0])!r} 90.0 {10000.0 / FT!r} {float(tas2cas(230.0, 10000.0)) / KTS!r}"
    assert cre["SWR123"] == f"00:00:00.00>CRE SWR123 A320 {state}"  # the recorded state, full precision
    assert cre["EZY4U"].startswith("00:01:40.00>CRE EZY4U B738 47.2 7.0 90.0 ")  # appears 100 s into the window
    assert cre["AC002"].startswith("00:00:00.00>CRE AC002 ZZZZ ")  # no callsign; a type BlueSky does not know (it flies the B744)
    assert cre["EZY4U_2"].startswith("00:02:30.00>CRE EZY4U_2 B744 ")  # the repeated callsign made unique; no type: the B744
    # every aircraft gets its route points ahead of it, then altitude and speed targets every decision step
    assert flights.route_points(0).tolist() == [0, 48, 96]  # the ownship is at sample 30 at the window start
    ahead = [f"ADDWPT SWR123 {la!r} {lo!r}" for la, lo in zip(flights.lat[[48, 96]].tolist(), flights.lon[[48, 96]].tolist())]
    assert [ln.split(">")[1] for ln in body if "ADDWPT SWR123" in ln] == ahead
    assert all(ln.startswith("00:00:00.00>") for ln in body if "ADDWPT SWR123" in ln)
    assert sum(">SPD SWR123 " in ln for ln in body) == 60 and sum(">ALT SWR123 " in ln for ln in body) == 60
    assert not any("VNAV" in ln or "LNAV" in ln for ln in body)  # ADDWPT engages LNAV; the profile is flown with ALT and SPD
    # each is deleted at the first decision step after its last recorded sample, or at the end of the window
    dels = {ln.split()[1]: ln.split(">")[0] for ln in body if ">DEL " in ln}
    t_end = np.minimum(flights.t_end[list(window.flights)] - window.start, 600.0)
    assert dels == {acid: time_stamp(min(np.floor(t / 10.0 + 1e-9) * 10.0 + 10.0, 600.0)) for acid, t in zip(SCN_ACIDS, t_end)}
    assert dels["EZY4U"] < "00:10:00.00" and dels["AC002"] < "00:10:00.00" and dels["SWR123"] == "00:10:00.00"


def test_scn_file_of_a_window_replays_exactly_on_the_core() -> None:
    """The file played by the scenario player flies as the replay with nobody acting flew the window: the same positions, bit for bit."""
    flights, window = _scn_window()
    scenario = parse_scenario(window_scenario(flights, window), "w.scn")
    track = _fly_window(flights, window)
    sim = Simulator(1, slots_needed(scenario), dt=fidelity_dt, max_waypoints=waypoints_needed(scenario))
    player = ScenarioPlayer([scenario], sim)
    seen = np.zeros(len(SCN_ACIDS), bool)
    for t, lat, lon, alt, active in track:
        player.advance(int(round(t / fidelity_dt)) - player.steps_done)
        slot_of = {acid: s for s, acid in player.slots(0)}
        assert set(slot_of) == {SCN_ACIDS[s] for s in np.flatnonzero(active)}, t
        for s in np.flatnonzero(active):
            j = slot_of[SCN_ACIDS[s]]
            assert (sim.lat[0, j], sim.lon[0, j], sim.alt[0, j]) == (lat[s], lon[s], alt[s]), (t, SCN_ACIDS[s])
        seen |= active
    assert seen.all()
    # the aircraft moved and climbed: the comparison is not of states that stay put
    climber = [alt[3] for _, _, _, alt, active in track if active[3]]
    assert track[-1][1][0] != track[0][1][0] and climber[-1] - climber[0] > 500.0


@pytest.mark.bluesky
def test_bluesky_plays_the_scn_file_of_a_window(tmp_path) -> None:
    """BlueSky 1.1.1 plays the file (PCALL) as the core flew the window, within the core's fidelity contract (tests/core/test_reference.py)."""
    from bluesky_gym.backends.bluesky_sim import BlueSkyPhysics, load_bluesky
    from tests.core.test_reference import TOL

    flights, window = _scn_window()
    path = tmp_path / "w.scn"
    path.write_text(window_scenario(flights, window))
    track = _fly_window(flights, window)
    bs = load_bluesky()
    physics = BlueSkyPhysics(1, dt=fidelity_dt)  # a clean simulator: traffic reset, DT, FF
    try:
        start = bs.sim.simt
        physics.command(f"PCALL {path}")
        for t, lat, lon, alt, active in track:
            while bs.sim.simt - start < t - 1e-9:
                bs.sim.step()
            ids = list(bs.traf.id)
            assert sorted(ids) == sorted(SCN_ACIDS[s] for s in np.flatnonzero(active)), t
            for s in np.flatnonzero(active):
                i = ids.index(SCN_ACIDS[s])
                for name, got, want in (("lat", bs.traf.lat[i], lat[s]), ("lon", bs.traf.lon[i], lon[s]), ("alt", bs.traf.alt[i], alt[s])):
                    assert abs(float(got) - float(want)) <= TOL[name], (t, SCN_ACIDS[s], name, float(got), float(want))
    finally:
        physics.close()


def test_the_scn_commands_of_the_realtraffic_page_run(tmp_path, monkeypatch, capsys) -> None:
    """The page's ``realtraffic scn`` and ``replay`` commands, as written, on synthetic stand-ins for the sample collections."""
    import shlex
    from pathlib import Path

    from bluesky_gym.cli import main
    from bluesky_gym.realtraffic.cache import collection_path
    from bluesky_gym.realtraffic.sources import SAMPLE_COLLECTIONS

    page = Path(__file__).resolve().parents[2] / "docs" / "realtraffic.md"
    commands = [
        shlex.split(ln, comments=True)[1:]
        for ln in page.read_text().splitlines()
        if ln.startswith(("bluesky-gym realtraffic scn", "bluesky-gym replay"))
    ]
    assert [c[:2] for c in commands] == [["realtraffic", "scn"], ["replay", "episode.scn"]]
    for k, name in enumerate(SAMPLE_COLLECTIONS):
        stand_in = dataclasses.replace(traffic_collection(n_flights=24, spacing_s=300.0, seed=k), name=name)
        stand_in.save(collection_path(name, tmp_path / "cache"))
    monkeypatch.setenv("BLUESKY_GYM_CACHE", str(tmp_path / "cache"))
    monkeypatch.chdir(tmp_path)
    for argv in commands:
        assert main(argv) == 0, argv
    name = capsys.readouterr().out.split("episode.scn: ")[1].split(",")[0]
    assert name in SAMPLE_COLLECTIONS
    text = (tmp_path / "episode.scn").read_text()
    # the title names the window's own collection and its time in that collection's clock (not the combined one)
    assert text.startswith(f"# {name}: 600 s from 2024-01-01T") and ">CRE SYN" in text
    assert (tmp_path / "episode.csv").stat().st_size > 0


def test_a_window_of_combined_collections_maps_back_to_its_collection() -> None:
    from bluesky_gym.realtraffic.cache import combine, window_of_part

    parts = [traffic_collection(n_flights=4), traffic_collection(n_flights=5, seed=1)]
    combined, shifts = combine(parts, "a+b")
    w = windows(parts[1], 600.0, 60.0, 30.0, 1, 10)[0]
    moved = Window(w.start + shifts[1], w.duration, w.ownship + 4, tuple(f + 4 for f in w.traffic))
    assert np.array_equal(
        combined.at(np.array(moved.flights), np.full(len(w.flights), moved.start + 30.0))["lat"],
        parts[1].at(np.array(w.flights), np.full(len(w.flights), w.start + 30.0))["lat"],
    )
    k, back = window_of_part(parts, moved)
    assert k == 1 and back.flights == w.flights and back.start == pytest.approx(w.start, abs=1e-9) and back.duration == w.duration
    with pytest.raises(ValueError, match="span several collections"):
        window_of_part(parts, Window(0.0, 600.0, 0, (5,)))
    with pytest.raises(ValueError, match="not a flight of the collections"):
        window_of_part(parts, Window(0.0, 600.0, 9, ()))


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
    player = WindowPlayer(sim, flights)
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
