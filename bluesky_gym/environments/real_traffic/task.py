"""RealTrafficCREnv-v0: fly a recorded flight through the recorded traffic around it, keeping separation.

Every episode is a window of recorded ADS-B traffic (:mod:`bluesky_gym.realtraffic`): one flight
recorded over the whole window is the ownship, the recorded aircraft around it fly their recorded
routes and profiles (:class:`~bluesky_gym.realtraffic.scenario.WindowPlayer`). The agent steers
the ownship relative to its own recorded path (heading and speed, optionally altitude offsets);
with a zero action it follows the recording. Reward: stay near the recorded route and keep
5 NM / 1000 ft from every other aircraft.

Episodes are drawn from the windows of a split: ``split="train"`` or ``"test"`` (or ``"auto"``,
where the environment picks the test split for episodes reset with a seed of the evaluation
range, see :meth:`RealTrafficTask.set_test_split`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from bluesky_gym.core.commands import select_altitude, select_speed, select_track
from bluesky_gym.core.jit import grid_range, jit, jit_inline, scratch
from bluesky_gym.core.physics import Physics
from bluesky_gym.core.scalar import clip, maximum, minimum, mod, sign
from bluesky_gym.core.units import FT, KTS, NM
from bluesky_gym.realtraffic.cache import collection_path, combine, load_collection, unprepared
from bluesky_gym.realtraffic.flights import RecordedFlights, lerp, sample_weight
from bluesky_gym.realtraffic.scenario import (
    MAX_ROUTE_POINTS,
    SEPARATION_NM,
    SEPARATION_VERTICAL,
    Window,
    WindowPlayer,
    profile_commands,
    profile_targets,
    split_windows,
    windows,
)
from bluesky_gym.realtraffic.sources import SAMPLE_COLLECTIONS
from bluesky_gym.tasks.base import (
    Array,
    BoolArray,
    BoxSpec,
    StepGeometry,
    Task,
    TaskConfig,
    check_int,
    check_range,
    kwik_separation,
)
from bluesky_gym.tasks.compiled import DEG2RAD, initial_bearing_scalar, sample_means, wrap180_scalar

SPLITS = ("auto", "train", "test")
LABELS = ("near", "all", "none")
SPLIT_BY = ("time", "collection")
DECISION_STEP = 10.0  # s
WINDOW_STRIDE = 60.0  # s between window starts

# MDP
INTRUSION_NM = SEPARATION_NM  # NM horizontal separation
INTRUSION_VERTICAL = SEPARATION_VERTICAL  # m vertical separation
D_HEADING = 30.0  # deg of heading offset from the recorded path per unit action
D_SPEED = 10.0  # m/s CAS offset from the recorded speed per unit action
D_ALTITUDE = 1000.0 * FT  # m altitude offset from the recorded profile per unit action
CARROT_S = 60.0  # s: the ownship's heading reference is the recorded position this far ahead
ROUTE_PENALTY = -0.1  # per NM of distance from the recorded route, per step
ROUTE_PENALTY_CAP = 20.0  # NM: larger distances count as this
INTRUSION_PENALTY = -1.0  # per aircraft within 5 NM and 1000 ft, per step
NUM_INTRUDERS = 5  # closest aircraft in the observation
INTRUDER_FEATURES = 7  # values per intruder: east, north offset, relative velocity east, north, relative altitude, distance, present
ROUTE_SPAN_S = 120.0  # s: the route near the ownship is the recording from now - span to now + span
POSITION_SCALE = 20.0  # NM
VELOCITY_SCALE = 250.0  # m/s
ALTITUDE_SCALE = 3000.0  # m
SPEED_SCALE = 20.0  # m/s
ROUTE_SCALE = 5.0  # NM
VS_SCALE = 10.0  # m/s
EARTH_RADIUS_NM = 6371000.0 / NM
OWNSHIP_FEATURES = 6  # route deviation, cos and sin of the drift, CAS error, altitude error, vertical speed
AVERAGE_ROUTE_EMPTY = 0.0  # the info's average route deviation before the first decision step
MIN_SEGMENT2 = 1e-12  # NM^2: floor of a recorded route segment's squared length (a repeated sample)
# -v1 declared bounds (float32_spaces), chosen to hold for every reachable state:
MAX_SPEED = 700.0 * KTS  # m/s: recorded ground speeds stay below 700 kt (the cleaning drops faster samples); so do the simulated TAS
ROUTE_BOUND = 10.0  # the route deviation is clipped to +-10 (50 NM) in every version
SPEED_ERROR_BOUND = 20.0  # CAS minus recorded CAS (both below MAX_SPEED), / SPEED_SCALE: +-400 m/s
ALTITUDE_BOUND = 5.0  # altitude differences: +-15 km (the simulated aircraft stay below their ceiling, 12.6 km at most)
VS_BOUND = 4.0  # vertical speed: +-40 m/s (the types' largest vsmax is about 19 m/s)
VELOCITY_BOUND = 4.0  # relative ground velocity: +-1000 m/s (twice MAX_SPEED and more)


@dataclass(frozen=True)
class RealTrafficConfig(TaskConfig):
    """Scenario options of the real-traffic task.

    Attributes:
        collections: Recorded collections: ``traffic`` sample names (cleaned once into the cache
            directory) or paths of ``.npz`` files written by ``bluesky-gym realtraffic prepare``.
        split: ``"train"``, ``"test"`` or ``"auto"`` (test for evaluation-range seeds, else train).
        split_by: ``"time"`` (the last ``test_fraction`` of every collection's time is the test
            part) or ``"collection"`` (the ``test_collections`` are the test part).
        test_fraction: Share of each collection's time held out (``split_by="time"``).
        test_collections: Held-out collections (``split_by="collection"``).
        window_s: Episode length [s] (a multiple of the 10 s decision step).
        radius_nm: Traffic within this distance of the ownship at some time of the window is in the scenario.
        min_traffic: Windows with fewer aircraft around the ownship are not used.
        max_traffic: At most this many (the closest) other aircraft per episode.
        altitude_action: Add a third action, an altitude offset from the recorded profile.
        cache_dir: Directory of the cleaned collections (default: see :mod:`bluesky_gym.realtraffic.cache`).
        labels: Callsign labels in rendered frames: ``"near"`` (aircraft within 20 NM of the
            ownship, and any in a loss of separation), ``"all"`` or ``"none"``; in the
            ``"human"`` window the aircraft under the mouse pointer is labelled whatever this says.
    """

    collections: tuple[str, ...] = SAMPLE_COLLECTIONS
    split: str = "auto"
    split_by: str = "time"
    test_fraction: float = 0.3
    test_collections: tuple[str, ...] = ("quickstart",)
    window_s: float = 600.0
    radius_nm: float = 30.0
    min_traffic: int = 2
    max_traffic: int = 24
    altitude_action: bool = False
    cache_dir: str | None = None
    labels: str = "near"

    def __post_init__(self) -> None:
        super().__post_init__()  # the switches (float32_spaces, altitude_action) must be True or False
        for name in ("collections", "test_collections"):
            value = getattr(self, name)
            if isinstance(value, str):
                object.__setattr__(self, name, (value,))
            elif isinstance(value, list):
                object.__setattr__(self, name, tuple(value))

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first invalid option."""
        if not self.collections or not all(isinstance(c, str) and c for c in self.collections):
            raise ValueError(f"collections must be a non-empty tuple of names or .npz paths, got {self.collections!r}")
        if self.cache_dir is not None and not isinstance(self.cache_dir, str):
            raise ValueError(f"cache_dir must be a path string or None, got {self.cache_dir!r}")
        _check_no_repeat("collections", self.collections, self.cache_dir)
        _check_no_repeat("test_collections", self.test_collections, self.cache_dir)
        if self.split not in SPLITS:
            raise ValueError(f"split must be one of {SPLITS}, got {self.split!r}")
        if self.split_by not in SPLIT_BY:
            raise ValueError(f"split_by must be one of {SPLIT_BY}, got {self.split_by!r}")
        check_range("test_fraction", self.test_fraction, 0.0, 1.0, strict_low=True)
        if self.test_fraction >= 1.0:
            raise ValueError(f"test_fraction must be < 1, got {self.test_fraction}")
        if self.split_by == "collection":
            unknown = [c for c in self.test_collections if c not in self.collections]
            if unknown or not self.test_collections or set(self.test_collections) == set(self.collections):
                raise ValueError(f"test_collections must be some but not all of collections {self.collections}, got {self.test_collections!r}")
        check_range("window_s", self.window_s, DECISION_STEP)
        if abs(self.window_s / DECISION_STEP - round(self.window_s / DECISION_STEP)) > 1e-9:
            raise ValueError(f"window_s must be a multiple of {DECISION_STEP:.0f} s, got {self.window_s}")
        check_range("radius_nm", self.radius_nm, 0.0, strict_low=True)
        check_int("min_traffic", self.min_traffic, 0)
        check_int("max_traffic", self.max_traffic, 1, 200)
        if self.min_traffic > self.max_traffic:
            raise ValueError(f"min_traffic ({self.min_traffic}) must be <= max_traffic ({self.max_traffic})")
        if not isinstance(self.altitude_action, bool):
            raise ValueError(f"altitude_action must be True or False, got {self.altitude_action!r}")
        if self.labels not in LABELS:
            raise ValueError(f"labels must be one of {LABELS}, got {self.labels!r}")


