"""The policies of every agent layout: random, MVP, a trained SB3 model, and the multi-agent classical rule.

A policy is bound to the environment or task it acts in (:meth:`Policy.bind`), then maps a batch
of observations (key -> (rows..., *shape)) to actions (rows..., dim): ``(n_envs, dim)`` for the
single-agent environments (the controlled row of an episode is its ownship, slot 0),
``(n_envs, n_agents, dim)`` for a batched multi-agent task (every agent slot; entries of empty
slots are ignored by the task). The single-agent reference policies
(:mod:`bluesky_gym.training.policies`) and the multi-agent evaluation
(:mod:`bluesky_gym.multiagent.evaluation`) use the same classes:

* :class:`RandomPolicy`: uniform actions in the action box from a seeded generator.
* :class:`MVPPolicy`: BlueSky's Modified Voltage Potential conflict resolution
  (:class:`~bluesky_gym.core.resolution.MVPResolver`) mapped to the actions by an
  :class:`MVPMapping`: for a multi-agent task, RMETHH ``BOTH`` (heading and speed actions) or
  ``HDG`` (heading only) with the task's intrusion distance as protected zone, every agent
  without an active resolution steering to its goal; for a single-agent environment, the
  environment's mapping (named by its registry row, :func:`bluesky_gym.training.policies.mvp_mapping`) with its nominal policy
  (docs/baselines.md).
* :class:`SB3Policy`: a Stable-Baselines3 model, shared by every agent of a multi-agent task
  (parameter sharing), optionally with the observation normalisation it was trained with.
* :class:`GeometricCRPolicy`, the multi-agent classical conflict-resolution rule: every agent
  checks its conflicts with BlueSky's state-based detection (:func:`bluesky_gym.core.conflicts.detect`:
  straight-line prediction; detection radius 1.2 x the task's intrusion distance, look-ahead
  120 s, chosen among a few values on SectorCR).
  With a conflict, it takes the intruder with the smallest predicted distance at the closest
  point of approach and turns away from it by a full heading step: left when that intruder passes
  on its right at the CPA, right otherwise. Without a conflict it steers to its goal (the heading
  action that cancels its drift, at most a full step). It keeps its speed. The rule reads the
  simulator state directly, not the observation.
"""

from __future__ import annotations

import abc
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from bluesky_gym.core.conflicts import PZ_HEIGHT, PZ_RADIUS, detect
from bluesky_gym.core.physics import Physics
from bluesky_gym.core.resolution import ConflictResolver, ResolutionSettings
from bluesky_gym.core.resolvers import resolver_class
from bluesky_gym.core.units import KTS, NM
from bluesky_gym.environments.descent.task import ACTION_2_MS
from bluesky_gym.multiagent.base import Array, MultiAgentTask

Obs = dict[str, Array]
MIN_ACTION = 0.01  # -: |a| <= VS_SELECT_EPS / ACTION_2_MS (0.008) selects BlueSky's default vertical speed; stay above

DEFAULT_LOOKAHEAD = 120.0  # s: conflict look-ahead of the classical rule
DEFAULT_MARGIN = 1.2  # detection radius / intrusion distance of the classical rule


def bound_task(env: Any) -> Any:
    """The task an environment (a Gymnasium or PettingZoo shell, wrapped or not) runs, or ``env`` itself when it is a task."""
    base = getattr(env, "unwrapped", env)
    return getattr(base, "task", base)


class Policy(abc.ABC):
    """A batched policy: observations (rows..., *shape) to actions (rows..., dim), for every agent layout."""

    #: Name shown in result tables.
    name: str = "policy"

    def reset(self, envs: NDArray[np.bool_] | None = None) -> None:  # noqa: B027 - stateless by default
        """Forget the memory of the episodes ``envs`` (a mask; all when None: a new batch of episodes starts)."""

    def bind(self, env: Any) -> None:  # noqa: B027 - observation-only policies need nothing
        """Attach the policy to the batched environment or multi-agent task it is about to act in (before its reset).

        Policies that read the simulator state (``mvp``, the multi-agent classical rule) keep it;
        the others ignore it, except to learn the layout of the rows.
        """

    @abc.abstractmethod
    def act(self, obs: Obs) -> Array:
        """Actions for a batch of observations."""


