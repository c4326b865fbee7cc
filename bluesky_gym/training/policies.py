"""Policies for evaluation: the reference policies and a wrapper around trained SB3 models.

Two reference policies exist for every environment, so that scores can be normalised
(``(score - random) / (classical - random)``):

* ``random``: uniform actions in the action box, from a generator with a fixed seed.
* ``classical``: a simple hand-written controller that only reads the observation (it sees what
  an agent sees, decoded with the environment's normalisation constants):

  - DescentEnv-v0: hold the target altitude; descend along a glide path (``GLIDE_SLOPE`` m per
    km of runway distance, down to ``RUNWAY_ALT`` m) once that path is below the target.
  - VerticalCREnv-v0: the descent controller, plus, for the closest intruder that is closing in
    within ``VERTICAL_ALERT_KM`` km and less than ``VERTICAL_ALERT_ALT`` m away vertically, an
    altitude at least that far above or below it (whichever side it already is on; above when
    below would be too low).
  - HorizontalCREnv-v0: turn to the waypoint; turn away (full heading step) from the closest
    intruder that is closing in within ``HORIZONTAL_ALERT_KM`` km in front of the aircraft.
  - PlanWaypointEnv-v0: fly to the nearest waypoint not reached yet.
  - SectorCREnv-v0 and MergeEnv-v0: turn to the waypoint (FAF, then runway); for the intruder
    with the nearest predicted loss of separation (closest point of approach closer than the
    protected zone plus margin, within a look-ahead time, computed from relative position and
    velocity), turn away from the side on which it passes.
  - StaticObstacleEnv-v0: fly at the highest speed towards the goal on the heading closest to
    it whose straight path (to the goal, at most ``OBSTACLE_LOOKAHEAD_KM``) stays outside every
    obstacle's enclosing circle plus ``OBSTACLE_MARGIN_KM``.

  Controllers that need the previous observation (closing-in tests in VerticalCR and
  HorizontalCR, whose intruders are not sorted) keep it per environment; :meth:`Policy.reset`
  clears it for the environments whose episodes restarted.

These controllers are baselines, not optimised solutions: they show what an agent has to beat.

A third reference exists for the environments with traffic (those whose registry row names an
MVP mapping, ``EnvEntry.mvp``):

* ``mvp``: BlueSky's Modified Voltage Potential conflict resolution
  (:class:`~bluesky_gym.core.resolution.MVPResolver`, the field's classical baseline), with the
  RMETH setting that matches the action space, mapped to the environment's actions; without an
  active resolution the aircraft does what the classical controller does without intruders
  (steer to the goal, or the descent profile). It reads the simulator state through the
  :class:`~bluesky_gym.core.physics.Physics` interface, so it is bound to its batched environment
  with :meth:`Policy.bind` before acting (see docs/baselines.md).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from bluesky_gym.core.units import FT, KTS, NM, NM2KM
from bluesky_gym.envs.registry import ENVIRONMENTS, entry, resolve
from bluesky_gym.multiagent.policies import MIN_ACTION as MIN_ACTION  # the one policy module of every agent layout
from bluesky_gym.multiagent.policies import MVPMapping as MVPMapping
from bluesky_gym.multiagent.policies import MVPPolicy as MVPPolicy
from bluesky_gym.multiagent.policies import Obs as Obs
from bluesky_gym.multiagent.policies import Policy as Policy
from bluesky_gym.multiagent.policies import RandomPolicy as RandomPolicy
from bluesky_gym.multiagent.policies import SB3Policy as SB3Policy
from bluesky_gym.multiagent.policies import vertical_speed_action
from bluesky_gym.tasks import REFERENCE_POLICIES as REFERENCE_POLICIES
from bluesky_gym.tasks import RESOLUTION_REFERENCES as RESOLUTION_REFERENCES
from bluesky_gym.tasks import horizontal_cr, merge, plan_waypoint, sector_cr, static_obstacle, vertical_cr
from bluesky_gym.tasks import real_traffic as rt
from bluesky_gym.tasks.descent import ALT_MEAN, ALT_STD, RWY_DIS_MEAN, RWY_DIS_STD, DescentTask
from bluesky_gym.tasks.plan_waypoint import PlanWaypointConfig
from bluesky_gym.tasks.static_obstacle import StaticObstacleConfig

Array = NDArray[np.float64]

# The observation and action scales the controllers decode with are the tasks' own (imported, or
# derived from them in one expression); the numbers declared here are the controllers' tuning.
# The -v1 ids read these observations with the same scales (only entries the controllers do not
# read, airspeed and vertical speeds, are normalised differently there).

# --- DescentEnv-v0 / VerticalCREnv-v0 (docs/environments-v0.md §1 and §2) ------------------------
STEP_S_VERTICAL = DescentTask.dt * DescentTask.action_frequency  # s per decision step
GROUND_SPEED_EST = 0.17  # km/s, typical ground speed of the descent scenarios (CAS 150 m/s)
GLIDE_SLOPE = 80.0  # m per km of runway distance: steeper than the ~70 m/km possible, as the command lags
RUNWAY_ALT = 60.0  # m, altitude aimed at over the runway threshold (alt <= 0 before it crashes)
VERTICAL_ALERT_KM = 40.0  # km: intruders closer than this (and closing in) are avoided
VERTICAL_ALERT_ALT = 450.0  # m: vertical distance kept from an alerting intruder
VERTICAL_MIN_ALT = 300.0  # m: do not avoid downwards below this

# --- HorizontalCREnv-v0 / PlanWaypointEnv-v0 ---------------------------------------------------
HORIZONTAL_ALERT_KM = 30.0  # km: closing intruders in front and nearer than this are avoided
# Scenario options that set an observation scale: the defaults until the controller is bound to
# its environment (Policy.bind), then that environment's values.
WAYPOINT_DIST_PLAN = float(PlanWaypointConfig.waypoint_distance_max)  # km per unit of waypoint_distance (default scenario)
CAPTURE_KM = PlanWaypointConfig.distance_margin_km  # km: waypoints this near count as reached (default scenario)

# --- SectorCREnv-v0 / MergeEnv-v0 / RealTrafficCREnv-v0 ------------------------------------------
SECTOR_LOOKAHEAD_S = 180.0  # s: conflict look-ahead
MERGE_LOOKAHEAD_S = 300.0  # s: conflict look-ahead
REAL_TRAFFIC_LOOKAHEAD_S = 300.0  # s: conflict look-ahead
REAL_TRAFFIC_VERTICAL_ALERT_M = 2000.0 * FT  # m: traffic further above or below is not avoided
REAL_TRAFFIC_FAR_M = 1e9  # m: where an ignored intruder is put
CPA_MARGIN = 1.0  # -: alert when the predicted miss distance is below margin * protected zone

# --- StaticObstacleEnv-v0 ----------------------------------------------------------------------
OBSTACLE_DIST_SCALE = float(StaticObstacleConfig.waypoint_distance_max)  # km per unit of distance (default scenario)
OBSTACLE_RADIUS_SCALE_KM = static_obstacle.RADIUS_SCALE_NM * NM2KM  # km per unit of restricted_area_radius
OBSTACLE_MARGIN_KM = 3.0  # km: clearance kept from an obstacle's enclosing circle
OBSTACLE_LOOKAHEAD_KM = 60.0  # km: length of the path checked for obstacles
CANDIDATE_TURNS = np.arange(-180.0, 180.0, 5.0)  # deg, relative headings searched


class FunctionPolicy(Policy):
    """A stateless policy given as a function of the batched observation.

    Args:
        act: Batched observation dict -> batch of actions.
        name: Name shown in result tables.
    """

    def __init__(self, act: Callable[[Obs], Array], name: str) -> None:
        self._act, self.name = act, name

    def act(self, obs: Obs) -> Array:
        """The function's actions."""
        return self._act(obs)


