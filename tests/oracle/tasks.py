"""Readable numpy forms of the traffic tasks' observation and separation geometry (test oracles).

The package computes these quantities once, in :mod:`bluesky_gym.tasks.compiled`; the tests
compare that to the forms here to the last bit. Each function takes the simulator's
(n_envs, max_aircraft) arrays with the ownship in slot 0, as the single-agent tasks see them.
"""

from __future__ import annotations

import numpy as np

from bluesky_gym.core.units import NM2KM
from bluesky_gym.environments.merge import task as mg
from bluesky_gym.environments.sector_cr import task as sc
from bluesky_gym.tasks.base import wrap180
from bluesky_gym.tasks.geometry import latlon_to_nm
from tests.oracle.geometry import ref_kwikdist, ref_kwikdist_matrix, ref_kwikqdrdist

Array = np.ndarray


def kwik_separation(lat: Array, lon: Array, alt: Array, active: Array, intrusion_nm: float, vertical_m: float | None = None) -> tuple[Array, Array]:
    """Kwik distance [NM] from the ownship (slot 0) to every other active aircraft, and the intrusion flags."""
    dist = ref_kwikdist(lat[:, :1], lon[:, :1], lat, lon)
    other = active.copy()
    other[:, 0] = False
    dist = np.where(other, dist, np.inf)
    los = other & (dist < intrusion_nm)
    if vertical_m is not None:
        los &= np.abs(alt[:, :1] - alt) < vertical_m
    return dist, los


def relative_velocity(hdg: Array, tas: Array) -> tuple[Array, Array]:
    """(vx_r, vy_r) [m/s]: each intruder's TAS vector minus the ownship's, north / east, (n, m - 1)."""
    vx = np.cos(np.deg2rad(hdg)) * tas
    vy = np.sin(np.deg2rad(hdg)) * tas
    return vx[:, 1:] - vx[:, :1], vy[:, 1:] - vy[:, :1]


def sector_observation(sim, wpt_lat: Array, wpt_lon: Array) -> dict[str, Array]:
    """SectorCREnv-v0's observation: drift to the own waypoint (n,), airspeed, 4 closest intruders by flat distance."""
    s = sim
    qdr, _ = ref_kwikqdrdist(s.lat[:, 0], s.lon[:, 0], wpt_lat, wpt_lon)
    drift = wrap180(s.hdg[:, 0] - qdr)
    loc = latlon_to_nm(sc.CENTER, np.stack([s.lat, s.lon], axis=-1)) * NM2KM * sc.M_PER_KM
    rel = loc[:, 1:] - loc[:, :1]
    dist = np.sqrt(np.sum(rel**2, axis=-1))
    vx_r, vy_r = relative_velocity(s.hdg, s.tas)
    track = np.arctan2(vy_r, vx_r)
    order = np.argsort(np.where(s.active[:, 1:], dist, np.inf), axis=1, kind="stable")[:, : sc.NUM_AC_STATE]
    x, y, vx, vy, trk, d = np.moveaxis(
        np.take_along_axis(np.stack([rel[..., 0], rel[..., 1], vx_r, vy_r, track, dist], axis=-1), order[..., None], axis=1), -1, 0
    )
    return {
        "cos(drift)": np.cos(np.deg2rad(drift))[:, None],
        "sin(drift)": np.sin(np.deg2rad(drift))[:, None],
        "airspeed": ((s.tas[:, :1] - sc.AIRSPEED_MEAN) / sc.AIRSPEED_STD),
        "x_r": x / sc.POSITION_SCALE,
        "y_r": y / sc.POSITION_SCALE,
        "vx_r": vx / sc.VX_SCALE,
        "vy_r": vy / sc.VY_SCALE,
        "cos(track)": np.cos(trk),
        "sin(track)": np.sin(trk),
        "distances": (d - sc.DISTANCE_MEAN) / sc.DISTANCE_STD,
    }


