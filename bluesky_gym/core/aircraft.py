"""Aircraft types: the OpenAP data of every type, read as BlueSky 1.1.1 reads it [docs/dynamics.md §1.2, §1.2b].

BlueSky's default performance model (OpenAP) takes its numbers from the ``openap`` package
(version 2.6.2): the aircraft files (mass, wing, engine count and default engine), the engine
table (static thrust, bypass ratio), the drag polars (clean polar, flap and gear increments) and
the WRAP kinematic parameters (speed envelopes per phase, ceiling, maximum Mach, climb rates,
take-off acceleration) and the engine's ICAO fuel flows (fitted as BlueSky fits them). :func:`aircraft_performance` builds one
:class:`~bluesky_gym.core.performance.AircraftPerformance` per type from the same files with the
same arithmetic, once per process (cached). The step kernel reads these numbers as rows of a
``(types, N_COEFFICIENTS)`` table (:func:`~bluesky_gym.core.performance.table_row`).

Rotorcraft (helicopters and drones) come from BlueSky's own OpenAP rotor table
(:data:`ROTOR_TABLE`, BlueSky 1.1.1's ``performance/OpenAP/rotor/aircraft.json``, not part of the
``openap`` package); BlueSky flies them with its rotor model: a fixed envelope in TAS, a fixed
maximum acceleration and no drag, thrust or fuel flow [docs/dynamics.md §1.2b].

Type names resolve as in BlueSky (:func:`resolve_type`): case-insensitive; OpenAP's synonyms
(e.g. ``AT72`` flies with the E145 data) are types of their own; a rotorcraft is a type of its
own; any other name falls back to the B744 without a warning.
"""

from __future__ import annotations

import functools
import warnings
from typing import Any

from bluesky_gym.core.performance import AXMAX_CREATED, AircraftPerformance

#: The type of every aircraft unless another is asked for.
DEFAULT_TYPE = "A320"
#: What BlueSky 1.1.1's OpenAP model flies for a type it does not know.
FALLBACK_TYPE = "B744"
#: BlueSky 1.1.1's OpenAP rotor table (``performance/OpenAP/rotor/aircraft.json``), per type:
#: OEW [kg], MTOW [kg], number of engines, and the envelope: minimum and maximum TAS [m/s], minimum
#: (descent, negative) and maximum vertical speed [m/s], ceiling [m]. Every type has all five
#: envelope values, so BlueSky's defaults for missing ones (-20, 20, -5, 5, 2500) never apply.
ROTOR_TABLE: dict[str, tuple[float, float, int, float, float, float, float, float]] = {
    "EC35": (1490.0, 2835.0, 2, -20.0, 71.95, -7.62, 7.62, 6096.0),  # Eurocopter EC135
    "M600": (9.1, 15.1, 6, -18.0, 18.0, -5.0, 5.0, 2500.0),  # DJI Matrice 600
    "AMZN": (9.1, 20.0, 8, -44.0, 44.0, -8.0, 8.0, 2500.0),  # Amazon octocopter
    "MNET": (9.1, 15.1, 4, -11.0, 11.0, -5.0, 5.0, 2500.0),  # Matternet quadrocopter
    "PHAN4": (0.92, 1.4, 4, -20.0, 20.0, -4.0, 6.0, 6000.0),  # DJI Phantom 4
    "M100": (1.8, 3.6, 4, -22.0, 22.0, -4.0, 5.0, 3000.0),  # DJI Matrice 100
    "M200": (3.645, 6.14, 4, -23.0, 23.0, -3.0, 5.0, 3000.0),  # DJI Matrice 200
    "MAVIC": (0.494, 0.734, 4, -18.0, 18.0, -3.0, 5.0, 5000.0),  # DJI Mavic Pro
    "HORSEFLY": (4.3, 8.8, 8, -22.3, 22.3, -8.0, 8.0, 2500.0),  # Horsefly Gen 5.3
}
#: The rotorcraft of BlueSky 1.1.1's OpenAP rotor table: BlueSky flies them with its rotor model.
ROTORCRAFT_TYPES: tuple[str, ...] = tuple(ROTOR_TABLE)
#: Flap deflections BlueSky assumes for the take-off and landing drag polars [deg].
FLAP_TAKEOFF = 15.0
FLAP_LANDING = 40.0
#: Oswald-factor increments per degree of flap, rear- and wing-mounted engines (BlueSky's values).
DELTA_E_REAR = 0.0046
DELTA_E_WING = 0.0026
INSTALL_HINT = "pip install openap==2.6.2"
#: Thrust ratios of ICAO's engine emission data points (zero, idle, approach, climb-out, take-off),
#: to which BlueSky fits the fuel flow per engine (a quadratic, with the point (0, 0) added).
FUEL_THRUST_RATIOS = (0.0, 0.07, 0.3, 0.85, 1.0)