def _angle(sin: Array, cos: Array) -> Array:
    """Angle [deg, (-180, 180]] from its sine and cosine."""
    return np.degrees(np.arctan2(sin, cos))


class _ClosingTracker:
    """Previous intruder distances per environment, to tell which intruders are closing in."""

    def __init__(self) -> None:
        self.prev: Array | None = None

    def reset(self, envs: NDArray[np.bool_] | None) -> None:
        if self.prev is None:
            return
        if envs is None:
            self.prev = None
        else:
            self.prev[np.asarray(envs, dtype=bool)] = np.nan

    def closing(self, dist: Array) -> NDArray[np.bool_]:
        """Whether each distance decreased since the last call (True without a previous value)."""
        if self.prev is None or self.prev.shape != dist.shape:
            self.prev = np.full(dist.shape, np.nan)
        out = ~(dist >= self.prev)  # NaN (no history) counts as closing
        self.prev = dist.copy()
        return out


class DescentController(Policy):
    """DescentEnv-v0: hold the target altitude, then follow a glide path to the runway."""

    name = "classical"

    def target_altitude(self, obs: Obs) -> tuple[Array, Array]:
        """Return the current and the wanted altitude [m] at the end of the next step."""
        alt = obs["altitude"][:, 0] * ALT_STD + ALT_MEAN
        target = obs["target_altitude"][:, 0] * ALT_STD + ALT_MEAN
        rd_next = obs["runway_distance"][:, 0] * RWY_DIS_STD + RWY_DIS_MEAN - GROUND_SPEED_EST * STEP_S_VERTICAL
        glide = RUNWAY_ALT + GLIDE_SLOPE * np.maximum(rd_next, 0.0)
        return alt, np.minimum(target, glide)

    def act(self, obs: Obs) -> Array:
        """Compute the controller's actions."""
        alt, wanted = self.target_altitude(obs)
        return vertical_speed_action((wanted - alt) / STEP_S_VERTICAL)[:, None]


