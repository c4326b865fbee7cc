"""The compiled observation and reward geometry of the traffic tasks (the only implementation).

Written with numpy arrays, one step of SectorCR, Merge or StaticObstacle at one episode would
issue a hundred small numpy calls (kwik geometry, sorting the intruders, polygon tests), costing
far more than the physics, and at large batches a dozen passes over (episodes, aircraft) arrays.
The functions here compute those quantities in one loop per episode with numba.

They are bit-identical to the readable numpy forms kept as test oracles (``tests/oracle``): the
same operations in the same order (numpy's ``deg2rad``/``rad2deg`` factors, its float remainder,
left-to-right products), no floating-point contraction, and the tests compare both to the last
bit. Without numba they run as plain Python (see :mod:`bluesky_gym.core.jit`).

The observation functions work on rows (episode ``envs[r]``, ownship slot ``own[r]``): the
single-agent tasks pass ownship slot 0 of every episode, the multi-agent tasks every active slot.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from bluesky_gym.core.commands import select_speed, select_track
from bluesky_gym.core.jit import AVAILABLE, grid_range, jit, jit_inline, scratch
from bluesky_gym.core.scalar import mod as _mod
from bluesky_gym.core.units import KTS, MPS2KT, NM, NM2KM, R_EARTH

__all__ = ["AVAILABLE"]

Array = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]

DEG2RAD = np.pi / 180.0  # numpy's deg2rad factor
_DEG = 180.0 / np.pi  # numpy's rad2deg factor
_KWIK_R = R_EARTH  # m: Earth radius of BlueSky's Python kwik forms
_KWIK_NM = NM  # m per NM in those forms
_M_PER_KM = 1000.0


# --- BlueSky's Python kwik forms (tasks/geometry.ref_kwik*), per pair of points -----------------
@jit_inline
def _kwik_parts(lata, lona, latb, lonb):  # type: ignore[no-untyped-def]
    dlat = (latb - lata) * DEG2RAD
    dlon = (_mod((lonb - lona) + 180.0, 360.0) - 180.0) * DEG2RAD
    cavelat = math.cos((lata + latb) * DEG2RAD * 0.5)
    return dlat, dlon, cavelat


@jit_inline
def _dist_of_parts(dlat, dlon, cavelat):  # type: ignore[no-untyped-def]
    return _KWIK_R * math.sqrt(dlat * dlat + dlon * dlon * cavelat * cavelat) / _KWIK_NM


@jit_inline
def _qdr_of_parts(dlat, dlon, cavelat):  # type: ignore[no-untyped-def]
    return _mod(math.atan2(dlon * cavelat, dlat) * _DEG, 360.0)


@jit_inline
def _matrix_dist_of_parts(dlat, dlon, cavelat):  # type: ignore[no-untyped-def]
    return _KWIK_R * math.sqrt(dlat * dlat + (dlon * dlon) * (cavelat * cavelat)) / _KWIK_NM


@jit_inline
def kwikdist_scalar(lata, lona, latb, lonb):  # type: ignore[no-untyped-def]
    """:func:`~bluesky_gym.tasks.geometry.ref_kwikdist` [NM]."""
    dlat, dlon, cavelat = _kwik_parts(lata, lona, latb, lonb)
    return _dist_of_parts(dlat, dlon, cavelat)


@jit_inline
def kwikqdrdist_scalar(lata, lona, latb, lonb):  # type: ignore[no-untyped-def]
    """:func:`~bluesky_gym.tasks.geometry.ref_kwikqdrdist`: bearing [deg, 0..360) and distance [NM]."""
    dlat, dlon, cavelat = _kwik_parts(lata, lona, latb, lonb)
    return _qdr_of_parts(dlat, dlon, cavelat), _dist_of_parts(dlat, dlon, cavelat)


@jit_inline
def wrap180_scalar(x):  # type: ignore[no-untyped-def]
    """The reference's single wrap (:func:`bluesky_gym.tasks.base.wrap180`)."""
    if x > 180.0:
        return x - 360.0
    if x < -180.0:
        return x + 360.0
    return x


@jit_inline
def _closest(key, active, out, best):  # type: ignore[no-untyped-def]
    """Indices of the ``len(out)`` smallest ``key[j]`` over active j (ties: lower j first).

    The first columns of a stable argsort of ``where(active, key, inf)``; empty slots count as
    inf. ``key`` and ``active`` run over the intruders (slots 1.. of the airspace); ``best`` is
    scratch space of ``len(out)`` floats.
    """
    k = out.shape[0]
    filled = 0
    for j in range(key.shape[0]):
        d = key[j] if active[j] else np.inf
        if filled < k:
            pos = filled
            filled += 1
        elif d < best[k - 1]:
            pos = k - 1
        else:
            continue
        while pos > 0 and d < best[pos - 1]:
            best[pos] = best[pos - 1]
            out[pos] = out[pos - 1]
            pos -= 1
        best[pos] = d
        out[pos] = j


@jit_inline
def polygon_contains(y, x, py, px, nv):  # type: ignore[no-untyped-def]
    """Even-odd test of point (lat y, lon x) against the first ``nv`` vertices of (py, px).

    BlueSky's 2-D ``checkInside`` for one point and one polygon.
    """
    inside = False
    for v in range(nv):
        w = v + 1 if v + 1 < nv else 0
        y1, x1, y2, x2 = py[v], px[v], py[w], px[w]
        if (y1 > y) != (y2 > y) and x < (x2 - x1) * (y - y1) / (y2 - y1) + x1:
            inside = not inside
    return inside


