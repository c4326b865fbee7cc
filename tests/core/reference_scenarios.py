"""The BlueSky 1.1.1 reference scenarios (see tests/data/reference/README.md), replayed on the core."""

from __future__ import annotations

import csv
import lzma
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TextIO

import numpy as np

from bluesky_gym.core import Simulator
from bluesky_gym.core.units import FPM, FT, KTS

DATA = Path(__file__).resolve().parents[1] / "data" / "reference"
#: Recordings larger than this are stored xz-compressed (``NAME.csv.xz``); the repository's file-size limit.
COMPRESS_ABOVE_BYTES = 500 * 1024


def recording_path(name: str) -> Path:
    """The file of a recording: ``NAME.csv``, or ``NAME.csv.xz`` for one over :data:`COMPRESS_ABOVE_BYTES`."""
    plain = DATA / f"{name}.csv"
    return plain if plain.exists() else DATA / f"{name}.csv.xz"


def open_recording(name: str) -> TextIO:
    """Open a recording (plain or xz-compressed CSV) as text, for ``csv`` readers."""
    path = recording_path(name)
    if path.suffix == ".xz":
        return lzma.open(path, "rt", encoding="utf-8", newline="")
    return open(path, newline="")


def recording_names(pattern: str = "*") -> set[str]:
    """Names of the recordings matching a glob pattern (without ``.csv`` / ``.csv.xz``)."""
    return {p.name.removesuffix(".xz").removesuffix(".csv") for p in DATA.glob(f"{pattern}.csv*")}


Event = Callable[[Simulator, int], None]  # (sim, env) -> None


@dataclass
class Scenario:
    name: str
    dt: float
    duration: float
    aircraft: list[str]
    setup: Callable[[Simulator, int], None]
    events: dict[float, list[Event]] = field(default_factory=dict)
    max_aircraft: int = 4

    @property
    def steps(self) -> int:
        return int(round(self.duration / self.dt))


def _cre(slot, lat, lon, hdg, alt, spd, actype=None):
    return lambda sim, env: sim.create(env, slot, lat, lon, hdg, alt, spd, actype=actype)


def _hdg(slot, hdg):
    return lambda sim, env: sim.cmd_heading(env, slot, hdg)


def _spd_kts(slot, kts):
    return lambda sim, env: sim.cmd_speed(env, slot, kts * KTS)


def _write(slot, **kw):
    def f(sim, env):
        for k, v in kw.items():
            getattr(sim, k)[env, slot] = v

    return f


def _seq(*fs):
    def f(sim, env):
        for g in fs:
            g(sim, env)

    return f


def _creconfs(sim, env):
    sim.create(env, 0, 52.0, 4.0, 45.0, 200 * 100 * FT, 250 * KTS)
    sim.creconfs(env, 0, 1, 90.0, 1.0, 120.0)
    sim.creconfs(env, 0, 2, 200.0, 0.0, 150.0, spd=200 * KTS)
    sim.creconfs(env, 0, 3, 300.0, 2.0, 100.0, dh=500.0, tlosv=90.0)


def _wind_s12(sim, env):
    sim.create(env, 0, 52.0, 4.0, 0.0, 100 * 100 * FT, 250 * KTS)
    sim.wind.add_points(env, [52.0], [4.0], [-10.0], [15.0])


# Aircraft types (tests/data/reference/README.md, s13-s16).
TYPES_ENROUTE = [
    "A319",
    "A320",
    "A321",
    "B737",
    "B738",
    "B744",
    "B772",
    "A332",
    "A359",
    "B788",
    "E190",
    "E145",
    "CRJ9",
    "C550",
    "GLF6",
    "ZZZZ",
    "AT72",
]
TYPES_TAKEOFF = ["A320", "B744", "E145", "C550", "A388", "ZZZZ"]


def _types_enroute(sim, env):
    for i, t in enumerate(TYPES_ENROUTE):
        sim.create(env, i, 52.0, 4.0 + 0.5 * i, 0.0, 100 * 100 * FT, 250 * KTS, actype=t)


def _types_takeoff(sim, env):
    for i, t in enumerate(TYPES_TAKEOFF):
        sim.create(env, i, 52.0, 4.0 + 0.5 * i, 0.0, 0.0, 0.0, actype=t)


def _all(n, *makers):
    """Events: each maker(slot) for every slot 0..n-1, in the recorded order (aircraft by aircraft)."""
    return [m(i) for i in range(n) for m in makers]


def _vs_fpm(slot, fpm):
    return lambda sim, env: sim.cmd_vertical_speed(env, slot, fpm * FPM)


