"""Scenario files played by BlueSky 1.1.1 (PCALL) and by the scenario player, compared column by column.

The recordings are ``tests/data/reference/pcall_*.csv``, made by ``make_reference.py pcall_<name>`` from
the files in ``tests/data/reference/scn`` (see the README there). Tolerances are those of the core's
fidelity contract (tests/core/test_reference.py).
"""

from __future__ import annotations

import csv

import numpy as np
import pytest

from bluesky_gym.core import Simulator
from bluesky_gym.scenarios import TRAJECTORY_COLUMNS, ScenarioPlayer, parse_scenario, read_scenario
from bluesky_gym.scenarios.player import slots_needed, waypoints_needed
from tests.core.reference_scenarios import DATA, open_recording
from tests.core.test_reference import TOL

#: name -> (file, dt [s], duration [s]), as in make_reference.py's SCN_SCENARIOS.
SCN = {
    "pcall_super8": ("super8.scn", 1.0, 300),
    "pcall_sphere3x4": ("sphere3x4.scn", 1.0, 150),
    "pcall_commands": ("commands.scn", 1.0, 150),
    "pcall_route": ("route.scn", 1.0, 400),
    "pcall_direct_lnav": ("direct_lnav.scn", 1.0, 400),
    "pcall_export_descent": ("export_descent.scn", 1.0, 200),
    "pcall_export_vertical_cr": ("export_vertical_cr.scn", 1.0, 100),
    "pcall_reso_super8": ("reso_super8.scn", 1.0, 400),
    "pcall_reso_super8_dt5": ("reso_super8.scn", 5.0, 400),
    "pcall_reso_methods": ("reso_methods.scn", 1.0, 400),
    "pcall_reso_route": ("reso_route.scn", 1.0, 400),
    "pcall_reso_wall": ("reso_wall.scn", 1.0, 400),
    "pcall_fuel_types": ("fuel_types.scn", 1.0, 400),
    "pcall_fuel_types_dt05": ("fuel_types.scn", 0.5, 150),
    "pcall_fuel_reso": ("fuel_reso.scn", 1.0, 300),
    "pcall_rotor_mixed": ("rotor_mixed.scn", 1.0, 300),
    "pcall_rotor_mixed_dt05": ("rotor_mixed.scn", 0.5, 120),
    "pcall_rotor_reso": ("rotor_reso.scn", 1.0, 300),
}
ANGLES = ("hdg", "trk", "ap_trk")
#: The recordings with BlueSky's performance outputs (columns thrust, drag, fuelflow).
FUEL = ("pcall_fuel_types", "pcall_fuel_types_dt05", "pcall_fuel_reso")
#: The recordings of rotorcraft beside fixed-wing aircraft (also with the performance outputs).
ROTOR = ("pcall_rotor_mixed", "pcall_rotor_mixed_dt05", "pcall_rotor_reso")
PERF_OUTPUTS = ("thrust", "drag", "fuelflow")


def load(name: str) -> list[dict[str, str]]:
    with open_recording(name) as fh:
        return list(csv.DictReader(fh))


def replay(name: str, n_envs: int = 1, env: int = 0, geo: str = "compiled") -> list[list[object]]:
    file, dt, duration = SCN[name]
    scenario = read_scenario(DATA / "scn" / file)
    sim = Simulator(n_envs, slots_needed(scenario), dt=dt, max_waypoints=max(4, waypoints_needed(scenario)), geo=geo)
    player = ScenarioPlayer([scenario] * n_envs, sim)
    rows = [r for r, e in zip(player.snapshot(0), player.scenario_of_rows()) if e == env]
    for k in range(1, int(duration / dt) + 1):
        player.step()
        rows += [r for r, e in zip(player.snapshot(k * dt), player.scenario_of_rows()) if e == env]
    return rows