def merge_observation(sim, wpt_reach: Array) -> dict[str, Array]:
    """MergeEnv-v0's observation: drift and distance to the current target, 5 closest intruders by kwikdist_matrix."""
    s = sim
    tlat, tlon = mg.target(wpt_reach != 0)
    qdr, dist = ref_kwikqdrdist(s.lat[:, 0], s.lon[:, 0], tlat, tlon)
    drift = wrap180(s.hdg[:, 0] - qdr)
    brg, d_int = ref_kwikqdrdist(s.lat[:, :1], s.lon[:, :1], s.lat[:, 1:], s.lon[:, 1:])
    d_sort = ref_kwikdist_matrix(s.lat[:, :1], s.lon[:, :1], s.lat[:, 1:], s.lon[:, 1:])
    vx_r, vy_r = relative_velocity(s.hdg, s.tas)
    track = np.arctan2(vy_r, vx_r)
    order = np.argsort(np.where(s.active[:, 1:], d_sort, np.inf), axis=1, kind="stable")[:, : mg.NUM_AC_STATE]

    def closest(a: Array) -> Array:
        return np.take_along_axis(a, order, axis=1)

    d_m = d_int * NM2KM * mg.M_PER_KM
    return {
        "cos(drift)": np.cos(np.deg2rad(drift))[:, None],
        "sin(drift)": np.sin(np.deg2rad(drift))[:, None],
        "airspeed": s.tas[:, :1].copy(),
        "waypoint_dist": (dist / mg.WAYPOINT_DIST_SCALE)[:, None],
        "faf_reached": wpt_reach[:, None].astype(np.float64),
        "x_r": closest(d_m * np.cos(np.deg2rad(brg))) / mg.POSITION_SCALE,
        "y_r": closest(d_m * np.sin(np.deg2rad(brg))) / mg.POSITION_SCALE,
        "vx_r": closest(vx_r) / mg.SPEED_SCALE,
        "vy_r": closest(vy_r) / mg.SPEED_SCALE,
        "cos(track)": np.cos(closest(track)),
        "sin(track)": np.sin(closest(track)),
        "distances": closest(d_sort) / mg.WAYPOINT_DIST_SCALE,
    }


def intruder_relative_state(sim_lat: Array, sim_lon: Array, hdg: Array, gs: Array) -> dict[str, Array]:
    """Ownship-relative geometry of the intruders (slots 1..) in slot order (VerticalCR, HorizontalCR)."""
    qdr, dist = ref_kwikqdrdist(sim_lat[:, :1], sim_lon[:, :1], sim_lat[:, 1:], sim_lon[:, 1:])
    own_hdg = hdg[:, :1]
    bearing = wrap180(own_hdg - qdr)
    heading_difference = own_hdg - hdg[:, 1:]
    x_dif = -np.cos(np.deg2rad(heading_difference)) * gs[:, 1:]
    y_dif = gs[:, :1] - np.sin(np.deg2rad(heading_difference)) * gs[:, 1:]
    return {
        "dist_km": dist * NM2KM,
        "cos_bearing": np.cos(np.deg2rad(bearing)),
        "sin_bearing": np.sin(np.deg2rad(bearing)),
        "x_dif": x_dif,
        "y_dif": y_dif,
    }