class RandomPolicy(Policy):
    """Uniform random actions in the action box, from a seeded generator.

    Args:
        low: Lower bound of the action box (per component); None: the bound task's.
        high: Upper bound; None: the bound task's.
        seed: Seed of the action generator.
    """

    name = "random"

    def __init__(self, low: Array | None = None, high: Array | None = None, seed: int = 0) -> None:
        self.low = None if low is None else np.asarray(low, dtype=np.float64)
        self.high = None if high is None else np.asarray(high, dtype=np.float64)
        self.seed = seed
        self.rng = np.random.default_rng(seed)
        self.lead = 1  # leading batch axes of the observation: 2 for a multi-agent task (episode, agent)

    def bind(self, env: Any) -> None:
        """Take the action box of a multi-agent task when none was given (a task's rows are its agent slots)."""
        task = bound_task(env)
        if isinstance(task, MultiAgentTask):
            self.lead = 2
            spec = task.action_spec
            if self.low is None or self.high is None:
                self.low = np.broadcast_to(np.asarray(spec.low, dtype=np.float64), spec.shape)
                self.high = np.broadcast_to(np.asarray(spec.high, dtype=np.float64), spec.shape)

    def reset(self, envs: NDArray[np.bool_] | None = None) -> None:
        """At a new batch of episodes (``envs`` None), restart the action generator: every evaluation sees the same actions."""
        if envs is None:
            self.rng = np.random.default_rng(self.seed)

    def act(self, obs: Obs) -> Array:
        """Draw one action per row."""
        if self.low is None or self.high is None:
            raise RuntimeError("the random policy needs its action box: give low and high, or bind(task) it to a multi-agent task")
        lead = next(iter(obs.values())).shape[: self.lead]
        return self.rng.uniform(self.low, self.high, size=(*lead, *self.low.shape))


class GeometricCRPolicy(Policy):
    """The classical rule: turn away from the most critical conflict, else steer to the goal.

    Args:
        lookahead: Look-ahead time of the conflict detection [s].
        margin: Protected-zone radius used for detection, as a multiple of the task's intrusion distance.
    """

    name = "classical"

    def __init__(self, lookahead: float = DEFAULT_LOOKAHEAD, margin: float = DEFAULT_MARGIN) -> None:
        self.lookahead = float(lookahead)
        self.margin = float(margin)

    def bind(self, env: Any) -> None:
        """Read the state of the multi-agent task ``env``."""
        task = bound_task(env)
        if not isinstance(task, MultiAgentTask):
            raise ValueError(f"the classical rule steers every agent of a multi-agent task, got {env!r}")
        self.task = task

    def act(self, obs: Obs) -> Array:
        """Return the rule's heading actions (speed actions are zero)."""
        task = self.task
        s = task.sim
        c = detect(
            s.lat, s.lon, s.alt, s.gs, s.trk, s.vs, s.active, rpz=task.intrusion_distance * NM * self.margin, hpz=PZ_HEIGHT, lookahead=self.lookahead
        )
        key = np.where(c.conflict, np.nan_to_num(c.dcpa, nan=0.0), np.inf)
        j = np.argmin(key, axis=2)[..., None]  # (n_envs, n_agents, 1): most critical intruder
        has_conflict = np.isfinite(np.take_along_axis(key, j, axis=2)[..., 0])

        def at(a: Array) -> Array:
            return np.take_along_axis(a, j, axis=2)[..., 0]

        # Intruder position relative to the agent now (east, north) and at the CPA.
        q = np.deg2rad(at(c.qdr))
        d = at(c.dist)
        tcpa = np.maximum(at(c.tcpa), 0.0)
        trk = np.deg2rad(s.trk)
        u, v = s.gs * np.sin(trk), s.gs * np.cos(trk)
        du = at(u[:, None, :] - u[:, :, None])  # intruder minus agent velocity
        dv = at(v[:, None, :] - v[:, :, None])
        east = d * np.sin(q) + du * tcpa
        north = d * np.cos(q) + dv * tcpa
        side = (np.degrees(np.arctan2(east, north)) - s.hdg + 180.0) % 360.0 - 180.0
        turn = np.where(side > 0.0, -1.0, 1.0)  # passes on the right: turn left, and vice versa
        steer = np.clip(-task.agent_drift() / task.heading_step, -1.0, 1.0)
        heading = np.where(has_conflict, turn, steer)
        out = np.zeros((task.n_envs, task.n_agents, *task.action_spec.shape))
        out[..., 0] = heading
        return out