class VerticalCRController(DescentController):
    """VerticalCREnv-v0: the descent controller plus vertical avoidance of closing intruders."""

    def __init__(self) -> None:
        self.tracker = _ClosingTracker()

    def reset(self, envs: NDArray[np.bool_] | None = None) -> None:
        """Forget the previous intruder distances of ``envs`` (all when None)."""
        self.tracker.reset(envs)

    def act(self, obs: Obs) -> Array:
        """Compute the controller's actions."""
        alt, wanted = self.target_altitude(obs)
        dist = obs["intruder_distance"] * vertical_cr.INTRUDER_DISTANCE_SCALE  # (n, k) km
        dalt = obs["altitude_difference"] * ALT_STD  # intruder minus own, m
        closing = self.tracker.closing(dist)
        # Intruders near the wanted altitude that are closing in.
        near = closing & (dist < VERTICAL_ALERT_KM) & (np.abs(wanted[:, None] - (alt[:, None] + dalt)) < VERTICAL_ALERT_ALT)
        d_alert = np.where(near, dist, np.inf)
        k = np.argmin(d_alert, axis=1)
        rows = np.arange(len(k))
        alert = np.isfinite(d_alert[rows, k])
        int_alt = alt + dalt[rows, k]
        below = int_alt - VERTICAL_ALERT_ALT
        above = int_alt + VERTICAL_ALERT_ALT
        go_below = (int_alt > alt) & (below > VERTICAL_MIN_ALT)
        avoid = np.where(go_below, np.minimum(wanted, below), np.maximum(wanted, above))
        wanted = np.where(alert, avoid, wanted)
        return vertical_speed_action((wanted - alt) / STEP_S_VERTICAL)[:, None]


