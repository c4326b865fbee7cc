"""SectorCREnv-v0: cross a random convex sector towards an exit point among traffic (docs/environments-v0.md §5)."""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from bluesky_gym.core.physics import Physics
from bluesky_gym.core.units import FL, KTS
from bluesky_gym.tasks import compiled
from bluesky_gym.tasks.base import (
    DEFAULT_TYPES,
    Array,
    BoolArray,
    BoxSpec,
    StepGeometry,
    Task,
    TaskConfig,
    TypeMix,
    check_pair,
    check_range,
    check_type_mix,
    command_heading_and_speed,
    draw_types,
    kwik_separation,
    typed,
)
from bluesky_gym.tasks.geometry import initial_bearing, nm_to_latlon, polygon_area, random_convex_polygon, ref_kwikdist

# Scenario (reference values).
AC_DENSITY_RANGE = (0.003, 0.007)  # aircraft per NM^2 ("uniform" mode)
AC_DENSITY_MU = 0.005  # aircraft per NM^2 ("normal" mode mean)
AC_DENSITY_SIGMA = 0.001  # aircraft per NM^2 ("normal" mode standard deviation)
POLY_AREA_RANGE = (2400, 3750)  # NM^2: minimum polygon area, area of the circumscribed circle
CENTER = (51.990426702297746, 4.376124857109851)  # deg: sector centre (TU Delft Aerospace faculty)
ALTITUDE = 350.0  # m: the reference's "FL350" is passed to ``cre`` as metres (docs/environments-v0.md §5)
AC_SPD = 150.0  # m/s CAS at creation
DENSITY_MODES = ("normal", "uniform")

# MDP (reference values).
INTRUSION_DISTANCE = 5.0  # NM, horizontal only
NUM_AC_STATE = 4  # intruders in the observation (the closest ones)
MIN_AIRCRAFT = NUM_AC_STATE + 1  # at least this many aircraft (agent included) per episode
DRIFT_PENALTY = -0.1  # per rad of |drift|, per step
AVERAGE_DRIFT_EMPTY = 0.0  # rad: the average_drift info before the first step (the reference's mean of nothing is NaN)
INTRUSION_PENALTY = -1.0  # per intruder within INTRUSION_DISTANCE, per step
D_HEADING = 22.5  # deg of heading change per unit action
D_VELOCITY = 20 / 3  # per unit action; the reference calls it kts but adds it to CAS in m/s
AIRSPEED_MEAN = 150.0  # m/s: airspeed observation is (TAS - 150) / 6
AIRSPEED_STD = 6.0  # m/s
POSITION_SCALE = 13000.0  # m: x_r, y_r
VX_SCALE = 32.0  # m/s: vx_r (north)
VY_SCALE = 66.0  # m/s: vy_r (east)
DISTANCE_MEAN = 50000.0  # m: distances observation is (d - 50000) / 15000
DISTANCE_STD = 15000.0  # m
M_PER_KM = 1000.0

# Normal-mode densities are clipped at mu + DENSITY_CLIP_SIGMAS * sigma (a draw above it has
# probability 2.9e-7), so that the aircraft slots can be sized for the worst case.
DENSITY_CLIP_SIGMAS = 5.0
MAX_AIRCRAFT_LIMIT = 500  # largest worst-case traffic count a configuration may ask for
MAX_AREA_RATIO = 0.9  # min area / circle area: above this the polygon generator needs many points
INITIAL_VERTEX_CAPACITY = 16  # polygon vertex slots, grown when a polygon needs more
CANDIDATES_PER_AIRCRAFT = 2  # rejection-sampling candidates drawn per missing aircraft and round

# -v1 (see SectorCRConfig).
FLIGHT_LEVEL_ALTITUDE = 350 * FL  # m: FL350, the reference's intended ALTITUDE
AIRSPEED_MEAN_V1 = 180.0  # m/s: airspeed observation (TAS - 180) / 80, TAS at FL350 in [120, 237] m/s
AIRSPEED_STD_V1 = 80.0  # m/s
EXIT_MARGIN = INTRUSION_DISTANCE  # NM: leaving the sector within this distance of the own waypoint is the exit
EARLY_EXIT_PENALTY = INTRUSION_PENALTY  # per decision step left, when the sector is left elsewhere
# -v1 declared bounds: positions within 50 x 13 km, relative speeds within twice the fastest TAS.
POSITION_BOUND = 50.0
VX_BOUND = 16.0
VY_BOUND = 8.0
DISTANCE_BOUNDS = (-4.0, 50.0)