@dataclass(frozen=True)
class MVPMapping:
    """How MVP drives an environment: RMETH setting, protected zone and the action normalisation.

    Attributes:
        nominal: Factory of the policy flown without an active resolution (observation only);
            None: steer to the goal with the task's drift (the multi-agent tasks).
        rmethh: BlueSky ``RMETHH`` value (None: not given).
        rmethv: BlueSky ``RMETHV`` value (None: not given).
        rpz_nm: Protected-zone radius [NM] (the environment's intrusion distance).
        hpz_m: Protected-zone half height [m].
        heading_step: Degrees of heading change per unit of action 0, or None (no heading action).
        speed_step: m/s of CAS change per unit of action 1, or None (no speed action).
        vertical: Action 0 is a vertical speed (``ACTION_2_MS`` m/s per unit).
    """

    nominal: Callable[[], Policy] | None = None
    rmethh: str | None = None
    rmethv: str | None = None
    rpz_nm: float = PZ_RADIUS / NM
    hpz_m: float = PZ_HEIGHT
    heading_step: float | None = None
    speed_step: float | None = None
    vertical: bool = False


def multiagent_mvp_mapping(task: MultiAgentTask) -> MVPMapping:
    """MVP's mapping of a multi-agent task: RMETHH ``BOTH`` with a speed action, else ``HDG``; the task's action steps and intrusion distance."""
    if getattr(task, "heading_step", None) is None:
        raise ValueError(f"no MVP mapping for {task.name}: it has no heading action step (heading_step)")
    speed_step = task.speed_step
    if speed_step is not None and getattr(task.config, "speed_step_in_knots", False):
        speed_step *= KTS
    return MVPMapping(
        rmethh="BOTH" if speed_step is not None else "HDG", rpz_nm=task.intrusion_distance, heading_step=task.heading_step, speed_step=speed_step
    )


def vertical_speed_action(v_cmd: Array) -> Array:
    """Vertical-speed command [m/s] to an action, avoiding BlueSky's default-VS band."""
    a = np.clip(v_cmd / ACTION_2_MS, -1.0, 1.0)
    return np.where(np.abs(a) < MIN_ACTION, np.where(a < 0, -MIN_ACTION, MIN_ACTION), a)