class HorizontalCRController(Policy):
    """HorizontalCREnv-v0: steer to the waypoint; turn away from the closest closing intruder."""

    name = "classical"

    def __init__(self) -> None:
        self.tracker = _ClosingTracker()

    def reset(self, envs: NDArray[np.bool_] | None = None) -> None:
        """Forget the previous intruder distances of ``envs`` (all when None)."""
        self.tracker.reset(envs)

    def act(self, obs: Obs) -> Array:
        """Compute the controller's actions."""
        drift = _angle(obs["sin_drift"][:, 0], obs["cos_drift"][:, 0])
        a = np.clip(-drift / horizontal_cr.D_HEADING, -1.0, 1.0)
        dist = obs["intruder_distance"] * horizontal_cr.DISTANCE_SCALE
        closing = self.tracker.closing(dist)
        ahead = obs["cos_difference_pos"] > 0.0
        threat = np.where(closing & ahead & (dist < HORIZONTAL_ALERT_KM), dist, np.inf)
        k = np.argmin(threat, axis=1)
        rows = np.arange(len(k))
        alert = np.isfinite(threat[rows, k])
        # difference_pos = hdg - bearing > 0: the intruder is on the left, so turn right (a > 0).
        away = np.where(obs["sin_difference_pos"][rows, k] >= 0.0, 1.0, -1.0)
        return np.where(alert, away, a)[:, None]


def _task_config(env: Any) -> Any:
    """The scenario configuration of the task behind ``env`` (None when it has no task)."""
    task = getattr(getattr(env, "unwrapped", env), "task", None)
    return getattr(task, "config", None)


class PlanWaypointController(Policy):
    """PlanWaypointEnv-v0: fly to the nearest waypoint not yet reached.

    The waypoint distances are decoded with the default scenario's normalisation and capture
    radius, or with those of the environment the controller is bound to.
    """

    name = "classical"

    def __init__(self) -> None:
        self.distance_scale_km = WAYPOINT_DIST_PLAN
        self.capture_km = CAPTURE_KM

    def bind(self, env: Any) -> None:
        """Decode with the waypoint-distance normalisation and capture radius of ``env``'s scenario."""
        config = _task_config(env)
        if isinstance(config, PlanWaypointConfig):
            self.distance_scale_km = float(config.waypoint_distance_max)
            self.capture_km = float(config.distance_margin_km)

    def act(self, obs: Obs) -> Array:
        """Compute the controller's actions."""
        dist = obs["waypoint_distance"] * self.distance_scale_km
        open_ = (obs["waypoint_reached"] < 0.5) & (dist >= self.capture_km)
        k = np.argmin(np.where(open_, dist, np.inf), axis=1)
        rows = np.arange(len(k))
        drift = _angle(obs["sin_difference"][rows, k], obs["cos_difference"][rows, k])
        a = np.clip(-drift / plan_waypoint.D_HEADING, -1.0, 1.0)
        return np.where(open_.any(axis=1), a, 0.0)[:, None]


def _cpa_turn(rn: Array, re: Array, vn: Array, ve: Array, pz: float, lookahead: float) -> tuple[NDArray[np.bool_], Array]:
    """Decide on a conflict alert and turn direction from relative positions and velocities.

    Args:
        rn: Intruder position north of the ownship [m], (n, k).
        re: Intruder position east of the ownship [m], (n, k).
        vn: Intruder velocity relative to the ownship, north [m/s], (n, k).
        ve: Intruder velocity relative to the ownship, east [m/s], (n, k).
        pz: Protected-zone radius [m].
        lookahead: Alert horizon [s].

    Returns:
        Per environment: whether some intruder alerts, and the turn (+1 right, -1 left) away from
        the most urgent one.

    """
    v2 = np.maximum(vn * vn + ve * ve, 1e-9)
    tcpa = -(rn * vn + re * ve) / v2
    mn, me = rn + vn * tcpa, re + ve * tcpa  # intruder relative position at the CPA
    dcpa = np.hypot(mn, me)
    inside = np.hypot(rn, re) < pz
    alert = inside | ((tcpa > 0.0) & (tcpa < lookahead) & (dcpa < CPA_MARGIN * pz))
    urgency = np.where(alert, np.maximum(tcpa, 0.0), np.inf)
    k = np.argmin(urgency, axis=1)
    rows = np.arange(len(k))
    # The ownship moves relative to the intruder along w = -v; moving towards -m (away from the
    # intruder's CPA side) widens the miss. With similar speeds the heading is within 90 deg of w,
    # so "-m right of w" means "turn right". Dead-on conflicts (m ~ 0) turn right.
    wn, we = -vn[rows, k], -ve[rows, k]
    cross = wn * (-me[rows, k]) - we * (-mn[rows, k])
    turn = np.where(cross >= 0.0, 1.0, -1.0)
    return np.any(alert, axis=1), turn


