"""The .scn reader: every argument form BlueSky accepts, and every error naming file, line and command."""

from __future__ import annotations

import pytest

from bluesky_gym.core.command_text import (
    is_latitude,
    parse_altitude,
    parse_heading,
    parse_latitude,
    parse_longitude,
    parse_number,
    parse_speed,
    parse_switch,
    parse_time,
    parse_vertical_speed,
    split_arguments,
)
from bluesky_gym.core.units import FPM, FT, KTS
from bluesky_gym.scenarios import ScenarioError, parse_scenario, read_scenario
from bluesky_gym.scenarios.parser import (
    AddWaypoint,
    Altitude,
    Asas,
    Create,
    CreateConflict,
    Delete,
    Destination,
    Direct,
    Heading,
    Ignored,
    Lnav,
    Speed,
    TimeStep,
    VerticalSpeed,
    Vnav,
)


@pytest.mark.parametrize(
    ("text", "want"),
    [
        ("FL350", 35000 * FT),
        ("fl050", 5000 * FT),
        ("FL10", 1000 * FT),
        ("5000", 5000 * FT),
        ("-200", -200 * FT),
        ("12.5", 12.5 * FT),
    ],
)
def test_altitudes(text: str, want: float) -> None:
    assert parse_altitude(text) == want


@pytest.mark.parametrize(
    ("text", "want"),
    [
        ("250", 250 * KTS),
        ("1.0", 1.0 * KTS),
        ("M.78", 0.78),
        ("m78", 0.78),
        ("M0.78", 0.78),
        ("0.78", 0.78),
        ("0.1", 0.1 * KTS),  # BlueSky: Mach only for 0.1 < v < 1
    ],
)
def test_speeds(text: str, want: float) -> None:
    assert parse_speed(text) == want


@pytest.mark.parametrize(
    ("text", "want"),
    [
        ("52.5", 52.5),
        ("N52.5", 52.5),
        ("S12.25", -12.25),
        ("-12.25", -12.25),
        ("N52'30'00\"", 52.5),
        ("S01'30'36\"", -(1 + 30 / 60 + 36 / 3600)),
        ("N52\N{DEGREE SIGN}15'", 52.25),
    ],
)
def test_latitudes(text: str, want: float) -> None:
    assert is_latitude(text)
    assert parse_latitude(text) == pytest.approx(want, abs=1e-15)


@pytest.mark.parametrize(
    ("text", "want"),
    [("4.5", 4.5), ("E4.5", 4.5), ("W004.5", -4.5), ("-4.5", -4.5), ("E004'30'00\"", 4.5), ("W002'15'", -2.25), ("1e-3", 1e-3)],
)
def test_longitudes(text: str, want: float) -> None:
    assert parse_longitude(text) == pytest.approx(want, abs=1e-15)


def test_other_argument_forms() -> None:
    assert parse_heading("090") == 90.0
    assert parse_heading("270T") == 270.0
    assert parse_heading("-115.5") == -115.5
    assert parse_vertical_speed("-1500") == -1500 * FPM
    assert parse_time("90") == 90.0
    assert parse_time("01:30") == 90.0
    assert parse_time("01:00:30.5") == 3630.5
    assert parse_switch("on") is True and parse_switch("OFF") is False
    assert not is_latitude("SUGOL") and not is_latitude("KL204")
    assert split_arguments("AC1,A320 52, 4 ,,FL100  250") == ["AC1", "A320", "52", "4", "", "FL100", "250"]
    assert split_arguments("'a b', c") == ["a b", "c"]


@pytest.mark.parametrize(
    ("fun", "text", "match"),
    [
        (parse_altitude, "FLX", "altitude"),
        (parse_altitude, "high", "altitude"),
        (parse_speed, "fast", "speed"),
        (parse_heading, "090M", "magnetic"),
        (parse_heading, "north", "heading"),
        (parse_latitude, "N95", "outside"),
        (parse_latitude, "Nxx", "latitude"),
        (parse_longitude, "Exx", "longitude"),
        (parse_time, "1:2:3:4", "time"),
        (parse_vertical_speed, "up", "vertical speed"),
        (parse_switch, "maybe", "ON or OFF"),
    ],
)
def test_bad_arguments(fun, text: str, match: str) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(ValueError, match=match):
        fun(text)