# --- shared by the tasks -----------------------------------------------------------------------
@jit
def kwik_separation(envs, own, lat, lon, alt, active, intrusion_nm, vertical_m, dist_out, los_out):  # type: ignore[no-untyped-def]
    """Kwik distance [NM] from ownship slot ``own[r]`` of episode ``envs[r]`` to every slot, and the intrusion flags.

    Row ``r`` of ``dist_out``/``los_out`` (p, m): inf / False for the ownship and empty slots.
    ``vertical_m`` NaN means a purely horizontal intrusion test.
    """
    for r in grid_range(envs.shape[0]):
        e = envs[r]
        o = own[r]
        lat0, lon0, alt0 = lat[e, o], lon[e, o], alt[e, o]
        for j in range(lat.shape[1]):
            if active[e, j] and j != o:
                d = kwikdist_scalar(lat0, lon0, lat[e, j], lon[e, j])
                dist_out[r, j] = d
                los = d < intrusion_nm
                if los and not math.isnan(vertical_m):
                    los = abs(alt0 - alt[e, j]) < vertical_m
                los_out[r, j] = los
            else:
                dist_out[r, j] = np.inf
                los_out[r, j] = False


@jit
def ownship_in_polygons(lat, lon, poly_lat, poly_lon, n_vertices, out):  # type: ignore[no-untyped-def]
    """Whether each episode's ownship (slot 0) lies in each of its polygons.

    ``poly_*`` are (n, K, V), ``n_vertices`` (n, K), ``out`` (n, K).
    """
    for e in grid_range(poly_lat.shape[0]):
        for k in range(poly_lat.shape[1]):
            out[e, k] = polygon_contains(lat[e, 0], lon[e, 0], poly_lat[e, k], poly_lon[e, k], n_vertices[e, k])


@jit
def points_in_owner_polygon(lat, lon, owner, poly_lat, poly_lon, n_vertices, out):  # type: ignore[no-untyped-def]
    """Even-odd test of points (P,) each against the polygon of its episode ``owner[p]``.

    ``poly_*`` are (n, V) and ``n_vertices`` (n,); ``out`` is (P,).
    """
    for p in grid_range(lat.shape[0]):
        e = owner[p]
        out[p] = polygon_contains(lat[p], lon[p], poly_lat[e], poly_lon[e], n_vertices[e])


@jit_inline
def _other_slots(active, e, o, slots, act):  # type: ignore[no-untyped-def]
    """The slots other than the ownship ``o`` of episode ``e`` in slot order into ``slots`` (m - 1), their activity into ``act``."""
    for j in range(o):
        slots[j] = j
        act[j] = active[e, j]
    for j in range(o + 1, active.shape[1]):
        slots[j - 1] = j
        act[j - 1] = active[e, j]


@jit_inline
def _count_active(act):  # type: ignore[no-untyped-def]
    c = 0
    for i in range(act.shape[0]):
        if act[i]:
            c += 1
    return c


@jit
def intruder_relative_state(envs, own, lat, lon, hdg, gs, active, nearest, out, count_out):  # type: ignore[no-untyped-def]
    """Ownship-relative geometry of the other aircraft, per (episode, ownship) row, into ``out`` (5, p, k).

    Rows: dist_km, cos_bearing, sin_bearing, x_dif, y_dif (the expressions of
    :func:`bluesky_gym.environments.vertical_cr.task.intruder_relative_state`). Row ``r`` is ownship slot
    ``own[r]`` of episode ``envs[r]``. With ``nearest`` False the other slots follow in slot
    order (the first k; the single-agent tasks' creation order); with ``nearest`` True they are
    the k nearest active ones by kwik distance (ties: lower slot first; empty slots last).
    ``count_out`` (p,) receives the number of other active aircraft.
    """
    m = lat.shape[1]
    k = out.shape[2]
    slots = scratch(m - 1, np.int64)
    act = scratch(m - 1, np.bool_)
    key = scratch(m - 1, np.float64)
    order = scratch(k, np.int64)
    best = scratch(k, np.float64)
    for r in grid_range(envs.shape[0]):
        e = envs[r]
        o = own[r]
        lat0, lon0, hdg0, gs0 = lat[e, o], lon[e, o], hdg[e, o], gs[e, o]
        _other_slots(active, e, o, slots, act)
        count_out[r] = _count_active(act)
        if nearest:
            for i in range(m - 1):
                if act[i]:  # (_closest reads the keys of active slots only)
                    key[i] = kwikdist_scalar(lat0, lon0, lat[e, slots[i]], lon[e, slots[i]])
            _closest(key, act, order, best)
        else:
            for i in range(k):
                order[i] = i
        for i in range(k):
            j = slots[order[i]]
            qdr, dist = kwikqdrdist_scalar(lat0, lon0, lat[e, j], lon[e, j])
            bearing = wrap180_scalar(hdg0 - qdr) * DEG2RAD
            difference = (hdg0 - hdg[e, j]) * DEG2RAD
            out[0, r, i] = dist * NM2KM
            out[1, r, i] = math.cos(bearing)
            out[2, r, i] = math.sin(bearing)
            out[3, r, i] = -math.cos(difference) * gs[e, j]
            out[4, r, i] = gs0 - math.sin(difference) * gs[e, j]