def _check_no_repeat(option: str, names: tuple[str, ...], directory: str | None) -> None:
    """Refuse a collection named twice (by the same name, or two paths of one file): its windows would be played twice."""
    seen: dict[Path, str] = {}
    for name in names:
        if not isinstance(name, str) or not name:
            continue  # reported by the type check
        key = collection_path(name, directory).expanduser().resolve()
        if key in seen:
            same = repr(name) if seen[key] == name else f"{seen[key]!r} and {name!r}"
            raise ValueError(f"{option} name {same} more than once (one file, {key}); give every collection once")
        seen[key] = name


@dataclass(frozen=True)
class EpisodeData:
    """The recorded flights of a configuration and its windows, per split."""

    flights: RecordedFlights
    train: tuple[Window, ...]
    test: tuple[Window, ...]


def episode_data(config: RealTrafficConfig) -> EpisodeData:
    """Flights and train/test windows of ``config``.

    Computed once per process for the options that shape them and the collection files they are
    read from: another cache directory (``cache_dir``, or ``BLUESKY_GYM_CACHE`` when it is None) or
    a rewritten file is read again.
    """
    files = []
    for name in config.collections:
        path = collection_path(name, config.cache_dir)
        stat = path.stat() if path.exists() else None
        files.append((str(path), stat.st_mtime_ns if stat else -1, stat.st_size if stat else -1))
    return _episode_data(dataclasses.replace(config, split="auto", altitude_action=False, labels="near"), tuple(files))