SCN = """# a comment
00:00:00.00>DT 0.5
00:00:00.00>CRE AC1 A320 52 4 45 FL350 250   # trailing comment
00:00:00.00>CREATE AC2,A320,N52'10'00",E004'30'00",,10000,M.6
00:00:00.00>CRECONFS INT1 A320 AC1 90 1.0 01:30 FL10 60 M.7
00:00:00.00>PAN 52 4
00:00:05.00>AC1 HDG 90; SPD AC1 M.7

00:00:10.50>ALT AC1 FL300 -2000
00:00:10.50>VS AC2 \\
            1200 # continued
00:00:20.00>ADDWPT AC2 52.3 4.6
00:00:20.00>DEST AC2 AC1
00:00:21.00>DIRECT AC2 AC2001
00:00:22.00>LNAV AC2 OFF
00:00:23.00>VNAV AC2 OFF
00:00:30.00>DEL AC1, AC2
00:00:15.00>TURN INT1 180
00:00:40.00>ASAS ON; RESO OFF; NOISE OFF
"""


def test_a_scenario_file_is_parsed_in_time_order() -> None:
    sc = parse_scenario(SCN, "test.scn")
    kinds = [type(c) for c in sc.commands]
    assert kinds == [
        TimeStep,
        Create,
        Create,
        CreateConflict,
        Ignored,
        Heading,
        Speed,
        Altitude,
        VerticalSpeed,
        Heading,  # 00:00:15 sorted before the 00:00:20 commands (stable sort)
        AddWaypoint,
        Destination,
        Direct,
        Lnav,
        Vnav,
        Delete,
        Asas,
        Asas,
        Ignored,
    ]
    c = sc.commands
    assert sc.dt == 0.5 and sc.callsigns == ["AC1", "AC2", "INT1"] and sc.end_time == 40.0
    assert c[1] == Create(0.0, c[1].source, "AC1", "A320", c[1].position, 45.0, 35000 * FT, 250 * KTS)  # type: ignore[attr-defined]
    assert c[1].source.line == 3 and c[1].source.file == "test.scn"
    assert c[2].hdg == 0.0 and c[2].position.lat == pytest.approx(52 + 1 / 6) and c[2].spd == 0.6  # type: ignore[attr-defined]
    assert (c[3].target, c[3].tlosh, c[3].dh, c[3].tlosv, c[3].spd) == ("AC1", 90.0, 1000 * FT, 60.0, 0.7)  # type: ignore[attr-defined]
    assert c[7].time == 10.5 and c[7].vs == -2000 * FPM  # type: ignore[attr-defined]
    assert c[8].source.line == 10 and c[8].vs == 1200 * FPM  # type: ignore[attr-defined]
    assert c[11].position.aircraft == "AC1"  # type: ignore[attr-defined]
    assert c[12].waypoint == 0 and c[13].on is False  # type: ignore[attr-defined]
    assert c[15].acids == ("AC1", "AC2")  # type: ignore[attr-defined]


def test_read_scenario_names_the_file(tmp_path) -> None:  # type: ignore[no-untyped-def]
    p = tmp_path / "x.scn"
    p.write_text("00:00:00.00>CRE AC1 A320 52 4\n00:00:01.00>HDG AC9 90\n")
    with pytest.raises(ScenarioError, match=r"x\.scn:2: HDG: no aircraft 'AC9'"):
        read_scenario(p)
    with pytest.raises(ScenarioError, match="cannot read"):
        read_scenario(tmp_path / "missing.scn")


