"""Conflict detection and resolution commands (MVP, EBY, SWARM, SSD) in scenario files: reading, BlueSky's settings bookkeeping, playing."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from bluesky_gym.core import Simulator
from bluesky_gym.core.physics import ConflictResolutionCommands
from bluesky_gym.core.resolution import RESO_FACTOR, AsasConfig, ResolutionSettings
from bluesky_gym.core.units import FT, NM
from bluesky_gym.scenarios import ScenarioError, ScenarioPlayer, parse_scenario, read_scenario
from bluesky_gym.scenarios.parser import Asas
from bluesky_gym.scenarios.player import TRAJECTORY_COLUMNS, slots_needed, waypoints_needed
from tests.core.reference_scenarios import DATA

try:
    import pyclipper  # noqa: F401  (RESO SSD needs the ssd extra)

    HAVE_PYCLIPPER = True
except ImportError:
    HAVE_PYCLIPPER = False
needs_pyclipper = pytest.mark.skipif(not HAVE_PYCLIPPER, reason="RESO SSD needs pyclipper (the ssd extra)")


def configs(text: str) -> list[AsasConfig]:
    """The ASAS configuration after each ASAS command of a scenario text (commands at time 0)."""
    lines = "".join(f"00:00:00.00>{line}\n" for line in text.strip().splitlines())
    return [c.config for c in parse_scenario(lines, "t.scn").commands if isinstance(c, Asas)]


def test_commands_and_aliases_set_what_bluesky_sets() -> None:
    """Values as BlueSky 1.1.1 shows them after the same commands (cd.rpz_def, cr.resofach, ...)."""
    got = configs(
        """
        ASAS ON
        RESO MVP
        PZR 3
        PZHEIGHT 800
        DTLOOK 00:03:20
        RESOFACH 1.2
        RESOFACV 0.9
        RMETHH HDG
        CDMETHOD CSTATEBASED
        """
    )
    assert got[0] == AsasConfig(detector="STATEBASED")  # ON: the first registered method
    assert got[1].resolving and got[1].settings == ResolutionSettings()
    assert (got[2].rpz, got[3].hpz, got[4].lookahead) == (3 * NM, 800 * FT, 200.0)
    assert (got[5].settings.resofach, got[6].settings.resofacv) == (1.2, 0.9)
    assert got[7].settings == ResolutionSettings(True, False, True, False, 1.2, 0.9) and got[7].settings.mode == 2
    # CSTATEBASED is another detection method: its zones start from the defaults, MVP's settings stay.
    assert got[8] == AsasConfig("CSTATEBASED", True, got[7].settings)


def test_settings_belong_to_the_selected_method() -> None:
    """BlueSky keeps zones per detection method and factors/switches per resolution method (checked in BlueSky 1.1.1)."""
    got = configs(
        """
        ZONER 3
        DTLOOK 200
        RMETHH SPD
        RFACH 1.5
        ASAS ON
        RESO MVP
        RSZONER 4
        ZONER 6
        RFACV 1.3
        RMETHV ON
        ASAS OFF
        """
    )
    assert (got[0].rpz, got[1].lookahead) == (3 * NM, 200.0)  # on "detection off"
    assert (got[4].rpz, got[4].lookahead) == (5 * NM, 300.0)  # STATEBASED: its own defaults
    assert got[5].settings == ResolutionSettings()  # RMETHH and RFACH before RESO MVP do not reach MVP
    assert got[6].settings.resofach == 4 / (5 * NM) * NM  # an absolute resolution zone of 4 NM
    assert got[7].settings.resofach == (4 / (5 * NM) * NM) * (5 * NM) / NM / (6 * NM) * NM  # still 4 NM after ZONER 6
    assert got[7].settings.resofach == pytest.approx(4 / 6)
    assert got[9].settings.mode == 3 and got[9].settings.resofacv == 1.3
    assert got[10] == AsasConfig(None, True, got[9].settings, 3 * NM, 1000 * FT, 200.0)  # back to "off" and its zone
    assert not got[10].resolving


def test_no_ops_are_accepted() -> None:
    got = configs("ASAS\nRESO\nZONER\nRMETHH\nPRIORULES\nPRIORULES ON FF1\nNORESO\nRESOOFF\nDTNOLOOK 10\nZONER -1\nRESO MVP\nPRIORULES OFF")
    assert all(c == AsasConfig() for c in got[:-2])
    assert got[-1] == got[-2] == AsasConfig(resolution=True)


@pytest.mark.parametrize(
    ("lines", "match"),
    [
        (["RESO MVP", "PRIORULES ON FF1"], "priority rules are not supported"),
        (["RESO MVP", "NORESO AC1"], "NORESO"),
        (["RESOOFF AC1"], "RESOOFF"),
        (["ZONER 5 AC1"], "per-aircraft values"),
        (["DTLOOK 100 AC1"], "per-aircraft values"),
        (["RESO FANCY"], "resolution method 'FANCY' is not supported; choose one of OFF, MVP, EBY, SWARM, SSD"),
        (["RESO SSD", "PRIORULES ON RS2"], "SSD priority code 'RS2' is not supported"),
        (["RESO SSD", "PRIORULES OFF RS7"], "SSD priority code 'RS7' is not supported"),
        (["RESO SSD", "PRIORULES ON"], "PRIORULES ON needs a priority code with RESO SSD"),
        (["RESO SSD", "PRIORULES ON FF1"], "SSD priority code 'FF1' not understood"),
        (["RESO SWARM", "PRIORULES ON FF1"], "priority rules are not supported by the core's SWARM"),
        (["ASAS FANCY"], "detection method 'FANCY' not known"),
        (["RESO MVP", "RMETHH SIDEWAYS"], "'SIDEWAYS' not understood"),
        (["RFACH -1"], "RFACH must be > 0"),
        (["ZONER five"], "cannot read 'FIVE' as a distance"),
        (["DTLOOK soon"], "cannot read 'SOON' as a time"),
    ],
)
def test_unsupported_asas_commands_name_file_and_line(lines: list[str], match: str) -> None:
    text = "00:00:00.00>CRE AC1 A320 52 4\n" + "".join(f"00:00:01.00>{line}\n" for line in lines)
    with pytest.raises(ScenarioError, match=match) as err:
        parse_scenario(text, "bad.scn")
    assert str(err.value).startswith(f"bad.scn:{len(lines) + 1}: ") and "\n" not in str(err.value)


@pytest.mark.parametrize("off", ["RESO OFF", "ASAS OFF"])
def test_switching_resolution_off_after_it_flew_is_refused(off: str) -> None:
    head = "00:00:00.00>ASAS ON\n00:00:00.00>RESO MVP\n"
    assert not configs(f"ASAS ON\nRESO MVP\n{off}")[-1].resolving  # before any step: fine
    with pytest.raises(ScenarioError, match=r"t\.scn:3: .*switching conflict resolution off once it flew is not supported"):
        parse_scenario(head + f"00:00:10.00>{off}\n", "t.scn")


def test_eby_and_swarm_are_selected_with_their_own_settings() -> None:
    """RESO EBY|SWARM name the method; RMETH switches reach MVP and SWARM (which inherits them), not EBY (BlueSky ignores them there)."""
    got = configs(
        """
        ASAS ON
        RESO EBY
        RMETHH HDG
        RFACH 1.2
        PRIORULES ON FF1
        RESO SWARM
        RMETHV V/S
        RESO EBY
        PLUGINS LOAD SWARM
        """
    )
    assert got[1] == AsasConfig("STATEBASED", True, method="EBY") and got[1].resolving
    assert got[2].settings == ResolutionSettings()  # RMETHH under EBY: no effect
    assert got[3].settings.resofach == 1.2 and got[4] == got[3]  # PRIORULES: EBY ignores them
    assert got[5] == AsasConfig("STATEBASED", True, method="SWARM")  # its own factors, from the defaults
    assert got[6].settings.mode == 3 and got[6].method == "SWARM"
    assert got[7].method == "EBY" and got[7].settings.resofach == 1.2 and got[7].settings.mode == 0  # EBY's settings kept
    assert len(got) == 8  # PLUGINS is not an ASAS command (ignored: the core has the plugins built in)


def test_ssd_is_selected_with_its_default_rule() -> None:
    """RESO SSD names the method; PRIORULES with RS1 (its default rule) is accepted, RMETH switches do not reach it."""
    got = configs("ASAS CSTATEBASED\nRESO SSD\nPRIORULES ON RS1\nRMETHH HDG\nRFACH 1.2\nPLUGINS LOAD SSD")
    assert got[1] == AsasConfig("CSTATEBASED", True, method="SSD") and got[1].resolving
    assert got[2] == got[1] and got[3] == got[1]  # RS1 and RMETHH: no change
    assert got[4].settings.resofach == 1.2 and got[4].method == "SSD"


def test_switching_method_after_it_flew_is_refused() -> None:
    assert configs("ASAS ON\nRESO MVP\nRESO EBY")[-1].method == "EBY"  # before any step: fine
    with pytest.raises(ScenarioError, match=r"t\.scn:3: .*switching from RESO EBY to RESO SWARM once it flew is not supported"):
        parse_scenario("00:00:00.00>ASAS ON\n00:00:00.00>RESO EBY\n00:00:05.00>RESO SWARM\n", "t.scn")


@pytest.mark.parametrize("method", ["EBY", "SWARM", pytest.param("SSD", marks=needs_pyclipper)])
def test_eby_and_swarm_scenarios_fly_on_the_core(method: str) -> None:
    """A creconfs conflict flown with RESO EBY|SWARM|SSD: the aircraft leave their tracks, and not as MVP would."""
    text = (
        "00:00:00.00>ASAS CSTATEBASED\n00:00:00.00>RESO {}\n"
        "00:00:00.00>CRE OWN A320 52 4 90 FL100 250\n00:00:00.00>CRECONFS INT A320 OWN 60 0.5 120\n"
    )
    tracks = {}
    for m in ("MVP", method):
        scenario = parse_scenario(text.format(m), "c.scn")
        sim = _sim(scenario)
        rows = _replay([scenario], sim, 60)
        assert sim.conflict_resolution(0).method == m
        tracks[m] = np.array([r[TRAJECTORY_COLUMNS.index("trk")] for r in rows if r[1] == "OWN"])
    assert np.max(np.abs(tracks[method] - 90.0)) > 1.0  # the method resolved
    assert np.max(np.abs(tracks[method] - tracks["MVP"])) > 0.1  # differently from MVP


def test_swarm_needs_the_all_pairs_search() -> None:
    scenario = parse_scenario("00:00:00.00>CRE OWN A320 52 4 90 FL100 250\n00:00:00.00>ASAS ON\n00:00:00.00>RESO SWARM\n", "g.scn")
    sim = Simulator(1, 4, pair_search="grid")
    with pytest.raises(ScenarioError, match=r"g\.scn:3: .*RESO SWARM needs pair_search 'all-pairs', this simulator has 'grid'"):
        ScenarioPlayer([scenario], sim).step()


def _replay(scenarios: list[Any], sim: Any, steps: int) -> list[list[object]]:
    player = ScenarioPlayer(scenarios, sim)
    rows = player.snapshot(0.0)
    for k in range(1, steps + 1):
        player.step()
        rows += player.snapshot(float(k))
    return rows


def _sim(scenario: Any, n_envs: int = 1, dt: float = 1.0) -> Simulator:
    return Simulator(n_envs, slots_needed(scenario), dt=dt, max_waypoints=max(4, waypoints_needed(scenario)))


def test_copies_and_neighbours_in_a_batch_fly_as_alone() -> None:
    """Resolution acts per airspace: copies resolve exactly as the file alone, and an airspace without it is untouched."""
    reso = read_scenario(DATA / "scn" / "reso_methods.scn")
    plain = read_scenario(DATA / "scn" / "super8.scn")
    steps = 150
    alone = _replay([reso], _sim(reso), steps)
    plain_alone = _replay([plain], _sim(plain), steps)
    sim = Simulator(3, 8, dt=1.0, max_waypoints=4)
    player = ScenarioPlayer([reso, plain, reso], sim)
    by_env: dict[int, list[list[object]]] = {0: [], 1: [], 2: []}
    for k in range(steps + 1):
        if k:
            player.step()
        for row, e in zip(player.snapshot(float(k)), player.scenario_of_rows()):
            by_env[e].append(row)
    assert by_env[0] == alone and by_env[2] == alone and by_env[1] == plain_alone
    # and the resolution did change the flight (the same file without RESO MVP flies otherwise)
    text = (DATA / "scn" / "reso_methods.scn").read_text().replace(">RESO MVP", ">RESO OFF")
    assert _replay([parse_scenario(text)], _sim(reso), steps) != alone


def test_a_physics_without_resolution_refuses_reso_mvp() -> None:
    class NoResolution:
        """A physics that only has the Physics commands."""

        def __init__(self, sim: Simulator) -> None:
            self._sim = sim

        def __getattr__(self, name: str) -> Any:
            if name == "set_conflict_resolution":
                raise AttributeError(name)
            return getattr(self._sim, name)

    detection_only = parse_scenario("00:00:00.00>CRE AC1 A320 52 4\n00:00:00.00>ASAS ON\n00:00:00.00>ZONER 4\n", "d.scn")
    physics = NoResolution(Simulator(1, 1))
    assert not isinstance(physics, ConflictResolutionCommands)
    ScenarioPlayer([detection_only], physics)  # type: ignore[list-item]  # detection alone changes no flight: accepted
    reso = parse_scenario("00:00:00.00>CRE AC1 A320 52 4\n00:00:00.00>ASAS ON\n00:00:00.00>RESO MVP\n", "r.scn")
    with pytest.raises(ScenarioError, match=r"r\.scn:3: this physics cannot fly conflict resolution"):
        ScenarioPlayer([reso], NoResolution(Simulator(1, 1)))  # type: ignore[list-item]


def test_resolution_needs_the_asas_interval() -> None:
    reso = parse_scenario("00:00:00.00>CRE AC1 A320 52 4\n00:00:00.00>ASAS ON\n00:00:00.00>RESO MVP\n", "r.scn")
    with pytest.raises(ScenarioError, match=r"r\.scn:3: .*conflict resolution needs dt >= 1.0 s"):
        ScenarioPlayer([reso], Simulator(1, 1, dt=0.5))


def test_simulator_resolution_state_is_per_airspace() -> None:
    sim = Simulator(2, 2)
    config = AsasConfig("CSTATEBASED", True)
    sim.set_conflict_resolution([1], config)
    assert sim.conflict_resolution(1) == config and sim.conflict_resolution(0) == AsasConfig()
    with pytest.raises(ValueError, match="cannot rewind"):
        sim.run(3, stop=lambda track: np.zeros(2, dtype=np.int64))
    sim.reset_envs([1])
    assert sim.conflict_resolution(1) == AsasConfig()
    assert RESO_FACTOR == config.settings.resofach


def test_the_shipped_resolution_geometry_is_the_recorded_one() -> None:
    """``super8_mvp`` plays the commands of ``reso_super8.scn``, which BlueSky recorded (pcall_reso_super8)."""
    from bluesky_gym.scenarios.geometries import shipped_scenario

    def commands(path: Any) -> list[tuple[float, str]]:
        return [(c.time, c.source.text) for c in read_scenario(path).commands]

    assert commands(shipped_scenario("super8_mvp")) == commands(DATA / "scn" / "reso_super8.scn")


@pytest.mark.bluesky
def test_resolution_in_wind_flies_as_in_bluesky() -> None:
    """In wind the resolution ground speed becomes a TAS against the wind (APorASAS): core and BlueSky backend side by side."""
    pytest.importorskip("bluesky")
    from bluesky_gym.backends.bluesky_sim import BlueSkyPhysics
    from bluesky_gym.scenarios import TRAJECTORY_COLUMNS
    from bluesky_gym.scenarios.geometries import super_conflict, with_resolution
    from tests.core.test_reference import TOL

    scenario = parse_scenario(with_resolution(super_conflict(6, radius_nm=25.0), detector="CSTATEBASED", settings=("RMETHH BOTH",)), "wind.scn")
    tracks: list[list[list[object]]] = []
    for sim in (Simulator(1, 6), BlueSkyPhysics(6)):
        try:
            sim.wind.add_points(0, [52.0], [4.0], [9.0], [-14.0])  # one point: the same wind everywhere
            tracks.append(_replay([scenario], sim, 300))
        finally:
            if isinstance(sim, BlueSkyPhysics):
                sim.close()
    core, bluesky = tracks
    assert len(core) == len(bluesky) == 6 * 301
    index = {c: TRAJECTORY_COLUMNS.index(c) for c in ("lat", "lon", "alt", "tas", "gs", "trk", "hdg", "vs")}
    start = {row[1]: float(row[index["trk"]]) for row in core[:6]}  # type: ignore[arg-type]
    turned = 0
    for a, b in zip(core, bluesky):
        for c, k in index.items():
            err = abs(float(a[k]) - float(b[k]))  # type: ignore[arg-type]
            err = min(err, 360.0 - err) if c in ("trk", "hdg") else err
            assert err <= TOL[c], (a[0], a[1], c, a[k], b[k])
        turned += abs((float(a[index["trk"]]) - start[a[1]] + 180.0) % 360.0 - 180.0) > 1.0  # type: ignore[arg-type]
    assert turned > 100  # the resolution did act


def test_statebased_bearings_depend_on_bluesky_geo_functions() -> None:
    """With BlueSky's compiled geo functions STATEBASED misses the approaching reverse pairs; with its Python ones it sees all."""
    from bluesky_gym.core.conflicts import detect, detect_statebased
    from bluesky_gym.scenarios.geometries import shipped_scenario

    sim = Simulator(1, 8)
    ScenarioPlayer([read_scenario(shipped_scenario("super8"))], sim)
    sim.run(150)  # all within the look-ahead time of each other, not yet in loss of separation
    state = (sim.lat, sim.lon, sim.alt, sim.gs, sim.trk, sim.vs, sim.active)
    symmetric = detect(*state).conflict[0]
    compiled = detect_statebased(*state).conflict[0]
    python = detect_statebased(*state, python_geo=True).conflict[0]
    assert symmetric.sum() == 56 and np.array_equal(python, symmetric)
    assert np.array_equal(compiled, np.triu(symmetric))  # only the pairs (i, j) with i < j
