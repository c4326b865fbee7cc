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
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from bluesky_gym.core.physics import Physics
from bluesky_gym.core.units import FT, KTS, NM
from bluesky_gym.realtraffic.cache import collection_path, combine, load_collection, unprepared
from bluesky_gym.realtraffic.flights import RecordedFlights
from bluesky_gym.realtraffic.scenario import MAX_ROUTE_POINTS, SEPARATION_NM, SEPARATION_VERTICAL, Window, WindowPlayer, split_windows, windows
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
    wrap180,
)
from bluesky_gym.tasks.geometry import initial_bearing

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
    """

    own: NDArray[np.int64]
    route_nm: Array
    cas_error: Array
    alt_error: Array
    intruders: Array


def measure(task: RealTrafficTask, envs: NDArray[np.int64], own: NDArray[np.int64]) -> RealTrafficGeometry:
    """Geometry of rows (episode ``envs[r]``, ownship slot ``own[r]``)."""
    sim = task.sim
    player = task.player
    sep, los = kwik_separation(sim, envs, own, INTRUSION_NM, INTRUSION_VERTICAL)
    now = player.now(envs)
    flight = player.flight[envs, own]
    lat0, lon0 = sim.lat[envs, own], sim.lon[envs, own]
    # the recorded route near now, as segments in a local flat frame around the ownship [NM]
    offsets = np.arange(-ROUTE_SPAN_S, ROUTE_SPAN_S + 1e-9, task.flights.period)
    rec = task.flights.at(np.repeat(flight[:, None], len(offsets), 1), now[:, None] + offsets[None, :])
    coslat = np.cos(np.radians(lat0))[:, None]
    x = (wrap180(rec["lon"] - lon0[:, None])) * 60.0 * coslat
    y = (rec["lat"] - lat0[:, None]) * 60.0
    x0, y0, x1, y1 = x[:, :-1], y[:, :-1], x[:, 1:], y[:, 1:]
    dx, dy = x1 - x0, y1 - y0
    seg2 = np.maximum(dx * dx + dy * dy, 1e-12)
    u = np.clip(-(x0 * dx + y0 * dy) / seg2, 0.0, 1.0)
    px, py = x0 + u * dx, y0 + u * dy
    d = np.hypot(px, py)
    k = np.argmin(d, axis=1)
    r = np.arange(len(envs))
    side = np.sign(dx[r, k] * (0.0 - y0[r, k]) - dy[r, k] * (0.0 - x0[r, k]))  # > 0: ownship left of the route
    route_nm = -side * d[r, k]
    sched_alt, sched_cas = player.targets(envs, own, now)
    carrot = task.flights.at(flight, now + CARROT_S)
    bearing = initial_bearing(lat0, lon0, carrot["lat"], carrot["lon"])
    drift = wrap180(sim.hdg[envs, own] - bearing)
    # closest aircraft, in the ownship's flat frame
    order = np.argsort(sep, axis=1, kind="stable")[:, :NUM_INTRUDERS]
    dist = np.take_along_axis(sep, order, 1)
    present = np.isfinite(dist)
    ee = envs[:, None]
    lat_i, lon_i = sim.lat[ee, order], sim.lon[ee, order]
    ix = wrap180(lon_i - lon0[:, None]) * 60.0 * coslat
    iy = (lat_i - lat0[:, None]) * 60.0
    vx = sim.gseast[ee, order] - sim.gseast[envs, own][:, None]
    vy = sim.gsnorth[ee, order] - sim.gsnorth[envs, own][:, None]
    dz = sim.alt[ee, order] - sim.alt[envs, own][:, None]
    feats = np.stack(
        [ix / POSITION_SCALE, iy / POSITION_SCALE, vx / VELOCITY_SCALE, vy / VELOCITY_SCALE, dz / ALTITUDE_SCALE, dist / POSITION_SCALE, present],
        axis=-1,
    )
    feats = np.where(present[..., None], feats, 0.0)
    return RealTrafficGeometry(
        envs=envs,
        separation_nm=sep,
        los=los,
        drift_deg=drift,
        goal_reached=np.zeros(len(envs), bool),
        own=own,
        route_nm=route_nm,
        cas_error=sim.cas[envs, own] - sched_cas,
        alt_error=sim.alt[envs, own] - sched_alt,
        intruders=feats,
    )


def observation(task: RealTrafficTask, g: RealTrafficGeometry) -> dict[str, Array]:
    """Observation of the rows of ``g``."""
    sim = task.sim
    rad = np.radians(g.drift_deg if g.drift_deg is not None else np.zeros(len(g.envs)))
    ownship = np.stack(
        [
            np.clip(g.route_nm / ROUTE_SCALE, -ROUTE_BOUND, ROUTE_BOUND),
            np.cos(rad),
            np.sin(rad),
            g.cas_error / SPEED_SCALE,
            g.alt_error / ALTITUDE_SCALE,
            sim.vs[g.envs, g.own] / VS_SCALE,
        ],
        axis=1,
    )
    intruders = g.intruders.copy()
    if task.config.float32_spaces:  # -v1: one vector of the rows, intruder by intruder
        intruders = intruders.reshape(len(g.envs), NUM_INTRUDERS * INTRUDER_FEATURES)
    return {"ownship": ownship, "intruders": intruders}


def reward(g: RealTrafficGeometry) -> tuple[Array, dict[str, Array]]:
    """Reward of the rows of ``g`` and its components (route, intrusion)."""
    route = ROUTE_PENALTY * np.minimum(np.abs(g.route_nm), ROUTE_PENALTY_CAP)
    intrusion = INTRUSION_PENALTY * g.los.sum(axis=1)
    return route + intrusion, {"route": route, "intrusion": intrusion}


def steer(task: RealTrafficTask, envs: NDArray[np.int64], own: NDArray[np.int64], action: Array) -> None:
    """Apply actions (rows, 2 or 3) to ownship slots: heading offset from the recorded path, speed and altitude offsets."""
    sim = task.sim
    player = task.player
    now = player.now(envs)
    carrot = task.flights.at(player.flight[envs, own], now + CARROT_S)
    bearing = initial_bearing(sim.lat[envs, own], sim.lon[envs, own], carrot["lat"], carrot["lon"])
    sim.cmd_heading(envs, own, (bearing + D_HEADING * action[:, 0]) % 360.0)
    alt_offset = D_ALTITUDE * action[:, 2] if action.shape[1] > 2 else 0.0
    player.guide(envs, own, now, alt_offset=alt_offset, cas_offset=D_SPEED * action[:, 1])


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
        self.route_sum += np.abs(g.route_nm)
        self.intrusions += g.los.sum(axis=1)
        return r, np.zeros(self.n_envs, bool), parts

    def episode_info(self) -> dict[str, Array]:
        """``total_reward``, ``total_intrusions`` and the mean |route deviation| so far [NM]."""
        steps = np.maximum(self.stats.steps, 1)
        return {
            "total_reward": self.stats.total_reward.copy(),
            "total_intrusions": self.intrusions.copy(),
            "average_route_deviation_nm": np.where(self.stats.steps > 0, self.route_sum / steps, 0.0),
        }

    def kpis(self) -> dict[str, Array]:
        """The common KPIs and the mean |route deviation| [NM]."""
        out = super().kpis()
        out["kpi_mean_route_deviation_nm"] = np.where(self.stats.steps > 0, self.route_sum / np.maximum(self.stats.steps, 1), np.nan)
        return out


class RealTrafficAllAgentsTask(RealTrafficTask):
    """The real-traffic task with every recorded aircraft steered by an agent (the multi-agent form).

    No aircraft gets the recorded profile from the scenario; each agent's action is applied with
    :func:`steer` to its own slot, its observation and reward are :func:`observation` and
    :func:`reward` of its own row. It is the scenario of the multi-agent layout
    :class:`~bluesky_gym.environments.real_traffic.multiagent.RealTrafficMultiAgentTask`.
    """

    guided_traffic: ClassVar[bool] = False