@jit
def goal_geometry(envs, own, lat, lon, hdg, goal_lat, goal_lon, drift_out, dist_out):  # type: ignore[no-untyped-def]
    """Drift wrap180(heading - kwik bearing to the goal) [deg] and kwik distance [NM] of each row's ownship to its goal.

    Row ``r``: ownship slot ``own[r]`` of episode ``envs[r]``, goal (``goal_lat[r]``, ``goal_lon[r]``).
    """
    for r in grid_range(envs.shape[0]):
        e = envs[r]
        o = own[r]
        qdr, dist = kwikqdrdist_scalar(lat[e, o], lon[e, o], goal_lat[r], goal_lon[r])
        drift_out[r] = wrap180_scalar(hdg[e, o] - qdr)
        dist_out[r] = dist


@jit_inline
def _velocity(hdg, tas, e, j):  # type: ignore[no-untyped-def]
    """TAS vector (north, east) [m/s] of slot ``j`` of episode ``e`` (heading and TAS, not track and GS, as the reference)."""
    return math.cos(hdg[e, j] * DEG2RAD) * tas[e, j], math.sin(hdg[e, j] * DEG2RAD) * tas[e, j]


# --- actions: heading and speed changes (SectorCR, Merge) ----------------------------------------
@jit_inline
def _heading_speed(hdg, cas, a_heading, a_speed, d_heading, d_speed):  # type: ignore[no-untyped-def]
    """HDG wrap180(hdg + d_heading a0) [deg]; SPD (CAS + d_speed a1) * 1.94384 kt, in m/s (* 0.514444)."""
    return wrap180_scalar(hdg + a_heading * d_heading), (cas + a_speed * d_speed) * MPS2KT * KTS


@jit
def heading_speed_targets(envs, own, action, hdg, cas, d_heading, d_speed, hdg_out, spd_out):  # type: ignore[no-untyped-def]
    """The heading [deg] and CAS [m/s] commanded by the clipped ``action`` (p, 2) of each row.

    Row ``r``: ownship slot ``own[r]`` of episode ``envs[r]`` (see
    :func:`bluesky_gym.tasks.base.command_heading_and_speed`).
    """
    for r in grid_range(envs.shape[0]):
        e = envs[r]
        o = own[r]
        hdg_out[r], spd_out[r] = _heading_speed(hdg[e, o], cas[e, o], action[r, 0], action[r, 1], d_heading, d_speed)


@jit
def command_heading_speed(envs, own, action, hdg, cas, d_heading, d_speed, ap_trk, swlnav, selspd, swvnavspd):  # type: ignore[no-untyped-def]
    """:func:`heading_speed_targets` given as the native core's HDG and SPD commands, written into its autopilot state.

    What :meth:`~bluesky_gym.core.Simulator.cmd_heading` and
    :meth:`~bluesky_gym.core.Simulator.cmd_speed` do in an airspace without wind: the track
    selected is the heading, LNAV and VNAV speed are switched off. The device step
    (:mod:`bluesky_gym.environments.sector_cr.device_step`) launches it on the simulator's device state.
    """
    for r in grid_range(envs.shape[0]):
        e = envs[r]
        o = own[r]
        trk, spd = _heading_speed(hdg[e, o], cas[e, o], action[r, 0], action[r, 1], d_heading, d_speed)
        select_track(e, o, trk, ap_trk, swlnav)
        select_speed(e, o, spd, selspd, swvnavspd)


# --- actions: a heading change from a reference heading (HorizontalCR, PlanWaypoint) -------------
@jit_inline
def _heading_target(reference, a, d_heading):  # type: ignore[no-untyped-def]
    """HDG [deg] = ``reference`` + ``d_heading`` a, not wrapped (the reference's stack command passes it on unchanged)."""
    return reference + a * d_heading


@jit
def heading_targets(reference, action, d_heading, out):  # type: ignore[no-untyped-def]
    """The heading [deg] the clipped ``action`` (rows, 1) commands in each row: :func:`_heading_target` of ``reference[r]``."""
    for r in grid_range(out.shape[0]):
        out[r] = _heading_target(reference[r], action[r, 0], d_heading)


@jit
def command_heading(envs, own, reference, action, d_heading, ap_trk, swlnav):  # type: ignore[no-untyped-def]
    """:func:`heading_targets` given as the native core's HDG command (:func:`~bluesky_gym.core.commands.select_track`).

    Row ``r``: slot ``own[r]`` of episode ``envs[r]``, its reference heading ``reference[r]``.
    The device steps of HorizontalCR and PlanWaypoint launch it on the simulator's device state.
    """
    for r in grid_range(envs.shape[0]):
        select_track(envs[r], own[r], _heading_target(reference[r], action[r, 0], d_heading), ap_trk, swlnav)