def horizontal_cr_observation(sim, wpt_lat: Array, wpt_lon: Array) -> dict[str, Array]:
    """HorizontalCREnv-v0's observation: intruders in slot order, waypoint distance and drift."""
    from bluesky_gym.environments.horizontal_cr import task as hc

    s = sim
    rel = intruder_relative_state(s.lat, s.lon, s.hdg, s.gs)
    qdr, dist = ref_kwikqdrdist(s.lat[:, 0], s.lon[:, 0], wpt_lat, wpt_lon)
    drift = wrap180(s.hdg[:, 0] - qdr)
    return {
        "intruder_distance": rel["dist_km"] / hc.DISTANCE_SCALE,
        "cos_difference_pos": rel["cos_bearing"],
        "sin_difference_pos": rel["sin_bearing"],
        "x_difference_speed": rel["x_dif"] / hc.SPEED_SCALE,
        "y_difference_speed": rel["y_dif"] / hc.SPEED_SCALE,
        "waypoint_distance": (dist * NM2KM / hc.DISTANCE_SCALE)[:, None],
        "cos_drift": np.cos(np.deg2rad(drift))[:, None],
        "sin_drift": np.sin(np.deg2rad(drift))[:, None],
    }


def horizontal_cr_reward(sim, wpt_lat: Array, wpt_lon: Array, reached: Array) -> tuple[Array, Array, dict[str, Array], Array]:
    """HorizontalCREnv-v0's reward of every episode, with the intruder count, the components and |drift| [rad].

    ``reached``: whether each waypoint was reached before this step (the reach term is paid once).
    """
    from bluesky_gym.environments.horizontal_cr import task as hc

    s = sim
    qdr, dist = ref_kwikqdrdist(s.lat[:, 0], s.lon[:, 0], wpt_lat, wpt_lon)
    drift = wrap180(s.hdg[:, 0] - qdr)
    newly = (dist * NM2KM < hc.DISTANCE_MARGIN) & ~reached
    _, los = kwik_separation(s.lat, s.lon, s.alt, s.active, hc.INTRUSION_DISTANCE)
    reach = np.where(newly, hc.REACH_REWARD, 0.0)
    drift_reward = np.abs(np.deg2rad(drift)) * hc.DRIFT_PENALTY
    count = los.sum(axis=1)
    intrusion = count * hc.INTRUSION_PENALTY
    return reach + drift_reward + intrusion, count, {"reach": reach, "drift": drift_reward, "intrusion": intrusion}, np.abs(np.deg2rad(drift))


def horizontal_cr_extra_track(distflown: Array, start_wpt_dist_km: Array) -> Array:
    """HorizontalCR's extra track [km]: the ownship's distance flown less the start's distance to the capture circle."""
    from bluesky_gym.environments.horizontal_cr import task as hc

    return distflown[:, 0] / 1000.0 - (start_wpt_dist_km - hc.DISTANCE_MARGIN)  # type: ignore[no-any-return]


# --- the step's end (bluesky_gym.tasks.compiled: truncation, sample_means, episode_kpis, clip_to_bounds) ---
def truncation(steps: Array, time_limit: int, terminated: Array, cut: Array) -> Array:
    """Truncated episodes: at the time limit or cut by the task, never a terminated one."""
    return ~terminated & ((steps >= time_limit) | cut)  # type: ignore[no-any-return]


def sample_means(total: Array, count: Array, empty: float) -> Array:
    """``total / count``, ``empty`` where ``count`` is 0."""
    with np.errstate(invalid="ignore"):
        return np.where(count > 0, total / np.maximum(count, 1), empty)


def episode_kpis(steps: Array, los_count: Array, los_steps: Array, min_sep: Array, drift_sum: Array, drift_n: Array,
                 distflown: Array, fuelburn: Array, dt: float, action_frequency: int) -> list[Array]:  # fmt: skip
    """The common KPIs, in the order of ``bluesky_gym.tasks.base.KPI_KEYS``."""
    return [
        los_count.astype(np.float64),
        los_steps.astype(np.float64),
        min_sep.copy(),
        sample_means(drift_sum, drift_n, np.nan),
        distflown[:, 0] / 1000.0,
        fuelburn[:, 0].copy(),
        steps * dt * action_frequency,
    ]


def clip_to_bounds(values: Array, low: Array, high: Array) -> Array:
    """numpy's clip of every row to the bounds of its columns."""
    return np.minimum(np.maximum(values, low), high)  # type: ignore[no-any-return]