@pytest.mark.parametrize(
    ("line", "match"),
    [
        ("CRE AC1 A320 52 4", "already exists"),
        ("FLY AC1 90", "unsupported command 'FLY'"),
        ("HDG AC1", "HDG: missing argument hdg"),
        ("HDG AC1 90 100", "HDG: too many arguments"),
        ("HDG AC1 090M", "magnetic"),
        ("ALT AC1 high", "ALT: cannot read 'high' as an altitude"),
        ("SPD AC1 fast", "SPD: cannot read"),
        ("CRE AC2 A320 SUGOL", "navigation database"),
        ("CRE AC2 A320 N99 4", "outside"),
        ("ADDWPT AC1 52 4 FL100", "constraints"),
        ("DIRECT AC1 AC1005", "not in the route"),
        ("LNAV AC1 ON", "no waypoints"),
        ("VNAV AC1 ON", "VNAV ON is not supported"),
        ("RESO FANCY", "resolution method 'FANCY' is not supported"),
        ("NOISE ON", "turbulence"),
        ("DT 0", "dt must be > 0"),
        ("DEL", "missing argument"),
        ("CRECONFS I1 A320 AC9 90 1 60", "no aircraft 'AC9'"),
        ("AREA 1 1 -1 -1", "unsupported command 'AREA'"),
    ],
)
def test_errors_name_file_line_and_command(line: str, match: str) -> None:
    text = f"00:00:00.00>CRE AC1 A320 52 4\n# comment\n00:00:01.00>{line}\n"
    with pytest.raises(ScenarioError, match=match) as err:
        parse_scenario(text, "bad.scn")
    assert str(err.value).startswith("bad.scn:3: ")
    assert "\n" not in str(err.value)


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("CRE AC1 A320 52 4\n", r"bad\.scn:1: expected 'HH:MM:SS\.hh>COMMAND args'"),
        ("00:61:00.00>CRE AC1 A320 52 4\n", "invalid time stamp"),
        ("00:00:00.00>CRE AC1 A320 52 4 \\\n", "continuation of nothing"),
        ("00:00:00.00>HDG AC1 \\\n   90\n", "shorter than 10 characters"),
        ("00:00:00.00>CRE AC1 A320 52 4 \\\n\n00:00:00.00>PAN 1 1\n", "followed by an empty line"),
        ("00:00:05.00>DT 1\n", "DT is only supported at time 0"),
        ("00:00:00.00> \n", "without a command"),
    ],
)
def test_file_level_errors(text: str, match: str) -> None:
    with pytest.raises(ScenarioError, match=match):
        parse_scenario(text, "bad.scn")


def test_deleted_callsign_can_be_created_again() -> None:
    sc = parse_scenario("00:00:00.00>CRE AC1 A320 52 4\n00:00:10.00>DEL AC1\n00:00:20.00>CRE AC1 A320 53 4\n00:00:30.00>HDG AC1 90\n")
    assert sc.callsigns == ["AC1", "AC1"]
    with pytest.raises(ScenarioError, match="no aircraft 'AC1'"):
        parse_scenario("00:00:00.00>CRE AC1 A320 52 4\n00:00:10.00>DEL AC1\n00:00:30.00>HDG AC1 90\n")


@pytest.mark.parametrize(
    ("fun", "text"),
    [
        (parse_altitude, "nan"),
        (parse_altitude, "inf"),
        (parse_altitude, "1e999"),
        (parse_speed, "nan"),
        (parse_speed, "M.nan"),
        (parse_speed, "inf"),
        (parse_vertical_speed, "-inf"),
        (parse_heading, "nan"),
        (parse_heading, "infT"),
        (parse_latitude, "nan"),
        (parse_longitude, "nan"),
        (parse_longitude, "-inf"),
        (parse_time, "nan"),
        (parse_time, "01:inf"),
        (parse_number, "NaN"),
    ],
)
def test_non_finite_arguments_are_refused(fun, text: str) -> None:  # type: ignore[no-untyped-def]
    """Python's float reads nan, inf and 1e999; a scenario argument must be a finite number."""
    with pytest.raises(ValueError, match=f"must be a finite number, got '{text}'|cannot read '{text}'"):
        fun(text)


