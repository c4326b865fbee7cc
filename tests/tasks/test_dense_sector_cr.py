"""DenseSectorCREnv-v0 task: the spawn-rate curriculum, the entering and leaving traffic, the options and the KPIs."""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest

from bluesky_gym.environments.dense_sector_cr.task import DenseSectorCRConfig, DenseSectorCRTask, expected_entries, spawn_rate
from bluesky_gym.environments.sector_cr.task import CENTER, SectorCRTask, worst_case_aircraft
from bluesky_gym.tasks import compiled
from bluesky_gym.tasks.geometry import initial_bearing, latlon_to_nm

from .conftest import seeded_task

_task = functools.partial(seeded_task, DenseSectorCRTask)
STEP_S = DenseSectorCRTask.dt * DenseSectorCRTask.action_frequency


def _hold(task: DenseSectorCRTask, steps: int) -> None:
    for _ in range(steps):
        task.step(np.zeros((task.n_envs, 2)))


def test_rate_rises_linearly_then_holds_and_its_integral_by_hand() -> None:
    c = DenseSectorCRConfig(spawn_rate_start=60.0, spawn_rate_end=180.0, rise_time_s=600.0)
    np.testing.assert_allclose(spawn_rate(c, np.array([0.0, 300.0, 600.0, 900.0])), [60.0, 120.0, 180.0, 180.0])
    # 0..600 s: (60 * 600 + 0.5 * (120 / 600) * 600^2) / 3600 = 20 aircraft; then 180 / h for 300 s: 15 more.
    np.testing.assert_allclose(expected_entries(c, np.array([0.0, 600.0, 900.0])), [0.0, 20.0, 35.0])


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"spawn_rate_start": 200.0, "spawn_rate_end": 100.0}, "spawn_rate_end must be >= spawn_rate_start"),
        ({"spawn_rate_start": -1.0}, "spawn_rate_start must be >= 0.0"),
        ({"spawn_rate_end": 4000.0}, "spawn_rate_end must be >= 0.0 and <= 3600.0"),
        ({"spawn_rate_end": float("nan")}, "spawn_rate_end must be a finite number"),
        ({"rise_time_s": 0.0}, "rise_time_s must be > 0.0"),
        ({"max_spawned": 2.5}, "max_spawned must be an integer"),
        ({"max_spawned": 1000}, "max_spawned must be in \\[0, 462\\]"),
        ({"ac_density_mode": "dense"}, "ac_density_mode must be one of"),
    ],
)
def test_bad_options_are_named_in_one_line(options: dict[str, object], message: str) -> None:
    with pytest.raises(ValueError, match=message) as info:
        DenseSectorCRTask.make_config(options)
    assert "\n" not in str(info.value)


def test_slots_are_the_initial_worst_case_plus_max_spawned() -> None:
    task = DenseSectorCRTask(1, DenseSectorCRTask.make_config({"max_spawned": 7}))
    assert task.sim.max_aircraft == worst_case_aircraft(task.config) + 7 == 38 + 7


def test_the_initial_scenario_is_sector_crs() -> None:
    dense, sector = _task(seeds=[4, 9]), seeded_task(SectorCRTask, seeds=[4, 9])
    m = sector.sim.max_aircraft
    np.testing.assert_array_equal(dense.num_ac, sector.num_ac)
    for name in ("lat", "lon", "hdg", "active"):
        np.testing.assert_array_equal(getattr(dense.sim, name)[:, :m], getattr(sector.sim, name))
    assert not dense.sim.active[:, m:].any()
    np.testing.assert_array_equal(dense.next_slot, dense.num_ac)


def test_no_rate_no_entries() -> None:
    task = _task(seeds=[1, 2], spawn_rate_start=0.0, spawn_rate_end=0.0)
    before = task.sim.active.sum(axis=1)
    _hold(task, 40)
    assert (task.spawned == 0).all() and (task.sim.active.sum(axis=1) <= before).all()