@pytest.mark.parametrize("name", sorted(SCN))
def test_scenario_file_matches_bluesky(name: str) -> None:
    ref = load(name)
    got = replay(name)
    assert len(got) == len(ref), f"{name}: {len(got)} rows, BlueSky recorded {len(ref)}"
    worst: dict[str, float] = {}
    for row, want in zip(got, ref):
        values = dict(zip(TRAJECTORY_COLUMNS, row))
        assert float(values["t"]) == float(want["t"]) and values["acid"] == want["acid"], (values["t"], values["acid"], want["t"], want["acid"])
        for col, tol in TOL.items():
            err = abs(float(values[col]) - float(want[col]))  # type: ignore[arg-type]
            if col in ANGLES:
                err = min(err, 360.0 - err)
            worst[col] = max(worst.get(col, 0.0), err)
            assert err <= tol, f"{name} {want['acid']} {col}: t={want['t']} got {values[col]!r} want {want[col]!r} (|d|={err:.3g} > {tol})"
    assert set(worst) == set(TOL)


def _bits(x: object) -> int:
    """The float's bit pattern (one pattern for every NaN)."""
    v = float(x)  # type: ignore[arg-type]
    return -1 if v != v else int(np.float64(v).view(np.int64))


@pytest.mark.parametrize("name", FUEL + ROTOR)
def test_performance_outputs_match_bluesky_bit_for_bit(name: str) -> None:
    """Mixed types: every column of every row, thrust, drag and fuel flow included, equals BlueSky's to the last bit.

    These recordings were made by BlueSky 1.1.1 on the machine type the tests run on (same libm),
    so nothing is left to a tolerance: not the outputs, and not the state they are computed from.
    """
    ref = load(name)
    got = replay(name)
    assert len(got) == len(ref), f"{name}: {len(got)} rows, BlueSky recorded {len(ref)}"
    assert set(PERF_OUTPUTS) <= set(ref[0])
    moved = {c: 0 for c in PERF_OUTPUTS}
    for row, want in zip(got, ref):
        values = dict(zip(TRAJECTORY_COLUMNS, row))
        assert values["acid"] == want["acid"]
        for col in TRAJECTORY_COLUMNS[2:]:
            assert _bits(values[col]) == _bits(want[col]), f"{name} {want['acid']} {col}: t={want['t']} got {values[col]!r} want {want[col]!r}"
        for col in PERF_OUTPUTS:
            moved[col] += float(want[col]) != 0.0
    if name in FUEL:
        assert min(moved.values()) > len(ref) // 2, moved  # the outputs are computed, not left at 0
    else:
        assert min(moved.values()) > len(ref) // 10, moved  # the fixed-wing aircraft's outputs are computed


ROTOR_IDS = {
    "pcall_rotor_mixed": ("R01", "R02", "R03", "R04", "R05", "R06", "R07", "R08", "R09"),
    "pcall_rotor_reso": ("OWN1", "INT1", "INT2", "INT3", "INT4", "OWN3", "INT6"),
}