def _alt_fl(slot, fl):
    return lambda sim, env: sim.cmd_altitude(env, slot, fl * 100 * FT)


def _types_one_call(types):
    """s15: BlueSky gives all aircraft of one traf.cre call the LAST type's data; ``types`` says what the core is told."""

    def setup(sim, env):
        sim.create(env, [0, 1, 2], 52.0, [4.0, 4.5, 5.0], 0.0, 3048.0, 128.6, actype=types[:3])
        sim.create(env, [3, 4], 52.0, [5.5, 6.0], 0.0, 3048.0, 128.6, actype=types[3:])

    return setup


def _types_creconfs(sim, env):
    sim.create(env, 0, 52.0, 4.0, 45.0, 200 * 100 * FT, 250 * KTS, actype="B738")
    sim.creconfs(env, 0, 1, 90.0, 1.0, 120.0, actype="E190")
    sim.creconfs(env, 0, 2, 200.0, 0.0, 150.0, spd=200 * KTS, actype="B744")
    sim.creconfs(env, 0, 3, 300.0, 2.0, 100.0, dh=500.0, tlosv=90.0, actype="C550")
    sim.creconfs(env, 0, 4, 30.0, 0.5, 80.0, dh=-400.0, tlosv=60.0, spd=0.6, actype="ZZZZ")
    sim.creconfs(env, 0, 5, 250.0, 3.0, 140.0, actype="AT72")


SCENARIOS: dict[str, Scenario] = {
    s.name: s
    for s in [
        Scenario("s1_straight_fl350", 1, 120, ["AC1"], _cre(0, 52.0, 4.0, 45.0, 350 * 100 * FT, 250 * KTS)),
        Scenario(
            "s2_hdg_turns_fl200",
            1,
            200,
            ["AC1"],
            _cre(0, 52.0, 4.0, 0.0, 200 * 100 * FT, 250 * KTS),
            {0: [_hdg(0, 90)], 100: [_hdg(0, 300)]},
        ),
        Scenario(
            "s3_spd_change_fl100",
            1,
            240,
            ["AC1"],
            _cre(0, 52.0, 4.0, 90.0, 100 * 100 * FT, 150 * KTS),
            {0: [_spd_kts(0, 200)], 120: [_spd_kts(0, 160)]},
        ),
        Scenario(
            "s4_descent_selvs_gym",
            1,
            300,
            ["KL001"],
            _cre(0, 52.0, 4.0, 0.0, 3000.0, 150.0),
            {0: [_write(0, swvnav=False, selalt=0.0, selvs=-12.5)]},
        ),
        Scenario(
            "s5_climb_selvs_gym",
            1,
            720,
            ["KL001"],
            _cre(0, 52.0, 4.0, 0.0, 3000.0, 150.0),
            {0: [_write(0, swvnav=False, selalt=1e6, selvs=12.5)], 400: [_write(0, selvs=0.0)]},
        ),
        Scenario(
            "s6_alt_vs_stack",
            1,
            600,
            ["AC1"],
            _cre(0, 52.0, 4.0, 270.0, 100 * 100 * FT, 250 * KTS),
            {
                0: [lambda sim, env: sim.cmd_vertical_speed(env, 0, 2500 * FPM), lambda sim, env: sim.cmd_altitude(env, 0, 200 * 100 * FT)],
                300: [lambda sim, env: sim.cmd_altitude(env, 0, 120 * 100 * FT)],
            },
        ),
        Scenario(
            "s7_route_lnav",
            1,
            900,
            ["AC1"],
            _cre(0, 52.0, 4.0, 0.0, 100 * 100 * FT, 250 * KTS),
            {0: [lambda sim, env, p=p: sim.add_waypoint(env, 0, *p) for p in [(52.3, 4.0), (52.3, 4.5), (52.0, 4.5)]]},
        ),
        Scenario("s9_creconfs", 1, 300, ["KL001", "INT1", "INT2", "INT3"], _creconfs),
        Scenario(
            "s10_gym_horizontal_alt0_dt5",
            5,
            300,
            ["KL001"],
            _cre(0, 52.0, 4.0, 0.0, 0.0, 150.0),
            {0: [_hdg(0, 60)], 100: [_hdg(0, 330)]},
        ),
        Scenario(
            "s11_descent_dt5",
            5,
            400,
            ["KL001"],
            _cre(0, 52.0, 4.0, 0.0, 3000.0, 150.0),
            {0: [_write(0, swvnav=False, selalt=1500.0, selvs=-12.5)]},
        ),
        Scenario("s12_wind_constant_gymwrapper", 1, 300, ["AC1"], _wind_s12, {0: [_hdg(0, 90)], 150: [_hdg(0, 200)]}),
        Scenario(
            "s13_types_enroute",
            1,
            400,
            [f"T{i:02d}" for i in range(len(TYPES_ENROUTE))],
            _types_enroute,
            {
                0: _all(len(TYPES_ENROUTE), lambda i: _hdg(i, 90), lambda i: _spd_kts(i, 300), lambda i: _vs_fpm(i, 4000), lambda i: _alt_fl(i, 180)),
                200: _all(len(TYPES_ENROUTE), lambda i: _spd_kts(i, 220), lambda i: _hdg(i, 300), lambda i: _alt_fl(i, 120)),
            },
            max_aircraft=len(TYPES_ENROUTE),
        ),
        Scenario(
            "s14_types_takeoff",
            1,
            300,
            [f"G{i:02d}" for i in range(len(TYPES_TAKEOFF))],
            _types_takeoff,
            {
                0: _all(len(TYPES_TAKEOFF), lambda i: _spd_kts(i, 250), lambda i: _vs_fpm(i, 3000), lambda i: _alt_fl(i, 50)),
                150: _all(len(TYPES_TAKEOFF), lambda i: _hdg(i, 45)),
            },
            max_aircraft=len(TYPES_TAKEOFF),
        ),
        Scenario(
            "s15_types_one_call",
            1,
            200,
            ["Q1", "Q2", "Q3", "Q4", "Q5"],
            _types_one_call(["B744", "B744", "B744", "C550", "C550"]),
            {0: _all(5, lambda i: _spd_kts(i, 300), lambda i: _alt_fl(i, 200))},
            max_aircraft=5,
        ),
        Scenario(
            "s16_types_creconfs_asas",
            1,
            200,
            ["KL001", "INT1", "INT2", "INT3", "INT4", "INT5"],
            _types_creconfs,
            {40: [_spd_kts(2, 230), _alt_fl(0, 220)], 100: [_hdg(1, 180)]},
            max_aircraft=6,
        ),
    ]
}

