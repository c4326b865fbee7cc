"""Aircraft types on the core: the data, resolution of names, creation and per-aircraft performance."""

from __future__ import annotations

import numpy as np
import pytest

from bluesky_gym.core import Simulator
from bluesky_gym.core.aircraft import (
    FALLBACK_TYPE,
    ROTOR_TABLE,
    ROTORCRAFT_TYPES,
    aircraft_performance,
    check_types,
    is_rotorcraft,
    resolve_type,
    supported_types,
)
from bluesky_gym.core.units import FT, KTS

STATE = ("lat", "lon", "alt", "hdg", "tas", "cas", "vs", "ax", "axmax", "vmin", "vmax", "phase")


def _fly(sim: Simulator, env: int, slots: list[int], steps: int) -> None:
    sim.cmd_speed(env, slots, 300 * KTS)
    sim.cmd_altitude(env, slots, 250 * 100 * FT)
    sim.cmd_heading(env, slots, 135.0)
    sim.run(steps)


def test_type_names_resolve_as_in_bluesky() -> None:
    assert len(supported_types()) == 58
    assert resolve_type("b738") == "B738"
    assert resolve_type("AT72") == "AT72"  # a synonym is a type of its own (with the E145's data)
    assert resolve_type("XX99") == FALLBACK_TYPE == "B744"
    assert resolve_type("ec35") == "EC35" and resolve_type("Phan4") == "PHAN4"  # rotorcraft: types of their own
    with pytest.raises(TypeError, match="string"):
        resolve_type(320)  # type: ignore[arg-type]
    assert aircraft_performance("AT72").mass == aircraft_performance("E145").mass
    assert aircraft_performance("xx99") is aircraft_performance("B744")
    with pytest.raises(ValueError, match="'XX99' is not supported; supported types: A124, .*B744"):
        check_types(["A320", "XX99"])


def test_rotorcraft_have_bluesky_rotor_data_and_are_accepted_where_asked() -> None:
    assert set(ROTORCRAFT_TYPES) == set(ROTOR_TABLE) and len(ROTORCRAFT_TYPES) == 9
    assert not set(ROTORCRAFT_TYPES) & set(supported_types())
    ec35 = aircraft_performance("EC35")
    assert ec35.rotor and not aircraft_performance("A320").rotor and is_rotorcraft("ec35") and not is_rotorcraft("A320")
    assert (ec35.mass, ec35.engine_count, ec35.vmin_enroute, ec35.vmax_enroute, ec35.vsmin, ec35.vsmax, ec35.hmax) == (
        2162.5,
        2,
        -20.0,
        71.95,
        -7.62,
        7.62,
        6096.0,
    )
    assert ec35.axmax_initial == 2.0 and np.isnan(ec35.wing_area) and np.isnan(ec35.fuel_a)
    for name in ROTORCRAFT_TYPES:
        p = aircraft_performance(name)
        assert p.vmin_enroute < 0 < p.vmax_enroute and p.vsmin < 0 < p.vsmax and p.hmax >= 2500 and p.mass > 0, name
    assert check_types(["mavic", "A320"], rotorcraft=True) == ("MAVIC", "A320")
    with pytest.raises(ValueError, match="aircraft type 'EC35' is a rotorcraft, which this option does not accept; fixed-wing types: A124"):
        check_types(["A320", "EC35"])
    with pytest.raises(ValueError, match="'XX99' is not supported; supported types: A124, .*; rotorcraft: EC35, M600"):
        check_types("XX99", rotorcraft=True)


def test_rotorcraft_fly_the_rotor_model() -> None:
    """Creation defaults, the first performance update, the TAS envelope and the vertical-rate clip, beside a fixed-wing aircraft."""
    sim = Simulator(1, 3)
    sim.create(0, [0, 1, 2], 52.0, [4.0, 4.1, 4.2], 90.0, 300.0, [30.0, 5.0, 100.0], actype=["EC35", "M600", "A320"])
    assert (sim.vmin[0, 0], sim.vmax[0, 0], sim.axmax[0, 0]) == (-20.0, 71.95, 2.0)
    sim.cmd_speed(0, [0, 1], 300 * KTS)
    sim.cmd_altitude(0, [0, 1], 20000 * FT)
    sim.step()
    assert sim.phase[0, 0] == sim.phase[0, 1] == 0 and sim.axmax[0, 0] == sim.axmax[0, 1] == 3.5
    assert sim.thrust[0, 0] == sim.drag[0, 0] == sim.fuelflow[0, 0] == 0.0 and sim.fuelflow[0, 2] > 0
    sim.run(120)
    assert sim.tas[0, 0] == 71.95 and sim.tas[0, 1] == 18.0  # the TAS bound, at any altitude
    assert sim.vs[0, 0] == 7.62 and sim.vs[0, 1] == 5.0  # the default 7.62 m/s clipped to vsmax
    assert sim.fuelburn[0, 0] == sim.fuelburn[0, 1] == 0.0 and sim.fuelburn[0, 2] > 0
    sim.run(600)
    assert sim.alt[0, 1] == 2500.0  # the M600's ceiling


def test_every_type_has_a_plausible_envelope() -> None:
    for name in supported_types():
        p = aircraft_performance(name)
        assert 0 < p.vmin_approach <= p.vmax_approach <= p.vmax_enroute, name
        assert 0 < p.vmin_enroute < p.vmax_enroute and 0.4 < p.mmo < 1.0 and 5000 < p.hmax < 16000, name
        assert p.mass > 1000 and p.static_thrust > 1000 and p.v_rotate > 0 and p.vsmax > 0, name