@lru_cache(maxsize=4)
def _episode_data(config: RealTrafficConfig, files: tuple[tuple[str, int, int], ...]) -> EpisodeData:
    del files  # part of the cache key
    parts = [load_collection(name, config.cache_dir) for name in config.collections]
    flights, shifts = combine(parts, "+".join(config.collections))
    train: list[Window] = []
    test: list[Window] = []
    base = 0
    for name, part, shift in zip(config.collections, parts, shifts):
        found = windows(part, config.window_s, WINDOW_STRIDE, config.radius_nm, config.min_traffic, config.max_traffic)
        moved = [Window(w.start + shift, w.duration, w.ownship + base, tuple(t + base for t in w.traffic)) for w in found]
        if config.split_by == "time":
            tr, te = split_windows(moved, config.test_fraction, float(part.t0.min()) + shift, float(part.t_end.max()) + shift)
        else:
            tr, te = ([], moved) if name in config.test_collections else (moved, [])
        train += tr
        test += te
        base += part.n_flights
    if not train or not test:
        raise ValueError(
            f"collections {config.collections} give {len(train)} training and {len(test)} test windows of {config.window_s:.0f} s "
            f"with at least {config.min_traffic} aircraft within {config.radius_nm} NM; both splits need some"
        )
    return EpisodeData(flights, tuple(train), tuple(test))


@dataclass(frozen=True)
class RealTrafficGeometry(StepGeometry):
    """The step's geometry: route deviation and the closest aircraft of every ownship row.

    Attributes:
        own: (rows,) ownship slot of each row.
        route_nm: (rows,) signed distance from the recorded route [NM] (positive: right of it).
        cas_error: (rows,) CAS minus the recorded speed [m/s].
        alt_error: (rows,) altitude minus the recorded altitude [m].
        intruders: (rows, NUM_INTRUDERS, 7) closest aircraft (see the environment's observation).
        ownship: (rows, 6) the observation's ``ownship`` entry (see the environment's observation).
    """

    own: NDArray[np.int64]
    route_nm: Array
    cas_error: Array
    alt_error: Array
    intruders: Array
    ownship: Array


# --- the step's rules as kernels: the CPU task and the device step run the same ---------------------
@jit_inline
def _less(a, b):
    """The sort order of numpy of floats: NaN after everything."""
    return a < b or (b != b and a == a)


