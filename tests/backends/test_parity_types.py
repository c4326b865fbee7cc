"""Aircraft types on the native core and on the real BlueSky 1.1.1: the data, and mixed fleets side by side.

Needs the ``bluesky`` extra (numpy < 2.4); skipped when BlueSky cannot be imported.
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("bluesky")

from bluesky_gym.backends.bluesky_sim import BlueSkyPhysics, load_bluesky
from bluesky_gym.core import Simulator
from bluesky_gym.core.aircraft import ROTORCRAFT_TYPES, aircraft_performance, supported_types
from tests.core.reference_scenarios import SCENARIOS, Scenario, _types_one_call

from .parity import CORE_TOL, ENV_TOL, compare_states, random_core_scenario, run_core_scenario, run_env_episodes

pytestmark = pytest.mark.bluesky

MIXED = ["A320", "B744", "E190", "C550", "A388", "CRJ9", "AT72", "ZZZZ"]
ROTORS = ["EC35", "M600", "MAVIC", "AMZN"]


def test_every_type_has_the_coefficients_bluesky_loads() -> None:
    """Every fixed-wing type of BlueSky's OpenAP coefficient tables, every number equal to the last bit."""
    coeff = load_bluesky().traf.perf.coeff
    assert set(supported_types()) == set(coeff.acs_fixwing) == {t.upper() for t in coeff.actypes_fixwing}
    assert set(ROTORCRAFT_TYPES) == set(coeff.actypes_rotor)
    for name in supported_types():
        p = aircraft_performance(name)
        ac, lim, dp = coeff.acs_fixwing[name], coeff.limits_fixwing[name], coeff.dragpolar_fixwing[name]
        eng = ac["engines"][next(iter(ac["engines"]))]
        want = {
            "mass": 0.5 * (ac["oew"] + ac["mtow"]),
            "wing_area": ac["wing"]["area"],
            "engine_count": int(ac["engine"]["number"]),
            "engine_max_thrust": eng["max_thrust"],
            "bypass_ratio": eng["bpr"],
            "cd0_clean": dp["cd0_clean"],
            "k_clean": dp["k_clean"],
            "cd0_takeoff": dp["cd0_to"],
            "k_takeoff": dp["k_to"],
            "cd0_gear": dp["delta_cd_gear"],
            "cd0_landing": dp["cd0_ld"],
            "k_landing": dp["k_ld"],
            "vmin_enroute": lim["vminer"],
            "vmax_enroute": lim["vmaxer"],
            "vmin_approach": lim["vminap"],
            "vmax_approach": lim["vmaxap"],
            "vmax_ground": lim["vmaxic"],
            "v_rotate": lim["vminto"],
            "hmax": lim["hmax"],
            "vsmax": lim["vsmax"],
            "mmo": lim["mmo"],
            "axmax_initial": lim["axmax"],
        }
        for field, value in want.items():
            assert getattr(p, field) == value, (name, field, getattr(p, field), value)


def test_every_rotorcraft_has_the_data_bluesky_loads() -> None:
    """BlueSky's rotor table, every number the rotor model uses equal to the last bit, and what BlueSky sets at creation."""
    coeff = load_bluesky().traf.perf.coeff
    for name in ROTORCRAFT_TYPES:
        p, ac, lim = aircraft_performance(name), coeff.acs_rotor[name], coeff.limits_rotor[name]
        want = {
            "mass": 0.5 * (ac["oew"] + ac["mtow"]),
            "engine_count": int(ac["n_engines"]),
            "vmin_enroute": lim["vmin"],
            "vmax_enroute": lim["vmax"],
            "vsmin": lim["vsmin"],
            "vsmax": lim["vsmax"],
            "hmax": lim["hmax"],
        }
        for field, value in want.items():
            assert getattr(p, field) == value, (name, field, getattr(p, field), value)
    bs = BlueSkyPhysics(2, dt=1.0)
    try:
        bs.create(0, [0, 1], 52.0, [4.0, 5.0], 0.0, 300.0, 20.0, actype=["Mavic", "A320"])
        perf = bs._bs.traf.perf
        assert list(perf.lifttype) == [2, 1] and list(perf.actype) == ["MAVIC", "A320"]
        assert (perf.vmin[0], perf.vmax[0], perf.axmax[0]) == (-18.0, 18.0, aircraft_performance("MAVIC").axmax_initial)
    finally:
        bs.close()