# --- SectorCR ----------------------------------------------------------------------------------
@jit
def sector_observe(envs, own, lat, lon, hdg, tas, active, wpt_lat, wpt_lon, center, scales, drift_out, own_out, intruder_out, count_out):  # type: ignore[no-untyped-def]
    """SectorCR's observation geometry of (episode ``envs[r]``, ownship slot ``own[r]``) rows.

    Args:
        envs: (p,) the episode of each row.
        own: (p,) the ownship slot of each row.
        lat: (n, m) latitudes [deg].
        lon: (n, m) longitudes [deg].
        hdg: (n, m) headings [deg].
        tas: (n, m) true airspeeds [m/s].
        active: (n, m) occupied slots.
        wpt_lat: (p,) latitude of each row's ownship waypoint [deg].
        wpt_lon: (p,) its longitude [deg].
        center: (lat, lon, cos(radians(lat))) of the flat projection.
        scales: (airspeed mean, airspeed std, position, vx, vy, distance mean, distance std).
        drift_out: (p,) drift [deg].
        own_out: (p, 3) cos(drift), sin(drift), airspeed.
        intruder_out: (p, 7, k) x_r, y_r, vx_r, vy_r, cos(track), sin(track), distances of the
            k closest other aircraft by flat distance (ties: lower slot first; when fewer are
            active, empty slots follow in slot order).
        count_out: (p,) number of other active aircraft.
    """
    spd_mean, spd_std, pos_scale, vx_scale, vy_scale, d_mean, d_std = scales
    clat, clon, ccos = center
    m = lat.shape[1]
    k = intruder_out.shape[2]
    slots = scratch(m - 1, np.int64)
    act = scratch(m - 1, np.bool_)
    key = scratch(m - 1, np.float64)
    order = scratch(k, np.int64)
    best = scratch(k, np.float64)
    rx = scratch(m - 1, np.float64)
    ry = scratch(m - 1, np.float64)
    for r in grid_range(envs.shape[0]):
        e = envs[r]
        o = own[r]
        qdr, _ = kwikqdrdist_scalar(lat[e, o], lon[e, o], wpt_lat[r], wpt_lon[r])
        drift = wrap180_scalar(hdg[e, o] - qdr)
        drift_out[r] = drift
        own_out[r, 0] = math.cos(drift * DEG2RAD)
        own_out[r, 1] = math.sin(drift * DEG2RAD)
        own_out[r, 2] = (tas[e, o] - spd_mean) / spd_std
        # Flat positions [m] around the sector centre (geometry.latlon_to_nm * 1852).
        x0 = (lat[e, o] - clat) * 60.0 * NM2KM * _M_PER_KM
        y0 = (lon[e, o] - clon) * 60.0 * ccos * NM2KM * _M_PER_KM
        _other_slots(active, e, o, slots, act)
        count_out[r] = _count_active(act)
        # Other slots j < o go to row entry j, j > o to j - 1: two contiguous loops (vectorisable).
        for j in range(o):
            rx[j] = (lat[e, j] - clat) * 60.0 * NM2KM * _M_PER_KM - x0
            ry[j] = (lon[e, j] - clon) * 60.0 * ccos * NM2KM * _M_PER_KM - y0
        for j in range(o + 1, m):
            rx[j - 1] = (lat[e, j] - clat) * 60.0 * NM2KM * _M_PER_KM - x0
            ry[j - 1] = (lon[e, j] - clon) * 60.0 * ccos * NM2KM * _M_PER_KM - y0
        for i in range(m - 1):
            key[i] = math.sqrt(rx[i] * rx[i] + ry[i] * ry[i])
        _closest(key, act, order, best)
        vxo, vyo = _velocity(hdg, tas, e, o)
        for i in range(k):
            q = order[i]
            vxj, vyj = _velocity(hdg, tas, e, slots[q])
            vx, vy = vxj - vxo, vyj - vyo  # relative TAS vector
            trk = math.atan2(vy, vx)
            intruder_out[r, 0, i] = rx[q] / pos_scale
            intruder_out[r, 1, i] = ry[q] / pos_scale
            intruder_out[r, 2, i] = vx / vx_scale
            intruder_out[r, 3, i] = vy / vy_scale
            intruder_out[r, 4, i] = math.cos(trk)
            intruder_out[r, 5, i] = math.sin(trk)
            intruder_out[r, 6, i] = (key[q] - d_mean) / d_std


@jit
def slots_in_polygons(envs, own, lat, lon, poly_lat, poly_lon, n_vertices, out):  # type: ignore[no-untyped-def]
    """Even-odd test of aircraft slot ``own[r]`` of episode ``envs[r]`` against that episode's polygon.

    ``poly_*`` are (n, V), ``n_vertices`` (n,), ``out`` (p,).
    """
    for r in grid_range(envs.shape[0]):
        e = envs[r]
        out[r] = polygon_contains(lat[e, own[r]], lon[e, own[r]], poly_lat[e], poly_lon[e], n_vertices[e])


@jit
def sector_reward(drift, los, drift_penalty, intrusion_penalty, reward_out, drift_out, intrusion_out, count_out):  # type: ignore[no-untyped-def]
    """SectorCR's reward of each row: ``drift_penalty`` |drift| [rad] and ``intrusion_penalty`` per intruder in LoS.

    ``drift`` (p,) [deg] and ``los`` (p, m) are the row's :func:`sector_observe` drift and
    :func:`kwik_separation` flags; out: the reward, its two components and the intruder count.
    """
    for r in grid_range(drift.shape[0]):
        count = 0
        for j in range(los.shape[1]):
            if los[r, j]:
                count += 1
        d = abs(drift[r] * DEG2RAD) * drift_penalty
        intrusion = count * intrusion_penalty + 0.0  # + 0.0: no intrusion gives +0.0, as the reference's integer 0
        drift_out[r] = d
        intrusion_out[r] = intrusion
        count_out[r] = count
        reward_out[r] = d + intrusion