@jit_inline
def _route_deviation(t0, offset, period, rec_lat, rec_lon, f, now, offsets, lat0, lon0, coslat):
    """Signed distance [NM] of the point (lat0, lon0) from flight ``f``'s recorded route at ``now + offsets`` (positive: right of it).

    The recorded positions in a flat frame around the point [NM]; the closest of their segments
    (the first, on a tie); the side from the cross product with it.
    """
    best = np.inf
    best_dx = best_dy = best_x0 = best_y0 = 0.0
    xp = yp = 0.0
    for k in range(offsets.shape[0]):
        i0, w = sample_weight(t0, offset, period, f, now + offsets[k])
        x = wrap180_scalar(lerp(rec_lon, i0, w) - lon0) * 60.0 * coslat
        y = (lerp(rec_lat, i0, w) - lat0) * 60.0
        if k > 0:
            dx = x - xp
            dy = y - yp
            seg2 = maximum(dx * dx + dy * dy, MIN_SEGMENT2)
            u = clip(-(xp * dx + yp * dy) / seg2, 0.0, 1.0)
            d = math.hypot(xp + u * dx, yp + u * dy)
            if k == 1 or (best == best and (d != d or d < best)):  # np.argmin: the first smallest, or the first NaN
                best, best_dx, best_dy, best_x0, best_y0 = d, dx, dy, xp, yp
        xp = x
        yp = y
    side = sign(best_dx * (0.0 - best_y0) - best_dy * (0.0 - best_x0))  # > 0: left of the route
    return -side * best


@jit
def measure_rows(
    envs,
    own,
    start,
    elapsed,
    flight,
    t0,
    offset,
    period,
    rec_lat,
    rec_lon,
    rec_alt,
    rec_gs,
    offsets,
    lat,
    lon,
    alt,
    hdg,
    cas,
    vs,
    gseast,
    gsnorth,
    separation,
    route_out,
    drift_out,
    cas_error_out,
    alt_error_out,
    ownship_out,
    intruder_out,
):
    """:func:`measure` of rows (episode ``envs[r]``, ownship slot ``own[r]``) from their separations [NM].

    The separations are :func:`~bluesky_gym.tasks.compiled.kwik_separation`'s.

    The route deviation [NM] (recorded route from ``now + offsets[0]`` to ``now + offsets[-1]``),
    the drift from the bearing to the recorded position :data:`CARROT_S` ahead [deg], the CAS and
    altitude errors from the recorded profile's targets, the observation's ``ownship`` entry
    and the :data:`NUM_INTRUDERS` closest aircraft (a stable sort of the separations; an empty
    row is zeros). Episode ``e``'s recorded-time clock is ``start[e] + elapsed[e]``.
    """
    best = scratch(NUM_INTRUDERS, np.float64)
    order = scratch(NUM_INTRUDERS, np.int64)
    for r in grid_range(envs.shape[0]):
        e = envs[r]
        o = own[r]
        now = start[e] + elapsed[e]
        f = flight[e, o]
        lat0 = lat[e, o]
        lon0 = lon[e, o]
        coslat = math.cos(lat0 * DEG2RAD)
        route = _route_deviation(t0, offset, period, rec_lat, rec_lon, f, now, offsets, lat0, lon0, coslat)
        sched_alt, sched_cas = profile_targets(t0, offset, period, rec_alt, rec_gs, f, now)
        i0, w = sample_weight(t0, offset, period, f, now + CARROT_S)
        drift = wrap180_scalar(hdg[e, o] - initial_bearing_scalar(lat0, lon0, lerp(rec_lat, i0, w), lerp(rec_lon, i0, w)))
        cas_error = cas[e, o] - sched_cas
        alt_error = alt[e, o] - sched_alt
        route_out[r] = route
        drift_out[r] = drift
        cas_error_out[r] = cas_error
        alt_error_out[r] = alt_error
        rad = drift * DEG2RAD
        ownship_out[r, 0] = clip(route / ROUTE_SCALE, -ROUTE_BOUND, ROUTE_BOUND)
        ownship_out[r, 1] = math.cos(rad)
        ownship_out[r, 2] = math.sin(rad)
        ownship_out[r, 3] = cas_error / SPEED_SCALE
        ownship_out[r, 4] = alt_error / ALTITUDE_SCALE
        ownship_out[r, 5] = vs[e, o] / VS_SCALE
        # the closest aircraft: the first NUM_INTRUDERS of a stable sort of the row's separations
        filled = 0
        for j in range(separation.shape[1]):
            d = separation[r, j]
            if filled < NUM_INTRUDERS:
                pos = filled
                filled += 1
            elif _less(d, best[NUM_INTRUDERS - 1]):
                pos = NUM_INTRUDERS - 1
            else:
                continue
            while pos > 0 and _less(d, best[pos - 1]):
                best[pos] = best[pos - 1]
                order[pos] = order[pos - 1]
                pos -= 1
            best[pos] = d
            order[pos] = j
        for q in range(NUM_INTRUDERS):
            present = q < filled and not math.isinf(best[q]) and not math.isnan(best[q])
            if present:
                j = order[q]
                intruder_out[r, q, 0] = wrap180_scalar(lon[e, j] - lon0) * 60.0 * coslat / POSITION_SCALE
                intruder_out[r, q, 1] = (lat[e, j] - lat0) * 60.0 / POSITION_SCALE
                intruder_out[r, q, 2] = (gseast[e, j] - gseast[e, o]) / VELOCITY_SCALE
                intruder_out[r, q, 3] = (gsnorth[e, j] - gsnorth[e, o]) / VELOCITY_SCALE
                intruder_out[r, q, 4] = (alt[e, j] - alt[e, o]) / ALTITUDE_SCALE
                intruder_out[r, q, 5] = best[q] / POSITION_SCALE
                intruder_out[r, q, 6] = 1.0
            else:
                for c in range(INTRUDER_FEATURES):
                    intruder_out[r, q, c] = 0.0