def test_unknown_type_is_a_b744() -> None:
    bs = BlueSkyPhysics(3, dt=1.0)
    try:
        bs.create(0, [0, 1], 52.0, [4.0, 5.0], 0.0, 3000.0, 150.0, actype=["zzzz", "B744"])
        perf = bs._bs.traf.perf
        assert list(perf.actype) == ["B744", "B744"]
        assert perf.mass[0] == perf.mass[1] == aircraft_performance("ZZZZ").mass
        assert bs.aircraft_type(0, [0, 1]) == ["ZZZZ", "B744"]
    finally:
        bs.close()


def _replay_side_by_side(sc: Scenario) -> None:
    bs = BlueSkyPhysics(sc.max_aircraft, dt=sc.dt)
    nat = Simulator(1, sc.max_aircraft, dt=sc.dt, geo=bs.geo)
    try:
        for s in (nat, bs):
            sc.setup(s, 0)
        n = len(sc.aircraft)
        assert nat.aircraft_type(0, np.arange(n)) == bs.aircraft_type(0, np.arange(n))
        compare_states(nat, bs, f"{sc.name} t=0", 0.0)
        for k in range(sc.steps):
            for s in (nat, bs):
                for ev in sc.events.get(k * sc.dt, []):
                    ev(s, 0)
                s.step()
            compare_states(nat, bs, f"{sc.name} t={(k + 1) * sc.dt:g}", 0.0)
    finally:
        bs.close()


@pytest.mark.parametrize("name", ["s13_types_enroute", "s14_types_takeoff", "s16_types_creconfs_asas"])
def test_mixed_fleet_scenarios_are_bit_identical(name: str) -> None:
    """17 types en route, six taking off, mixed creconfs: every state array equal after every step."""
    _replay_side_by_side(SCENARIOS[name])


def test_mixed_creation_in_one_call_gives_each_aircraft_its_type() -> None:
    """The backend creates a mixed batch in runs of equal type, so BlueSky's one-call quirk does not apply."""
    sc = SCENARIOS["s15_types_one_call"]
    own = ["E145", "A320", "B744", "B744", "C550"]
    _replay_side_by_side(Scenario(sc.name, sc.dt, sc.duration, sc.aircraft, _types_one_call(own), sc.events, sc.max_aircraft))


@pytest.mark.parametrize(("seed", "types"), [(0, MIXED), (1, MIXED), (2, MIXED), (3, MIXED), (4, MIXED + ROTORS), (5, MIXED + ROTORS)])
def test_random_mixed_fleet_scenario(seed: int, types: list[str]) -> None:
    """The random parity scenarios with every created aircraft of a random type (rotorcraft among them in the last two)."""
    sc = random_core_scenario(seed, types=types)
    bs = BlueSkyPhysics(sc.max_aircraft, dt=sc.dt, max_waypoints=4)
    try:
        nat = Simulator(1, sc.max_aircraft, dt=sc.dt, max_waypoints=4, geo=bs.geo)
        run_core_scenario(sc, {"kernel": nat}, bs, CORE_TOL)
        act = np.flatnonzero(nat.active[0])
        assert nat.aircraft_type(0, act) == bs.aircraft_type(0, act)
    finally:
        bs.close()


@pytest.mark.parametrize("env_id", ["HorizontalCREnv-v0", "VerticalCREnv-v0", "SectorCREnv-v0", "MergeEnv-v0"])
def test_env_episodes_with_a_type_mix_match(env_id: str) -> None:
    """The traffic environments with mixed intruder and ownship types, on both backends side by side."""
    options = {"intruder_types": {"A320": 0.4, "B744": 0.3, "E190": 0.2, "C550": 0.1}, "ownship_types": ("B738", "A388")}
    episodes = [(300 + k, 15 if k == 0 else 5) for k in range(3)]
    dev, steps = run_env_episodes(env_id, episodes, 15, ENV_TOL, options=options)
    assert steps >= len(episodes)
    print(f"{env_id} with a type mix: {steps} steps; largest scaled deviation {dev.max:.2e}: {dev.summary()}")


def test_horizontal_cr_episodes_with_rotorcraft_match() -> None:
    """HorizontalCREnv with a rotorcraft ownship and rotor and fixed-wing intruders, on both backends side by side."""
    options = {"intruder_types": {"A320": 0.4, "EC35": 0.2, "M600": 0.2, "MAVIC": 0.2}, "ownship_types": ("EC35", "AMZN")}
    episodes = [(400 + k, 15 if k == 0 else 5) for k in range(3)]
    dev, steps = run_env_episodes("HorizontalCREnv-v0", episodes, 15, ENV_TOL, options=options)
    assert steps >= len(episodes)
    print(f"HorizontalCREnv-v0 with rotorcraft: {steps} steps; largest scaled deviation {dev.max:.2e}: {dev.summary()}")
