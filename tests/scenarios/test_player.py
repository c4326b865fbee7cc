"""The scenario player, the replay command, the benchmark geometries and the episode export."""

from __future__ import annotations

import csv
import math
import os
import re
import time
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import bluesky_gym
from bluesky_gym.cli import main
from bluesky_gym.core import Simulator
from bluesky_gym.core.command_text import speed, time_stamp
from bluesky_gym.core.geo import qdrdist
from bluesky_gym.core.units import FT, KTS, NM
from bluesky_gym.scenarios import TRAJECTORY_COLUMNS, ScenarioError, ScenarioPlayer, parse_scenario, read_scenario
from bluesky_gym.scenarios.export import ScenarioRecorder, unique_callsigns
from bluesky_gym.scenarios.geometries import shipped_scenario, shipped_scenarios, sphere_conflict, super_conflict, wall_conflict, write_shipped
from bluesky_gym.scenarios.player import UnknownAircraftTypeWarning, common_dt, slots_needed, unknown_types, waypoints_needed
from tests.core.reference_scenarios import DATA, open_recording

TIMED = """00:00:00.00>CRE AC1 A320 52 4 0 FL100 250
00:00:02.50>HDG AC1 90
00:00:04.00>SPD AC1 200
"""


def test_commands_act_in_the_first_step_starting_at_or_after_their_time() -> None:
    sc = parse_scenario(TIMED)
    sim = Simulator(1, 1, dt=1.0)
    player = ScenarioPlayer([sc], sim)
    ap_trk, selspd = [], []
    for _ in range(6):
        player.step()
        ap_trk.append(sim.ap_trk[0, 0])
        selspd.append(sim.selspd[0, 0])
    # HDG at 2.5 s runs before the step from 3 to 4 s; SPD at 4 s before the step from 4 to 5 s.
    assert ap_trk == [0.0, 0.0, 0.0, 90.0, 90.0, 90.0]
    assert selspd[3] == pytest.approx(250 * KTS) and selspd[4] == pytest.approx(200 * KTS)


