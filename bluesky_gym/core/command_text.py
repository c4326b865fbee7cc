"""BlueSky command text, both ways: values written as BlueSky 1.1.1's stack reads them, and read back.

The one place that writes BlueSky command text (the scenario exporter, the scenario geometries
and the BlueSky backend use it) and that reads its argument forms (the scenario parser,
:mod:`bluesky_gym.scenarios.parser`, uses it); each writer is the inverse of a reader.

Writing:

* numbers (:func:`number`): the shortest positional text that reads back as exactly the same
  float (``repr``'s digits, never an exponent: BlueSky's argument parsers read ``1e-05`` as a
  name, not a number), with a decimal point as ``repr`` writes it (``150.0``, ``-0.0``);
* numbers to a fixed number of decimals (:func:`fixed`, for files read by people);
* altitudes in feet, vertical speeds in feet per minute, speeds in knots CAS or as a Mach number
  ``M0.78`` (:func:`altitude`, :func:`vertical_speed`, :func:`speed`), from SI values;
* times as ``HH:MM:SS.hh`` (:func:`time_stamp`), switches as ``ON``/``OFF``, and whole commands
  (:func:`command`, :func:`timed`).

Reading, each argument text to the value in the core's units (m, m/s, deg, s) or a
:class:`ValueError` with a one-line message, in the forms of BlueSky 1.1.1's stack:

* altitude: ``FL350`` (flight level, hundreds of feet) or a number of feet (``5000``);
* speed: a number of knots CAS (``250``), or a Mach number written ``M.78``, ``M78``, ``M0.78`` or
  ``0.78`` (a plain number between 0.1 and 1 is a Mach number); negative speeds are refused
  (BlueSky creates an aircraft flying backwards);
* vertical speed: feet per minute (``-1500``);
* heading: degrees true, optionally ``T``-suffixed (``090``, ``90T``); magnetic headings (``M``)
  need BlueSky's magnetic-variation model and are refused;
* latitude: ``52.3``, ``N52.3``, ``S12.5``, or degrees'minutes'seconds ``N52'18'0.5"`` (``'``, ``"``
  or the degree sign separate the parts);
* longitude: ``4.5``, ``E4.5``, ``W004.5``, ``E004'30'00"``;
* time: ``SS.hh``, ``MM:SS.hh`` or ``HH:MM:SS.hh``.

Python's ``float`` also reads ``nan``, ``inf`` and ``1e999`` (infinite); every reader here
refuses a value that is not a finite number (BlueSky accepts them and flies NaN), and every
writer refuses to write one.
"""

from __future__ import annotations

import math

import numpy as np

from bluesky_gym.core.units import CASMACH_THRESHOLD, FPM, FT, KTS, MACH_MIN

#: Characters separating degrees, minutes and seconds in a latitude or longitude.
DMS_SEPARATORS = ("'", '"', "\N{DEGREE SIGN}")


# ----------------------------------------------------------------------------------------------
# Writing
# ----------------------------------------------------------------------------------------------
def number(x: float) -> str:
    """The shortest positional text that reads back as exactly ``x``: ``repr``'s digits, never an exponent (``1e-05`` is ``0.00001``).

    Raises:
        ValueError: ``x`` is not a finite number (BlueSky would fly NaN).
    """
    value = float(x)
    if not math.isfinite(value):
        raise ValueError(f"BlueSky commands need finite numbers, got {value!r}")
    return np.format_float_positional(value, unique=True, trim="0")


def fixed(x: float, decimals: int) -> str:
    """``x`` with ``decimals`` digits after the point (``%.6f``): text that reads back as exactly ``round(x, decimals)``.

    For files meant to be read by people (the benchmark geometries), where a fixed precision reads
    better than :func:`number`'s full one.

    Raises:
        ValueError: ``x`` is not a finite number, or ``decimals`` is negative.
    """
    value = float(x)
    if not math.isfinite(value):
        raise ValueError(f"BlueSky commands need finite numbers, got {value!r}")
    if decimals < 0:
        raise ValueError(f"decimals must be >= 0, got {decimals}")
    return f"{value:.{int(decimals)}f}"


def altitude(alt: float) -> str:
    """An altitude [m] as BlueSky's altitude argument: feet."""
    return number(float(alt) / FT)


def vertical_speed(vs: float) -> str:
    """A vertical speed [m/s] as BlueSky's argument: feet per minute."""
    return number(float(vs) / FPM)