@jit
def sector_episode_reward(  # type: ignore[no-untyped-def]
    envs,
    drift,
    count,
    inside,
    lat,
    lon,
    wpt_lat,
    wpt_lon,
    steps,
    time_limit,
    exit_ends,
    exit_margin,
    exit_penalty,
    drift_rad_sum,
    drift_rad_n,
    total_intrusions,
    reward,
    exit_out,
    terminated_out,
):
    """SectorCR's episode side of the reward of rows ``envs`` (the agent, slot 0): info sums, and ``-v1``'s sector exit.

    Adds |drift| [rad] and the intruder count to the episode sums. With ``exit_ends`` (``-v1``)
    leaving the sector (``inside`` False) terminates; unless the agent is within
    ``exit_margin`` [NM] (kwik) of its own waypoint, it adds ``exit_penalty`` per decision step
    left (``time_limit - (steps + 1)``, the step counts before this step's record) to ``reward``
    and ``exit_out``. Without it nothing terminates and ``exit_out`` is left alone.
    """
    for r in grid_range(envs.shape[0]):
        e = envs[r]
        drift_rad_sum[e] += abs(drift[r] * DEG2RAD)
        drift_rad_n[e] += 1
        total_intrusions[e] += count[r]
        if not exit_ends:
            terminated_out[r] = False
            continue
        left = not inside[r]
        at_exit = kwikdist_scalar(lat[e, 0], lon[e, 0], wpt_lat[e, 0], wpt_lon[e, 0]) < exit_margin
        steps_left = max(time_limit - (steps[e] + 1), 0)
        penalty = exit_penalty * steps_left if (left and not at_exit) else 0.0
        exit_out[r] = penalty
        reward[r] = reward[r] + penalty
        terminated_out[r] = left


# --- Merge -------------------------------------------------------------------------------------
@jit
def merge_observe(envs, own, lat, lon, hdg, tas, active, target_lat, target_lon, scales, own_out, intruder_out, count_out):  # type: ignore[no-untyped-def]
    """Merge's observation geometry of (episode ``envs[r]``, ownship slot ``own[r]``) rows.

    Args:
        envs: (p,) the episode of each row.
        own: (p,) the ownship slot of each row.
        lat: (n, m) latitudes [deg].
        lon: (n, m) longitudes [deg].
        hdg: (n, m) headings [deg].
        tas: (n, m) true airspeeds [m/s].
        active: (n, m) occupied slots.
        target_lat: (p,) latitude of each row's current target [deg].
        target_lon: (p,) its longitude [deg].
        scales: (position, speed, distance) divisors.
        own_out: (p, 4) drift [deg], target distance [NM], cos(drift), sin(drift).
        intruder_out: (p, 7, k) x_r, y_r, vx_r, vy_r, cos(track), sin(track), distances of the
            k closest other aircraft by kwik distance (ties: lower slot first; when fewer are
            active, empty slots follow in slot order).
        count_out: (p,) number of other active aircraft.
    """
    pos_scale, spd_scale, d_scale = scales
    m = lat.shape[1]
    k = intruder_out.shape[2]
    slots = scratch(m - 1, np.int64)
    act = scratch(m - 1, np.bool_)
    key = scratch(m - 1, np.float64)
    order = scratch(k, np.int64)
    best = scratch(k, np.float64)
    dlats = scratch(m - 1, np.float64)
    dlons = scratch(m - 1, np.float64)
    cavs = scratch(m - 1, np.float64)
    for r in grid_range(envs.shape[0]):
        e = envs[r]
        o = own[r]
        lat0, lon0 = lat[e, o], lon[e, o]
        qdr, dist = kwikqdrdist_scalar(lat0, lon0, target_lat[r], target_lon[r])
        drift = wrap180_scalar(hdg[e, o] - qdr)
        own_out[r, 0] = drift
        own_out[r, 1] = dist
        own_out[r, 2] = math.cos(drift * DEG2RAD)
        own_out[r, 3] = math.sin(drift * DEG2RAD)
        _other_slots(active, e, o, slots, act)
        count_out[r] = _count_active(act)
        for i in range(m - 1):
            # The kwik parts of each active pair once: the sort key is kwikdist_matrix's grouping,
            # the observed distance and bearing kwikqdrdist's.
            if act[i]:
                dlat, dlon, cavelat = _kwik_parts(lat0, lon0, lat[e, slots[i]], lon[e, slots[i]])
                dlats[i], dlons[i], cavs[i] = dlat, dlon, cavelat
                key[i] = _matrix_dist_of_parts(dlat, dlon, cavelat)
        _closest(key, act, order, best)
        vxo, vyo = _velocity(hdg, tas, e, o)
        for i in range(k):
            q = order[i]
            j = slots[q]
            if act[q]:
                dlat, dlon, cavelat = dlats[q], dlons[q], cavs[q]
            else:  # padding: an empty slot
                dlat, dlon, cavelat = _kwik_parts(lat0, lon0, lat[e, j], lon[e, j])
                key[q] = _matrix_dist_of_parts(dlat, dlon, cavelat)
            d_int = _dist_of_parts(dlat, dlon, cavelat)
            brg = _qdr_of_parts(dlat, dlon, cavelat)
            d_m = d_int * NM2KM * _M_PER_KM
            vxj, vyj = _velocity(hdg, tas, e, j)
            vx, vy = vxj - vxo, vyj - vyo  # relative TAS vector
            trk = math.atan2(vy, vx)
            intruder_out[r, 0, i] = d_m * math.cos(brg * DEG2RAD) / pos_scale
            intruder_out[r, 1, i] = d_m * math.sin(brg * DEG2RAD) / pos_scale
            intruder_out[r, 2, i] = vx / spd_scale
            intruder_out[r, 3, i] = vy / spd_scale
            intruder_out[r, 4, i] = math.cos(trk)
            intruder_out[r, 5, i] = math.sin(trk)
            intruder_out[r, 6, i] = key[q] / d_scale


