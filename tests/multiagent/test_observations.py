"""Per-agent observations against hand-computed relative geometry, and against the single-agent tasks."""

from __future__ import annotations

import math

import numpy as np
import pytest
from gymnasium.utils import seeding

from bluesky_gym.environments.horizontal_cr.multiagent import HorizontalCRMultiAgentTask
from bluesky_gym.environments.horizontal_cr.task import HorizontalCRTask
from bluesky_gym.environments.merge.multiagent import MergeMultiAgentTask
from bluesky_gym.environments.merge.task import MergeTask
from bluesky_gym.environments.sector_cr.multiagent import SectorCRMultiAgentTask
from bluesky_gym.environments.sector_cr.task import CENTER, SectorCRTask

R_EARTH = 6371000.0
NM = 1852.0


def _place(task, aircraft: list[tuple[float, float, float, float]], origin: tuple[float, float]) -> None:
    """Keep only ``len(aircraft)`` aircraft, at (north NM, east NM, heading deg, TAS m/s) from ``origin``.

    Positions use the flat conversion lat = lat0 + north / 60, lon = lon0 + east / (60 cos lat0).
    """
    s = task.sim
    s.active[0] = False
    for k, (north, east, hdg, tas) in enumerate(aircraft):
        s.active[0, k] = True
        s.lat[0, k] = origin[0] + north / 60.0
        s.lon[0, k] = origin[1] + east / (60.0 * math.cos(math.radians(origin[0])))
        s.hdg[0, k] = s.trk[0, k] = hdg
        s.tas[0, k] = s.gs[0, k] = tas


def _kwik(lat1: float, lon1: float, lat2: float, lon2: float) -> tuple[float, float]:
    """Flat-earth bearing [deg] and distance [NM] written out by hand."""
    dlat = math.radians(lat2 - lat1)
    dlon = math.radians(lon2 - lon1)
    c = math.cos(math.radians(0.5 * (lat1 + lat2)))
    return math.degrees(math.atan2(dlon * c, dlat)), R_EARTH * math.hypot(dlat, dlon * c) / NM


def _reset(task, seed: int = 0) -> None:
    task.seed(task.all_envs, [seeding.np_random(seed + i)[0] for i in range(task.n_envs)])
    task.reset()


def test_sector_observation_of_a_constructed_state() -> None:
    task = SectorCRMultiAgentTask(1)
    _reset(task)
    # 0 at the centre heading north at 150 m/s; 1 3 NM north heading south; 2 10 NM east heading
    # west at 160 m/s; 3 20 NM south-west heading north-east at 140 m/s.
    ac = [(0.0, 0.0, 0.0, 150.0), (3.0, 0.0, 180.0, 150.0), (0.0, 10.0, 270.0, 160.0), (-20.0, -20.0, 45.0, 140.0)]
    _place(task, ac, CENTER)
    # Agent 0's exit point due east: drift = 0 - 90.
    task.scenario.wpt_lat[0, 0] = CENTER[0]
    task.scenario.wpt_lon[0, 0] = CENTER[1] + 30 / (60 * math.cos(math.radians(CENTER[0])))
    obs = task.observation()

    def expect(i: int, j: int) -> dict[str, float]:
        (ni, ei, hi, vi), (nj, ej, hj, vj) = ac[i], ac[j]
        dn, de = (nj - ni) * NM, (ej - ei) * NM
        vn = vj * math.cos(math.radians(hj)) - vi * math.cos(math.radians(hi))
        ve = vj * math.sin(math.radians(hj)) - vi * math.sin(math.radians(hi))
        d = math.hypot(dn, de)
        trk = math.atan2(ve, vn)
        return {
            "x_r": dn / 13000,
            "y_r": de / 13000,
            "vx_r": vn / 32,
            "vy_r": ve / 66,
            "cos(track)": math.cos(trk),
            "sin(track)": math.sin(trk),
            "distances": (d - 50000) / 15000,
        }

    order = {0: [1, 2, 3], 1: [0, 2, 3], 2: [0, 1, 3], 3: [0, 1, 2]}
    for i, neighbours in order.items():
        for slot, j in enumerate(neighbours):
            for key, value in expect(i, j).items():
                assert obs[key][0, i, slot] == pytest.approx(value, abs=1e-6), (i, j, key)
        assert list(obs["traffic_mask"][0, i]) == [1.0, 1.0, 1.0, 0.0]
        for key in ("x_r", "y_r", "vx_r", "vy_r", "cos(track)", "sin(track)", "distances"):
            assert obs[key][0, i, 3] == 0.0  # padding
    assert obs["cos(drift)"][0, 0, 0] == pytest.approx(0.0, abs=1e-9)
    assert obs["sin(drift)"][0, 0, 0] == pytest.approx(-1.0)
    assert obs["airspeed"][0, :4, 0] == pytest.approx([0.0, 0.0, 10 / 6, -10 / 6])
    # Empty slots observe nothing.
    assert all(np.all(v[0, 4:] == 0.0) for v in obs.values())