@jit
def reward_rows(route_nm, los, reward_out, route_out, intrusion_out):
    """:func:`reward` of each row: route penalty (capped), intrusion penalty per aircraft in a loss of separation, and their sum."""
    for r in grid_range(route_nm.shape[0]):
        count = 0
        for j in range(los.shape[1]):
            if los[r, j]:
                count += 1
        route = ROUTE_PENALTY * minimum(abs(route_nm[r]), ROUTE_PENALTY_CAP)
        intrusion = INTRUSION_PENALTY * count
        route_out[r] = route
        intrusion_out[r] = intrusion
        reward_out[r] = route + intrusion


@jit
def episode_sums(envs, route_nm, los, route_sum, intrusions):
    """The info's sums of episode ``envs[r]`` (:meth:`RealTrafficTask.reward`): |route deviation| [NM] and aircraft in a loss of separation."""
    for r in grid_range(envs.shape[0]):
        e = envs[r]
        count = 0
        for j in range(los.shape[1]):
            if los[r, j]:
                count += 1
        route_sum[e] += abs(route_nm[r])
        intrusions[e] += count


@jit_inline
def _steering(t0, offset, period, rec_lat, rec_lon, rec_alt, rec_gs, f, now, lat, lon, alt, vsmax, a_heading, a_speed, a_altitude):
    """:func:`steer`'s commands of one aircraft: HDG [deg], ALT [m] with its vertical speed [m/s] (0: none), SPD (CAS [m/s])."""
    i0, w = sample_weight(t0, offset, period, f, now + CARROT_S)
    bearing = initial_bearing_scalar(lat, lon, lerp(rec_lat, i0, w), lerp(rec_lon, i0, w))
    hdg = mod(bearing + D_HEADING * a_heading, 360.0)
    target, vs, spd = profile_commands(t0, offset, period, rec_alt, rec_gs, f, now, alt, vsmax, a_altitude, D_SPEED * a_speed)
    return hdg, target, vs, spd


@jit_inline
def _altitude_offset(action, r):
    """The altitude offset [m] of row ``r``'s action (0 without an altitude action)."""
    return D_ALTITUDE * action[r, 2] if action.shape[1] > 2 else 0.0


@jit
def steering_rows(
    envs,
    own,
    action,
    start,
    elapsed,
    flight,
    vsmax,
    t0,
    offset,
    period,
    rec_lat,
    rec_lon,
    rec_alt,
    rec_gs,
    lat,
    lon,
    alt,
    hdg_out,
    alt_out,
    vs_out,
    spd_out,
):
    """:func:`steer`'s commands of rows (episode ``envs[r]``, slot ``own[r]``, clipped ``action[r]``), given to the physics by the host."""
    for r in grid_range(envs.shape[0]):
        e = envs[r]
        o = own[r]
        hdg_out[r], alt_out[r], vs_out[r], spd_out[r] = _steering(
            t0, offset, period, rec_lat, rec_lon, rec_alt, rec_gs, flight[e, o], start[e] + elapsed[e], lat[e, o], lon[e, o], alt[e, o],
            vsmax[e, o], action[r, 0], action[r, 1], _altitude_offset(action, r),
        )  # fmt: skip


@jit
def steer_commands(
    envs, own, action, start, elapsed, flight, vsmax, t0, offset, period, rec_lat, rec_lon, rec_alt, rec_gs, lat, lon, alt,
    ap_trk, swlnav, selalt, swvnav, selvs, selspd, swvnavspd,
):  # fmt: skip
    """:func:`steering_rows` written into the autopilot state as the core's HDG (no wind), ALT and SPD commands (the device step's form)."""
    for r in grid_range(envs.shape[0]):
        e = envs[r]
        o = own[r]
        hdg, target, vs, spd = _steering(
            t0, offset, period, rec_lat, rec_lon, rec_alt, rec_gs, flight[e, o], start[e] + elapsed[e], lat[e, o], lon[e, o], alt[e, o],
            vsmax[e, o], action[r, 0], action[r, 1], _altitude_offset(action, r),
        )  # fmt: skip
        select_track(e, o, hdg, ap_trk, swlnav)
        select_altitude(e, o, target, vs, alt, selalt, swvnav, selvs)
        select_speed(e, o, spd, selspd, swvnavspd)