@jit
def merge_targets(after, faf_lat, faf_lon, rwy_lat, rwy_lon, lat_out, lon_out):  # type: ignore[no-untyped-def]
    """Merge's current target of each row: the FAF, then the runway once the FAF was reached (``after[r]``) [deg]."""
    for r in grid_range(after.shape[0]):
        if after[r]:
            lat_out[r] = rwy_lat
            lon_out[r] = rwy_lon
        else:
            lat_out[r] = faf_lat
            lon_out[r] = faf_lon


@jit
def merge_faf_now(after, own, faf_margin, faf_now_out, after_out):  # type: ignore[no-untyped-def]
    """``-v1``'s FAF reached in this step: rows not past the FAF within ``faf_margin`` [NM] of it; ``after_out`` adds them.

    ``own`` is :func:`merge_observe`'s ``own_out`` (column 1: the distance to the target [NM]).
    """
    for r in grid_range(after.shape[0]):
        now = not after[r] and own[r, 1] < faf_margin
        faf_now_out[r] = now
        after_out[r] = after[r] or now


@jit
def merge_goal(after, own, faf_now, goal_margin, reached_out):  # type: ignore[no-untyped-def]
    """The runway goal of each row: past the FAF and within ``goal_margin`` [NM] of the target (``own[r, 1]``).

    Under ``-v1`` (``faf_now`` has a value per row) not in the step the FAF was reached: the goal
    counts from the next step, as in ``-v0``.
    """
    for r in grid_range(after.shape[0]):
        reached = after[r] and own[r, 1] < goal_margin
        if faf_now.shape[0] > 0 and faf_now[r]:
            reached = False
        reached_out[r] = reached


@jit
def merge_reward(  # type: ignore[no-untyped-def]
    own,
    after,
    faf_now,
    goal,
    los,
    faf_margin,
    reach_reward,
    drift_penalty,
    intrusion_penalty,
    reward_out,
    reach_out,
    drift_out,
    intrusion_out,
    reach_faf_out,
    near_runway_out,
    count_out,
):
    """Merge's reward of each row: FAF reach, drift and intrusion penalties.

    The FAF is reached now where ``faf_now[r]`` (``-v1``; ``faf_now`` empty: ``-v0``, a row not
    past the FAF within ``faf_margin`` [NM] of it); the runway where the goal is reached
    (``goal[r]``) and the FAF is not reached now. The reward is ``reach_reward`` on reaching the
    FAF, plus ``drift_penalty`` |drift| [rad] (``own[r, 0]`` [deg]), plus ``intrusion_penalty``
    per intruder in LoS. Out: the reward, its three components, the two reach flags and the
    intruder count.
    """
    for r in grid_range(after.shape[0]):
        if faf_now.shape[0] > 0:
            reach_faf = faf_now[r]
        else:
            reach_faf = own[r, 1] < faf_margin and not after[r]
        count = 0
        for j in range(los.shape[1]):
            if los[r, j]:
                count += 1
        reach = reach_reward if reach_faf else 0.0
        d = abs(own[r, 0] * DEG2RAD) * drift_penalty
        intrusion = count * intrusion_penalty + 0.0  # + 0.0: no intrusion gives +0.0, as the reference's integer 0
        reach_out[r] = reach
        drift_out[r] = d
        intrusion_out[r] = intrusion
        reach_faf_out[r] = reach_faf
        near_runway_out[r] = not reach_faf and goal[r]
        count_out[r] = count
        reward_out[r] = reach + d + intrusion


@jit
def merge_episode_sums(envs, own, reach_faf, near_runway, count, wpt_reach, faf_reached, drift_rad_sum, drift_rad_n, total_intrusions):  # type: ignore[no-untyped-def]
    """Merge's episode side of the reward of rows ``envs`` (the ownship): the FAF flags and the info sums.

    ``wpt_reach[e]`` becomes 1 when the FAF is reached; ``faf_reached[e]`` 1 then, or 2 on
    reaching the runway; |drift| [rad] (``own[r, 0]`` [deg]) and the intruder count are added to
    the episode sums.
    """
    for r in grid_range(envs.shape[0]):
        e = envs[r]
        if reach_faf[r]:
            wpt_reach[e] = 1
            faf_reached[e] = 1
        elif near_runway[r]:
            faf_reached[e] = 2
        drift_rad_sum[e] += abs(own[r, 0] * DEG2RAD)
        drift_rad_n[e] += 1
        total_intrusions[e] += count[r]