def speed(v: float) -> str:
    """A CAS [m/s] or a Mach number as BlueSky's speed argument: knots, or ``M0.78``.

    A value ``MACH_MIN < v < CASMACH_THRESHOLD`` is a Mach number (as the core reads speeds).

    Raises:
        ValueError: ``v`` is not finite, or is a speed BlueSky 1.1.1's text cannot carry (a Mach
            number of 1 or more, a CAS under one knot that it would read as a Mach number).
    """
    value = float(v)
    if MACH_MIN < value < CASMACH_THRESHOLD:
        if value >= 1.0:
            raise ValueError(f"BlueSky 1.1.1's speed text has no form for Mach {value!r} (Mach 1 or more)")
        return f"M{number(value)}"
    text = number(value / KTS)
    if MACH_MIN < abs(float(text)) < 1.0:
        raise ValueError(f"a CAS of {value!r} m/s is {text} kt, which BlueSky reads as a Mach number")
    return text


def switch(on: bool) -> str:
    """``ON`` or ``OFF``."""
    return "ON" if on else "OFF"


def time_stamp(t: float) -> str:
    """``HH:MM:SS.hh`` of a time [s] (hundredths, rounded; negative times are 0)."""
    if not math.isfinite(float(t)):
        raise ValueError(f"a time stamp needs a finite time, got {t!r}")
    cs = int(round(max(float(t), 0.0) * 100.0))
    return f"{cs // 360000:02d}:{cs // 6000 % 60:02d}:{cs // 100 % 60:02d}.{cs % 100:02d}"


def command(name: str, *args: str | float) -> str:
    """One command: its name and arguments separated by blanks (numbers written by :func:`number`).

    Args:
        name: The command (``"HDG"``).
        *args: Text arguments (callsigns, types, already written values) as they are, integers
            as integers, other numbers (``float``, numpy floats) with :func:`number`; a bool is
            a switch.
    """
    parts = [name]
    for a in args:
        if isinstance(a, (bool, np.bool_)):
            parts.append(switch(bool(a)))
        elif isinstance(a, str):
            parts.append(a)
        elif isinstance(a, (int, np.integer)):
            parts.append(str(int(a)))
        else:
            parts.append(number(a))
    return " ".join(parts)


def timed(t: float, text: str) -> str:
    """A scenario line: ``HH:MM:SS.hh>`` then ``text``."""
    return f"{time_stamp(t)}>{text}"


# ----------------------------------------------------------------------------------------------
# Reading
# ----------------------------------------------------------------------------------------------


def finite(value: float, text: str, what: str) -> float:
    """``value`` when it is a finite number, else a :class:`ValueError` naming ``text`` as ``what``.

    Args:
        value: The number read from ``text``.
        text: The argument as written.
        what: What the argument is ("an altitude", "a speed", ...).
    """
    if not math.isfinite(value):
        raise ValueError(f"{what} must be a finite number, got {text!r}")
    return value


def parse_number(text: str, what: str = "a number") -> float:
    """A finite number (``float``'s forms; ``nan`` and infinities refused).

    Args:
        text: The argument as written.
        what: What the argument is, for the error message.
    """
    try:
        value = float(text)
    except ValueError:
        raise ValueError(f"cannot read {text!r} as {what}") from None
    return finite(value, text, what)


def split_arguments(text: str) -> list[str]:
    """Split a command's argument text as BlueSky does: on blanks and commas.

    One comma may follow an argument (with blanks around it); a comma with nothing before it is an
    omitted argument, returned as ``""``. Quotes around an argument are removed.

    Args:
        text: The argument text (everything after the command word).

    Returns:
        The arguments.
    """
    args: list[str] = []
    i, n = 0, len(text)
    while True:
        while i < n and text[i].isspace():
            i += 1
        if i >= n:
            return args
        if text[i] in "'\"":
            end = text.find(text[i], i + 1)
            end = n if end < 0 else end
            args.append(text[i + 1 : end])
            i = end + 1
        else:
            start = i
            while i < n and not text[i].isspace() and text[i] != ",":
                i += 1
            args.append(text[start:i])
        while i < n and text[i].isspace():
            i += 1
        if i < n and text[i] == ",":
            i += 1


def parse_altitude(text: str) -> float:
    """Altitude [m] from ``FLnnn`` or feet."""
    t = text.strip().upper()
    try:
        if t.startswith("FL") and len(t) >= 4:
            return 100.0 * int(t[2:]) * FT
        value = float(t) * FT
    except ValueError:
        raise ValueError(f"cannot read {text!r} as an altitude (FL350 or feet)") from None
    return finite(value, text, "an altitude")