def test_entering_aircraft_cross_the_sector_from_their_entry_point() -> None:
    task = _task(seeds=[3], spawn_rate_start=3600.0, spawn_rate_end=3600.0)
    first = int(task.next_slot[0])
    task.step(np.zeros((1, 2)))
    new = np.arange(first, int(task.next_slot[0]))
    assert new.size == task.spawned[0] > 0 and task.sim.active[0, new].all()
    nv = int(task.n_vertices[0])
    poly = task.poly_nm[0, :nv]
    # Starts: 0.5 NM inside the perimeter along the radius, so inside the sector.
    start_nm = latlon_to_nm(CENTER, np.stack([task.sim.lat[0, new], task.sim.lon[0, new]], axis=-1))
    inside = np.empty(new.size, bool)
    envs = np.zeros(new.size, np.int64)
    compiled.slots_in_polygons(envs, new, task.sim.lat, task.sim.lon, task.poly_lat, task.poly_lon, task.n_vertices, inside)
    assert inside.all()
    # Exit points on the perimeter: on one of the edges (zero cross product with it).
    exits = task.wpt_nm[0, new]
    on_edge = np.zeros(new.size, bool)
    for k in range(nv):
        a, b = poly[k], poly[(k + 1) % nv]
        cross = (b[0] - a[0]) * (exits[:, 1] - a[1]) - (b[1] - a[1]) * (exits[:, 0] - a[0])
        within = ((exits - a) @ (b - a) >= -1e-9) & ((exits - b) @ (a - b) >= -1e-9)
        on_edge |= (np.abs(cross) < 1e-6 * np.hypot(*(b - a))) & within
    assert on_edge.all()
    # Heading at creation: the initial bearing to the exit point (the aircraft flew one step since).
    radius = np.hypot(start_nm[:, 0], start_nm[:, 1])
    assert (radius < np.hypot(poly[:, 0], poly[:, 1]).max()).all()
    bearing = initial_bearing(task.sim.lat[0, new], task.sim.lon[0, new], task.wpt_lat[0, new], task.wpt_lon[0, new])
    np.testing.assert_allclose((task.sim.hdg[0, new] - bearing + 180.0) % 360.0 - 180.0, 0.0, atol=0.5)
    np.testing.assert_allclose(task.sim.cas[0, new], 150.0)


def test_traffic_outside_the_sector_is_removed_and_its_slot_not_reused() -> None:
    task = _task(seeds=[5], spawn_rate_start=3600.0, spawn_rate_end=3600.0)
    task.sim.lat[0, 1] = CENTER[0] + 2.0  # 120 NM north: outside
    task.step(np.zeros((1, 2)))
    assert not task.sim.active[0, 1]
    assert task.next_slot[0] > task.num_ac[0]
    _hold(task, 3)
    assert not task.sim.active[0, 1]  # never refilled: slots are not reused within the episode
    assert task.sim.active[0, 0]  # the ownship is not removed by the flow


def test_entries_beyond_max_spawned_are_dropped_and_counted() -> None:
    task = _task(seeds=[0], spawn_rate_start=3600.0, spawn_rate_end=3600.0, max_spawned=3)
    _hold(task, 5)  # about 25 entries expected
    assert task.spawned[0] == 3 and task.spawns_dropped[0] > 0
    info = task.episode_info()
    assert (info["spawned"][0], info["spawns_dropped"][0]) == (3, task.spawns_dropped[0])


def test_entries_follow_the_rising_rate() -> None:
    """Counts over many episodes against the Poisson expectations, early (slow) and late (fast) in the episode."""
    n = 48
    task = _task(n_envs=n, spawn_rate_start=90.0, spawn_rate_end=720.0, rise_time_s=500.0, max_spawned=200)
    _hold(task, 20)
    early = task.spawned.sum()
    _hold(task, 80)
    late_start = task.spawned.sum()
    _hold(task, 20)
    late = task.spawned.sum() - late_start
    c = task.config
    for count, (t0, t1) in ((early, (0.0, 100.0)), (late, (500.0, 600.0))):
        mean = n * float(expected_entries(c, np.array(t1)) - expected_entries(c, np.array(t0)))
        assert abs(count - mean) < 4 * math.sqrt(mean), (count, mean)
    assert late > 3 * early


def test_first_los_ignores_the_start_and_losses_per_flight_hour() -> None:
    task = _task(seeds=[2], spawn_rate_start=0.0, spawn_rate_end=0.0)
    sim = task.sim
    sim.active[0, 2:] = False
    # Slot 1 flies 2 NM ahead of the ownship on its heading and speed: a loss of separation from the start.
    for s, dist_nm in ((1, 2.0),):
        lat, lon = sim.lat[0, 0], sim.lon[0, 0]
        h = math.radians(sim.hdg[0, 0])
        sim.lat[0, s] = lat + dist_nm / 60.0 * math.cos(h)
        sim.lon[0, s] = lon + dist_nm / 60.0 * math.sin(h) / math.cos(math.radians(lat))
        sim.hdg[0, s], sim.cas[0, s], sim.tas[0, s], sim.gs[0, s] = sim.hdg[0, 0], sim.cas[0, 0], sim.tas[0, 0], sim.gs[0, 0]
    task.stats.clear(np.array([0]), sim.max_aircraft)
    task.record(task.measure(), None)  # as at a reset: this loss was there at the start
    _hold(task, 3)
    assert task.stats.los_count[0] == 1 and np.isnan(task.kpis()["kpi_time_to_first_los_s"][0])
    # A second aircraft put next to the ownship: a new loss in step 4.
    sim.active[0, 2] = True
    sim.lat[0, 2], sim.lon[0, 2], sim.alt[0, 2] = sim.lat[0, 0] + 1.0 / 60.0, sim.lon[0, 0], sim.alt[0, 0]
    _hold(task, 1)
    kpis = task.kpis()
    assert task.stats.los_count[0] == 2
    assert kpis["kpi_time_to_first_los_s"][0] == 4 * STEP_S
    assert kpis["kpi_los_per_flight_hour"][0] == 2 / (4 * STEP_S / 3600.0)
    assert kpis["kpi_aircraft_spawned"][0] == 0.0
