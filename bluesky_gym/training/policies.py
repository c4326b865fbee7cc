"""Policies for evaluation: the reference policies and a wrapper around trained SB3 models.

Two reference policies exist for every environment, so that scores can be normalised
(``(score - random) / (classical - random)``):

* ``random``: uniform actions in the action box, from a generator with a fixed seed.
* ``classical``: a simple hand-written controller that only reads the observation (it sees what
  an agent sees, decoded with the environment's normalisation constants). Each environment keeps
  its own in its folder (``bluesky_gym/environments/<name>/controller.py``, named by its registry
  row's ``classical``); this module holds what they share: the conflict geometry
  (:func:`cpa_turn`), the closing-in test of unsorted intruders (:class:`ClosingTracker`), the
  steer-and-avoid rule (:class:`SteerAndAvoid`) and steering to the goal (:class:`SteerToGoal`).
  Controllers that need the previous observation keep it per environment;
  :meth:`Policy.reset` clears it for the environments whose episodes restarted.

These controllers are baselines, not optimised solutions: they show what an agent has to beat.

A third reference exists for the environments with traffic (those whose registry row names an
MVP mapping, ``EnvEntry.mvp``, kept beside the environment's controller):

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

from bluesky_gym.core.units import KTS
from bluesky_gym.envs.registry import ENVIRONMENTS, entry, resolve
from bluesky_gym.multiagent.policies import MIN_ACTION as MIN_ACTION  # the one policy module of every agent layout
from bluesky_gym.multiagent.policies import MVPMapping as MVPMapping
from bluesky_gym.multiagent.policies import MVPPolicy as MVPPolicy
from bluesky_gym.multiagent.policies import Obs as Obs
from bluesky_gym.multiagent.policies import Policy as Policy
from bluesky_gym.multiagent.policies import RandomPolicy as RandomPolicy
from bluesky_gym.multiagent.policies import SB3Policy as SB3Policy
from bluesky_gym.multiagent.policies import vertical_speed_action as vertical_speed_action
from bluesky_gym.tasks import REFERENCE_POLICIES as REFERENCE_POLICIES
from bluesky_gym.tasks import RESOLUTION_REFERENCES as RESOLUTION_REFERENCES

Array = NDArray[np.float64]

# The observation and action scales the controllers decode with are the tasks' own (imported, or
# derived from them in one expression); the numbers declared by the controllers are their tuning.
# The -v1 ids read these observations with the same scales (only entries the controllers do not
# read, airspeed and vertical speeds, are normalised differently there).
CPA_MARGIN = 1.0  # -: alert when the predicted miss distance is below margin * protected zone


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


def angle(sin: Array, cos: Array) -> Array:
    """Angle [deg, (-180, 180]] from its sine and cosine."""
    return np.degrees(np.arctan2(sin, cos))


class ClosingTracker:
    """Previous intruder distances per environment, to tell which intruders are closing in."""

    def __init__(self) -> None:
        self.prev: Array | None = None

    def reset(self, envs: NDArray[np.bool_] | None) -> None:
        """Forget the previous distances of ``envs`` (all when None)."""
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


def task_config(env: Any) -> Any:
    """The scenario configuration of the task behind ``env`` (None when it has no task)."""
    task = getattr(getattr(env, "unwrapped", env), "task", None)
    return getattr(task, "config", None)


def cpa_turn(rn: Array, re: Array, vn: Array, ve: Array, pz: float, lookahead: float) -> tuple[NDArray[np.bool_], Array]:
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


class SteerAndAvoid(Policy):
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
        drift = angle(obs["sin(drift)"][:, 0], obs["cos(drift)"][:, 0])
        a = np.clip(-drift / self.heading_step, -1.0, 1.0)
        alert, turn = cpa_turn(
            obs["x_r"] * self.pos_scale,
            obs["y_r"] * self.pos_scale,
            obs["vx_r"] * self.vn_scale,
            obs["vy_r"] * self.ve_scale,
            self.pz_m,
            self.lookahead_s,
        )
        heading = np.where(alert, turn, a)
        return np.stack([heading, np.zeros_like(heading)], axis=1)


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
        drift = angle(obs[self.sin_key][:, 0], obs[self.cos_key][:, 0])
        out = np.zeros((drift.shape[0], self.dims))
        out[:, 0] = np.clip(-drift / self.heading_step, -1.0, 1.0)
        return out


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