def parse_speed(text: str) -> float:
    """CAS [m/s] from knots, or a Mach number from ``M.78``/``M78``/``0.78``."""
    t = text.strip().upper()
    mach = t.startswith("M")
    try:
        if mach:
            digits = t[1:]
            value = float(digits if digits.startswith(".") or "." in digits else "." + digits)
        else:
            value = float(t)
    except ValueError:
        raise ValueError(f"cannot read {text!r} as a speed (knots CAS or a Mach number like M.78)") from None
    finite(value, text, "a speed")
    if value < 0.0:
        raise ValueError(f"a speed must not be negative, got {text!r}")
    return value if mach or 0.1 < value < 1.0 else value * KTS


def parse_vertical_speed(text: str) -> float:
    """Vertical speed [m/s] from feet per minute."""
    try:
        value = float(text) * FPM
    except ValueError:
        raise ValueError(f"cannot read {text!r} as a vertical speed (feet per minute)") from None
    return finite(value, text, "a vertical speed")


def parse_heading(text: str) -> float:
    """True heading [deg] from ``090`` or ``90T``."""
    t = text.strip().upper()
    if "M" in t:
        raise ValueError(f"magnetic heading {text!r} is not supported (it needs BlueSky's magnetic-variation model); give a true heading")
    try:
        value = float(t.replace("T", ""))
    except ValueError:
        raise ValueError(f"cannot read {text!r} as a heading in degrees") from None
    return finite(value, text, "a heading")


def is_latitude(text: str) -> bool:
    """Whether ``text`` has the form of a latitude (as opposed to a waypoint or aircraft name)."""
    t = text.strip().upper().lstrip("+-")
    for sep in (*DMS_SEPARATORS, "."):
        t = t.replace(sep, "")
    if len(t) > 1 and t[0] in "NS":
        t = t[1:]
    return t.isdigit()


def _degrees(text: str, negative: bool) -> float:
    """Decimal degrees of an unsigned decimal or degrees'minutes'seconds text."""
    if any(sep in text for sep in DMS_SEPARATORS):
        for sep in DMS_SEPARATORS:
            text = text.replace(sep, "'")
        parts = [p for p in text.split("'") if p]
        value = sum(abs(float(p)) / 60.0**k for k, p in enumerate(parts))
        return -value if negative else value
    value = float(text)
    return -abs(value) if negative else value  # also -0.0 for -0


def parse_latitude(text: str) -> float:
    """Latitude [deg] from ``52.3``, ``N52.3``, ``S52.3`` or ``N52'18'0"``."""
    t = text.strip().upper()
    try:
        negative = t.startswith("S") or t.startswith("-")
        value = _degrees(t.lstrip("NS+-"), negative)
    except ValueError:
        raise ValueError(f"cannot read {text!r} as a latitude") from None
    finite(value, text, "a latitude")
    if not -90.0 <= value <= 90.0:
        raise ValueError(f"latitude {text!r} is outside [-90, 90] degrees")
    return value


def parse_longitude(text: str) -> float:
    """Longitude [deg] from ``4.5``, ``E4.5``, ``W4.5`` or ``E004'30'0"``."""
    t = text.strip().upper()
    try:
        try:
            value = float(t)
        except ValueError:
            negative = t.startswith("W") or t.startswith("-")
            value = _degrees(t.lstrip("EW+-"), negative)
    except ValueError:
        raise ValueError(f"cannot read {text!r} as a longitude") from None
    finite(value, text, "a longitude")
    if not -360.0 <= value <= 360.0:
        raise ValueError(f"longitude {text!r} is outside [-360, 360] degrees")
    return value


def parse_time(text: str) -> float:
    """Time [s] from ``SS.hh``, ``MM:SS.hh`` or ``HH:MM:SS.hh``."""
    parts = text.strip().split(":")
    try:
        if len(parts) > 3:
            raise ValueError
        seconds = float(parts[-1])
        if len(parts) > 1 and parts[-2]:
            seconds += 60.0 * int(parts[-2])
        if len(parts) > 2 and parts[-3]:
            seconds += 3600.0 * int(parts[-3])
    except ValueError:
        raise ValueError(f"cannot read {text!r} as a time (SS.hh, MM:SS.hh or HH:MM:SS.hh)") from None
    return finite(seconds, text, "a time")


def parse_switch(text: str) -> bool:
    """ON/OFF (also TRUE/FALSE, YES/NO, 1/0)."""
    t = text.strip().upper()
    if t in ("ON", "TRUE", "YES", "Y", "1"):
        return True
    if t in ("OFF", "FALSE", "NO", "N", "0"):
        return False
    raise ValueError(f"expected ON or OFF, got {text!r}")