class _SteerAndAvoid(Policy):
    """Steer to the target; turn away from the most urgent conflict (relative-traffic observations).

    Subclasses give the observation scales, the heading step and the conflict parameters.
    """

    name = "classical"
    heading_step: float  # deg per unit action
    pos_scale: float  # m per unit of x_r / y_r
    vn_scale: float  # m/s per unit of vx_r
    ve_scale: float  # m/s per unit of vy_r
    pz_m: float  # protected-zone radius [m]
    lookahead_s: float  # conflict look-ahead [s]

    def act(self, obs: Obs) -> Array:
        """Compute the controller's actions."""
        drift = _angle(obs["sin(drift)"][:, 0], obs["cos(drift)"][:, 0])
        a = np.clip(-drift / self.heading_step, -1.0, 1.0)
        alert, turn = _cpa_turn(
            obs["x_r"] * self.pos_scale,
            obs["y_r"] * self.pos_scale,
            obs["vx_r"] * self.vn_scale,
            obs["vy_r"] * self.ve_scale,
            self.pz_m,
            self.lookahead_s,
        )
        heading = np.where(alert, turn, a)
        return np.stack([heading, np.zeros_like(heading)], axis=1)


class SectorCRController(_SteerAndAvoid):
    """SectorCREnv-v0: steer to the exit waypoint; turn away from the most urgent conflict."""

    heading_step = sector_cr.D_HEADING
    pos_scale = sector_cr.POSITION_SCALE
    vn_scale = sector_cr.VX_SCALE
    ve_scale = sector_cr.VY_SCALE
    pz_m = sector_cr.INTRUSION_DISTANCE * NM
    lookahead_s = SECTOR_LOOKAHEAD_S


class MergeController(_SteerAndAvoid):
    """MergeEnv-v0: steer to the FAF then the runway; turn away from the most urgent conflict."""

    heading_step = merge.D_HEADING
    pos_scale = merge.POSITION_SCALE
    vn_scale = merge.SPEED_SCALE
    ve_scale = merge.SPEED_SCALE
    pz_m = merge.INTRUSION_DISTANCE * NM
    lookahead_s = MERGE_LOOKAHEAD_S


class StaticObstacleController(Policy):
    """StaticObstacleEnv-v0: full speed on the heading nearest the goal with a clear path.

    The distances are decoded with the default scenario's normalisation, or with that of the
    environment the controller is bound to.
    """

    name = "classical"

    def __init__(self) -> None:
        self.distance_scale_km = OBSTACLE_DIST_SCALE

    def bind(self, env: Any) -> None:
        """Decode with the distance normalisation of ``env``'s scenario."""
        config = _task_config(env)
        if isinstance(config, StaticObstacleConfig):
            self.distance_scale_km = float(config.waypoint_distance_max)

    def act(self, obs: Obs) -> Array:
        """Compute the controller's actions."""
        goal_rel = -_angle(obs["destination_waypoint_sin_drift"][:, 0], obs["destination_waypoint_cos_drift"][:, 0])  # deg, + right
        goal_km = obs["destination_waypoint_distance"][:, 0] * self.distance_scale_km
        d = obs["restricted_area_distance"] * self.distance_scale_km  # (n, m) km
        r = obs["restricted_area_radius"] * OBSTACLE_RADIUS_SCALE_KM + OBSTACLE_MARGIN_KM
        beta = -_angle(obs["sin_difference_restricted_area_pos"], obs["cos_difference_restricted_area_pos"])  # + right
        # Candidate relative headings (n, c); the path to check for each (n, c, m).
        cand = CANDIDATE_TURNS[None, :]
        rel = np.radians(beta[:, None, :] - cand[:, :, None])
        along = d[:, None, :] * np.cos(rel)
        across = np.abs(d[:, None, :] * np.sin(rel))
        length = np.minimum(goal_km, OBSTACLE_LOOKAHEAD_KM)[:, None, None]
        inside = (d < r)[:, None, :]  # already within an enclosing circle: that circle is ignored
        blocked = ~inside & (across < r[:, None, :]) & (along > 0.0) & (along < length + r[:, None, :])
        clear = ~np.any(blocked, axis=2)
        off_goal = np.abs((cand - goal_rel[:, None] + 180.0) % 360.0 - 180.0)
        best = np.argmin(np.where(clear, off_goal, np.inf), axis=1)
        turn = np.where(clear.any(axis=1), CANDIDATE_TURNS[best], goal_rel)
        heading = np.clip(turn / static_obstacle.D_HEADING, -1.0, 1.0)
        return np.stack([heading, np.ones_like(heading)], axis=1)