def _openap() -> Any:
    """The ``openap`` package (imported on first use: it takes about a second)."""
    try:
        import openap
    except ImportError as exc:  # pragma: no cover - openap is a dependency
        raise ImportError(f"aircraft types need the openap package (OpenAP 2.6.2, as BlueSky 1.1.1 uses): {INSTALL_HINT}") from exc
    return openap


@functools.lru_cache(maxsize=1)
def supported_types() -> tuple[str, ...]:
    """Every fixed-wing type BlueSky 1.1.1 flies with its own data, synonyms included (upper case, sorted)."""
    names = _openap().prop.available_aircraft(use_synonym=True)
    return tuple(sorted({str(n).upper() for n in names}))


def resolve_type(name: str) -> str:
    """The type whose data an aircraft of type ``name`` flies with, as BlueSky 1.1.1 decides it.

    Args:
        name: Type designator, any case (e.g. ``"b738"``).

    Returns:
        ``name`` in upper case when OpenAP has it (directly or as a synonym) or it is one of
        BlueSky's rotorcraft, else ``"B744"``.

    Raises:
        TypeError: ``name`` is not a string.
    """
    if not isinstance(name, str):
        raise TypeError(f"aircraft type must be a string, got {type(name).__name__} {name!r}")
    upper = name.upper()
    if upper in ROTOR_TABLE:
        return upper
    return upper if upper in supported_types() else FALLBACK_TYPE


def is_rotorcraft(name: str) -> bool:
    """Whether an aircraft of type ``name`` (any case) flies with BlueSky's rotor model."""
    return isinstance(name, str) and name.upper() in ROTOR_TABLE


def _load_rotor(resolved: str) -> AircraftPerformance:
    """The performance data of a rotorcraft, as BlueSky's OpenAP model loads it (``perfoap.create``).

    The fixed-wing quantities BlueSky does not have for a rotorcraft (wing, engine thrust, drag
    polars, phase envelopes, Mach limit, fuel-flow fit) are NaN; the step kernel does not read them.
    """
    oew, mtow, engines, vmin, vmax, vsmin, vsmax, hmax = ROTOR_TABLE[resolved]
    nan = float("nan")
    return AircraftPerformance(
        name=resolved,
        mass=0.5 * (oew + mtow),
        wing_area=nan,
        engine_count=engines,
        engine_max_thrust=nan,
        bypass_ratio=nan,
        cd0_clean=nan,
        k_clean=nan,
        cd0_takeoff=nan,
        k_takeoff=nan,
        cd0_gear=nan,
        cd0_landing=nan,
        k_landing=nan,
        vmin_enroute=vmin,
        vmax_enroute=vmax,
        vmin_approach=nan,
        vmax_approach=nan,
        vmax_ground=nan,
        v_rotate=nan,
        hmax=hmax,
        vsmax=vsmax,
        vsmin=vsmin,
        mmo=nan,
        axmax_initial=AXMAX_CREATED,
        fuel_a=nan,
        fuel_b=nan,
        fuel_c=nan,
        rotor=True,
    )