def test_merge_observation_of_a_constructed_state() -> None:
    task = MergeMultiAgentTask(1)
    _reset(task)
    origin = (53.0, 4.7)
    ac = [
        (0.0, 0.0, 180.0, 170.0),
        (0.0, 6.0, 270.0, 160.0),
        (-2.0, -2.0, 90.0, 150.0),
        (30.0, 0.0, 180.0, 170.0),
        (40.0, 5.0, 200.0, 165.0),
        (60.0, 0.0, 180.0, 170.0),
        (80.0, 0.0, 180.0, 170.0),
    ]
    _place(task, ac, origin)
    obs = task.observation()
    s = task.sim
    # Agent 0: neighbours in kwik-distance order 2 (2.83 NM), 1 (6 NM), 3, 4, 5.
    expected_order = [2, 1, 3, 4, 5]
    for slot, j in enumerate(expected_order):
        qdr, d = _kwik(s.lat[0, 0], s.lon[0, 0], s.lat[0, j], s.lon[0, j])
        vn = ac[j][3] * math.cos(math.radians(ac[j][2])) - ac[0][3] * math.cos(math.radians(ac[0][2]))
        ve = ac[j][3] * math.sin(math.radians(ac[j][2])) - ac[0][3] * math.sin(math.radians(ac[0][2]))
        assert obs["distances"][0, 0, slot] == pytest.approx(d / 250, rel=1e-9)
        assert obs["x_r"][0, 0, slot] == pytest.approx(d * NM * math.cos(math.radians(qdr)) / 1e6, abs=1e-9)
        assert obs["y_r"][0, 0, slot] == pytest.approx(d * NM * math.sin(math.radians(qdr)) / 1e6, abs=1e-9)
        assert obs["vx_r"][0, 0, slot] == pytest.approx(vn / 150, abs=1e-9)
        assert obs["vy_r"][0, 0, slot] == pytest.approx(ve / 150, abs=1e-9)
        assert obs["cos(track)"][0, 0, slot] == pytest.approx(math.cos(math.atan2(ve, vn)), abs=1e-9)
    # Target: the FAF (not reached yet): drift = heading - bearing to it, distance / 250.
    qdr, d = _kwik(s.lat[0, 0], s.lon[0, 0], 54.161036, 4.713196)
    drift = 180.0 - qdr
    assert obs["waypoint_dist"][0, 0, 0] == pytest.approx(d / 250, rel=1e-5)
    assert obs["sin(drift)"][0, 0, 0] == pytest.approx(math.sin(math.radians(drift)), abs=1e-5)
    assert obs["airspeed"][0, 0, 0] == 170.0
    # The last aircraft's nearest neighbour is the one 20 NM south of it; 6 others exist, 5 kept.
    assert obs["traffic_mask"][0, 6].tolist() == [1.0] * 5
    assert obs["distances"][0, 6, 0] == pytest.approx(_kwik(s.lat[0, 6], s.lon[0, 6], s.lat[0, 5], s.lon[0, 5])[1] / 250)