def test_advance_equals_stepping() -> None:
    sc = read_scenario(DATA / "scn" / "commands.scn")
    a, b = Simulator(1, slots_needed(sc)), Simulator(1, slots_needed(sc))
    pa, pb = ScenarioPlayer([sc], a), ScenarioPlayer([sc], b)
    for _ in range(150):
        pa.step()
    pb.advance(150)
    for name in ("lat", "lon", "alt", "tas", "hdg", "vs"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    assert pa.snapshot(150) == pb.snapshot(150)


def test_player_errors() -> None:
    sc = parse_scenario("00:00:00.00>CRE AC1 B744 52 4\n00:00:00.00>CRE AC2 zzzz 52 5\n", "types.scn")
    sim = Simulator(1, 2)
    with pytest.warns(UnknownAircraftTypeWarning, match="types.scn:2: aircraft type 'ZZZZ' is unknown to BlueSky"):
        ScenarioPlayer([sc], sim)
    assert sim.aircraft_type([0, 0], [0, 1]) == ["B744", "ZZZZ"]
    assert sim.aircraft_performance(0, 1).name == "B744"  # BlueSky's fallback for an unknown type
    rotor = parse_scenario("00:00:00.00>CRE AC1 ec35 52 4 90 1000 100\n", "rotor.scn")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a rotorcraft is no unknown type
        ScenarioPlayer([rotor], sim := Simulator(1, 1))
    assert sim.aircraft_type(0, 0) == ["EC35"] and sim.aircraft_performance(0, 0).rotor
    two = parse_scenario("00:00:00.00>CRE AC1 A320 52 4\n00:00:00.00>CRE AC2 A320 52 5\n", "two.scn")
    with pytest.raises(ScenarioError, match="creates 2 aircraft, the physics has 1 slots"):
        ScenarioPlayer([two], Simulator(1, 1))
    with pytest.raises(ScenarioError, match="2 scenarios need 2 airspaces"):
        ScenarioPlayer([two, two], Simulator(1, 2))
    dt = parse_scenario("00:00:00.00>DT 2\n", "dt.scn")
    with pytest.raises(ScenarioError, match="DT 2.0 s differs"):
        ScenarioPlayer([dt], Simulator(1, 1, dt=1.0))
    assert common_dt([dt, two], None) == 2.0 and common_dt([two], None) == 1.0
    with pytest.raises(ScenarioError, match="differs from the requested time step"):
        common_dt([dt], 1.0)
    full = parse_scenario("00:00:00.00>CRE AC1 A320 52 4\n" + "".join(f"00:00:00.00>ADDWPT AC1 52.{k} 4\n" for k in range(5)), "route.scn")
    assert waypoints_needed(full) == 5
    with pytest.raises(ScenarioError, match="needs 5 route waypoints"):
        ScenarioPlayer([full], Simulator(1, 1, max_waypoints=4))


def test_geometries() -> None:
    sc = parse_scenario(super_conflict(8, radius_nm=40.0), "super")
    assert len(sc.callsigns) == 8
    for c in sc.commands:
        qdr, dist = qdrdist(c.position.lat, c.position.lon, 52.0, 4.0)  # type: ignore[attr-defined]
        assert dist == pytest.approx(40.0, rel=2e-3)  # the ellipsoid vs the sphere of the generator
        assert abs((float(qdr) - c.hdg + 180.0) % 360.0 - 180.0) < 0.01  # type: ignore[attr-defined]
        assert c.alt == 20000 * FT  # type: ignore[attr-defined]
    sphere = parse_scenario(sphere_conflict(4, 3), "sphere")
    alts = sorted({c.alt for c in sphere.commands if hasattr(c, "hdg") and hasattr(c, "position")})  # type: ignore[attr-defined]
    assert alts == pytest.approx([18000 * FT, 20000 * FT, 22000 * FT])
    climbs = [c for c in sphere.commands if type(c).__name__ == "Altitude"]
    assert len(climbs) == 8 and all(c.vs * (c.alt - 20000 * FT) > 0 for c in climbs)  # type: ignore[attr-defined]
    wall = parse_scenario(wall_conflict(3, spacing_nm=2.0), "wall")
    hdgs = [c.hdg for c in wall.commands]  # type: ignore[attr-defined]
    assert hdgs == [90.0] * 3 + [270.0] * 3
    for bad in (lambda: super_conflict(1), lambda: sphere_conflict(4, 2), lambda: wall_conflict(0), lambda: super_conflict(4, radius_nm=-1.0)):
        with pytest.raises(ValueError):
            bad()


def test_shipped_scenarios_are_the_generated_ones(tmp_path: Path) -> None:
    fresh = {p.name: p.read_text() for p in write_shipped(tmp_path)}
    shipped = {p.name: p.read_text() for p in shipped_scenarios()}
    assert shipped == fresh
    assert shipped_scenario("super8") == shipped_scenario("super8.scn")
    with pytest.raises(FileNotFoundError, match="no shipped scenario"):
        shipped_scenario("nothing")


def test_super_conflict_converges() -> None:
    """All aircraft of the shipped super conflict meet near the centre at the same time."""
    sc = read_scenario(shipped_scenario("super8"))
    sim = Simulator(1, 8)
    player = ScenarioPlayer([sc], sim)
    t_centre = 40 * NM / sim.tas[0, 0]
    player.advance(int(t_centre))
    _, dist = qdrdist(sim.lat[0], sim.lon[0], 52.0, 4.0)
    assert np.all(dist < 1.0)


def _rows(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def test_replay_cli_writes_the_reference_columns(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "t.csv"
    assert main(["replay", str(DATA / "scn" / "route.scn"), "--duration", "20", "--out", str(out), "--quiet"]) == 0
    rows = _rows(out)
    with open_recording("pcall_fuel_types") as fh:  # recorded with every column, thrust, drag and fuelflow too
        header = next(csv.reader(fh))
    assert list(rows[0]) == header == list(TRAJECTORY_COLUMNS)
    assert list(TRAJECTORY_COLUMNS[-3:]) == ["thrust", "drag", "fuelflow"]
    assert len(rows) == 2 * 21 and rows[0]["t"] == "0" and rows[-1]["t"] == "20"
    ref = _rows(DATA / "pcall_route.csv")[: len(rows)]
    assert [r["lat"] for r in rows] == [r["lat"] for r in ref]
    # several files and copies: one airspace each, a leading scenario column
    out2 = tmp_path / "many.csv"
    assert main(["replay", "super8", str(DATA / "scn" / "route.scn"), "--copies", "2", "--duration", "3", "--out", str(out2)]) == 0
    many = _rows(out2)
    assert list(many[0])[0] == "scenario" and len(many) == 4 * (2 * 8 + 2 * 2)
    names = {r["scenario"] for r in many}
    assert names == {"super8#0", "super8#1", f"{DATA / 'scn' / 'route.scn'}#0", f"{DATA / 'scn' / 'route.scn'}#1"}
    err = capsys.readouterr().err
    assert "replayed 4 scenario(s), 20 aircraft, 3 steps" in err and "simulated seconds per wall second" in err


def test_replay_cli_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bad.scn"
    bad.write_text("00:00:00.00>CRE AC1 A320 52 4\n00:00:01.00>RESO FANCY\n")
    assert main(["replay", str(bad), "--duration", "5"]) == 2
    assert "bad.scn:2: RESO: resolution method 'FANCY' is not supported" in capsys.readouterr().err
    assert main(["replay", "nothing.scn", "--duration", "5"]) == 2
    assert "no shipped scenario" in capsys.readouterr().err
    assert main(["replay", "super8", "--duration", "2.5", "--dt", "1"]) == 2
    assert "not a whole number of steps" in capsys.readouterr().err
    assert main(["replay"]) == 2
    assert main(["replay", "--list"]) == 0
    assert "super8.scn" in capsys.readouterr().out


def test_export_helpers() -> None:
    assert time_stamp(0.0) == "00:00:00.00" and time_stamp(3725.256) == "01:02:05.26"
    assert speed(0.78) == "M0.78" and speed(150 * KTS) == repr(150 * KTS / KTS)


@pytest.mark.parametrize("env_id", ["HorizontalCREnv-v0", "MergeEnv-v0", "DescentEnv-v0", "VerticalCREnv-v0", "SectorCREnv-v0"])
def test_exported_episode_replays_exactly(env_id: str) -> None:
    """An episode written by the recorder and played back on the core flies the same trajectories."""
    bluesky_gym.register_envs()
    env = gym.make(env_id)
    rec = env.unwrapped.task.wrap_physics(ScenarioRecorder)  # type: ignore[attr-defined]
    assert isinstance(rec, ScenarioRecorder)
    env.reset(seed=3)
    env.action_space.seed(3)
    sim = env.unwrapped.task.sim  # type: ignore[attr-defined]
    track = []
    for _ in range(25):
        _, _, te, tr, _ = env.step(env.action_space.sample())
        track.append((sim.simt - rec.episodes[0][-1].start, sim.lat[0].copy(), sim.lon[0].copy(), sim.alt[0].copy(), sim.active[0].copy()))
        if te or tr:
            break
    text = rec.scenario_text(title=env_id)
    assert text.startswith(f"# {env_id}") and ">CRE AC000 A320" in text
    sc = parse_scenario(text, env_id)
    replay = Simulator(1, max(slots_needed(sc), 1), dt=sim.dt, max_waypoints=max(4, waypoints_needed(sc)))
    player = ScenarioPlayer([sc], replay)
    for t, lat, lon, alt, active in track:
        player.advance(int(round(t / sim.dt)) - player.steps_done)
        slot_of = {acid: s for s, acid in player.slots(0)}
        for s in np.flatnonzero(active):
            j = slot_of[f"AC{s:03d}"]
            assert (replay.lat[0, j], replay.lon[0, j]) == (lat[s], lon[s])
            assert math.isclose(replay.alt[0, j], alt[s], abs_tol=1e-6)
    env.close()


def test_recorder_logs_every_command_and_episodes() -> None:
    sim = Simulator(2, 3)
    rec = ScenarioRecorder(sim)
    rec.reset_envs()
    rec.create([0, 1], 0, 52.0, 4.0, 10.0, 3000.0, 150.0)
    rec.creconfs(0, 0, 1, 90.0, 1.0, 120.0)
    rec.wind.add_points(0, [52.0], [4.0], [-10.0], [0.0])
    rec.run(2)
    rec.cmd_heading(0, 0, 45.0)
    rec.cmd_speed(0, 0, 0.7)
    rec.cmd_altitude(0, 0, 2000.0, -5.0)
    rec.cmd_vertical_speed(0, 1, 3.0)
    rec.add_waypoint(0, 0, 52.5, 4.5)
    rec.set_destination(0, 0, 53.0, 4.5)
    rec.cmd_lnav(0, 0, False)
    rec.cmd_direct(0, 0, 0)
    rec.set_autopilot(0, 1, selalt=1000.0, selvs=-2.0, swvnav=False, ap_trk=10.0)
    rec.set_state(0, 1, alt=2500.0)
    rec.delete(0, 1)
    rec.step()
    lines = rec.scenario_text(0).splitlines()
    body = [ln.split(">", 1)[1].split()[0] for ln in lines if ">" in ln]
    assert body == [
        "DT",
        "CRE",
        "CRE",
        "WIND",
        "HDG",
        "SPD",
        "ALT",
        "VS",
        "ADDWPT",
        "DEST",
        "LNAV",
        "DIRECT",
        "VNAV",
        "VS",
        "ALT",
        "HDG",
        "MOVE",
        "DEL",
    ]
    assert any(ln.startswith("00:00:02.00>HDG AC000 45.0") for ln in lines)
    assert "WIND 52.0 4.0 0.0 " in rec.scenario_text(0)  # wind from the north
    assert rec.logged_episodes(1) == 1 and rec.scenario_text(1).count(">CRE") == 1
    rec.reset_envs([1])
    assert rec.logged_episodes(1) == 1  # the new episode has nothing logged yet
    with pytest.raises(ValueError, match="not episode 5"):
        rec.scenario_text(0, episode=5)
    # the delegated state is the inner physics' state
    assert np.shares_memory(rec.lat, sim.lat) and rec.n_envs == 2


class _TypedSimulator(Simulator):
    """A simulator whose create/creconfs take an aircraft type (the interface per-aircraft types add)."""

    def __init__(self, *args, **kwargs) -> None:  # type: ignore[no-untyped-def]
        super().__init__(*args, **kwargs)
        self.types: dict[tuple[int, int], str] = {}

    def create(self, env, slot, lat=52.0, lon=4.0, hdg=0.0, alt=0.0, spd=0.0, actype="A320") -> None:  # type: ignore[no-untyped-def, override]
        super().create(env, slot, lat, lon, hdg, alt, spd)
        for e, s in zip(np.atleast_1d(env), np.broadcast_to(np.atleast_1d(slot), np.atleast_1d(env).shape)):
            self.types[int(e), int(s)] = actype

    def creconfs(self, env, target, slot, dpsi, dcpa, tlosh, dh=None, tlosv=None, spd=None, actype="A320") -> None:  # type: ignore[no-untyped-def, override]
        super().creconfs(env, target, slot, dpsi, dcpa, tlosh, dh, tlosv, spd)
        self.types[int(np.atleast_1d(env)[0]), int(np.atleast_1d(slot)[0])] = actype


def test_aircraft_types_reach_a_physics_that_takes_them() -> None:
    sc = parse_scenario("00:00:00.00>CRE AC1 B744 52 4 0 FL200 250\n00:00:00.00>CRECONFS I1 E190 AC1 90 1 120\n", "types.scn")
    sim = _TypedSimulator(1, 2)
    ScenarioPlayer([sc], sim)
    assert sim.types == {(0, 0): "B744", (0, 1): "E190"}
    rec = ScenarioRecorder(_TypedSimulator(1, 1))
    rec.create(0, 0, actype="b744")
    assert ">CRE AC000 B744 " in rec.scenario_text()


ROOT = Path(__file__).resolve().parents[2]


def _replay_commands(page: Path) -> list[list[str]]:
    """The ``bluesky-gym replay`` command lines of a page (without comments), native backend only."""
    lines = [ln.split("#", 1)[0].split() for ln in page.read_text().splitlines() if ln.startswith("bluesky-gym replay")]
    return [ln[1:] for ln in lines if "bluesky" not in ln[1:]]


@pytest.mark.parametrize("page", ["README.md", "docs/scenarios.md"])
def test_the_replay_commands_of_the_docs_run(page: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    commands = _replay_commands(ROOT / page)
    assert len(commands) >= 3
    monkeypatch.chdir(tmp_path)
    for argv in commands:
        assert main([*argv, "--quiet"]) == 0, argv
    assert (tmp_path / "super8.csv").stat().st_size > 0


def test_the_python_snippets_of_the_scenarios_page_run(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    from tests.docs.test_tutorials import run_page

    page = run_page("scenarios.md", tmp_path, monkeypatch)
    out = capsys.readouterr().out
    assert "32 rows at t=600 s" in out
    assert "['B744', 'E190', 'ZZZZ'] B744" in out  # the aircraft types section
    # conflict resolution: the super conflict collides without it, keeps 5 NM with CSTATEBASED, and loses
    # separation with ASAS ON (STATEBASED's reverse bearings; BlueSky's own recording comes within 2.0 NM)
    assert "closest approach [NM]: 0.0 without resolution" in out
    assert page.closest[0] < 0.1 and 0.5 < page.closest[1] < 5.0 and page.closest[2] > 5.0
    assert len(page.rows) == 4 * 8  # four copies of eight aircraft
    assert parse_scenario((tmp_path / "episode.scn").read_text()).callsigns[0] == "AC000"


def test_recorder_writes_given_callsigns_valid_and_unique() -> None:
    assert unique_callsigns(["klm 12", "", "KLM12", "AC003", "ab-c/1"], reserved=["AC004"]) == ["KLM12", "AC001", "KLM12_2", "AC003", "ABC1"]
    assert unique_callsigns(["AC004", "x"], reserved=["AC004"]) == ["AC004_2", "X"]
    sim = Simulator(2, 3, max_waypoints=4)
    rec = ScenarioRecorder(sim)
    rec.reset_envs()
    assert rec.set_callsigns(0, ["swr 1", "AC002"]) == ["SWR1", "AC002_2"]  # slot 2 keeps its name AC002
    rec.create(0, [0, 1, 2], 52.0, 4.0, 90.0, 3000.0, 150.0)
    rec.create(1, 0, 52.0, 4.0, 90.0, 3000.0, 150.0)
    rec.run(1)
    rec.cmd_heading(0, [0, 1, 2], 45.0)
    rec.add_waypoint(0, 0, 52.5, 4.5)
    rec.cmd_direct(0, 0, 0)
    rec.delete(0, 1)
    text = rec.scenario_text(0)
    assert [ln.split(">", 1)[1].split()[1] for ln in text.splitlines() if ">CRE " in ln] == ["SWR1", "AC002_2", "AC002"]
    assert "00:00:01.00>HDG SWR1 45.0" in text and "HDG AC002_2 45.0" in text and "DIRECT SWR1 SWR1001" in text and "DEL AC002_2" in text
    assert ">CRE AC000 " in rec.scenario_text(1)  # other airspaces keep the slot names
    sc = parse_scenario(text, "named.scn")
    assert sc.callsigns == ["SWR1", "AC002_2", "AC002"]
    rec.reset_envs([0])
    assert rec.acid(0, 0) == "AC000"  # a reset restores the slot names


@pytest.mark.parametrize(
    ("line", "match"),
    [
        ("CRE AC2 A320 52 4 90 1e30 250", r"AC2: the new aircraft's tas, .* would not be finite"),  # finite, but beyond the atmosphere
        ("CRECONFS I1 A320 AC1 90 1 60 1e30 60", r"I1: the conflict geometry has no finite solution for the state of AC1 \(the intruder's .*"),
    ],
)
def test_a_creation_without_a_finite_state_is_refused(line: str, match: str) -> None:
    sc = parse_scenario(f"00:00:00.00>CRE AC1 A320 52 4 90 FL200 250\n00:00:00.00>{line}\n", "huge.scn")
    with pytest.raises(ScenarioError, match=match) as err:
        ScenarioPlayer([sc], Simulator(1, 2))
    assert str(err.value).startswith("huge.scn:2: ")


def test_check_finite_names_the_aircraft() -> None:
    sc = parse_scenario("00:00:00.00>CRE AC1 A320 52 4 90 FL200 250\n00:00:00.00>CRE AC2 A320 52 5 90 FL200 250\n", "two.scn")
    sim = Simulator(2, 2)
    player = ScenarioPlayer([sc, sc], sim)
    player.advance(3)
    player.check_finite(3.0)
    sim.alt[1, 1] = np.nan
    with pytest.raises(ScenarioError, match=r"two.scn: at t = 3 s the state of AC2 is not finite \(alt\)"):
        player.check_finite(3.0)


def test_unknown_aircraft_types_warn_once_per_type() -> None:
    text = "00:00:00.00>CRE AC1 ZZZZ 52 4\n00:00:00.00>CRE AC2 A320 52 5\n00:00:10.00>CRE AC3 zzzz 52 6\n00:00:20.00>CRECONFS AC4 QQ AC1 90 1 60\n"
    sc = parse_scenario(text, "types.scn")
    assert {t: str(s) for t, s in unknown_types([sc, sc]).items()} == {"ZZZZ": "types.scn:1", "QQ": "types.scn:4"}
    with pytest.warns(UnknownAircraftTypeWarning) as caught:
        player = ScenarioPlayer([sc, sc], Simulator(2, 4))
    messages = sorted(str(w.message) for w in caught)
    assert len(messages) == 2
    assert messages[0].startswith("types.scn:1: aircraft type 'ZZZZ' is unknown to BlueSky; it flies as the B744")
    assert messages[1].startswith("types.scn:4: aircraft type 'QQ' is unknown to BlueSky")
    player.advance(30)
    assert player.physics.aircraft_performance(0, 2).name == "B744"  # type: ignore[attr-defined]  # BlueSky's fallback is kept
    assert unknown_types([parse_scenario("00:00:00.00>CRE AC1 B738 52 4\n00:00:00.00>CRE AC2 A320 52 4\n00:00:00.00>CRE AC3 EC35 52 4\n")]) == {}


def test_replay_cli_flies_rotorcraft_as_bluesky(tmp_path: Path) -> None:
    """``bluesky-gym replay`` of rotorcraft beside fixed-wing aircraft writes BlueSky's recording, every column to the last digit."""
    out = tmp_path / "rotor.csv"
    assert main(["replay", str(DATA / "scn" / "rotor_mixed.scn"), "--duration", "300", "--out", str(out), "--quiet"]) == 0
    rows = _rows(out)
    with open_recording("pcall_rotor_mixed") as fh:
        ref = list(csv.DictReader(fh))
    assert len(rows) == len(ref) == 12 * 301
    assert {r["acid"] for r in rows} >= {"R01", "R09", "F01", "F03"}
    for got, want in zip(rows, ref):
        assert [float(got[c]) for c in TRAJECTORY_COLUMNS[2:]] == pytest.approx(
            [float(want[c]) for c in TRAJECTORY_COLUMNS[2:]], rel=0, abs=0, nan_ok=True
        ), (
            want["t"],
            want["acid"],
        )


def _replay_err(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str]:
    rc = main(["replay", *argv])
    return rc, capsys.readouterr().err


def test_replay_refuses_non_finite_numbers(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    scn, out = tmp_path / "x.scn", tmp_path / "x.csv"
    for line, match in (
        ("ALT AC1 nan", "x.scn:2: ALT: an altitude must be a finite number, got 'nan'"),
        ("DT inf", "x.scn:2: DT: a time step must be a finite number, got 'inf'"),
        ("CRECONFS I1 A320 AC1 90 1 60 0 0", "x.scn:2: CRECONFS: no finite conflict geometry"),
    ):
        scn.write_text(f"00:00:00.00>CRE AC1 A320 52 4 90 FL200 250\n00:00:{'00' if 'DT' in line else '10'}.00>{line}\n")
        rc, err = _replay_err(capsys, str(scn), "--out", str(out))
        assert rc == 2 and match in err and len(err.splitlines()) == 1, err
        assert not out.exists()


def test_replay_bounds_the_number_of_steps(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    scn = tmp_path / "dt.scn"
    scn.write_text("00:00:00.00>DT 1e-9\n00:00:00.00>CRE AC1 A320 52 4 90 FL200 250\n")
    rc, err = _replay_err(capsys, str(scn))
    assert rc == 2
    assert f"the default duration (0 s, the last command's time, + 60 s) in steps of 1e-09 s (DT in {scn}:1) is 60,000,000,000 steps" in err
    assert "more than --max-steps 1,000,000" in err
    rc, err = _replay_err(capsys, "super8", "--duration", "20", "--max-steps", "19", "--quiet")
    assert rc == 2 and "--duration 20 s in steps of 1 s (the default time step) is 20 steps, more than --max-steps 19" in err
    assert main(["replay", "super8", "--duration", "20", "--max-steps", "20", "--quiet"]) == 0


def test_replay_rounds_the_default_duration_up_to_a_whole_step(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    scn, out = tmp_path / "f.scn", tmp_path / "f.csv"
    scn.write_text("00:00:00.00>CRE AC1 A320 52 4 90 FL200 250\n00:00:10.50>HDG AC1 180\n")
    rc, err = _replay_err(capsys, str(scn), "--out", str(out), "--quiet")
    assert rc == 0, err
    rows = _rows(out)
    assert [r["t"] for r in rows] == [str(k) for k in range(72)]  # 70.5 s rounded up to 71 steps
    rc, err = _replay_err(capsys, str(scn), "--dt", "0.25", "--quiet")
    assert rc == 0 and "" == err
    rc, err = _replay_err(capsys, str(scn), "--duration", "2.5", "--dt", "1")
    assert rc == 2 and "--duration 2.5 s is not a whole number of steps of 1 s (--dt 1)" in err
    scn.write_text("00:00:00.00>DT 2\n00:00:00.00>CRE AC1 A320 52 4 90 FL200 250\n")
    rc, err = _replay_err(capsys, str(scn), "--duration", "3")
    assert rc == 2 and f"--duration 3 s is not a whole number of steps of 2 s (DT in {scn}:1)" in err


def test_replay_refuses_files_without_commands(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    for name, text in (("empty.scn", ""), ("comments.scn", "# a title\n\n   # nothing else\n")):
        (tmp_path / name).write_text(text)
        rc, err = _replay_err(capsys, str(tmp_path / name))
        assert rc == 2 and f"{tmp_path / name}: no commands (the file is empty or holds only comments and blank lines)" in err
    (tmp_path / "pan.scn").write_text("00:00:00.00>PAN 52 4\n")
    rc, err = _replay_err(capsys, str(tmp_path / "pan.scn"), "--quiet")
    assert rc == 0 and f"warning: {tmp_path / 'pan.scn'}: creates no aircraft" in err


def test_replay_warns_once_per_unknown_type(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    a, b = tmp_path / "a.scn", tmp_path / "b.scn"
    a.write_text("".join(f"00:00:00.00>CRE AC{k} {t} 52 {4 + k} 90 FL200 250\n" for k, t in enumerate(["A320", "ZZZZ", "ZZZZ"], start=1)))
    b.write_text("".join(f"00:00:00.00>CRE AC{k} {t} 52 {4 + k} 90 FL200 250\n" for k, t in enumerate(["ZZZZ", "B738"], start=1)))
    rc, err = _replay_err(capsys, str(a), str(b), "--copies", "2", "--duration", "5", "--quiet")
    assert rc == 0
    assert err.count("unknown to BlueSky") == 1
    assert f"bluesky-gym replay: warning: {a}:2: aircraft type 'ZZZZ' is unknown to BlueSky; it flies as the B744" in err


def test_replay_counts_compilation_apart_from_simulation(capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    """numba compiling (or loading) a kernel during the steps is reported apart, not as simulation time."""
    from numba.core.compiler_lock import global_compiler_lock

    step = ScenarioPlayer.step
    compiled = []

    def step_compiling_first(self: ScenarioPlayer) -> None:
        if not compiled:  # what a kernel's first call does: numba compiles it under its compiler lock
            with global_compiler_lock:
                time.sleep(0.5)
            compiled.append(True)
        step(self)

    monkeypatch.setattr(ScenarioPlayer, "step", step_compiling_first)
    assert main(["replay", "super8", "--duration", "5", "--out", os.devnull]) == 0
    err = capsys.readouterr().err
    m = re.search(r"in ([0-9.]+) s wall \(([0-9.]+) s compiling or loading the numba kernels, ([0-9.]+) s simulating\)", err)
    assert m is not None, err
    wall, compiling, simulating = map(float, m.groups())
    assert compiled and compiling >= 0.5 and simulating < 0.5 and compiling + simulating <= wall