@functools.cache
def _load(resolved: str) -> AircraftPerformance:
    """Build the performance data of an OpenAP type (upper case), as BlueSky's OpenAP coefficient loader does."""
    if resolved in ROTOR_TABLE:
        return _load_rotor(resolved)
    import numpy as np

    oa = _openap()
    mdl = resolved.lower()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # openap warns when it uses a synonym
        ac = oa.prop.aircraft(mdl, use_synonym=True)
        engine = oa.prop.engine(ac["engine"]["default"])
        wrap = oa.WRAP(ac=mdl)
        polar = oa.drag.Drag(resolved, use_synonym=True).polar

    def lo(v: dict[str, Any]) -> float:
        return float(v["minimum"])

    def hi(v: dict[str, Any]) -> float:
        return float(v["maximum"])

    ic, cl, cr, de, fa = (wrap.initclimb_vcas(), wrap.climb_const_vcas(), wrap.cruise_mean_vcas(), wrap.descent_const_vcas(), wrap.finalapp_vcas())
    vs_parts = (wrap.initclimb_vs(), wrap.climb_vs_pre_concas(), wrap.climb_vs_concas(), wrap.climb_vs_conmach())
    # Drag polars with flaps (BlueSky's formulas, evaluated with numpy as BlueSky does).
    cd0, k = polar["clean"]["cd0"], polar["clean"]["k"]
    flaps = polar["flaps"]
    flap_factor = flaps["lambda_f"] * (flaps["cf/c"]) ** 1.38 * flaps["Sf/S"]
    delta_cd_to = flap_factor * np.sin(np.deg2rad(FLAP_TAKEOFF)) ** 2
    delta_cd_ld = flap_factor * np.sin(np.deg2rad(FLAP_LANDING)) ** 2
    # Fuel flow per engine: BlueSky's least-squares quadratic through ICAO's points (numpy, as BlueSky).
    fuel_a, fuel_b, fuel_c = np.polyfit(FUEL_THRUST_RATIOS, [0, engine["ff_idl"], engine["ff_app"], engine["ff_co"], engine["ff_to"]], 2)
    de_per_deg = DELTA_E_REAR if ac["engine"]["mount"] == "rear" else DELTA_E_WING
    ar = ac["wing"]["span"] ** 2 / ac["wing"]["area"]
    return AircraftPerformance(
        name=resolved,
        mass=float(0.5 * (ac["oew"] + ac["mtow"])),
        wing_area=float(ac["wing"]["area"]),
        engine_count=int(ac["engine"]["number"]),
        engine_max_thrust=float(engine["max_thrust"]),
        bypass_ratio=float(engine["bpr"]),
        cd0_clean=float(cd0),
        k_clean=float(k),
        cd0_takeoff=float(cd0 + delta_cd_to),
        k_takeoff=float(1 / (1 / k + np.pi * ar * (de_per_deg * FLAP_TAKEOFF))),
        cd0_gear=float(polar["gears"]),
        cd0_landing=float(cd0 + delta_cd_ld),
        k_landing=float(1 / (1 / k + np.pi * ar * (de_per_deg * FLAP_LANDING))),
        vmin_enroute=min(lo(ic), lo(cl), lo(cr), lo(de), lo(fa)),
        vmax_enroute=max(hi(ic), hi(cl), hi(cr), hi(de), hi(fa)),
        vmin_approach=lo(fa),
        vmax_approach=hi(fa),
        vmax_ground=hi(ic),
        v_rotate=lo(wrap.takeoff_speed()),
        hmax=float(wrap.cruise_max_alt()["default"] * 1000.0),
        vsmax=max(hi(v) for v in vs_parts),
        vsmin=min(lo(v) for v in vs_parts),
        mmo=float(wrap.cruise_max_mach()["default"]),
        axmax_initial=hi(wrap.takeoff_acceleration()),
        fuel_a=float(fuel_a),
        fuel_b=float(fuel_b),
        fuel_c=float(fuel_c),
    )


def aircraft_performance(name: str) -> AircraftPerformance:
    """The performance data an aircraft of type ``name`` flies with in BlueSky 1.1.1 (cached per type).

    Args:
        name: Type designator, any case; unknown types give the B744 (BlueSky's fallback).
    """
    return _load(resolve_type(name))


def check_types(names: Any, what: str = "aircraft type", rotorcraft: bool = False) -> tuple[str, ...]:
    """Validate type names for an option that accepts only types with their own data (no fallback).

    Args:
        names: One name or an iterable of names.
        what: How the error message calls the value.
        rotorcraft: Whether BlueSky's rotorcraft (:data:`ROTORCRAFT_TYPES`) are accepted too.

    Returns:
        The names in upper case.

    Raises:
        ValueError: A name that BlueSky would replace by the B744, or a rotorcraft where they are
            not accepted; the message lists the accepted types.
    """
    items = (names,) if isinstance(names, str) else tuple(names)
    out = []
    for n in items:
        if isinstance(n, str) and n.upper() in ROTOR_TABLE and not rotorcraft:
            raise ValueError(f"{what} {n!r} is a rotorcraft, which this option does not accept; fixed-wing types: {', '.join(supported_types())}")
        if not isinstance(n, str) or n.upper() not in supported_types() + (ROTORCRAFT_TYPES if rotorcraft else ()):
            also = f"; rotorcraft: {', '.join(ROTORCRAFT_TYPES)}" if rotorcraft else ""
            raise ValueError(f"{what} {n!r} is not supported; supported types: {', '.join(supported_types())}{also}")
        out.append(n.upper())
    return tuple(out)