def test_create_with_types() -> None:
    sim = Simulator(2, 4)
    sim.create(0, [0, 1, 2], 52.0, 4.0, 0.0, 3000.0, 150.0, actype=["b744", "E190", "zzzz"])
    sim.create(1, 0, actype="C550")
    sim.create(1, 1)
    assert sim.aircraft_type(0, [0, 1, 2]) == ["B744", "E190", "ZZZZ"]
    assert sim.aircraft_type(1, [0, 1]) == ["C550", "A320"]
    assert sim.aircraft_performance(0, 2) is aircraft_performance("B744")
    b744, c550 = aircraft_performance("B744"), aircraft_performance("C550")
    # BlueSky's creation defaults: the en-route envelope and WRAP's take-off acceleration.
    assert (sim.vmin[0, 0], sim.vmax[0, 0], sim.axmax[0, 0]) == (b744.vmin_enroute, b744.vmax_enroute, b744.axmax_initial)
    assert (sim.vmax[1, 0], sim.axmax[1, 0]) == (c550.vmax_enroute, c550.axmax_initial)
    with pytest.raises(ValueError, match="expected one type or 2 types"):
        sim.create(1, [2, 3], actype=["A320"])
    with pytest.raises(TypeError, match="type name"):
        sim.create(1, 2, actype=[7])  # type: ignore[list-item]
    assert not sim.active[1, 2:].any()
    sim.reset_envs([0])
    sim.create(0, 0)
    assert sim.aircraft_type(0, 0) == ["A320"]


def test_types_fly_differently_and_unknown_flies_as_b744() -> None:
    sim = Simulator(1, 4)
    sim.create(0, [0, 1, 2, 3], 52.0, [4.0, 5.0, 6.0, 7.0], 0.0, 3000.0, 150.0, actype=["A320", "B744", "ZZZZ", "C550"])
    _fly(sim, 0, [0, 1, 2, 3], 200)
    for f in STATE[2:]:
        np.testing.assert_array_equal(getattr(sim, f)[0, 1], getattr(sim, f)[0, 2], err_msg=f)
    assert len({float(sim.distflown[0, i]) for i in (0, 1, 3)}) == 3  # different accelerations on the way


def test_reused_slot_flies_as_its_new_type() -> None:
    """A slot's cached performance values belong to the aircraft that was there before."""
    a = Simulator(1, 2)
    a.create(0, 0, 52.0, 4.0, 0.0, 3000.0, 150.0)
    a.run(5)
    a.delete(0, 0)
    a.create(0, 0, 52.0, 4.0, 0.0, 3000.0, 150.0, actype="B744")
    b = Simulator(1, 2)
    b.create(0, 0, 52.0, 4.0, 0.0, 3000.0, 150.0, actype="B744")
    for sim in (a, b):
        _fly(sim, 0, [0], 60)
    for f in STATE:
        assert getattr(a, f)[0, 0] == getattr(b, f)[0, 0], f


def test_mixed_airspace_among_others_equals_alone() -> None:
    """Batch invariance with types registered in another order (other table rows) by the other airspaces."""
    types = ["E145", "A388", "B738", "GLF6"]
    alone = Simulator(1, 4)
    alone.create(0, [0, 1, 2, 3], 50.0, [1.0, 2.0, 3.0, 4.0], 10.0, 5000.0, 140.0, actype=types)
    _fly(alone, 0, [0, 1, 2, 3], 120)
    many = Simulator(3, 4)
    many.create([0, 0, 2], [0, 1, 3], 40.0, 0.0, 0.0, 2000.0, 120.0, actype=["GLF6", "C550", "A388"])
    many.create(1, [0, 1, 2, 3], 50.0, [1.0, 2.0, 3.0, 4.0], 10.0, 5000.0, 140.0, actype=types)
    _fly(many, 1, [0, 1, 2, 3], 120)
    for f in STATE:
        np.testing.assert_array_equal(getattr(many, f)[1], getattr(alone, f)[0], err_msg=f)
    assert many.aircraft_types != alone.aircraft_types


def test_run_with_stop_keeps_types() -> None:
    sim = Simulator(2, 2)
    sim.create([0, 1], 0, 52.0, 4.0, 0.0, 3000.0, 150.0, actype=["B744", "E190"])
    sim.run(10, stop=lambda track: np.array([3, 0]))
    assert sim.aircraft_type([0, 1], 0) == ["B744", "E190"]


@pytest.mark.parametrize("dt", [1.0, 0.5, 5.0])
def test_fuel_burned_is_the_fuel_flow_summed_over_the_steps(dt: float) -> None:
    """``fuelburn`` adds each step's ``fuelflow`` (of that step's performance update) times dt, whether stepped or run."""
    types = ["A320", "B744", "C550", "E145"]
    stepped, ran = (Simulator(1, 4, dt=dt) for _ in range(2))
    for sim in (stepped, ran):
        sim.create(0, np.arange(4), 52.0, 4.0, 90.0, [3000.0, 9000.0, 6000.0, 1000.0], 150.0, actype=types)
        sim.cmd_speed(0, [0, 1], [200.0, 120.0])
        sim.cmd_altitude(0, [2, 3], [9000.0, 3000.0])
    n = int(round(120 / dt))
    want = np.zeros(4)
    for _ in range(n):
        stepped.step()
        want = want + stepped.fuelflow[0] * dt
    np.testing.assert_array_equal(stepped.fuelburn[0], want)
    ran.run(n)
    np.testing.assert_array_equal(ran.fuelburn[0], want)
    assert np.all(want > 0.0)