class SteerToGoal(Policy):
    """Cancel the drift to the goal with a heading action, at most a full step; speed action 0.

    Args:
        sin_key: Observation key of the drift's sine.
        cos_key: Observation key of the drift's cosine.
        heading_step: Degrees per unit of heading action.
        dims: Action size (the heading is component 0).
    """

    name = "steer"

    def __init__(self, sin_key: str, cos_key: str, heading_step: float, dims: int) -> None:
        self.sin_key, self.cos_key, self.heading_step, self.dims = sin_key, cos_key, heading_step, dims

    def act(self, obs: Obs) -> Array:
        """Heading actions towards the goal."""
        drift = _angle(obs[self.sin_key][:, 0], obs[self.cos_key][:, 0])
        out = np.zeros((drift.shape[0], self.dims))
        out[:, 0] = np.clip(-drift / self.heading_step, -1.0, 1.0)
        return out


# MVP's mapping of each environment with traffic, named by its registry row (``EnvEntry.mvp``).
# A -v1 id uses its -v0 mapping; with ``speed_step_in_knots`` (SectorCR-v1) the speed step is in knots.
HORIZONTAL_CR_MVP = MVPMapping(
    lambda: SteerToGoal("sin_drift", "cos_drift", horizontal_cr.D_HEADING, 1),
    rmethh="HDG",
    rpz_nm=horizontal_cr.INTRUSION_DISTANCE,
    heading_step=horizontal_cr.D_HEADING,
)
VERTICAL_CR_MVP = MVPMapping(DescentController, rmethv="V/S", rpz_nm=vertical_cr.INTRUSION_DISTANCE, hpz_m=vertical_cr.VERTICAL_MARGIN, vertical=True)
SECTOR_CR_MVP = MVPMapping(
    lambda: SteerToGoal("sin(drift)", "cos(drift)", sector_cr.D_HEADING, 2),
    rmethh="BOTH",
    rpz_nm=sector_cr.INTRUSION_DISTANCE,
    heading_step=sector_cr.D_HEADING,
    speed_step=sector_cr.D_VELOCITY,
)
MERGE_MVP = MVPMapping(
    lambda: SteerToGoal("sin(drift)", "cos(drift)", merge.D_HEADING, 2),
    rmethh="BOTH",
    rpz_nm=merge.INTRUSION_DISTANCE,
    heading_step=merge.D_HEADING,
    speed_step=merge.D_SPEED,
)


class RealTrafficController(Policy):
    """RealTrafficCREnv-v0: follow the recorded path; turn away from the most urgent conflict with traffic within 2000 ft."""

    name = "classical"

    def act(self, obs: Obs) -> Array:
        """Compute the controller's actions (heading and speed; zero: the recorded path and speed)."""
        intr = np.asarray(obs["intruders"])
        if intr.shape[-1] != rt.INTRUDER_FEATURES:  # -v1: the rows as one vector
            intr = intr.reshape(*intr.shape[:-1], rt.NUM_INTRUDERS, rt.INTRUDER_FEATURES)
        near = (intr[..., 6] > 0.5) & (np.abs(intr[..., 4] * rt.ALTITUDE_SCALE) < REAL_TRAFFIC_VERTICAL_ALERT_M)
        pos = rt.POSITION_SCALE * NM
        alert, turn = _cpa_turn(
            np.where(near, intr[..., 1] * pos, REAL_TRAFFIC_FAR_M),  # out of the vertical band: far away, never alerts
            np.where(near, intr[..., 0] * pos, REAL_TRAFFIC_FAR_M),
            intr[..., 3] * rt.VELOCITY_SCALE,
            intr[..., 2] * rt.VELOCITY_SCALE,
            rt.INTRUSION_NM * NM,
            REAL_TRAFFIC_LOOKAHEAD_S,
        )
        heading = np.where(alert, turn, 0.0)
        return np.stack([heading, np.zeros_like(heading)], axis=1)