# --- array forms of the scenario and kwik geometry (tasks/geometry.py wraps these) -------------
@jit_inline
def _point_at_distance(lat: float, lon: float, d_km: float, bearing: float, radius_km: float) -> tuple[float, float]:
    """Great-circle destination (lat, lon) [deg] at ``d_km`` along ``bearing`` [deg] (spherical)."""
    lat1 = lat * DEG2RAD
    lon1 = lon * DEG2RAD
    a = bearing * DEG2RAD
    dr = d_km / radius_km
    lat2 = math.asin(math.sin(lat1) * math.cos(dr) + math.cos(lat1) * math.sin(dr) * math.cos(a))
    lon2 = lon1 + math.atan2(math.sin(a) * math.sin(dr) * math.cos(lat1), math.cos(dr) - math.sin(lat1) * math.sin(lat2))
    return lat2 * _DEG, lon2 * _DEG


@jit_inline
def initial_bearing_scalar(lat1: float, lon1: float, lat2: float, lon2: float) -> float:
    """Great-circle initial bearing [deg, 0..360) from point 1 to point 2 (:func:`bluesky_gym.tasks.geometry.initial_bearing`).

    The coordinates are converted to radians before the longitude difference is taken, in the
    reference's operation order.
    """
    p1 = lat1 * DEG2RAD
    l1 = lon1 * DEG2RAD
    p2 = lat2 * DEG2RAD
    l2 = lon2 * DEG2RAD
    delta_lon = l2 - l1
    x = math.sin(delta_lon) * math.cos(p2)
    y = math.cos(p1) * math.sin(p2) - math.sin(p1) * math.cos(p2) * math.cos(delta_lon)
    return _mod(math.atan2(x, y) * _DEG + 360.0, 360.0)


@jit_inline
def _at(a: Array, i: int, j: int) -> float:
    """``a[i, j]`` of a 2-D array broadcast against (i, j): a dimension of length 1 repeats."""
    return float(a[i if a.shape[0] > 1 else 0, j if a.shape[1] > 1 else 0])


@jit
def point_at_distance(lat: Array, lon: Array, d_km: Array, bearing: Array, radius_km: float, lat_out: Array, lon_out: Array) -> None:
    """:func:`bluesky_gym.tasks.geometry.point_at_distance` of 2-D inputs broadcast to the outputs' shape."""
    for i in grid_range(lat_out.shape[0]):
        for j in range(lat_out.shape[1]):
            lat_out[i, j], lon_out[i, j] = _point_at_distance(_at(lat, i, j), _at(lon, i, j), _at(d_km, i, j), _at(bearing, i, j), radius_km)


@jit
def initial_bearing(lat1: Array, lon1: Array, lat2: Array, lon2: Array, out: Array) -> None:
    """:func:`bluesky_gym.tasks.geometry.initial_bearing` of 2-D inputs broadcast to the output's shape."""
    for i in grid_range(out.shape[0]):
        for j in range(out.shape[1]):
            out[i, j] = initial_bearing_scalar(_at(lat1, i, j), _at(lon1, i, j), _at(lat2, i, j), _at(lon2, i, j))


@jit
def kwikdist(lata: Array, lona: Array, latb: Array, lonb: Array, dist_out: Array) -> None:
    """:func:`bluesky_gym.tasks.geometry.ref_kwikdist` of 2-D inputs broadcast to the output's shape."""
    for i in grid_range(dist_out.shape[0]):
        for j in range(dist_out.shape[1]):
            dist_out[i, j] = kwikdist_scalar(_at(lata, i, j), _at(lona, i, j), _at(latb, i, j), _at(lonb, i, j))


@jit
def kwikqdrdist(lata: Array, lona: Array, latb: Array, lonb: Array, qdr_out: Array, dist_out: Array) -> None:
    """:func:`bluesky_gym.tasks.geometry.ref_kwikqdrdist` of 2-D inputs broadcast to the outputs' shape."""
    for i in grid_range(dist_out.shape[0]):
        for j in range(dist_out.shape[1]):
            qdr_out[i, j], dist_out[i, j] = kwikqdrdist_scalar(_at(lata, i, j), _at(lona, i, j), _at(latb, i, j), _at(lonb, i, j))


@jit_inline
def _mean(total, count, empty):  # type: ignore[no-untyped-def]
    """``total / count``, the mean of ``count`` samples summed in ``total``; ``empty`` without a sample."""
    return total / count if count > 0 else empty


@jit_inline
def _episode_time(steps, dt, action_frequency):  # type: ignore[no-untyped-def]
    """Simulated time [s] of ``steps`` decision steps of ``action_frequency`` physics steps of ``dt`` [s]."""
    return steps * dt * action_frequency


