"""VerticalCREnv-v0: the descent task with level intruders to avoid vertically (docs/environments-v0.md §2)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from bluesky_gym.core import atmosphere as isa
from bluesky_gym.core.jit import grid_range, jit
from bluesky_gym.core.units import FT, KM
from bluesky_gym.environments.descent import task as descent
from bluesky_gym.environments.descent.task import (
    AC_SPD,
    ACTION_2_MS,
    ALT_STD,
    DEFAULT_RWY_DIS,
    VZ_BOUND,
    VZ_STD,
    DescentConfig,
    DescentMeasurement,
    DescentTask,
    _descent_reward,
    _measure_row,
)
from bluesky_gym.tasks import compiled
from bluesky_gym.tasks.base import (
    DEFAULT_TYPES,
    Array,
    BoolArray,
    BoxSpec,
    StepGeometry,
    TaskConfig,
    TypeMix,
    check_int,
    check_range,
    check_type_mix,
    draw_types,
    kwik_separation,
    typed,
)
from bluesky_gym.tasks.compiled import IntArray

INTRUSION_PENALTY = -50.0  # per intruder inside the intrusion cylinder, per step
INTRUSION_DISTANCE = 5.0  # NM, horizontal radius of the intrusion cylinder
VERTICAL_MARGIN = 1000 * FT  # m (304.8), half height of the intrusion cylinder
INTRUDER_DISTANCE_SCALE = DEFAULT_RWY_DIS  # km: intruder_distance is divided by 200 km
SPEED_SCALE = AC_SPD  # m/s: x/y_difference_speed are divided by 150
TLOSV = 1e11  # s: vertical time to loss of separation given to creconfs (intruder vs ~ 0)
INTRUDER_STATE = ("dist_km", "cos_bearing", "sin_bearing", "x_dif", "y_dif")  # rows of compiled.intruder_relative_state
# -v1 declared bounds: intruders within 5 x 200 km, altitude differences within 15000 m, speed
# differences within twice the fastest TAS (about 270 m/s), vertical ones within 2 x 20 m/s.
INTRUDER_DISTANCE_BOUND = 5.0
ALT_DIFFERENCE_BOUND = 5.0
SPEED_DIFFERENCE_BOUND = 4.0


def intruder_relative_state(sim_lat: Array, sim_lon: Array, hdg: Array, gs: Array) -> dict[str, Array]:
    """Ownship-relative geometry of the intruders (slots 1..) shared by the CR tasks.

    All inputs are (rows, max_aircraft) simulator arrays with the ownship in slot 0. The
    expressions and their operation order are the reference's (docs/environments-v0.md §2 and §3), computed
    by :func:`bluesky_gym.tasks.compiled.intruder_relative_state`.

    Returns:
        ``dist_km`` kwik distance [km]; ``cos_bearing``/``sin_bearing`` of
        wrap180(hdg_own - qdr_own->int); ``x_dif``/``y_dif`` [m/s], the intruder velocity seen in
        the reference's ownship frame (not yet normalised). Each (rows, max_aircraft - 1).

    """
    n, m = sim_lat.shape
    out = np.empty((5, n, m - 1))
    count = np.empty(n, np.int64)
    compiled.intruder_relative_state(np.arange(n), np.zeros(n, np.int64), sim_lat, sim_lon, hdg, gs, np.ones((n, m), bool), False, out, count)
    return dict(zip(INTRUDER_STATE, out))


@dataclass(frozen=True)
class VerticalCRMeasurement(DescentMeasurement):
    """One step's quantities of the vertical CR task: the descent ones and the intruders'.

    ``separation_nm``/``los``: the kwik distances and the 5 NM / 1000 ft intrusion cylinder.
    """

    intruders: dict[str, Array]  # intruder_relative_state, (rows, num_intruders) each
    alt_difference: Array  # (rows, num_intruders) m, intruder minus ownship altitude
    vs_difference: Array  # (rows, num_intruders) m/s, intruder minus ownship vertical speed


@dataclass(frozen=True)
class VerticalCRConfig(DescentConfig):
    """Scenario options of the vertical conflict-resolution task (defaults: the paper's).

    The descent options (``alt_min``, ``alt_max``, ``target_alt_dif``, ``runway_distance_km``)
    are inherited. Integer draws are uniform over ``[min, max)``, as the reference's ``randint``.

    Attributes:
        num_intruders: Number of intruders (observation vectors have this length).
        dpsi_min: Lowest intruder track offset from the ownship track [deg].
        dpsi_max: Upper bound of the track offset draw [deg].
        dcpa_min: Lowest predicted distance at the closest point of approach [NM].
        dcpa_max: Upper bound of the dcpa draw [NM].
        tlosh_min: Lowest time to horizontal loss of separation [s].
        tlosh_runway_fraction: The tlosh draw's upper bound is the time the ownship needs, at its
            initial ground speed, to fly this fraction of the runway distance.
        late_dh_floor: An intruder met after the average top of descent is at least this high
            above the ground [m].
        late_dh_above_target: ... and below the target altitude plus this margin [m].
        early_dh_band: An intruder met before the average top of descent is within this band
            around the target altitude [m].
        normalise_vertical_speed: ``-v1``: ``z_difference_speed`` is divided by 5 m/s as the
            ownship's ``vz`` is; ``-v0``: raw m/s (the reference's).
        intruder_types: Aircraft types of the intruders: a type name, names drawn with equal
            probability (e.g. ``("A320", "B744")``) or ``{name: weight}``. Default A320 only (the
            paper's fleet, no random draw). Types are BlueSky's OpenAP types (``bluesky_gym.core.aircraft.supported_types()``).
        ownship_types: Aircraft type(s) of the ownship, in the same form (default A320), drawn
            after the initial and target altitudes.

    """

    num_intruders: int = 5
    dpsi_min: int = 45
    dpsi_max: int = 315
    dcpa_min: int = 0
    dcpa_max: int = 5
    tlosh_min: int = 100
    tlosh_runway_fraction: float = 0.9
    late_dh_floor: int = 500
    late_dh_above_target: int = 100
    early_dh_band: int = 500
    normalise_vertical_speed: bool = False
    intruder_types: TypeMix = DEFAULT_TYPES
    ownship_types: TypeMix = DEFAULT_TYPES

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first invalid option."""
        super().validate()
        check_int("num_intruders", self.num_intruders, 1, 50)
        check_int("dpsi_min", self.dpsi_min, 0, 359)
        check_int("dpsi_max", self.dpsi_max, self.dpsi_min + 1, 360)
        check_int("dcpa_min", self.dcpa_min, 0)
        check_int("dcpa_max", self.dcpa_max, self.dcpa_min + 1)
        check_int("tlosh_min", self.tlosh_min, 1)
        check_range("tlosh_runway_fraction", self.tlosh_runway_fraction, 0.0, 1.0, strict_low=True)
        check_int("late_dh_floor", self.late_dh_floor, 0)
        check_int("late_dh_above_target", self.late_dh_above_target, 0)
        check_int("early_dh_band", self.early_dh_band, 1)
        check_type_mix("intruder_types", self.intruder_types)
        check_type_mix("ownship_types", self.ownship_types)
        lowest_target = self.alt_min - self.target_alt_dif
        if lowest_target + self.late_dh_above_target <= self.late_dh_floor:
            raise ValueError(
                f"late_dh_floor must be below the lowest target altitude plus late_dh_above_target "
                f"({lowest_target} + {self.late_dh_above_target} m), got {self.late_dh_floor}"
            )
        if lowest_target - self.early_dh_band < 0:
            raise ValueError(
                f"early_dh_band must be <= the lowest target altitude ({lowest_target} m) so that intruders "
                f"stay above the ground, got {self.early_dh_band}"
            )
        # The tlosh draw needs a non-empty range for the fastest ownship (highest start).
        gs_max = float(isa.vcas2tas(AC_SPD, float(self.alt_max - 1)))
        tlosh_max = int((self.runway_distance_km * self.tlosh_runway_fraction) * KM / gs_max)
        if tlosh_max <= self.tlosh_min:
            raise ValueError(
                f"tlosh_min must be below the tlosh upper bound ({tlosh_max} s for the fastest ownship, from "
                f"runway_distance_km * tlosh_runway_fraction), got {self.tlosh_min}"
            )


class VerticalCRTask(DescentTask):
    """Batched vertical CR task; see :class:`bluesky_gym.environments.vertical_cr.env.VerticalCREnv`.

    It extends the descent task (same ownship, action, altitude reward and termination) with
    intruders that hold their level.
    """

    env_id: ClassVar[str] = "VerticalCREnv-v0"
    config_class: ClassVar[type[TaskConfig]] = VerticalCRConfig
    info_keys: ClassVar[tuple[str, ...]] = ("total_reward", "total_intrusions", "final_altitude")
    config: VerticalCRConfig

    def max_aircraft(self) -> int:
        """Aircraft slots: the ownship plus ``num_intruders`` intruders."""
        return 1 + self.config.num_intruders

    def build_observation_spec(self) -> dict[str, BoxSpec]:
        """Descent entries followed by the intruder entries (reference key order)."""
        spec = super().build_observation_spec()
        n = self.config.num_intruders
        for k in (
            "intruder_distance",
            "cos_difference_pos",
            "sin_difference_pos",
            "altitude_difference",
            "x_difference_speed",
            "y_difference_speed",
            "z_difference_speed",
        ):
            spec[k] = BoxSpec((n,))
        if self.config.float32_spaces:
            spec["intruder_distance"] = BoxSpec((n,), 0.0, INTRUDER_DISTANCE_BOUND)
            spec["cos_difference_pos"] = spec["sin_difference_pos"] = BoxSpec((n,), -1.0, 1.0)
            spec["altitude_difference"] = BoxSpec((n,), -ALT_DIFFERENCE_BOUND, ALT_DIFFERENCE_BOUND)
            spec["x_difference_speed"] = spec["y_difference_speed"] = BoxSpec((n,), -SPEED_DIFFERENCE_BOUND, SPEED_DIFFERENCE_BOUND)
            spec["z_difference_speed"] = BoxSpec((n,), -2 * VZ_BOUND, 2 * VZ_BOUND)
        return spec

    # --- generator ------------------------------------------------------------------------------
    def allocate(self) -> None:
        """Allocate the per-episode arrays (the descent ones and the intrusion counter)."""
        super().allocate()
        self.total_intrusions = np.zeros(self.n_envs, np.int64)
        # The scenario draws of the current episodes, (n_envs, num_intruders) each.
        shape = (self.n_envs, self.config.num_intruders)
        self.conflict_dpsi = np.zeros(shape)  # deg
        self.conflict_dcpa = np.zeros(shape)  # NM
        self.conflict_tlosh = np.zeros(shape)  # s
        self.conflict_dh = np.zeros(shape)  # m

    def generate(self, envs: NDArray[np.int64]) -> None:
        """Create the ownship as in the descent task, then the intruders, drawing from the episode generators only."""
        super().generate(envs)  # ownship and target altitude (the first two draws of each episode)
        c = self.config
        n = c.num_intruders
        dpsi = np.empty((envs.size, n))
        dcpa = np.empty((envs.size, n))
        tlosh = np.empty((envs.size, n))
        dh = np.empty((envs.size, n))
        imix = check_type_mix("intruder_types", c.intruder_types)
        intruder_types: list[str] = []
        for k, e in enumerate(envs):
            rng = self.rngs[e]
            altitude = float(self.sim.alt[e, 0])
            target = float(self.target_alt[e])
            spd = float(self.sim.gs[e, 0])
            tlosh_max = int((c.runway_distance_km * c.tlosh_runway_fraction) * KM / spd)
            # The reference's "average top of descent": flight time to the runway - 2 * target / 12.5 m/s.
            average_tod = (c.runway_distance_km * KM / spd) - 2 * target / ACTION_2_MS
            for i in range(n):
                dpsi[k, i] = rng.integers(c.dpsi_min, c.dpsi_max)
                dcpa[k, i] = rng.integers(c.dcpa_min, c.dcpa_max)
                tlosh[k, i] = rng.integers(c.tlosh_min, tlosh_max)
                if tlosh[k, i] > average_tod:
                    # Met late: between the floor above ground and just above the target.
                    dh[k, i] = rng.integers(int(-altitude + c.late_dh_floor), int((target - altitude) + c.late_dh_above_target))
                else:
                    # Met early: around the target altitude.
                    dh[k, i] = rng.integers(int((target - altitude) - c.early_dh_band), int((target - altitude) + c.early_dh_band))
            intruder_types += draw_types(rng, imix, n)  # last: the rest of the scenario does not depend on them
        self.conflict_dpsi[envs], self.conflict_dcpa[envs], self.conflict_tlosh[envs], self.conflict_dh[envs] = dpsi, dcpa, tlosh, dh
        env = np.repeat(envs, n)
        slot = np.tile(np.arange(1, n + 1), envs.size)
        # creconfs adds dH in metres (its docstring says ft; docs/environments-v0.md §0), then the reference
        # forces the intruder to that altitude and selects it, so the intruder holds level.
        self.sim.creconfs(env, 0, slot, dpsi.ravel(), dcpa.ravel(), tlosh.ravel(), dh.ravel(), TLOSV, **typed(intruder_types))
        alt = self.sim.alt[env, 0] + dh.ravel()
        self.sim.set_state(env, slot, alt=alt)
        self.sim.cmd_altitude(env, slot, alt, 0.0)
        self.total_intrusions[envs] = 0

    def ownship_types(self, envs: NDArray[np.int64]) -> list[str]:
        """The ownship's type in each reset episode, drawn from ``ownship_types`` (no draw for one type)."""
        mix = check_type_mix("ownship_types", self.config.ownship_types)
        return [t for e in envs for t in draw_types(self.rngs[e], mix, 1)]

    # --- measure --------------------------------------------------------------------------------
    def measure(self, envs: NDArray[np.int64] | None = None) -> VerticalCRMeasurement:
        """The descent quantities, the intruders' relative state and the intrusion cylinder test, of episodes ``envs``.

        Kernels :func:`vertical_cr_measure`,
        :func:`~bluesky_gym.tasks.compiled.kwik_separation` and
        :func:`~bluesky_gym.tasks.compiled.intruder_relative_state`.
        """
        ids = self.all_envs if envs is None else np.asarray(envs, dtype=np.int64)
        s = self.sim
        p, k = ids.size, s.max_aircraft - 1
        own = self.ownship[ids]
        alt, vs, runway_km, goal = np.empty(p), np.empty(p), np.empty(p), np.empty(p, bool)
        alt_difference, vs_difference = np.empty((p, k)), np.empty((p, k))
        vertical_cr_measure(
            ids, own, s.lat, s.lon, s.alt, s.vs, self.config.runway_distance_km, alt, vs, runway_km, goal, alt_difference, vs_difference
        )
        separation_nm, los = kwik_separation(s, ids, own, INTRUSION_DISTANCE, VERTICAL_MARGIN)
        intruders = np.empty((len(INTRUDER_STATE), p, k))
        compiled.intruder_relative_state(ids, own, s.lat, s.lon, s.hdg, s.gs, s.active, False, intruders, np.empty(p, np.int64))
        return VerticalCRMeasurement(
            envs=ids,
            separation_nm=separation_nm,
            los=los,
            drift_deg=None,
            goal_reached=goal,
            alt=alt,
            vs=vs,
            runway_km=runway_km,
            intruders=dict(zip(INTRUDER_STATE, intruders)),
            alt_difference=alt_difference,
            vs_difference=vs_difference,
        )

    # --- observation ----------------------------------------------------------------------------
    def observe(self, g: StepGeometry | None = None) -> dict[str, Array]:
        """The descent entries, then the intruders in creation order (slots 1..n, no sorting; docs/environments-v0.md §2; :func:`observation`)."""
        g = self.measure() if g is None else g
        assert isinstance(g, VerticalCRMeasurement)
        return observation(g, self.target_alt, self.config.normalise_vertical_speed)

    # --- reward ---------------------------------------------------------------------------------
    def reward(self, g: StepGeometry) -> tuple[Array, BoolArray, dict[str, Array]]:
        """Descent reward and termination plus -50 per intruder inside the 5 NM / 1000 ft cylinder (:func:`vertical_cr_reward`)."""
        assert isinstance(g, VerticalCRMeasurement)
        n = g.envs.size
        reward, terminated = np.empty(n), np.empty(n, bool)
        altitude, crash, runway, intrusion = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
        vertical_cr_reward(
            g.envs,
            g.alt,
            g.runway_km,
            g.los,
            self.target_alt,
            self.final_altitude,
            self.total_intrusions,
            reward,
            terminated,
            altitude,
            crash,
            runway,
            intrusion,
        )
        return reward, terminated, {"altitude": altitude, "crash": crash, "runway": runway, "intrusion": intrusion}

    def episode_info(self) -> dict[str, Array]:
        """Info keys of the reference, (n_envs,) each."""
        return {
            "total_reward": self.stats.total_reward.copy(),
            "total_intrusions": self.total_intrusions.copy(),  # type: ignore[dict-item]  # an int count, as the reference reports it
            "final_altitude": self.final_altitude.copy(),
        }


def observation(g: VerticalCRMeasurement, target_alt: Array, normalise_vertical_speed: bool) -> dict[str, Array]:
    """The descent entries, then the intruder entries of rows ``g.envs`` (scalings of the measurement).

    numpy arrays on the CPU, torch tensors in the device step
    (:mod:`bluesky_gym.environments.vertical_cr.device_step`), the same operations on both.
    """
    obs = descent.observation(g, target_alt)
    rel = g.intruders
    obs["intruder_distance"] = rel["dist_km"] / INTRUDER_DISTANCE_SCALE
    obs["cos_difference_pos"] = rel["cos_bearing"]
    obs["sin_difference_pos"] = rel["sin_bearing"]
    obs["altitude_difference"] = g.alt_difference / ALT_STD
    obs["x_difference_speed"] = rel["x_dif"] / SPEED_SCALE
    obs["y_difference_speed"] = rel["y_dif"] / SPEED_SCALE
    # m/s, not normalised in -v0 (reference quirk); -v1 divides by vz's 5 m/s.
    obs["z_difference_speed"] = g.vs_difference / VZ_STD if normalise_vertical_speed else g.vs_difference
    return obs


# --- kernels: the task's rules, run by the CPU task and launched by the device step ------------------
@jit
def vertical_cr_measure(
    envs: IntArray,
    own: IntArray,
    lat: Array,
    lon: Array,
    alt: Array,
    vs: Array,
    runway_distance_km: float,
    alt_out: Array,
    vs_out: Array,
    runway_out: Array,
    goal_out: BoolArray,
    alt_difference_out: Array,
    vs_difference_out: Array,
) -> None:
    """:func:`~bluesky_gym.environments.descent.task.descent_measure` of each row, and the other slots' altitude and vertical speed differences.

    Row ``r``: ownship slot ``own[r]`` of episode ``envs[r]``; ``alt_difference_out`` [m] and
    ``vs_difference_out`` [m/s] (p, m - 1): each other slot in slot order minus the ownship.
    """
    for r in grid_range(envs.shape[0]):
        e = envs[r]
        o = own[r]
        _measure_row(r, e, o, lat, lon, alt, vs, runway_distance_km, alt_out, vs_out, runway_out, goal_out)
        alt0, vs0 = alt[e, o], vs[e, o]
        for i in range(alt_difference_out.shape[1]):
            j = i if i < o else i + 1
            alt_difference_out[r, i] = alt[e, j] - alt0
            vs_difference_out[r, i] = vs[e, j] - vs0


@jit
def vertical_cr_reward(
    envs: IntArray,
    alt: Array,
    runway_km: Array,
    los: BoolArray,
    target_alt: Array,
    final_altitude: Array,
    total_intrusions: IntArray,
    reward_out: Array,
    terminated_out: BoolArray,
    altitude_out: Array,
    crash_out: Array,
    runway_out: Array,
    intrusion_out: Array,
) -> None:
    """The descent step (:func:`~bluesky_gym.environments.descent.task.descent_reward`) plus -50 per intruder in the intrusion cylinder.

    Row ``r`` (episode ``envs[r]``): ``los`` (p, m) the intrusion flags (False for the ownship);
    their count is added to ``total_intrusions[e]``.
    """
    for r in grid_range(envs.shape[0]):
        e = envs[r]
        reward, terminated_out[r], altitude_out[r], crash_out[r], runway_out[r], final_altitude[e] = _descent_reward(
            alt[r], runway_km[r], target_alt[e], final_altitude[e]
        )
        count = 0
        for j in range(los.shape[1]):
            if los[r, j]:
                count += 1
        intrusion = count * INTRUSION_PENALTY
        intrusion_out[r] = intrusion
        reward_out[r] = reward + intrusion
        total_intrusions[e] += count