@pytest.mark.parametrize(
    "line",
    [
        "ALT AC1 nan",
        "ALT AC1 inf",
        "ALT AC1 1e999",
        "ALT AC1 FL100 nan",
        "HDG AC1 nan",
        "SPD AC1 nan",
        "VS AC1 -inf",
        "CRE AC2 A320 52 4 nan nan nan",
        "CRE AC2 A320 52 4 90 FL100 inf",
        "CRE AC2 A320 52 inf",
        "CRECONFS I1 A320 AC1 nan 1 60",
        "CRECONFS I1 A320 AC1 90 nan 60",
        "CRECONFS I1 A320 AC1 90 1 inf",
        "CRECONFS I1 A320 AC1 90 1 60 FL10 nan",
        "DT inf",
        "DT nan",
        "ZONER nan",
        "ZONEDH inf",
        "DTLOOK nan",
        "RFACH inf",
        "RSZONER nan",
        "ADDWPT AC1 52 nan",
    ],
)
def test_non_finite_numbers_are_refused_with_file_and_line(line: str) -> None:
    text = f"00:00:00.00>CRE AC1 A320 52 4 90 FL200 250\n# comment\n00:00:00.00>{line}\n"
    with pytest.raises(ScenarioError, match="must be a finite number") as err:
        parse_scenario(text, "bad.scn")
    assert str(err.value).startswith("bad.scn:3: ") and "\n" not in str(err.value)


@pytest.mark.parametrize(
    ("args", "which"),
    [
        ("0 0", "dH 0 ft and tlos_ver 0 s"),  # BlueSky: 0 * (0 - 1000 ft) / 0, NaN
        ("FL10 0", "dH 1000 ft and tlos_ver 0 s"),
        ("-2000 00:00", "dH -2000 ft and tlos_ver 0 s"),  # infinite
        ("500", "tlos_hor (tlos_ver omitted) 0 s"),  # tlos_ver defaults to tlos_hor
    ],
)
def test_creconfs_without_a_finite_vertical_speed_is_refused(args: str, which: str) -> None:
    tlosh = "0" if "tlos_hor" in which else "60"
    text = f"00:00:00.00>CRE AC1 A320 52 4 90 FL200 250\n00:00:00.00>CRECONFS I1 A320 AC1 90 1 {tlosh} {args}\n"
    with pytest.raises(ScenarioError, match="no finite conflict geometry") as err:
        parse_scenario(text, "conf.scn")
    assert str(err.value).startswith("conf.scn:2: CRECONFS: ") and which in str(err.value)
    fine = parse_scenario(text.replace(f"{tlosh} {args}", f"{tlosh} {args.split()[0]} 30"), "conf.scn")
    assert isinstance(fine.commands[-1], CreateConflict) and fine.commands[-1].tlosv == 30.0


@pytest.mark.parametrize(
    "line", ["CRE AC2 A320 52 4 90 -5000 -250", "CRE AC2 A320 52 4 90 FL100 -0.5", "SPD AC1 -250", "CRECONFS I1 A320 AC1 90 1 60 0 60 -250"]
)
def test_negative_speeds_are_refused(line: str) -> None:
    """BlueSky creates an aircraft with a negative speed flying backwards; the reader refuses it."""
    with pytest.raises(ScenarioError, match="a speed must not be negative, got '-0?[.0-9]*'"):
        parse_scenario(f"00:00:00.00>CRE AC1 A320 52 4 90 FL200 250\n00:00:00.00>{line}\n", "neg.scn")


def test_negative_altitudes_are_read_as_bluesky_reads_them() -> None:
    """Below sea level is an altitude (docs/scenarios.md §3): read, not refused."""
    sc = parse_scenario("00:00:00.00>CRE AC1 A320 52 4 90 -5000 250\n00:00:01.00>ALT AC1 -200\n")
    assert sc.commands[0].alt == -5000 * FT and sc.commands[1].alt == -200 * FT  # type: ignore[attr-defined]


def test_creconfs_speed_zero_is_the_targets_speed() -> None:
    """BlueSky's creconfs tests "if spd:", so a speed of 0 is an omitted one (the target's ground speed)."""
    sc = parse_scenario("00:00:00.00>CRE AC1 A320 52 4 90 FL200 250\n00:00:00.00>CRECONFS I1 A320 AC1 90 1 60 0 60 0\n")
    assert sc.commands[1].spd is None  # type: ignore[attr-defined]
