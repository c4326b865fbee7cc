"""BlueSky command text both ways: every command and every number form written by
:mod:`bluesky_gym.core.command_text` reads back, through the scenario parser, as the value written.

Numbers are compared bit for bit (their sign and every bit of the float); a value in other units
(feet, knots, feet per minute) is compared with the written number times the unit, which is what
BlueSky computes from the same text.
"""

from __future__ import annotations

import math
import struct

import numpy as np
import pytest

from bluesky_gym.core.command_text import (
    altitude,
    command,
    fixed,
    number,
    parse_altitude,
    parse_heading,
    parse_latitude,
    parse_longitude,
    parse_number,
    parse_speed,
    parse_time,
    parse_vertical_speed,
    speed,
    split_arguments,
    time_stamp,
    timed,
    vertical_speed,
)
from bluesky_gym.core.units import FPM, FT, KTS, NM
from bluesky_gym.scenarios import parse_scenario
from bluesky_gym.scenarios.parser import (
    DETECTION_COMMANDS,
    TYPED_COMMANDS,
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

#: Number forms: exponents in ``repr``, signed zeros, the largest and smallest doubles, subnormals,
#: integers past 2**53, values with 17 significant digits.
FORMS = (
    0.0,
    -0.0,
    1e-05,
    -1e-05,
    1.5e-07,
    1e16,
    1e22,
    -1e22,
    1.7976931348623157e308,
    -1.7976931348623157e308,
    2.2250738585072014e-308,
    5e-324,
    -5e-324,
    2.0**53 + 2.0,
    0.1,
    1 / 3,
    123456.789,
    359.99999999999994,
    52.123456789012345,
)


def bits(x: float) -> int:
    """The 64 bits of a double (so that -0.0 and 0.0 differ)."""
    return int(struct.unpack("<Q", struct.pack("<d", x))[0])


def random_doubles(n: int, seed: int = 0) -> list[float]:
    """``n`` finite doubles drawn uniformly over bit patterns (every exponent equally likely)."""
    raw = np.random.default_rng(seed).integers(0, 2**64, size=4 * n, dtype=np.uint64).view(np.float64)
    return [float(x) for x in raw[np.isfinite(raw)][:n]]


@pytest.mark.parametrize("x", [*FORMS, *random_doubles(2000)])
def test_a_number_reads_back_bit_for_bit_without_an_exponent(x: float) -> None:
    text = number(x)
    assert "e" not in text.lower() and " " not in text, text
    assert bits(float(text)) == bits(x) and bits(parse_number(text)) == bits(x)
    assert number(float(text)) == text  # one text per number


@pytest.mark.parametrize("decimals", [0, 1, 2, 6])
@pytest.mark.parametrize("x", [*FORMS, *random_doubles(200, seed=1)])
def test_a_fixed_precision_number_reads_back_as_the_rounded_value(x: float, decimals: int) -> None:
    text = fixed(x, decimals)
    assert "e" not in text.lower() and len(text.partition(".")[2]) == decimals
    assert bits(parse_number(text)) == bits(round(x, decimals))


@pytest.mark.parametrize("x", [math.nan, math.inf, -math.inf])
def test_no_text_for_a_non_finite_number(x: float) -> None:
    with pytest.raises(ValueError, match="finite numbers"):
        number(x)
    with pytest.raises(ValueError, match="finite numbers"):
        command("HDG", "AC000", x)
    with pytest.raises(ValueError, match="finite numbers"):
        fixed(x, 2)


def test_a_number_is_as_short_as_repr() -> None:
    for x in FORMS:
        digits = repr(x).lower().split("e")[0].replace("-", "").replace(".", "").strip("0")
        assert number(x).replace("-", "").replace(".", "").strip("0") == digits or "e" in repr(x), (x, number(x))


@pytest.mark.parametrize("x", FORMS)
def test_units_read_back_as_the_number_written(x: float) -> None:
    """An SI value written in BlueSky's units reads back as the written number times the unit."""
    for write, read, unit in ((altitude, parse_altitude, FT), (vertical_speed, parse_vertical_speed, FPM)):
        if not math.isfinite(x / unit):  # no number of feet (per minute) for the largest doubles
            with pytest.raises(ValueError, match="finite numbers"):
                write(x)
            continue
        text = write(x)
        assert bits(read(text)) == bits(float(text) * unit)
    assert bits(parse_heading(number(x))) == bits(x)
    if abs(x) <= 90.0:
        assert bits(parse_latitude(number(x))) == bits(x)
    if abs(x) <= 360.0:
        assert bits(parse_longitude(number(x))) == bits(x)


@pytest.mark.parametrize("v", [0.0, 1e-05, 0.78, 0.1000000000000001, 0.9999999999999999, 2.0, 128.6111, 250 * KTS, 1e22])
def test_speeds_read_back(v: float) -> None:
    text = speed(v)
    parsed = parse_speed(text)
    if 0.1 < v < 2.0:  # a Mach number, written M0.78
        assert text.startswith("M") and bits(parsed) == bits(v)
    else:  # knots CAS
        assert bits(parsed) == bits(float(text) * KTS) and math.isclose(parsed, v, rel_tol=1e-15, abs_tol=1e-300)


@pytest.mark.parametrize("v", [1.0, 1.5, 0.08])
def test_speeds_without_a_text_are_refused(v: float) -> None:
    """Mach 1 and above, and a CAS of a fraction of a knot (0.08 m/s: 0.16 kt), have no SPD text BlueSky 1.1.1 reads back."""
    with pytest.raises(ValueError, match=r"Mach"):
        speed(v)


@pytest.mark.parametrize("t", [0.0, 0.004, 0.005, 59.995, 3599.994, 3725.256, 86399.99, 360000.0])
def test_time_stamps_read_back_to_the_hundredth(t: float) -> None:
    stamp = time_stamp(t)
    assert abs(parse_time(stamp) - round(t * 100.0) / 100.0) < 1e-9  # whole hundredths of a second
    (parsed,) = parse_scenario(timed(t, command("ECHO", "x")), "t").commands
    assert abs(parsed.time - parse_time(stamp)) < 1e-9


def test_command_arguments() -> None:
    assert command("HDG", "AC000", 90.0) == "HDG AC000 90.0"
    assert command("LNAV", "AC000", True) == "LNAV AC000 ON" and command("VNAV", "AC000", np.bool_(False)) == "VNAV AC000 OFF"
    assert command("ALT", "AC000", np.float64(1e-05), np.int64(7), 20000) == "ALT AC000 0.00001 7 20000"
    assert split_arguments(command("CRE", "A", "B", -0.0, 1e22)) == ["CRE", "A", "B", "-0.0", "1" + "0" * 22 + ".0"]


def _scenario(values: dict[str, float]) -> tuple[str, dict[str, type]]:
    """A scenario with every command the parser types, its numbers taken from ``values``."""
    v = values
    lines = [
        (0.0, command("DT", v["dt"])),
        (0.0, command("CRE", "AC000", "A320", v["lat"], v["lon"], v["hdg"], altitude(v["alt"]), speed(v["cas"]))),
        (0.0, command("CRE", "AC001", "B738", v["lat"], v["lon"], v["hdg"], altitude(v["alt"]), speed(v["mach"]))),
        (0.0, command("CRECONFS", "AC002", "A320", "AC000", v["hdg"], v["dcpa"], v["tlos"], altitude(v["dh"]), v["tlos"], speed(v["cas"]))),
        (1.0, command("HDG", "AC000", v["hdg"])),
        (1.0, command("SPD", "AC000", speed(v["cas"]))),
        (1.0, command("ALT", "AC000", altitude(v["alt"]), vertical_speed(v["vs"]))),
        (1.0, command("VS", "AC000", vertical_speed(v["vs"]))),
        (2.0, command("ADDWPT", "AC000", v["lat"], v["lon"])),
        (2.0, command("DEST", "AC000", v["lat"], v["lon"])),
        (2.0, command("DIRECT", "AC000", "AC000001")),
        (2.0, command("LNAV", "AC000", True)),
        (2.0, command("VNAV", "AC000", False)),
        (2.0, command("NOISE", False)),
        (2.0, command("ASAS", "ON")),
        (2.0, command("RESO", "MVP")),
        (2.0, command("ZONER", v["zone"])),
        (2.0, command("ZONEDH", v["zone"])),
        (2.0, command("DTLOOK", v["tlos"])),
        (2.0, command("RFACH", v["factor"])),
        (2.0, command("RFACV", v["factor"])),
        (3.0, command("DEL", "AC000", "AC001")),
    ]
    return "\n".join(timed(t, text) for t, text in lines) + "\n", {}


#: Values of the commands, in the core's units (m, m/s, deg, s), each set exercising number forms.
CASES = {
    "plain": {"dt": 1.0, "lat": 52.0, "lon": 4.0, "hdg": 90.0, "alt": 3000.0, "cas": 128.6, "mach": 0.78, "dcpa": 0.5, "tlos": 300.0,
              "dh": 600.0, "vs": -7.5, "zone": 5.0, "factor": 1.05},
    "exponents": {"dt": 1e-05, "lat": 1e-05, "lon": -1e-07, "hdg": 1e-05, "alt": 1e-05, "cas": 1e-05, "mach": 0.1000000000000001,
                  "dcpa": 1e-05, "tlos": 1e-05, "dh": 1e22, "vs": 1e-05, "zone": 1e-05, "factor": 1e-05},
    "negative zero": {"dt": 0.05, "lat": -0.0, "lon": -0.0, "hdg": -0.0, "alt": -0.0, "cas": -0.0, "mach": 0.9999999999999999,
                      "dcpa": -0.0, "tlos": 1e-300, "dh": -0.0, "vs": -0.0, "zone": -0.0, "factor": 5e-324},
    "large": {"dt": 1e16, "lat": -89.99999999999999, "lon": 359.99999999999994, "hdg": 1.7976931348623157e308, "alt": 1e300, "cas": 1e300,
              "mach": 1.9999999999999998e0 / 2, "dcpa": 1e22, "tlos": 1e22, "dh": -1e300, "vs": 1e300, "zone": 1e300, "factor": 1e308},
    "17 digits": {"dt": 1 / 3, "lat": 52.123456789012345, "lon": 4.987654321098765, "hdg": 359.99999999999994, "alt": 10668.000000000002,
                  "cas": 128.61111111111111, "mach": 0.7812345678901234, "dcpa": 0.30000000000000004, "tlos": 299.99999999999994,
                  "dh": 304.79999999999995, "vs": -5.079999999999999, "zone": 4.999999999999999, "factor": 1.0500000000000003},
}  # fmt: skip


@pytest.mark.parametrize("case", CASES)
def test_every_command_reads_back_as_written(case: str) -> None:
    v = CASES[case]
    text, _ = _scenario(v)
    commands = parse_scenario(text, case).commands
    kinds = [type(c) for c in commands]
    assert kinds == [TimeStep, Create, Create, CreateConflict, Heading, Speed, Altitude, VerticalSpeed, AddWaypoint, Destination, Direct,
                     Lnav, Vnav, Ignored, Asas, Asas, Asas, Asas, Asas, Asas, Asas, Delete]  # fmt: skip
    dt, cre, cre_mach, creconfs, hdg, spd, alt, vs, addwpt, dest, direct, lnav, vnav, _noise, *asas, dele = commands

    def feet(x: float) -> float:
        return float(altitude(x)) * FT

    def knots(x: float) -> float:
        return parse_speed(speed(x))

    same = [
        (dt.dt, v["dt"]),
        (cre.position.lat, v["lat"]),
        (cre.position.lon, v["lon"]),
        (cre.hdg, v["hdg"]),
        (cre.alt, feet(v["alt"])),
        (cre.spd, knots(v["cas"])),
        (cre_mach.spd, v["mach"]),
        (creconfs.dpsi, v["hdg"]),
        (creconfs.dcpa, v["dcpa"]),
        (creconfs.tlosh, v["tlos"]),
        (creconfs.dh, feet(v["dh"])),
        (creconfs.tlosv, v["tlos"]),
        (hdg.hdg, v["hdg"]),
        (spd.spd, knots(v["cas"])),
        (alt.alt, feet(v["alt"])),
        (alt.vs, float(vertical_speed(v["vs"])) * FPM),
        (vs.vs, float(vertical_speed(v["vs"])) * FPM),
        (addwpt.position.lat, v["lat"]),
        (addwpt.position.lon, v["lon"]),
        (dest.position.lat, v["lat"]),
        (dest.position.lon, v["lon"]),
    ]
    for k, (got, want) in enumerate(same):
        assert bits(got) == bits(want), (k, got, want)
    if creconfs.spd is not None:  # a CAS of 0 is "the target's speed", as BlueSky reads it
        assert bits(creconfs.spd) == bits(knots(v["cas"]))
    assert (direct.waypoint, lnav.on, dele.acids) == (0, True, ("AC000", "AC001"))
    assert vnav.acid == "AC000"
    config = asas[-1].config
    if v["zone"] > 0:
        assert bits(config.rpz) == bits(v["zone"] * NM) and bits(config.hpz) == bits(v["zone"] * FT)
    assert bits(config.lookahead) == bits(v["tlos"])
    assert bits(config.settings.resofach) == bits(v["factor"]) and bits(config.settings.resofacv) == bits(v["factor"])


def test_every_command_of_the_parser_is_written_here() -> None:
    """A command the parser learns gets a case in :func:`_scenario` (aliases aside)."""
    text, _ = _scenario(CASES["plain"])
    written = {line.split(">", 1)[1].split()[0] for line in text.splitlines()}
    aliases = {"CREATE", "DELETE", "HEADING", "TURN", "SPEED"}
    assert TYPED_COMMANDS - aliases <= written
    assert {"ASAS", "RESO", "ZONER", "ZONEDH", "DTLOOK", "RFACH", "RFACV"} <= written & DETECTION_COMMANDS
