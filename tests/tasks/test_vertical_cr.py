"""VerticalCREnv-v0 task: reward, observation, scenario generation and options (docs/environments-v0.md §2)."""

from __future__ import annotations

import functools

import gymnasium as gym
import numpy as np
import pytest

import bluesky_gym
from bluesky_gym.core import atmosphere as isa
from bluesky_gym.environments.vertical_cr.task import VerticalCRConfig, VerticalCRTask

from .conftest import NM, R_EARTH, east_of, north_of, seeded_task

_task = functools.partial(seeded_task, VerticalCRTask)


def _place_ownship(task: VerticalCRTask, alt: float, target: float) -> None:
    s = task.sim
    s.lat[:, 0], s.lon[:, 0], s.alt[:, 0], s.hdg[:, 0] = 52.0, 4.0, alt, 0.0
    task.target_alt[:] = target
    # Intruders far away by default (50 km east), at the ownship's altitude.
    s.lat[:, 1:] = 52.0
    s.lon[:, 1:] = east_of(52.0, 4.0, 50_000.0)
    s.alt[:, 1:] = alt


# --- reward ----------------------------------------------------------------------------------------
def test_reward_altitude_term_and_intrusion_cylinder() -> None:
    task = _task(3)
    _place_ownship(task, alt=3000.0, target=2600.0)
    s = task.sim
    # env 0: intruder 1 at 4 NM, 200 m above -> intrusion.
    s.lat[0, 1], s.lon[0, 1], s.alt[0, 1] = north_of(52.0, 4 * NM), 4.0, 3200.0
    # env 1: intruder 1 at 4 NM but 400 m above (outside 304.8 m); intruder 2 at 6 NM level.
    s.lat[1, 1], s.lon[1, 1], s.alt[1, 1] = north_of(52.0, 4 * NM), 4.0, 3400.0
    s.lat[1, 2], s.lon[1, 2], s.alt[1, 2] = 52.0, east_of(52.0, 4.0, 6 * NM), 3000.0
    # env 2: two intruders inside (1 NM, 100 m below; 3 NM, 300 m above).
    s.lat[2, 1], s.lon[2, 1], s.alt[2, 1] = north_of(52.0, 1 * NM), 4.0, 2900.0
    s.lat[2, 3], s.lon[2, 3], s.alt[2, 3] = 52.0, east_of(52.0, 4.0, 3 * NM), 3300.0
    reward, terminated, comp = task.reward(task.measure())
    alt_term = -(5 / 3000) * 400.0
    np.testing.assert_allclose(comp["altitude"], alt_term, rtol=1e-12)
    np.testing.assert_array_equal(comp["intrusion"], [-50.0, 0.0, -100.0])
    np.testing.assert_allclose(reward, [alt_term - 50, alt_term, alt_term - 100], rtol=1e-12)
    assert terminated.dtype == bool and not terminated.any()
    np.testing.assert_array_equal(task.total_intrusions, [1, 0, 2])
    task.reward(task.measure())
    np.testing.assert_array_equal(task.total_intrusions, [2, 0, 4])  # counted per intruder per step
    info = task.episode_info()
    assert set(info) == {"total_reward", "total_intrusions", "final_altitude"}


def test_reward_crash_and_runway_terminate_with_intrusions_added() -> None:
    task = _task(2)
    _place_ownship(task, alt=3000.0, target=3000.0)
    s = task.sim
    s.alt[0, 0] = -5.0  # crashed; intruders 50 km away
    s.lat[1, 0] = north_of(52.0, 201_000.0)  # past the runway, 250 m up
    s.alt[1, 0] = 250.0
    s.lat[1, 2], s.lon[1, 2], s.alt[1, 2] = north_of(52.0, 203_000.0), 4.0, 300.0  # 2 km ahead, 50 m above
    g = task.measure()
    reward, terminated, comp = task.reward(g)
    np.testing.assert_array_equal(terminated, [True, True])
    assert reward[0] == -100.0 and task.final_altitude[0] == -100.0
    np.testing.assert_allclose(reward[1], 250.0 * (-50 / 3000) - 50.0, rtol=1e-12)
    assert task.final_altitude[1] == 250.0
    np.testing.assert_array_equal(comp["intrusion"], [0.0, -50.0])
    assert g.goal_reached.tolist() == [False, True]