def route_offsets(period: float) -> Array:
    """Times [s] relative to now of the recorded positions that make the route near the ownship (every ``period`` within :data:`ROUTE_SPAN_S`)."""
    return np.arange(-ROUTE_SPAN_S, ROUTE_SPAN_S + 1e-9, period)


def measure(task: RealTrafficTask, envs: NDArray[np.int64], own: NDArray[np.int64]) -> RealTrafficGeometry:
    """Geometry of rows (episode ``envs[r]``, ownship slot ``own[r]``).

    The kernels :func:`~bluesky_gym.tasks.compiled.kwik_separation` and :func:`measure_rows`.
    """
    sim = task.sim
    player = task.player
    sep, los = kwik_separation(sim, envs, own, INTRUSION_NM, INTRUSION_VERTICAL)
    p = len(envs)
    route, drift, cas_error, alt_error = np.empty(p), np.empty(p), np.empty(p), np.empty(p)
    ownship, intruders = np.empty((p, OWNSHIP_FEATURES)), np.empty((p, NUM_INTRUDERS, INTRUDER_FEATURES))
    f = task.flights
    measure_rows(
        envs, own, player.start, player.elapsed, player.flight, f.t0, f.offset, float(f.period), f.lat, f.lon, f.alt, f.gs, task.route_offsets,
        sim.lat, sim.lon, sim.alt, sim.hdg, sim.cas, sim.vs, sim.gseast, sim.gsnorth, sep, route, drift, cas_error, alt_error, ownship, intruders,
    )  # fmt: skip
    return RealTrafficGeometry(
        envs=envs,
        separation_nm=sep,
        los=los,
        drift_deg=drift,
        goal_reached=np.zeros(p, bool),
        own=own,
        route_nm=route,
        cas_error=cas_error,
        alt_error=alt_error,
        intruders=intruders,
        ownship=ownship,
    )


def observation(task: RealTrafficTask, g: RealTrafficGeometry) -> dict[str, Any]:
    """Observation of the rows of ``g`` (numpy arrays or tensors): the measured entries; ``-v1``: the intruder rows as one vector."""
    intruders = g.intruders
    if task.config.float32_spaces:  # -v1: one vector of the rows, intruder by intruder
        intruders = intruders.reshape(int(g.envs.shape[0]), NUM_INTRUDERS * INTRUDER_FEATURES)
    return {"ownship": g.ownship, "intruders": intruders}


def reward(g: RealTrafficGeometry) -> tuple[Array, dict[str, Array]]:
    """Reward of the rows of ``g`` and its components (route, intrusion): the kernel :func:`reward_rows`."""
    p = len(g.envs)
    r, route, intrusion = np.empty(p), np.empty(p), np.empty(p)
    reward_rows(g.route_nm, g.los, r, route, intrusion)
    return r, {"route": route, "intrusion": intrusion}


def steer(task: RealTrafficTask, envs: NDArray[np.int64], own: NDArray[np.int64], action: Array) -> None:
    """Apply actions (rows, 2 or 3) to ownship slots: heading offset from the recorded path, speed and altitude offsets.

    The kernel :func:`steering_rows` (the commands), then the physics' HDG, ALT and SPD commands.
    """
    sim = task.sim
    player = task.player
    f = task.flights
    p = len(envs)
    hdg, alt, vs, spd = np.empty(p), np.empty(p), np.empty(p), np.empty(p)
    steering_rows(
        envs, own, np.ascontiguousarray(action, dtype=np.float64), player.start, player.elapsed, player.flight, player.vsmax,
        f.t0, f.offset, float(f.period), f.lat, f.lon, f.alt, f.gs, sim.lat, sim.lon, sim.alt, hdg, alt, vs, spd,
    )  # fmt: skip
    sim.cmd_heading(envs, own, hdg)
    sim.cmd_altitude(envs, own, alt, vs)
    sim.cmd_speed(envs, own, spd)


def position_bound(config: RealTrafficConfig) -> float:
    """The ``-v1`` bound of an intruder's offsets and distance (in units of POSITION_SCALE).

    A recorded aircraft of a window comes within ``radius_nm`` of the ownship at some time of the
    window; at any other time of the window the recordings are at most 2 ``MAX_SPEED`` x
    ``window_s`` further apart, and each simulated aircraft is at most 2 ``MAX_SPEED`` x
    ``window_s`` from where it was created on its recording.
    """
    reach_nm = config.radius_nm + 4.0 * MAX_SPEED * config.window_s / NM
    return float(np.ceil(reach_nm / POSITION_SCALE))