@pytest.mark.parametrize("name", sorted(ROTOR_IDS))
def test_rotorcraft_fly_the_rotor_model_in_the_recordings(name: str) -> None:
    """What the bit-for-bit replay of the rotor recordings covers: BlueSky's rotor model, in flight.

    Every rotor type of the table flies; the envelope is the type's TAS range, the phase NA, axmax
    3.5 m/s^2 (2 at creation), no drag, thrust or fuel flow; the speeds reach the envelope's bounds,
    vertical rates are clipped to vsmax (climbs and descents alike: the autopilot's rate is a
    magnitude) without the fixed-wing acceleration factor, ceilings hold.
    """
    from bluesky_gym.core.aircraft import ROTOR_TABLE

    rows = [r for r in load(name) if r["acid"] in ROTOR_IDS[name]]
    scn = (DATA / "scn" / SCN[name][0]).read_text().upper()
    for r in rows:
        assert r["phase"] == "0" and float(r["axmax"]) == (2.0 if r["t"] == "0" else 3.5), r
        assert float(r["thrust"]) == float(r["drag"]) == float(r["fuelflow"]) == 0.0, r
    types = {line.split()[1]: line.split()[2] for line in scn.splitlines() if ">CRE" in line}
    for acid in ROTOR_IDS[name]:
        mine = [r for r in rows if r["acid"] == acid]
        _, _, _, vmin, vmax, _, vsmax, hmax = ROTOR_TABLE[types[acid]]
        assert {(float(r["vmin_cas"]), float(r["vmax_cas"])) for r in mine} == {(vmin, vmax)}
        assert max(float(r["tas"]) for r in mine[1:]) <= max(vmax, float(mine[0]["tas"])), acid
        assert all(abs(float(r["vs"])) <= vsmax for r in mine), acid  # a magnitude: vsmax bounds descents too
        assert max(float(r["alt"]) for r in mine) <= hmax, acid
    if name == "pcall_rotor_mixed":
        assert set(types.values()) >= set(ROTOR_TABLE)
        final = {r["acid"]: r for r in rows if r["t"] == "300"}
        assert float(final["R01"]["alt"]) == 500 * 0.3048  # EC35: climbed at 7.62 m/s towards its 6096 m ceiling, then down
        peak = {a: max(float(r["tas"]) for r in rows if r["acid"] == a) for a in ("R01", "R02", "R09")}
        assert peak == {"R01": 71.95, "R02": 18.0, "R09": 22.3}  # SPD beyond vmax: held at the TAS bound
        assert max(float(r["vs"]) for r in rows if r["acid"] == "R02") == 5.0  # M600: 7.62 m/s default clipped to vsmax
        # M200 (vsmin -3, vsmax 5): VS -1000 fpm is a rate of 5.08 m/s, clipped to 5, and it descends at 5 m/s
        assert min(float(r["vs"]) for r in rows if r["acid"] == "R07") == -5.0
        hover = [r for r in rows if r["acid"] == "R02" and 130 <= float(r["t"]) <= 180]
        assert min(float(r["tas"]) for r in hover) == 0.0  # SPD 0: it hovers (vmin < 0)


def test_copies_in_a_batch_equal_the_single_replay() -> None:
    """Copy 2 of 3 of a scenario in one batch flies exactly as the scenario alone."""
    alone = replay("pcall_commands")
    batched = replay("pcall_commands", n_envs=3, env=2)
    assert batched == alone


def test_recordings_cover_the_scenario_commands() -> None:
    """The recorded files use the commands and argument forms the player claims to support."""
    text = " ".join((DATA / "scn" / f).read_text() for f, _, _ in SCN.values())
    for word in (
        "CRE ",
        "CRECONFS",
        "DEL ",
        "HDG",
        "SPD",
        "ALT",
        "VS ",
        "ADDWPT",
        "DEST",
        "VNAV",
        "DIRECT",
        "LNAV",
        "DT ",
        "M.6",
        "N52'",
        "FL",
        ";",
        "\\",
        "ASAS ON",
        "CDMETHOD CSTATEBASED",
        "RESO MVP",
        "RMETHH",
        "RMETHV",
        "RFACH",
        "RFACV",
        "ZONER",
        "ZONEDH",
        "RSZONER",
        "DTLOOK",
    ):
        assert word in text, word
    assert np.isfinite([float(r["lat"]) for r in load("pcall_route")]).all()