# Recorded column -> simulator attribute.
COLUMNS = {
    "lat": "lat",
    "lon": "lon",
    "alt": "alt",
    "tas": "tas",
    "cas": "cas",
    "mach": "mach",
    "gs": "gs",
    "hdg": "hdg",
    "trk": "trk",
    "vs": "vs",
    "gsnorth": "gsnorth",
    "gseast": "gseast",
    "ax": "ax",
    "selspd": "selspd",
    "selalt": "selalt",
    "selvs": "selvs",
    "ap_trk": "ap_trk",
    "ap_tas": "ap_tas",
    "ap_vs": "ap_vs",
    "ap_alt": "ap_alt",
    "phase": "phase",
    "axmax": "axmax",
    "vmin_cas": "vmin",
    "vmax_cas": "vmax",
    "swlnav": "swlnav",
    "swvnav": "swvnav",
    "windnorth": "windnorth",
    "windeast": "windeast",
}


def load_reference(name: str) -> dict[str, dict[str, np.ndarray]]:
    """Recorded trajectories: {acid: {column: array over time}} (time in column 't')."""
    out: dict[str, dict[str, list[float]]] = {}
    with open_recording(name) as fh:
        for row in csv.DictReader(fh):
            rec = out.setdefault(row["acid"], {})
            for k, v in row.items():
                if k != "acid":
                    rec.setdefault(k, []).append(float(v))
    return {a: {k: np.asarray(v) for k, v in cols.items()} for a, cols in out.items()}


def run(scenario: Scenario, sim: Simulator, env: int) -> dict[str, np.ndarray]:
    """Replay one scenario in airspace ``env`` of ``sim`` (all airspaces step together).

    Returns {column: array (steps+1, n_aircraft)}.
    """
    rows = {c: [] for c in COLUMNS}
    n = len(scenario.aircraft)

    def record():
        for c, attr in COLUMNS.items():
            rows[c].append(np.asarray(getattr(sim, attr)[env, :n], dtype=np.float64).copy())

    record()
    for k in range(scenario.steps):
        for ev in scenario.events.get(k * scenario.dt, []):
            ev(sim, env)
        sim.step()
        record()
    return {c: np.stack(v) for c, v in rows.items()}


def run_alone(scenario: Scenario) -> dict[str, np.ndarray]:
    sim = Simulator(1, scenario.max_aircraft, dt=scenario.dt)
    scenario.setup(sim, 0)
    return run(scenario, sim, 0)