RANDOM_POLICY_SEED = 0


#: Every reference policy name: the defaults, then the selectable ones.
SELECTABLE_REFERENCES: tuple[str, ...] = (*REFERENCE_POLICIES, *RESOLUTION_REFERENCES)


def optional_reference_names(env_id: str) -> tuple[str, ...]:
    """The selectable reference policies beyond :func:`reference_names` of an environment: ``eby``, ``swarm``, ``ssd`` where it has ``mvp``."""
    return tuple(RESOLUTION_REFERENCES) if entry(env_id).mvp is not None else ()


def reference_names(env_id: str) -> tuple[str, ...]:
    """The reference policies that exist for an environment (its registry row's): ``random``, ``classical``, and ``mvp`` where it has traffic."""
    return entry(env_id).reference_policies


def reference_policy(name: str, env_id: str, action_low: Array, action_high: Array) -> Policy:
    """Make a reference policy (``random``, ``classical``, ``mvp``, or ``eby``/``swarm``/``ssd``) of an environment.

    Args:
        name: ``"random"``, ``"classical"``, ``"mvp"``, ``"eby"``, ``"swarm"`` or ``"ssd"`` (the last four:
            environments with traffic; bind it to its environment with :meth:`Policy.bind` before acting).
        env_id: Environment id.
        action_low: Lower bound of the single-environment action box.
        action_high: Upper bound.

    """
    if name == "random":
        return RandomPolicy(action_low, action_high, seed=RANDOM_POLICY_SEED)
    if name == "classical":
        return classical_policy(env_id)
    if name == "mvp":
        return mvp_policy(env_id)
    if name in RESOLUTION_REFERENCES:
        return mvp_policy(env_id, RESOLUTION_REFERENCES[name])
    raise ValueError(f"unknown reference policy {name!r}; choose one of {', '.join(SELECTABLE_REFERENCES)}")


def classical_policy(env_id: str) -> Policy:
    """The ``classical`` reference policy of an environment: the controller its registry row names."""
    row = entry(env_id)
    if row.classical is None:
        raise ValueError(f"no classical controller for {env_id}; available: {', '.join(e.id for e in ENVIRONMENTS if e.classical)}")
    policy: Policy = resolve(row.classical)()
    return policy


def mvp_mapping(env_id: str) -> MVPMapping:
    """MVP's mapping of an environment with traffic: its registry row's, the speed step in knots where its configuration says so."""
    row = entry(env_id)
    if row.mvp is None:
        available = ", ".join(e.id for e in ENVIRONMENTS if e.mvp)
        raise ValueError(f"no MVP mapping for {env_id} (environments without traffic have nothing to resolve); available: {available}")
    mapping: MVPMapping = resolve(row.mvp)
    if mapping.speed_step is not None and dict(row.options).get("speed_step_in_knots", False):
        mapping = dataclasses.replace(mapping, speed_step=mapping.speed_step * KTS)
    return mapping


def mvp_policy(env_id: str, method: str = "MVP") -> MVPPolicy:
    """The ``mvp`` reference policy of an environment with traffic (bind it to that environment before acting).

    Args:
        env_id: Environment id (its registry row names an MVP mapping).
        method: The resolution method flown through the same mapping (``"EBY"``, ``"SWARM"``,
            ``"SSD"``: the ``eby``, ``swarm`` and ``ssd`` policies).
    """
    return MVPPolicy(mvp_mapping(env_id), env_id, method)