# --- episode statistics -------------------------------------------------------------------------
@jit
def record_step(  # type: ignore[no-untyped-def]
    envs,
    separation,
    los,
    stepped,
    reward,
    drift,
    goal,
    dt,
    action_frequency,
    in_los,
    min_sep,
    los_count,
    los_steps,
    steps,
    total_reward,
    drift_sum,
    drift_n,
    time_to_goal,
):
    """:meth:`bluesky_gym.tasks.base.Task.record`: the episode statistics of rows ``envs`` from a step's geometry.

    Always: the smallest separation, new losses of separation (pairs not in LoS before) and the
    LoS flags. When ``stepped`` (a decision step, not a reset) also the step count, return, steps
    in LoS, |drift| (when ``drift`` has a value per row) and the time to the goal of rows that
    reach it for the first time.
    """
    for r in grid_range(envs.shape[0]):
        e = envs[r]
        dmin = np.inf
        new = 0
        any_los = False
        for j in range(separation.shape[1]):
            d = separation[r, j]
            if d < dmin or d != d:  # NaN propagates as in np.min
                dmin = d
            flag = los[r, j]
            if flag:
                any_los = True
                if not in_los[e, j]:
                    new += 1
            in_los[e, j] = flag
        m = min_sep[e]
        if dmin < m or dmin != dmin:
            min_sep[e] = dmin
        los_count[e] += new
        if not stepped:
            continue
        steps[e] += 1
        total_reward[e] += reward[r]
        if any_los:
            los_steps[e] += 1
        if drift.shape[0] > 0:
            drift_sum[e] += abs(drift[r])
            drift_n[e] += 1
        if goal[r] and time_to_goal[e] != time_to_goal[e]:
            time_to_goal[e] = _episode_time(steps[e], dt, action_frequency)


# --- the step's end: truncation, episode outputs, the -v1 observation bounds -----------------------
@jit
def truncation(steps, time_limit, terminated, cut, truncated_out):  # type: ignore[no-untyped-def]
    """:meth:`bluesky_gym.tasks.base.Task.step`'s truncation of each episode ``e``.

    Truncated: not terminated, and at the time limit (``steps[e] >= time_limit``, the decision
    steps counted by this step's :func:`record_step`) or cut by the task (``cut[e]``,
    :meth:`~bluesky_gym.tasks.base.Task.truncate`).
    """
    for e in grid_range(truncated_out.shape[0]):
        truncated_out[e] = not terminated[e] and (steps[e] >= time_limit or cut[e])


@jit
def sample_means(total, count, empty, out):  # type: ignore[no-untyped-def]
    """The mean ``total[e] / count[e]`` of the samples an episode summed, or ``empty`` where it has none (``count[e] == 0``)."""
    for e in grid_range(out.shape[0]):
        out[e] = _mean(total[e], count[e], empty)


@jit
def episode_kpis(  # type: ignore[no-untyped-def]
    steps,
    los_count,
    los_steps,
    min_sep,
    drift_sum,
    drift_n,
    distflown,
    fuelburn,
    dt,
    action_frequency,
    los_count_out,
    los_steps_out,
    min_sep_out,
    drift_out,
    track_out,
    fuel_out,
    time_out,
):
    """The KPIs every task reports (:meth:`bluesky_gym.tasks.base.Task.kpis`), from the episode statistics of :func:`record_step`.

    Per episode ``e``: losses of separation and steps in one (as floats), the smallest separation
    [NM], the mean |drift| [deg] (NaN without a sample), the ownship's (slot 0) distance flown
    [km] (``distflown`` [m]) and fuel burned [kg], and the episode's simulated time [s].
    """
    for e in grid_range(steps.shape[0]):
        los_count_out[e] = los_count[e]
        los_steps_out[e] = los_steps[e]
        min_sep_out[e] = min_sep[e]
        drift_out[e] = _mean(drift_sum[e], drift_n[e], np.nan)
        track_out[e] = distflown[e, 0] / _M_PER_KM
        fuel_out[e] = fuelburn[e, 0]
        time_out[e] = _episode_time(steps[e], dt, action_frequency)


@jit
def extra_track(distflown, route_km, out):  # type: ignore[no-untyped-def]
    """The extra track of each episode [km]: the ownship's (slot 0) distance flown minus the episode's nominal route.

    ``distflown`` (n, m) [m]; ``route_km`` (n,) [km] (:attr:`bluesky_gym.tasks.base.Task.route_km_array`).
    """
    for e in grid_range(out.shape[0]):
        out[e] = distflown[e, 0] / _M_PER_KM - route_km[e]


@jit
def goal_kpis(time_to_goal, success_out, time_out):  # type: ignore[no-untyped-def]
    """The KPIs of a task with a goal (:meth:`bluesky_gym.tasks.base.Task.kpis`).

    Per episode: 1.0 where the goal was reached (it has a time to the goal), else 0.0, and that
    time [s] (NaN: not reached).
    """
    for e in grid_range(time_to_goal.shape[0]):
        t = time_to_goal[e]
        success_out[e] = 0.0 if t != t else 1.0
        time_out[e] = t


@jit
def clip_to_bounds(values, low, high, out):  # type: ignore[no-untyped-def]
    """``values`` (rows, k) clipped to ``[low[j], high[j]]`` in column j: ``np.minimum(np.maximum(values, low), high)``.

    As numpy's: NaN stays NaN, and a value equal to a bound gives the bound (its sign of zero).
    ``out`` may be ``values``.
    """
    for r in grid_range(values.shape[0]):
        for j in range(values.shape[1]):
            v = values[r, j]
            if not (v > low[j] or v != v):
                v = low[j]
            if not (v < high[j] or v != v):
                v = high[j]
            out[r, j] = v