class MVPPolicy(Policy):
    """MVP conflict resolution (BlueSky ``RESO MVP``) mapped to an environment's actions.

    Every controlled aircraft (the ownship of a single-agent environment, every agent of a
    multi-agent task) follows MVP's resolution while BlueSky's ASAS would (from the first conflict
    until its pairs are past their closest point of approach); otherwise it flies the mapping's
    nominal policy. Heading actions turn by the resolution's track change, speed actions change
    CAS by what gives the resolution ground speed, vertical-speed actions fly the resolution's
    vertical speed towards its altitude; all divided by the environment's action steps and
    clipped to the action box.

    Args:
        mapping: How MVP drives the environment; None: the mapping of the multi-agent task it
            is bound to (:func:`multiagent_mvp_mapping`).
        env_id: The environment the mapping is for; :meth:`bind` refuses another one.
        method: The resolution method, a ``RESO`` name of :data:`~bluesky_gym.core.resolvers.RESOLVERS`
            (``"MVP"``, the default; ``"EBY"``, ``"SWARM"`` or ``"SSD"`` give the ``eby``, ``swarm``
            and ``ssd`` policies, the same mapping flying that method's resolution).
    """

    name = "mvp"

    def __init__(self, mapping: MVPMapping | None = None, env_id: str | None = None, method: str = "MVP") -> None:
        self.env_id = env_id
        self.method = method
        self.name = method.lower()
        self.resolver_class = resolver_class(method)
        self.from_task = mapping is None  # the mapping comes from the multi-agent task bound
        self.mapping: MVPMapping | None = None
        self.resolver: ConflictResolver | None = None
        self.nominal: Policy | None = None
        self.physics: Physics | None = None
        self.task: MultiAgentTask | None = None
        if mapping is not None:
            self._use(mapping)

    def _use(self, mapping: MVPMapping) -> None:
        self.mapping = mapping
        settings = ResolutionSettings.from_methods(mapping.rmethh, mapping.rmethv)
        self.resolver = self.resolver_class(settings, rpz=mapping.rpz_nm * NM, hpz=mapping.hpz_m)
        self.nominal = mapping.nominal() if mapping.nominal is not None else None

    def bind(self, env: Any) -> None:
        """Use the physics of the batched environment or multi-agent task ``env``."""
        task = bound_task(env)
        if isinstance(task, MultiAgentTask):
            if self.from_task and (self.task is None or self.task.name != task.name or self.task.config != task.config):
                self._use(multiagent_mvp_mapping(task))
            self.task = task
        else:
            spec = getattr(getattr(env, "unwrapped", env), "spec", None)
            if task is None or self.env_id is None or getattr(spec, "id", getattr(task, "id", None)) != self.env_id:
                raise ValueError(f"the {self.name} policy of {self.env_id} needs that environment, got {env!r}")
        self.physics = task.sim
        assert self.resolver is not None
        self.resolver.reset()

    def reset(self, envs: NDArray[np.bool_] | None = None) -> None:
        """Forget the resolutions of the episodes ``envs`` (all when None)."""
        if self.nominal is not None:
            self.nominal.reset(envs)
        if self.resolver is not None:
            self.resolver.reset(envs)

    def act(self, obs: Obs) -> Array:
        """Resolution actions where MVP is active, the nominal policy's elsewhere."""
        if self.physics is None or self.resolver is None or self.mapping is None:
            raise RuntimeError(f"the {self.name} policy reads the simulator state: bind(env) it to its environment first")
        m, task = self.mapping, self.task
        if task is not None:  # every agent slot; nominal: steer to the goal, speed unchanged
            assert m.heading_step is not None
            action = np.zeros((task.n_envs, task.n_agents, *task.action_spec.shape))
            action[..., 0] = np.clip(-task.agent_drift() / m.heading_step, -1.0, 1.0)

            def rows(a: NDArray[Any]) -> NDArray[Any]:
                return a
        else:  # the ownship (slot 0) of every episode
            assert self.nominal is not None
            action = np.asarray(self.nominal.act(obs), dtype=np.float64).copy()

            def rows(a: NDArray[Any]) -> NDArray[Any]:
                return a[:, 0]

        cmd = self.resolver.update(self.physics)
        follow = rows(cmd.follow)
        if m.vertical:
            action[..., 0] = np.where(follow, vertical_speed_action(np.nan_to_num(rows(cmd.vertical_speed))), action[..., 0])
        if m.heading_step is not None:
            action[..., 0] = np.where(follow, np.clip(np.nan_to_num(rows(cmd.track_change)) / m.heading_step, -1.0, 1.0), action[..., 0])
        if m.speed_step is not None:
            action[..., 1] = np.where(follow, np.clip(np.nan_to_num(rows(cmd.cas_change)) / m.speed_step, -1.0, 1.0), action[..., 1])
        return action


class SB3Policy(Policy):
    """A trained Stable-Baselines3 model, acting deterministically by default.

    Bound to a multi-agent task, the one model acts for every agent (parameter sharing): the
    (n_envs, n_agents) observations are one batch of rows.

    Args:
        model: An SB3 algorithm instance (``PPO.load(...)`` etc.); for a multi-agent task, one
            whose observation space is one agent's (e.g. trained on
            :class:`~bluesky_gym.multiagent.sb3.SharedPolicyVecEnv`).
        deterministic: Use the mean / greedy action.
        name: Name shown in result tables.
        normalizer: The observation normalisation the model was trained with (an SB3
            ``VecNormalize``, e.g. :class:`~bluesky_gym.multiagent.sb3.LiveRowsVecNormalize`; only
            its ``normalize_obs`` is used, its statistics are not changed), or None.
    """

    def __init__(self, model: Any, deterministic: bool = True, name: str = "model", normalizer: Any = None) -> None:
        self.model = model
        self.deterministic = deterministic
        self.name = name
        self.normalizer = normalizer
        self.lead = 1

    def bind(self, env: Any) -> None:
        """Learn the layout of the rows (two batch axes for a multi-agent task)."""
        self.lead = 2 if isinstance(bound_task(env), MultiAgentTask) else 1

    def act(self, obs: Obs) -> Array:
        """Predict the model's actions."""
        lead = next(iter(obs.values())).shape[: self.lead]
        rows = {k: np.asarray(v).reshape(-1, *np.shape(v)[self.lead :]) for k, v in obs.items()} if self.lead > 1 else obs
        if self.normalizer is not None:
            rows = self.normalizer.normalize_obs(rows)
        action, _ = self.model.predict(rows, deterministic=self.deterministic)
        action = np.asarray(action, dtype=np.float64)
        return action.reshape(*lead, *action.shape[1:])