@dataclass(frozen=True)
class SectorCRConfig(TaskConfig):
    """Scenario options of the sector conflict-resolution task (defaults: the paper's).

    Attributes:
        ac_density_mode: ``"normal"`` (density ~ N(mu, sigma), clipped at mu + 5 sigma) or
            ``"uniform"`` (density ~ U(range)); the reference constructor argument.
        ac_density_range: (low, high) of the uniform density draw [aircraft / NM^2].
        ac_density_mu: Mean of the normal density draw [aircraft / NM^2].
        ac_density_sigma: Standard deviation of the normal density draw [aircraft / NM^2].
        poly_area_range: (minimum polygon area, area of the circle the vertices lie on) [NM^2].
        flight_level_altitude: ``-v1``: traffic at FL350 (10668 m), where BlueSky's envelope
            caps the CAS 150 m/s at M0.80 (TAS 237 m/s), and ``airspeed`` is (TAS - 180) / 80;
            ``-v0``: at 350 m (the reference's "FL350" used as metres) and (TAS - 150) / 6.
        speed_step_in_knots: ``-v1``: the speed action changes CAS by 20/3 kt per unit;
            ``-v0``: by 20/3 m/s (the reference's "kts" added to m/s).
        exit_ends_episode: ``-v1``: leaving the sector terminates the episode; within 5 NM of the
            own waypoint it is the exit (no penalty), elsewhere it costs 1 per decision step left
            (bluesky-gym #44: leaving early no longer escapes the penalties); ``-v0``: leaving
            truncates the episode without a penalty.
        intruder_types: Aircraft types of the other traffic: a type name, names drawn with equal
            probability (e.g. ``("A320", "B744")``) or ``{name: weight}``. Default A320 only (the
            paper's fleet, no random draw). Types are BlueSky's OpenAP types (``bluesky_gym.core.aircraft.supported_types()``).
        ownship_types: Aircraft type(s) of the agent's aircraft (slot 0), in the same form (default
            A320). Types are drawn after the start points.

    """

    ac_density_mode: str = "normal"
    ac_density_range: tuple[float, float] = AC_DENSITY_RANGE
    ac_density_mu: float = AC_DENSITY_MU
    ac_density_sigma: float = AC_DENSITY_SIGMA
    poly_area_range: tuple[float, float] = POLY_AREA_RANGE
    flight_level_altitude: bool = False
    speed_step_in_knots: bool = False
    exit_ends_episode: bool = False
    intruder_types: TypeMix = DEFAULT_TYPES
    ownship_types: TypeMix = DEFAULT_TYPES

    def __post_init__(self) -> None:
        super().__post_init__()
        # Lists given through gym.make keyword arguments are stored as tuples (hashable config).
        for name in ("ac_density_range", "poly_area_range"):
            value = getattr(self, name)
            if isinstance(value, list):
                object.__setattr__(self, name, tuple(value))

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first invalid option."""
        if not isinstance(self.ac_density_mode, str) or self.ac_density_mode not in DENSITY_MODES:
            raise ValueError(f"ac_density_mode must be one of {DENSITY_MODES}, got {self.ac_density_mode!r}")
        low, high = check_pair("ac_density_range", self.ac_density_range)
        if not 0 < low <= high:
            raise ValueError(f"ac_density_range must satisfy 0 < low <= high, got {self.ac_density_range}")
        check_range("ac_density_mu", self.ac_density_mu, 0.0, strict_low=True)
        check_range("ac_density_sigma", self.ac_density_sigma, 0.0)
        check_type_mix("intruder_types", self.intruder_types)
        check_type_mix("ownship_types", self.ownship_types)
        area_min, area_max = check_pair("poly_area_range", self.poly_area_range)
        if not 0 < area_min < area_max:
            raise ValueError(f"poly_area_range must satisfy 0 < min < max, got {self.poly_area_range}")
        if area_min > MAX_AREA_RATIO * area_max:
            raise ValueError(
                f"poly_area_range: the minimum area must be at most {MAX_AREA_RATIO} x the maximum (the polygon is "
                f"inscribed in a circle of the maximum area), got {self.poly_area_range}"
            )
        worst = worst_case_aircraft(self)
        if worst > MAX_AIRCRAFT_LIMIT:
            raise ValueError(
                f"the densities and poly_area_range allow up to {worst} aircraft per episode; at most {MAX_AIRCRAFT_LIMIT} are supported"
            )

    def density_cap(self) -> float:
        """Largest density a draw can give [aircraft / NM^2]."""
        if self.ac_density_mode == "normal":
            return float(self.ac_density_mu + DENSITY_CLIP_SIGMAS * self.ac_density_sigma)
        return float(self.ac_density_range[1])


# The flat projection of the observation, as geometry.latlon_to_nm evaluates it, and the
# observation scales, for the compiled observation.
FLAT_CENTER = (CENTER[0], CENTER[1], float(np.cos(np.radians(np.asarray(CENTER, dtype=np.float64))[0])))
OBS_SCALES = (AIRSPEED_MEAN, AIRSPEED_STD, POSITION_SCALE, VX_SCALE, VY_SCALE, DISTANCE_MEAN, DISTANCE_STD)


def worst_case_aircraft(config: SectorCRConfig) -> int:
    """Most aircraft (agent included) an episode of ``config`` can hold.

    The polygon is inscribed in a circle of area ``poly_area_range[1]``, so its area stays below
    that value and ``ceil(density * area) <= ceil(density_cap * max area)``.
    """
    return max(math.ceil(config.density_cap() * float(config.poly_area_range[1])), MIN_AIRCRAFT)


#: The observation entries of the agent's own features (:attr:`SectorGeometry.features`' columns) and of its intruders.
OWN_KEYS = ("cos(drift)", "sin(drift)", "airspeed")
INTRUDER_KEYS = ("x_r", "y_r", "vx_r", "vy_r", "cos(track)", "sin(track)", "distances")
OBS_SCALES_V1 = (AIRSPEED_MEAN_V1, AIRSPEED_STD_V1, *OBS_SCALES[2:])


def observation_scales(config: SectorCRConfig) -> tuple[float, ...]:
    """The normalisation constants of the compiled observation for ``config`` (airspeed's differ at FL350)."""
    return OBS_SCALES_V1 if config.flight_level_altitude else OBS_SCALES


def speed_change(config: SectorCRConfig) -> float:
    """CAS change per unit of the speed action: 20/3 m/s (``-v0``, the reference's "kts" added to m/s), 20/3 kt with ``speed_step_in_knots``."""
    return D_VELOCITY * KTS if config.speed_step_in_knots else D_VELOCITY


def bounds_v1(key: str) -> tuple[float, float]:
    """The ``-v1`` declared (low, high) of an observation entry of SectorCR (its multi-agent form too)."""
    return {
        "x_r": (-POSITION_BOUND, POSITION_BOUND),
        "y_r": (-POSITION_BOUND, POSITION_BOUND),
        "vx_r": (-VX_BOUND, VX_BOUND),
        "vy_r": (-VY_BOUND, VY_BOUND),
        "distances": DISTANCE_BOUNDS,
    }.get(key, (-1.0, 1.0))


# --- the step's geometry, observation and reward, for a set of ownship slots ----------------------
@dataclass(frozen=True)
class SectorGeometry(StepGeometry):
    """SectorCR's geometry of (episode, ownship slot) rows (see :func:`measure`).

    Attributes:
        own: (rows,) ownship slot of each row.
        features: (rows, 3) cos(drift), sin(drift), normalised airspeed.
        intruders: (rows, 7, NUM_AC_STATE) the observed closest other aircraft (:data:`INTRUDER_KEYS`).
        n_others: (rows,) other active aircraft (fewer than NUM_AC_STATE: the last entries are padding).
        inside: (rows,) whether the ownship is inside its sector.
    """

    own: NDArray[np.int64]
    features: Array
    intruders: Array
    n_others: NDArray[np.int64]
    inside: BoolArray


def measure(sim: Physics, sector: SectorCRTask, envs: NDArray[np.int64], own: NDArray[np.int64]) -> SectorGeometry:
    """Drift to the own waypoint, the closest other aircraft, separation and the sector test of each row.

    The drift is wrap180(heading - kwik bearing to the aircraft's waypoint) (BlueSky's Python kwik
    form); intruders are sorted by flat distance around :data:`CENTER`; separation is the kwik
    distance with a 5 NM horizontal intrusion test. The airspeed normalisation is the
    configuration's (:func:`observation_scales`).
    """
    n = len(envs)
    drift = np.empty(n)
    features = np.empty((n, 3))
    intruders = np.empty((n, 7, NUM_AC_STATE))
    n_others = np.empty(n, np.int64)
    compiled.sector_observe(
        envs,
        own,
        sim.lat,
        sim.lon,
        sim.hdg,
        sim.tas,
        sim.active,
        sector.wpt_lat[envs, own],
        sector.wpt_lon[envs, own],
        FLAT_CENTER,
        observation_scales(sector.config),
        drift,
        features,
        intruders,
        n_others,
    )
    separation, los = kwik_separation(sim, envs, own, INTRUSION_DISTANCE)
    inside = np.empty(n, bool)
    compiled.slots_in_polygons(envs, own, sim.lat, sim.lon, sector.poly_lat, sector.poly_lon, sector.n_vertices, inside)
    return SectorGeometry(envs, separation, los, drift, np.zeros(n, bool), own, features, intruders, n_others, inside)


def observation(g: SectorGeometry) -> dict[str, Array]:
    """SectorCREnv-v0's observation of every row (the reference's padding when fewer intruders are active)."""
    # airspeed is kept as in the reference although it leaves the declared [-1, 1] bound. (Views of
    # g's arrays, by indexing alone: the device step gives it its tensors.)
    obs = {key: g.features[:, i : i + 1] for i, key in enumerate(OWN_KEYS)}
    obs.update({key: g.intruders[:, i] for i, key in enumerate(INTRUDER_KEYS)})
    return obs


def reward(g: SectorGeometry) -> tuple[Array, NDArray[np.int64], dict[str, Array]]:
    """Per row: -0.1 |drift| [rad] - 1 per other aircraft within 5 NM; also the intrusion count."""
    assert g.drift_deg is not None
    n = len(g.drift_deg)
    r, drift_reward, intrusion, count = np.empty(n), np.empty(n), np.empty(n), np.empty(n, np.int64)
    compiled.sector_reward(g.drift_deg, g.los, DRIFT_PENALTY, INTRUSION_PENALTY, r, drift_reward, intrusion, count)
    return r, count, {"drift": drift_reward, "intrusion": intrusion}


class SectorCRTask(Task):
    """Batched sector CR task; see :class:`bluesky_gym.environments.sector_cr.env.SectorCREnv` for the MDP."""

    env_id: ClassVar[str] = "SectorCREnv-v0"
    dt: ClassVar[float] = 1.0
    action_frequency: ClassVar[int] = 5
    max_episode_steps: ClassVar[int] = 200
    config_class: ClassVar[type[TaskConfig]] = SectorCRConfig
    info_keys: ClassVar[tuple[str, ...]] = ("total_reward", "total_intrusions", "average_drift")
    has_goal: ClassVar[bool] = False
    config: SectorCRConfig

    def max_aircraft(self) -> int:
        """Slots for the worst case of the configured density and area ranges."""
        return worst_case_aircraft(self.config)

    def max_waypoints(self) -> int:
        """No routes are flown (the waypoints are only drift references)."""
        return 1

    def build_observation_spec(self) -> dict[str, BoxSpec]:
        """Declare the reference's keys; cos/sin(drift) and airspeed are bounded by [-1, 1]."""
        spec = {k: BoxSpec((1,), -1.0, 1.0) for k in OWN_KEYS}
        spec.update({k: BoxSpec((NUM_AC_STATE,)) for k in INTRUDER_KEYS})
        if self.config.float32_spaces:
            spec = {k: BoxSpec(v.shape, *bounds_v1(k)) for k, v in spec.items()}
        return spec

    def build_action_spec(self) -> BoxSpec:
        """Heading change and speed change, each in [-1, 1]."""
        return BoxSpec((2,), -1.0, 1.0)

    # --- generator ------------------------------------------------------------------------------
    def allocate(self) -> None:
        """Per-episode scenario arrays."""
        n, m = self.n_envs, self.sim.max_aircraft
        self._alloc_vertices(INITIAL_VERTEX_CAPACITY)
        self.n_vertices = np.zeros(n, np.int64)
        self.poly_area = np.zeros(n)  # NM^2
        self.density = np.zeros(n)  # aircraft / NM^2, as drawn (before the normal-mode clip)
        self.num_ac = np.zeros(n, np.int64)  # aircraft in the episode, agent included
        self.wpt_nm = np.zeros((n, m, 2))  # (north, east) NM from CENTER, one per aircraft
        self.wpt_lat = np.zeros((n, m))  # deg
        self.wpt_lon = np.zeros((n, m))
        self.total_intrusions = np.zeros(n, np.int64)
        self.drift_rad_sum = np.zeros(n)  # sum of |drift| [rad] (average_drift)
        self.drift_rad_n = np.zeros(n, np.int64)

    def _alloc_vertices(self, capacity: int) -> None:
        old = getattr(self, "poly_nm", None)
        self.poly_nm = np.zeros((self.n_envs, capacity, 2))  # (north, east) NM from CENTER
        self.poly_lat = np.zeros((self.n_envs, capacity))  # deg
        self.poly_lon = np.zeros((self.n_envs, capacity))
        if old is not None:
            k = old.shape[1]
            self.poly_nm[:, :k] = old
            self.poly_lat[:, :k], self.poly_lon[:, :k] = self._latlon(old)

    @staticmethod
    def _latlon(points_nm: Array) -> tuple[Array, Array]:
        ll = nm_to_latlon(CENTER, points_nm)
        return ll[..., 0], ll[..., 1]

    def generate(self, envs: NDArray[np.int64]) -> None:
        """Polygon, traffic count, perimeter waypoints and start points of each reset episode.

        Each episode draws from its own generator in the reference's order (polygon points,
        density, perimeter positions, start-point candidates); the geometry between the draws is
        done for all reset episodes at once where the draws do not depend on it.
        """
        c = self.config
        radius = np.sqrt(c.poly_area_range[1] / np.pi)  # NM: circle of the maximum area
        density_cap = c.density_cap()
        for e in envs:
            rng = self.rngs[e]
            # 1. Convex polygon: points on the circle, sorted by compass bearing, added until the
            #    shoelace area reaches the minimum.
            poly = random_convex_polygon(rng, radius, c.poly_area_range[0])
            area = polygon_area(poly)
            nv = len(poly)
            if nv > self.poly_nm.shape[1]:
                self._alloc_vertices(max(nv, 2 * self.poly_nm.shape[1]))
            self.poly_nm[e] = 0.0
            self.poly_nm[e, :nv] = poly
            self.n_vertices[e] = nv
            self.poly_area[e] = area
            # 2. Traffic count, agent included.
            if c.ac_density_mode == "normal":
                density = rng.normal(c.ac_density_mu, c.ac_density_sigma)
            else:
                density = rng.uniform(*c.ac_density_range)
            self.density[e] = density
            num_ac = int(max(np.ceil(min(density, density_cap) * area), MIN_AIRCRAFT))
            self.num_ac[e] = num_ac
            # 3. One waypoint per aircraft, uniform along the perimeter, sorted by perimeter position.
            cum = self._perimeter(poly)
            self.wpt_nm[e] = 0.0
            self.wpt_nm[e, :num_ac] = self._perimeter_points(poly, np.sort(rng.uniform(0, cum[-1], num_ac)), cum)
        # Polygons in (lat, lon); the padding repeats vertex 0 (ignored: n_vertices).
        lat_v, lon_v = self._latlon(self.poly_nm[envs])
        real = np.arange(self.poly_nm.shape[1]) < self.n_vertices[envs, None]
        self.poly_lat[envs] = np.where(real, lat_v, lat_v[:, :1])
        self.poly_lon[envs] = np.where(real, lon_v, lon_v[:, :1])
        # 4. Start points: uniform in the bounding box, kept when inside the sector.
        starts = self._sample_inside(envs, self.num_ac[envs], [self.rngs[e] for e in envs])
        # Waypoints in (lat, lon), element by element as one episode at a time would give them.
        used = np.arange(self.sim.max_aircraft) < self.num_ac[envs, None]
        wlat, wlon = self._latlon(self.wpt_nm[envs])
        self.wpt_lat[envs] = np.where(used, wlat, 0.0)
        self.wpt_lon[envs] = np.where(used, wlon, 0.0)
        cre_env, cre_slot = np.nonzero(used)
        cre_env = envs[cre_env]
        lat0 = np.concatenate([lat for lat, _ in starts])
        lon0 = np.concatenate([lon for _, lon in starts])
        hdg0 = initial_bearing(lat0, lon0, self.wpt_lat[cre_env, cre_slot], self.wpt_lon[cre_env, cre_slot])
        # Everyone flies straight at its waypoint's initial bearing, CAS 150 m/s, at 350 m (the
        # reference's ALTITUDE 350 "FL" used as metres). No routes: they never turn.
        # 5. Aircraft types (no draw for a one-type mix): the agent's, then the others', per episode.
        omix, imix = check_type_mix("ownship_types", c.ownship_types), check_type_mix("intruder_types", c.intruder_types)
        types = [t for e in envs for t in draw_types(self.rngs[e], omix, 1) + draw_types(self.rngs[e], imix, int(self.num_ac[e]) - 1)]
        alt = FLIGHT_LEVEL_ALTITUDE if c.flight_level_altitude else ALTITUDE
        self.sim.create(cre_env, cre_slot, lat0, lon0, hdg0, alt, AC_SPD, **typed(types))
        self.total_intrusions[envs] = 0
        self.drift_rad_sum[envs] = 0.0
        self.drift_rad_n[envs] = 0

    @staticmethod
    def _perimeter(poly: Array) -> list[float]:
        """Cumulative perimeter [NM] at the end of each edge (edge k: vertex k -> k+1, closing)."""
        # Scalar Python on a few vertices: np.roll / np.sum / np.cumsum's operations in their order.
        pts = np.asarray(poly, dtype=np.float64).tolist()
        n = len(pts)
        cum, total = [], 0.0
        for k in range(n):
            (x1, y1), (x2, y2) = pts[k], pts[(k + 1) % n]
            dx, dy = x2 - x1, y2 - y1
            total += math.sqrt(dx * dx + dy * dy)
            cum.append(total)
        return cum

    @classmethod
    def _perimeter_points(cls, poly: Array, d: Array, cum: list[float] | None = None) -> Array:
        """Points at perimeter positions ``d`` [NM], walking the edges from vertex 0 (``cum``: :meth:`_perimeter`)."""
        pts = np.asarray(poly, dtype=np.float64).tolist()
        cum = cls._perimeter(poly) if cum is None else cum
        n = len(pts)
        out = []
        for dist in np.asarray(d, dtype=np.float64).tolist():
            k = bisect.bisect_left(cum, dist)  # first edge whose end lies at or beyond d
            start = cum[k - 1] if k > 0 else 0.0  # perimeter at the edge's first vertex
            (x1, y1), (x2, y2) = pts[k], pts[(k + 1) % n]
            ex, ey = x2 - x1, y2 - y1
            frac = (dist - start) / math.sqrt(ex * ex + ey * ey)
            out.append((x1 + frac * ex, y1 + frac * ey))
        return np.array(out).reshape(-1, 2)

    def _sample_inside(self, envs: NDArray[np.int64], counts: NDArray[np.int64], rngs: list[np.random.Generator]) -> list[tuple[Array, Array]]:
        """``counts[i]`` start points uniform in sector ``envs[i]``: rejection sampling in the bounding box.

        Each round draws every still-incomplete episode's candidates from its own generator, then
        tests all candidates together.

        Returns:
            (lat, lon) of the start points of each episode, in ``envs`` order.
        """
        lows = [self.poly_nm[e, : self.n_vertices[e]].min(axis=0) for e in envs]
        highs = [self.poly_nm[e, : self.n_vertices[e]].max(axis=0) for e in envs]
        missing = np.asarray(counts, dtype=np.int64).copy()
        taken: list[list[tuple[Array, Array]]] = [[] for _ in envs]
        pending = np.flatnonzero(missing > 0)
        while pending.size:
            cands = [rngs[i].uniform(lows[i], highs[i], size=(CANDIDATES_PER_AIRCRAFT * missing[i] + 4, 2)) for i in pending]  # (north, east)
            sizes = np.array([len(x) for x in cands])
            clat, clon = self._latlon(np.concatenate(cands))
            owner = np.repeat(envs[pending], sizes)
            inside = self._start_inside(clat, clon, owner)
            first = np.concatenate([[0], np.cumsum(sizes)])
            for j, i in enumerate(pending):
                sel = slice(first[j], first[j + 1])
                take = np.flatnonzero(inside[sel])[: missing[i]]
                taken[i].append((clat[sel][take], clon[sel][take]))
                missing[i] -= take.size
            pending = np.flatnonzero(missing > 0)
        return [(np.concatenate([a for a, _ in t]), np.concatenate([b for _, b in t])) if t else (np.zeros(0), np.zeros(0)) for t in taken]

    def _start_inside(self, lat: Array, lon: Array, owner: NDArray[np.int64]) -> NDArray[np.bool_]:
        """Whether each point (lat, lon) lies in the sector of episode ``owner``."""
        inside = np.empty(lat.shape, bool)
        compiled.points_in_owner_polygon(lat, lon, owner, self.poly_lat, self.poly_lon, self.n_vertices, inside)
        return inside

    # --- dynamics interface ---------------------------------------------------------------------
    def apply_action(self, action: Array) -> None:
        """HDG wrap180(hdg + 22.5 a0); SPD (CAS + 20/3 a1) * 1.94384 kt (docs/environments-v0.md §5)."""
        command_heading_and_speed(self.sim, self.all_envs, self.ownship, action, D_HEADING, speed_change(self.config))

    # --- the step -----------------------------------------------------------------------------
    def measure(self, envs: NDArray[np.int64] | None = None) -> SectorGeometry:
        """The agent's (slot 0) geometry of episodes ``envs`` (all when None): :func:`measure`."""
        envs = self.all_envs if envs is None else np.asarray(envs, dtype=np.int64)
        return measure(self.sim, self, envs, self.ownship[: len(envs)])

    def observe(self, g: StepGeometry | None = None) -> dict[str, Array]:
        """Agent drift and airspeed, and the 4 closest intruders by flat distance."""
        return observation(self.measure() if g is None else g)  # type: ignore[arg-type]

    def reward(self, g: StepGeometry) -> tuple[Array, BoolArray, dict[str, Array]]:
        """Drift and intrusion penalties; ``-v0`` never terminates (leaving the sector truncates).

        ``-v1`` (``exit_ends_episode``): leaving the sector terminates, with a penalty of 1 per
        decision step left unless the agent left within 5 NM of its own waypoint (component ``exit``).
        """
        r, count, components = reward(g)  # type: ignore[arg-type]
        assert isinstance(g, SectorGeometry) and g.drift_deg is not None
        exits = self.config.exit_ends_episode
        exit_penalty, terminated = np.empty(self.n_envs), np.empty(self.n_envs, bool)
        compiled.sector_episode_reward(
            g.envs,
            g.drift_deg,
            count,
            g.inside,
            self.sim.lat,
            self.sim.lon,
            self.wpt_lat,
            self.wpt_lon,
            self.stats.steps,
            self.time_limit,
            exits,
            EXIT_MARGIN,
            EARLY_EXIT_PENALTY,
            self.drift_rad_sum,
            self.drift_rad_n,
            self.total_intrusions,
            r,
            exit_penalty,
            terminated,
        )  # (the stats count this step after the reward)
        if exits:
            components["exit"] = exit_penalty
        return r, terminated, components

    def exit_distance_nm(self) -> Array:
        """(n_envs,) kwik distance from the agent to its own waypoint (the sector exit) now [NM]."""
        return ref_kwikdist(self.sim.lat[:, 0], self.sim.lon[:, 0], self.wpt_lat[:, 0], self.wpt_lon[:, 0])

    def truncate(self, g: StepGeometry) -> BoolArray:
        """The agent has left the sector: ``-v0`` truncates there (the reference's ``truncated``).

        ``-v1`` terminates there (:meth:`reward`), and a terminated episode is never truncated.
        The device step (:mod:`~bluesky_gym.environments.sector_cr.device_step`) calls it with its
        geometry's tensors.
        """
        assert isinstance(g, SectorGeometry)
        return ~g.inside

    def agent_inside(self) -> BoolArray:
        """(n_envs,) whether the agent is inside its sector now (2-D even-odd test on lat/lon)."""
        return self.measure().inside

    def waypoint_drift(self) -> Array:
        """(n_envs,) agent drift wrap180(hdg - kwik qdr to its waypoint) now [deg]."""
        drift = self.measure().drift_deg
        assert drift is not None
        return drift

    def episode_info(self) -> dict[str, Array]:
        """Info keys of the reference, (n_envs,) each."""
        average_drift = np.empty(self.n_envs)  # mean |drift| [rad] of the episode's steps
        compiled.sample_means(self.drift_rad_sum, self.drift_rad_n, AVERAGE_DRIFT_EMPTY, average_drift)
        return {
            "total_reward": self.stats.total_reward.copy(),
            "total_intrusions": self.total_intrusions.copy(),  # type: ignore[dict-item]  # a count among the float entries
            "average_drift": average_drift,
        }