def bounds_v1(config: RealTrafficConfig) -> dict[str, BoxSpec]:
    """The ``-v1`` observation spec: finite bounds per entry, the intruder rows as one vector (docs/environments-v1.md)."""
    p = position_bound(config)
    own = np.array([ROUTE_BOUND, 1.0, 1.0, SPEED_ERROR_BOUND, ALTITUDE_BOUND, VS_BOUND])
    low = np.array([-p, -p, -VELOCITY_BOUND, -VELOCITY_BOUND, -ALTITUDE_BOUND, 0.0, 0.0])
    high = np.array([p, p, VELOCITY_BOUND, VELOCITY_BOUND, ALTITUDE_BOUND, p, 1.0])
    n = NUM_INTRUDERS * INTRUDER_FEATURES
    return {"ownship": BoxSpec((6,), -own, own), "intruders": BoxSpec((n,), np.tile(low, NUM_INTRUDERS), np.tile(high, NUM_INTRUDERS))}


class RealTrafficTask(Task):
    """Batched RealTrafficCREnv-v0 (see :class:`bluesky_gym.environments.real_traffic.env.RealTrafficCREnv`)."""

    env_id: ClassVar[str] = "RealTrafficCREnv-v0"
    dt: ClassVar[float] = 1.0
    action_frequency: ClassVar[int] = int(DECISION_STEP)
    max_episode_steps: ClassVar[int] = int(RealTrafficConfig.window_s / DECISION_STEP)
    config_class: ClassVar[type[TaskConfig]] = RealTrafficConfig
    info_keys: ClassVar[tuple[str, ...]] = ("total_reward", "total_intrusions", "average_route_deviation_nm")
    has_goal: ClassVar[bool] = False
    #: Whether the recorded aircraft other than the ownship fly their recorded profiles (False: they are agents too).
    guided_traffic: ClassVar[bool] = True
    config: RealTrafficConfig

    def __init__(
        self, n_envs: int = 1, config: TaskConfig | None = None, backend: str | Physics = "native", max_episode_steps: int | None = None
    ) -> None:
        cfg = config if config is not None else RealTrafficConfig()
        if isinstance(cfg, RealTrafficConfig):
            cfg.validate()
        super().__init__(n_envs, cfg, backend, max_episode_steps)

    @classmethod
    def episode_limit(cls, config: TaskConfig) -> int:
        """The window's decision steps (``window_s`` / 10 s)."""
        assert isinstance(config, RealTrafficConfig)
        return int(round(config.window_s / DECISION_STEP))

    def max_aircraft(self) -> int:
        """Ownship and the largest traffic count."""
        return int(self.config.max_traffic) + 1

    def max_waypoints(self) -> int:
        """Route points given to each aircraft."""
        return MAX_ROUTE_POINTS

    def allocate(self) -> None:
        """The per-episode arrays, and the episode data if they are prepared.

        A sample collection not cleaned into the cache yet is cleaned at the first reset (or first
        use of :attr:`data`), not here: making the environment, listing it and reading its spaces
        need no data. A ``.npz`` collection that does not exist is refused here.
        """
        self._data: EpisodeData | None = None
        self._player: WindowPlayer | None = None
        self._route_offsets: Array | None = None
        if not unprepared(self.config.collections, self.config.cache_dir):
            self._data = episode_data(self.config)
        self.test_split = np.full(self.n_envs, self.config.split == "test")
        self.window_index = np.full(self.n_envs, -1, np.int64)
        self.route_sum = np.zeros(self.n_envs)
        self.intrusions = np.zeros(self.n_envs)

    @property
    def data(self) -> EpisodeData:
        """The recorded flights and the windows of both splits (sample collections not cleaned yet are cleaned now, once)."""
        if self._data is None:
            self._data = episode_data(self.config)
        return self._data

    @property
    def flights(self) -> RecordedFlights:
        """The recorded flights the windows refer to."""
        return self.data.flights

    @property
    def route_offsets(self) -> Array:
        """Times [s] relative to now of the recorded positions that make the route near the ownship (:func:`route_offsets`)."""
        if self._route_offsets is None:
            self._route_offsets = route_offsets(self.flights.period)
        return self._route_offsets

    @property
    def player(self) -> WindowPlayer:
        """The player of the recorded traffic on the task's physics."""
        if self._player is None:
            self._player = WindowPlayer(self.sim, self.flights, guided_ownship=False, guided_traffic=self.guided_traffic)
        return self._player

    def wrap_physics(self, wrapper: Callable[[Physics], Physics]) -> Physics:
        """Put a wrapper around the physics (see :meth:`Task.wrap_physics`); the recorded traffic's player commands through it too."""
        wrapped = super().wrap_physics(wrapper)
        if self._player is not None:
            self._player.sim = wrapped
        return wrapped

    def set_test_split(self, envs: NDArray[np.int64], test: BoolArray) -> None:
        """Choose the split the next episodes of ``envs`` are drawn from (``split="auto"`` only; fixed splits ignore it)."""
        if self.config.split == "auto":
            self.test_split[np.asarray(envs, dtype=np.int64)] = np.asarray(test, dtype=bool)

    def build_observation_spec(self) -> dict[str, BoxSpec]:
        """``ownship`` (6,) and ``intruders`` (NUM_INTRUDERS, 7); ``-v1``: finite bounds per entry, ``intruders`` (35,) (:func:`bounds_v1`)."""
        if self.config.float32_spaces:
            return bounds_v1(self.config)
        return {"ownship": BoxSpec((6,)), "intruders": BoxSpec((NUM_INTRUDERS, INTRUDER_FEATURES))}

    def build_action_spec(self) -> BoxSpec:
        """Heading and speed offsets (and altitude with ``altitude_action``), each in [-1, 1]."""
        return BoxSpec((3 if self.config.altitude_action else 2,), -1.0, 1.0)

    def generate(self, envs: NDArray[np.int64]) -> None:
        """Draw a window of the episode's split with its own generator and load it."""
        chosen = []
        for e in envs:
            pool = self.data.test if self.test_split[e] else self.data.train
            k = int(self.rngs[int(e)].integers(len(pool)))
            self.window_index[e] = k
            chosen.append(pool[k])
        self.player.load(envs, chosen)
        self.route_sum[envs] = 0.0
        self.intrusions[envs] = 0.0

    def window(self, env: int) -> Window:
        """The window episode ``env`` plays."""
        pool = self.data.test if self.test_split[env] else self.data.train
        return pool[int(self.window_index[env])]

    def apply_action(self, action: Array) -> None:
        """Steer every ownship."""
        steer(self, self.all_envs, self.ownship, action)

    def advance(self) -> None:
        """The physics sub-steps, then the recorded traffic's appearances, departures and targets."""
        super().advance()
        self.player.advance_clock(DECISION_STEP)
        self.player.update()

    def measure(self, envs: NDArray[np.int64] | None = None) -> RealTrafficGeometry:
        """Geometry of episodes ``envs`` (all when None)."""
        envs = self.all_envs if envs is None else np.asarray(envs, dtype=np.int64)
        return measure(self, envs, self.ownship[envs])

    def observe(self, g: StepGeometry | None = None) -> dict[str, Array]:
        """Observation of the rows of ``g``."""
        geo = self.measure() if g is None else g
        assert isinstance(geo, RealTrafficGeometry)
        return observation(self, geo)

    def reward(self, g: StepGeometry) -> tuple[Array, BoolArray, dict[str, Array]]:
        """Route and intrusion penalties; never terminates."""
        assert isinstance(g, RealTrafficGeometry)
        r, parts = reward(g)
        episode_sums(g.envs, g.route_nm, g.los, self.route_sum, self.intrusions)
        return r, np.zeros(self.n_envs, bool), parts

    def episode_info(self) -> dict[str, Array]:
        """``total_reward``, ``total_intrusions`` and the mean |route deviation| so far [NM]."""
        return {
            "total_reward": self.stats.total_reward.copy(),
            "total_intrusions": self.intrusions.copy(),
            "average_route_deviation_nm": self.mean_route_deviation(AVERAGE_ROUTE_EMPTY),
        }

    def mean_route_deviation(self, empty: float) -> Array:
        """(n_envs,) the mean |route deviation| [NM] over the decision steps, ``empty`` before the first.

        The kernel :func:`~bluesky_gym.tasks.compiled.sample_means`.
        """
        out = np.empty(self.n_envs)
        sample_means(self.route_sum, self.stats.steps, empty, out)
        return out

    def kpis(self) -> dict[str, Array]:
        """The common KPIs and the mean |route deviation| [NM]."""
        out = super().kpis()
        out["kpi_mean_route_deviation_nm"] = self.mean_route_deviation(np.nan)
        return out


class RealTrafficAllAgentsTask(RealTrafficTask):
    """The real-traffic task with every recorded aircraft steered by an agent (the multi-agent form).

    No aircraft gets the recorded profile from the scenario; each agent's action is applied with
    :func:`steer` to its own slot, its observation and reward are :func:`observation` and
    :func:`reward` of its own row. It is the scenario of the multi-agent layout
    :class:`~bluesky_gym.environments.real_traffic.multiagent.RealTrafficMultiAgentTask`.
    """

    guided_traffic: ClassVar[bool] = False