# --- observation -----------------------------------------------------------------------------------
def test_observation_matches_hand_computed_geometry() -> None:
    task = _task(1)
    _place_ownship(task, alt=3000.0, target=2500.0)
    s = task.sim
    s.vs[0, 0], s.gs[0, 0] = -5.0, 170.0
    # (lat, lon, alt, hdg, gs, vs) of intruders 1-3:
    intruders = [
        (52.0, east_of(52.0, 4.0, 10_000.0), 3500.0, 270.0, 160.0, 0.0),  # 10 km east, westbound, 500 m above
        (north_of(52.0, 20_000.0), 4.0, 2700.0, 180.0, 150.0, 2.0),  # 20 km north, head-on, 300 m below, climbing
        (52.0, east_of(52.0, 4.0, -30_000.0), 3000.0, 0.0, 170.0, -5.0),  # 30 km west (left), same velocity
    ]
    for i, state in enumerate(intruders, start=1):
        s.lat[0, i], s.lon[0, i], s.alt[0, i], s.hdg[0, i], s.gs[0, i], s.vs[0, i] = state
    obs = task.observe()
    assert all(v.dtype == np.float64 for v in obs.values())
    np.testing.assert_allclose(obs["altitude"][0], [(3000 - 1500) / 3000])
    np.testing.assert_allclose(obs["vz"][0], [-1.0])
    np.testing.assert_allclose(obs["target_altitude"][0], [(2500 - 1500) / 3000])
    np.testing.assert_allclose(obs["intruder_distance"][0, :3], [10 / 200, 20 / 200, 30 / 200], rtol=1e-9)
    # Bearing wrap180(hdg - qdr): east -> -90 (right), north -> 0, west -> +90 (left).
    np.testing.assert_allclose(obs["cos_difference_pos"][0, :3], [0.0, 1.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(obs["sin_difference_pos"][0, :3], [-1.0, 0.0, 1.0], atol=1e-9)
    np.testing.assert_allclose(obs["altitude_difference"][0, :3], [500 / 3000, -300 / 3000, 0.0], atol=1e-12)
    # x = -cos(hdg_own - hdg_int) gs_int / 150; y = (gs_own - sin(hdg_own - hdg_int) gs_int) / 150.
    np.testing.assert_allclose(obs["x_difference_speed"][0, :3], [0.0, 150 / 150, -170 / 150], atol=1e-12)
    np.testing.assert_allclose(obs["y_difference_speed"][0, :3], [(170 - 160) / 150, 170 / 150, 170 / 150], atol=1e-12)
    # Vertical speed difference in m/s, not normalised.
    np.testing.assert_allclose(obs["z_difference_speed"][0, :3], [5.0, 7.0, 0.0], atol=1e-12)


# --- scenario generation ---------------------------------------------------------------------------
def test_generation_ranges_and_dh_rule_over_200_seeds() -> None:
    n = 200
    task = _task(n)
    s = task.sim
    assert s.active.shape == (n, 6) and s.active.all()
    alt_own = s.alt[:, 0]
    assert np.all(alt_own == np.round(alt_own)) and alt_own.min() >= 2000 and alt_own.max() <= 3999
    off = task.target_alt - alt_own
    assert np.all(off == np.round(off)) and off.min() >= -500 and off.max() <= 499
    for arr, lo, hi in ((task.conflict_dpsi, 45, 314), (task.conflict_dcpa, 0, 4)):
        assert np.all(arr == np.round(arr)) and arr.min() == lo and arr.max() == hi
    gs = s.gs[:, 0]
    tlosh_hi = np.floor(180_000.0 / gs)[:, None]
    tl = task.conflict_tlosh
    assert np.all(tl == np.round(tl)) and tl.min() >= 100 and np.all(tl < tlosh_hi)
    # dH: late intruders between 500 m above ground and target + 100 m; early ones target +- 500 m.
    dh = task.conflict_dh
    assert np.all(dh == np.round(dh))
    tod = (200_000.0 / gs - 2 * task.target_alt / 12.5)[:, None]
    late = tl > tod
    assert late.any() and (~late).any()
    rel = task.target_alt[:, None] - alt_own[:, None]
    lo = np.where(late, 500 - alt_own[:, None], rel - 500)
    hi = np.where(late, rel + 100, rel + 500)
    assert np.all(dh >= lo) and np.all(dh < hi)
    # Intruders are at alt_own + dH, selected there, and level.
    np.testing.assert_array_equal(s.alt[:, 1:], alt_own[:, None] + dh)
    np.testing.assert_array_equal(s.selalt[:, 1:], alt_own[:, None] + dh)
    assert np.abs(s.vs[:, 1:]).max() < 1e-7
    # Track offset dpsi and the ownship's ground speed (to within BlueSky's two ISA models: creconfs
    # converts GS to CAS with the layered model, creation converts back with the vector one).
    np.testing.assert_allclose(((s.hdg[:, 1:] - s.hdg[:, :1] - task.conflict_dpsi) + 180) % 360 - 180, 0.0, atol=1e-9)
    np.testing.assert_allclose(s.gs[:, 1:], np.broadcast_to(s.gs[:, :1], (n, 5)), rtol=1e-4)


def test_generation_places_intruders_on_the_drawn_conflict() -> None:
    task = _task(30)
    s = task.sim
    # Flat relative geometry (north, east) in metres.
    dn = np.radians(s.lat[:, 1:] - s.lat[:, :1]) * R_EARTH
    de = np.radians(s.lon[:, 1:] - s.lon[:, :1]) * R_EARTH * np.cos(np.radians(s.lat[:, :1]))
    vn = s.gs[:, 1:] * np.cos(np.radians(s.hdg[:, 1:])) - s.gs[:, :1] * np.cos(np.radians(s.hdg[:, :1]))
    ve = s.gs[:, 1:] * np.sin(np.radians(s.hdg[:, 1:])) - s.gs[:, :1] * np.sin(np.radians(s.hdg[:, :1]))
    tcpa = -(dn * vn + de * ve) / (vn**2 + ve**2)
    dcpa = np.hypot(dn + vn * tcpa, de + ve * tcpa)
    np.testing.assert_allclose(dcpa, task.conflict_dcpa * NM, rtol=0.01, atol=60.0)
    assert np.all(tcpa > task.conflict_tlosh)  # the 5 NM zone is entered after tlosh, CPA later


def test_draw_order_is_the_reference_order() -> None:
    """alt, target offset, then (dpsi, dcpa, tlosh, dH) per intruder, from the episode generator."""
    for seed in (0, 7, 123):
        task = _task(1, seeds=[seed])
        rng = np.random.default_rng(seed)
        alt = rng.integers(2000, 4000)
        target = alt + rng.integers(-500, 500)
        assert task.sim.alt[0, 0] == alt and task.target_alt[0] == target
        gs = float(isa.vcas2tas(150.0, float(alt)))
        for i in range(5):
            dpsi, dcpa, tlosh = rng.integers(45, 315), rng.integers(0, 5), rng.integers(100, int(180.0 * 1000 / gs))
            if tlosh > 200.0 * 1000 / gs - 2 * target / 12.5:
                dh = rng.integers(int(-alt + 500), int(target - alt + 100))
            else:
                dh = rng.integers(int(target - alt - 500), int(target - alt + 500))
            assert (task.conflict_dpsi[0, i], task.conflict_dcpa[0, i], task.conflict_tlosh[0, i], task.conflict_dh[0, i]) == (
                dpsi,
                dcpa,
                tlosh,
                dh,
            )


def test_intruders_hold_their_level() -> None:
    task = _task(4)
    alt0 = task.sim.alt[:, 1:].copy()
    for _ in range(3):
        task.step(np.full((4, 1), -1.0))
    np.testing.assert_allclose(task.sim.alt[:, 1:], alt0, atol=1e-6)


# --- options and spaces ----------------------------------------------------------------------------
def test_defaults_are_the_reference() -> None:
    c = VerticalCRConfig()
    assert (c.num_intruders, c.dpsi_min, c.dpsi_max, c.dcpa_min, c.dcpa_max, c.tlosh_min) == (5, 45, 315, 0, 5, 100)
    assert (c.tlosh_runway_fraction, c.late_dh_floor, c.late_dh_above_target, c.early_dh_band) == (0.9, 500, 100, 500)
    assert (c.alt_min, c.alt_max, c.target_alt_dif, c.runway_distance_km) == (2000, 4000, 500, 200.0)


@pytest.mark.parametrize(
    ("options", "match"),
    [
        ({"num_intruders": 0}, "num_intruders"),
        ({"num_intruders": 2.5}, "num_intruders must be an integer"),
        ({"dpsi_max": 45}, "dpsi_max"),
        ({"dpsi_min": -1}, "dpsi_min"),
        ({"dcpa_min": -1}, "dcpa_min"),
        ({"dcpa_max": 0}, "dcpa_max"),
        ({"tlosh_min": 0}, "tlosh_min"),
        ({"tlosh_min": 1000}, "tlosh_min must be below the tlosh upper bound"),
        ({"tlosh_runway_fraction": 0.0}, "tlosh_runway_fraction"),
        ({"tlosh_runway_fraction": float("nan")}, "tlosh_runway_fraction"),
        ({"late_dh_floor": 1600}, "late_dh_floor"),
        ({"early_dh_band": 1501}, "early_dh_band"),
        ({"early_dh_band": 0}, "early_dh_band"),
        ({"alt_max": 1999}, "alt_max"),
    ],
)
def test_invalid_options_raise(options: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        VerticalCRTask.make_config(options)


def test_options_change_the_scenario_and_the_spaces() -> None:
    bluesky_gym.register_envs()
    env = gym.make("VerticalCREnv-v0", num_intruders=3, dcpa_min=4, dcpa_max=5, dpsi_min=90, dpsi_max=91)
    obs, _ = env.reset(seed=2)
    assert obs["intruder_distance"].shape == (3,) and env.observation_space["z_difference_speed"].shape == (3,)
    task = env.unwrapped.task
    assert task.sim.max_aircraft == 4
    np.testing.assert_array_equal(task.conflict_dcpa[0], [4, 4, 4])
    np.testing.assert_array_equal(task.conflict_dpsi[0], [90, 90, 90])
    env.close()


# --- KPIs ------------------------------------------------------------------------------------------
def test_ownship_separation_uses_the_intrusion_cylinder() -> None:
    task = _task(1)
    _place_ownship(task, alt=3000.0, target=3000.0)
    s = task.sim
    s.lat[0, 1], s.lon[0, 1], s.alt[0, 1] = north_of(52.0, 4 * NM), 4.0, 3100.0  # inside
    s.lat[0, 2], s.lon[0, 2], s.alt[0, 2] = north_of(52.0, 2 * NM), 4.0, 3400.0  # above the cylinder
    s.active[0, 5] = False
    dist, los = task.ownship_separation()
    assert dist.shape == (1, 6) and dist[0, 0] == np.inf and dist[0, 5] == np.inf
    np.testing.assert_allclose(dist[0, 1:3], [4.0, 2.0], rtol=1e-9)
    assert los[0].tolist() == [False, True, False, False, False, False]


def test_intruder_relative_state_equals_the_numpy_oracle() -> None:
    from bluesky_gym.environments.vertical_cr.task import intruder_relative_state
    from tests.oracle.tasks import intruder_relative_state as oracle

    rng = np.random.default_rng(12)
    n, m = 40, 7
    lat = 52.0 + rng.normal(0, 0.5, (n, m))
    lon = rng.uniform(-180, 180, (n, m))  # the longitude difference wraps too
    hdg = rng.uniform(-200, 400, (n, m))  # bearings beyond the single wrap
    gs = rng.uniform(80, 260, (n, m))
    got, want = intruder_relative_state(lat, lon, hdg, gs), oracle(lat, lon, hdg, gs)
    assert got.keys() == want.keys()
    for k in want:
        np.testing.assert_array_equal(got[k], want[k], err_msg=k, strict=True)