@pytest.mark.bluesky
@pytest.mark.parametrize(
    "name",
    [
        "pcall_commands",
        "pcall_direct_lnav",
        "pcall_reso_methods",
        "pcall_reso_route",
        "pcall_reso_super8",
        "pcall_fuel_types",
        "pcall_fuel_reso",
        "pcall_rotor_mixed",
        "pcall_rotor_reso",
    ],
)
def test_bluesky_backend_plays_the_files_like_bluesky(name: str) -> None:
    """The same player on the BlueSky backend reproduces the PCALL recording (same commands, BlueSky's own physics)."""
    from bluesky_gym.backends.bluesky_sim import BlueSkyPhysics

    file, dt, duration = SCN[name]
    scenario = read_scenario(DATA / "scn" / file)
    sim = BlueSkyPhysics(slots_needed(scenario), dt=dt, max_waypoints=max(4, waypoints_needed(scenario)))
    try:
        player = ScenarioPlayer([scenario], sim)
        got = player.snapshot(0)
        for k in range(1, int(duration / dt) + 1):
            player.step()
            got += player.snapshot(k * dt)
        geo = sim.geo
    finally:
        sim.close()
    ref = load(name)
    if geo == "python" and "ASAS ON" in (DATA / "scn" / file).read_text():
        # BlueSky runs with its Python geo functions in this process (bluesky.tools.geo was imported
        # before bs.init), whose STATEBASED bearings are all correct, unlike those of the compiled
        # functions of the recording: the reference is then the core flying with the same geo set.
        ref = [{c: str(v) for c, v in zip(TRAJECTORY_COLUMNS, row)} for row in replay(name, geo="python")]
    assert len(got) == len(ref)
    for row, want in zip(got, ref):
        values = dict(zip(TRAJECTORY_COLUMNS, row))
        assert values["acid"] == want["acid"]
        for col, tol in TOL.items():
            err = abs(float(values[col]) - float(want[col]))  # type: ignore[arg-type]
            if col in ANGLES:
                err = min(err, 360.0 - err)
            assert err <= tol, f"{name} {want['acid']} {col}: t={want['t']} got {values[col]!r} want {want[col]!r}"
        if name in FUEL + ROTOR:  # the backend reports BlueSky's performance outputs
            for col in PERF_OUTPUTS:
                assert _bits(values[col]) == _bits(want[col]), f"{name} {want['acid']} {col}: t={want['t']} got {values[col]!r} want {want[col]!r}"


#: Values BlueSky reads and flies in its own way: an aircraft created below sea level (the ground
#: phase: its CAS slows to 89 m/s at most), and CRECONFS with a speed of 0 (BlueSky's "if spd:",
#: the target's ground speed); docs/scenarios.md §3.
EDGE_SCN = """00:00:00.00>CRE AC1 A320 52 4 90 -5000 250
00:00:00.00>CRE AC2 A320 52 4.5 90 FL100 250
00:00:00.00>CRECONFS I1 A320 AC2 90 1 60 0 60 0
00:00:00.00>CRECONFS I2 B738 AC2 45 2 90 -1500 120 M.6
00:00:10.00>ALT AC2 -200
"""


@pytest.mark.bluesky
def test_bluesky_backend_flies_the_edge_values_as_the_core() -> None:
    from bluesky_gym.backends.bluesky_sim import BlueSkyPhysics

    scenario = parse_scenario(EDGE_SCN, "edge.scn")
    runs = []
    for physics in (Simulator(1, slots_needed(scenario)), BlueSkyPhysics(slots_needed(scenario))):
        try:
            player = ScenarioPlayer([scenario], physics)
            rows = player.snapshot(0)
            for k in range(1, 61):
                player.step()
                rows += player.snapshot(k)
            runs.append(rows)
        finally:
            if isinstance(physics, BlueSkyPhysics):
                physics.close()
    core, bluesky = runs
    assert len(core) == len(bluesky) == 61 * 4
    cas = {r[1]: r[TRAJECTORY_COLUMNS.index("cas")] for r in core[-4:]}
    assert cas["AC1"] == pytest.approx(89.0, abs=0.5)  # the ground phase's envelope, below sea level
    for got, want in zip(core, bluesky):
        values, ref = dict(zip(TRAJECTORY_COLUMNS, got)), dict(zip(TRAJECTORY_COLUMNS, want))
        assert values["acid"] == ref["acid"]
        for col, tol in TOL.items():
            err = abs(float(values[col]) - float(ref[col]))  # type: ignore[arg-type]
            if col in ANGLES:
                err = min(err, 360.0 - err)
            assert err <= tol, f"{ref['acid']} {col}: t={ref['t']} core {values[col]!r}, BlueSky {ref[col]!r}"