def test_horizontal_observation_of_a_constructed_state() -> None:
    task = HorizontalCRMultiAgentTask(1)
    _reset(task)
    origin = (52.0, 4.0)
    ac = [(0.0, 0.0, 0.0, 89.0), (10.0, 0.0, 180.0, 89.0), (0.0, -5.0, 90.0, 80.0)]
    _place(task, ac, origin)
    obs = task.observation()
    s = task.sim

    def expect(i: int, j: int) -> tuple[float, ...]:
        qdr, d = _kwik(s.lat[0, i], s.lon[0, i], s.lat[0, j], s.lon[0, j])
        bearing = (ac[i][2] - qdr + 180.0) % 360.0 - 180.0
        dh = math.radians(ac[i][2] - ac[j][2])
        return (
            d * 1.852 / 150,
            math.cos(math.radians(bearing)),
            math.sin(math.radians(bearing)),
            -math.cos(dh) * ac[j][3] / 150,
            (ac[i][3] - math.sin(dh) * ac[j][3]) / 150,
        )

    keys = ("intruder_distance", "cos_difference_pos", "sin_difference_pos", "x_difference_speed", "y_difference_speed")
    # Sorted by distance: for agent 0, aircraft 2 (5 NM) before aircraft 1 (10 NM).
    for i, neighbours in {0: [2, 1], 1: [0, 2], 2: [0, 1]}.items():
        for slot, j in enumerate(neighbours):
            for key, value in zip(keys, expect(i, j), strict=True):
                assert obs[key][0, i, slot] == pytest.approx(value, abs=1e-9), (i, j, key)
        assert obs["traffic_mask"][0, i].tolist() == [1.0, 1.0, 0.0, 0.0, 0.0]
    # Aircraft 2 is due west of aircraft 0 (bearing 270, heading 0): relative bearing +90, i.e. left.
    assert obs["sin_difference_pos"][0, 0, 0] == pytest.approx(1.0, abs=1e-6)


@pytest.mark.parametrize(("ma_class", "sa_class"), [(SectorCRMultiAgentTask, SectorCRTask), (MergeMultiAgentTask, MergeTask)])
def test_agent_zero_sees_the_single_agent_observation(ma_class, sa_class) -> None:
    ma, sa = ma_class(3), sa_class(3)
    _reset(ma, 11)
    _reset(sa, 11)
    o_ma, o_sa = ma.observation(), sa.observe()
    assert set(o_ma) == set(o_sa) | {"traffic_mask"}
    for key, value in o_sa.items():
        # The same functions of the same rows: equal to the last bit.
        np.testing.assert_array_equal(o_ma[key][:, 0], value, err_msg=key)
    assert np.array_equal(ma.sim.active, sa.sim.active)


def test_horizontal_scenario_is_the_single_agent_one() -> None:
    ma, sa = HorizontalCRMultiAgentTask(2), HorizontalCRTask(2)
    _reset(ma, 4)
    _reset(sa, 4)
    for name in ("lat", "lon", "hdg", "tas"):
        assert np.array_equal(getattr(ma.sim, name), getattr(sa.sim, name))
    o_ma, o_sa = ma.observation(), sa.observe()
    for key in ("waypoint_distance", "cos_drift", "sin_drift"):
        assert np.array_equal(o_ma[key][:, 0], o_sa[key])
    # Same intruders, ordered by distance instead of creation order.
    for key in ("intruder_distance", "x_difference_speed"):
        assert np.allclose(np.sort(o_ma[key][:, 0], axis=1), np.sort(o_sa[key], axis=1))
    assert np.all(np.diff(o_ma["intruder_distance"][:, 0], axis=1) >= 0)


def test_horizontal_intruder_waypoints_mirror_the_start_about_the_cpa() -> None:
    task = HorizontalCRMultiAgentTask(4)
    _reset(task, 21)
    s = task.sim
    for e in range(4):
        for k in range(1, task.n_agents):
            qdr, d = _kwik(s.lat[e, k], s.lon[e, k], task.wpt_lat[e, k], task.wpt_lon[e, k])
            # On the initial (great-circle) track, and beyond the minimum waypoint distance.
            assert (qdr - s.hdg[e, k] + 180.0) % 360.0 - 180.0 == pytest.approx(0.0, abs=2.0)
            assert d * 1.852 >= task.config.waypoint_distance_min - 1e-6
            # Twice the distance flown to the closest point of approach with aircraft 0 (flat earth).
            q0, d0 = _kwik(s.lat[e, 0], s.lon[e, 0], s.lat[e, k], s.lon[e, k])
            rn, re = d0 * math.cos(math.radians(q0)), d0 * math.sin(math.radians(q0))
            vn = s.gs[e, k] * math.cos(math.radians(s.hdg[e, k])) - s.gs[e, 0] * math.cos(math.radians(s.hdg[e, 0]))
            ve = s.gs[e, k] * math.sin(math.radians(s.hdg[e, k])) - s.gs[e, 0] * math.sin(math.radians(s.hdg[e, 0]))
            tcpa = -(rn * vn + re * ve) * NM / (vn * vn + ve * ve)
            expected_km = max(2 * s.gs[e, k] * tcpa / 1000, task.config.waypoint_distance_min)
            assert d * 1.852 == pytest.approx(expected_km, rel=0.02)
    # The drift of every agent starts near zero.
    assert np.all(np.abs(task.agent_drift()[s.active]) < 2.0)
