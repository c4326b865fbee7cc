"""Joint policies for the batched multi-agent tasks: random, a classical geometric rule, a shared SB3 model.

A policy maps the task and its observation (key -> (n_envs, n_agents, *shape)) to joint actions
(n_envs, n_agents, dim). Entries of empty agent slots are ignored by the task.

* :class:`RandomPolicy`: uniform actions from a seeded generator.
* :class:`GeometricCRPolicy`, the classical conflict-resolution rule: every agent checks its
  conflicts with BlueSky's state-based detection (:func:`bluesky_gym.core.conflicts.detect`:
  straight-line prediction; detection radius 1.2 x the task's intrusion distance, look-ahead
  120 s, chosen among a few values on SectorCR).
  With a conflict, it takes the intruder with the smallest predicted distance at the closest
  point of approach and turns away from it by a full heading step: left when that intruder passes
  on its right at the CPA, right otherwise. Without a conflict it steers to its goal (the heading
  action that cancels its drift, at most a full step). It keeps its speed. The rule reads the
  simulator state directly, not the observation.
* :class:`MVPPolicy`: BlueSky's Modified Voltage Potential conflict resolution
  (:class:`~bluesky_gym.core.resolution.MVPResolver`) for every agent, with RMETHH ``BOTH``
  (heading and speed actions) or ``HDG`` (heading only) and the task's intrusion distance as
  protected zone; an agent without an active resolution steers to its goal like the classical
  rule (docs/baselines.md).
* :class:`SharedSB3Policy`: one Stable-Baselines3 model applied to every agent (parameter sharing).
"""

from __future__ import annotations

import abc
from typing import Any

import numpy as np

from bluesky_gym.core.conflicts import PZ_HEIGHT, detect
from bluesky_gym.core.resolution import MVPResolver, ResolutionSettings
from bluesky_gym.core.units import NM
from bluesky_gym.multiagent.base import Array, MultiAgentTask
from bluesky_gym.tasks import horizontal_cr, merge, sector_cr

DEFAULT_LOOKAHEAD = 120.0  # s: conflict look-ahead of the classical rule
DEFAULT_MARGIN = 1.2  # detection radius / intrusion distance of the classical rule

#: Heading change [deg] of a full heading action, per multi-agent environment.
D_HEADING: dict[str, float] = {
    "sector_cr_v0": sector_cr.D_HEADING,
    "merge_v0": merge.D_HEADING,
    "horizontal_cr_v0": horizontal_cr.D_HEADING,
}


#: CAS change [m/s] of a full speed action, per multi-agent environment with a speed action.
D_SPEED: dict[str, float] = {
    "sector_cr_v0": sector_cr.D_VELOCITY,
    "merge_v0": merge.D_SPEED,
}


class MultiAgentPolicy(abc.ABC):
    """A batched joint policy."""

    #: Name shown in result tables.
    name: str = "policy"

    def reset(self) -> None:  # noqa: B027 - stateless by default
        """Forget any memory (called when a new batch of episodes starts)."""

    @abc.abstractmethod
    def act(self, task: MultiAgentTask, obs: dict[str, Array]) -> Array:
        """Return joint actions (n_envs, n_agents, dim) for the task's current state and observation."""


class RandomPolicy(MultiAgentPolicy):
    """Uniform random actions in the action box.

    Args:
        seed: Seed of the action generator.
    """

    name = "random"

    def __init__(self, seed: int = 0) -> None:
        self.seed = seed
        self.rng = np.random.default_rng(seed)

    def reset(self) -> None:
        """Restart the action generator (every evaluation sees the same random actions)."""
        self.rng = np.random.default_rng(self.seed)

    def act(self, task: MultiAgentTask, obs: dict[str, Array]) -> Array:
        """Return uniform actions for every agent slot."""
        spec = task.action_spec
        return self.rng.uniform(spec.low, spec.high, size=(task.n_envs, task.n_agents, *spec.shape))


class GeometricCRPolicy(MultiAgentPolicy):
    """The classical rule: turn away from the most critical conflict, else steer to the goal.

    Args:
        lookahead: Look-ahead time of the conflict detection [s].
        margin: Protected-zone radius used for detection, as a multiple of the task's intrusion distance.
    """

    name = "classical"

    def __init__(self, lookahead: float = DEFAULT_LOOKAHEAD, margin: float = DEFAULT_MARGIN) -> None:
        self.lookahead = float(lookahead)
        self.margin = float(margin)

    def act(self, task: MultiAgentTask, obs: dict[str, Array]) -> Array:
        """Return the rule's heading actions (speed actions are zero)."""
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
        steer = np.clip(-task.agent_drift() / D_HEADING[task.name], -1.0, 1.0)
        heading = np.where(has_conflict, turn, steer)
        out = np.zeros((task.n_envs, task.n_agents, *task.action_spec.shape))
        out[..., 0] = heading
        return out


class MVPPolicy(MultiAgentPolicy):
    """MVP conflict resolution (BlueSky ``RESO MVP``) for every agent, else steer to the goal.

    Every aircraft follows MVP's resolution while BlueSky's ASAS would (from its first conflict
    until its pairs are past their closest point of approach): the heading action turns by the
    resolution's track change and, where the task has a speed action, the speed action changes
    CAS by what gives the resolution ground speed (RMETHH ``BOTH``; ``HDG`` without a speed
    action), each divided by the task's full step and clipped. Other agents steer to their goal.
    """

    name = "mvp"

    def __init__(self) -> None:
        self.resolver: MVPResolver | None = None
        self.task_name: str | None = None

    def reset(self) -> None:
        """Forget every resolution (a new batch of episodes starts)."""
        if self.resolver is not None:
            self.resolver.reset()

    def act(self, task: MultiAgentTask, obs: dict[str, Array]) -> Array:
        """Return MVP's heading (and speed) actions for every agent slot."""
        if task.name not in D_HEADING:
            raise ValueError(f"no MVP mapping for {task.name}; available: {', '.join(D_HEADING)}")
        speed_step = D_SPEED.get(task.name)
        if self.resolver is None or self.task_name != task.name:
            settings = ResolutionSettings.from_methods("BOTH" if speed_step is not None else "HDG")
            self.resolver = MVPResolver(settings, rpz=task.intrusion_distance * NM, hpz=PZ_HEIGHT)
            self.task_name = task.name
        cmd = self.resolver.update(task.sim)
        step = D_HEADING[task.name]
        steer = np.clip(-task.agent_drift() / step, -1.0, 1.0)
        out = np.zeros((task.n_envs, task.n_agents, *task.action_spec.shape))
        out[..., 0] = np.where(cmd.follow, np.clip(np.nan_to_num(cmd.track_change) / step, -1.0, 1.0), steer)
        if speed_step is not None:
            out[..., 1] = np.where(cmd.follow, np.clip(np.nan_to_num(cmd.cas_change) / speed_step, -1.0, 1.0), 0.0)
        return out


class SharedSB3Policy(MultiAgentPolicy):
    """One Stable-Baselines3 model acting for every agent (parameter sharing).

    Args:
        model: A trained SB3 model whose observation space is one agent's (e.g. trained on
            :class:`~bluesky_gym.multiagent.sb3.SharedPolicyVecEnv`).
        deterministic: Use the mean action.
        name: Name shown in result tables.
        normalizer: The observation normalisation the model was trained with (an SB3
            ``VecNormalize``, e.g. :class:`~bluesky_gym.multiagent.sb3.LiveRowsVecNormalize`; only
            its ``normalize_obs`` is used, its statistics are not changed), or None.
    """

    def __init__(self, model: Any, deterministic: bool = True, name: str = "shared PPO", normalizer: Any = None) -> None:
        self.model = model
        self.deterministic = deterministic
        self.name = name
        self.normalizer = normalizer

    def act(self, task: MultiAgentTask, obs: dict[str, Array]) -> Array:
        """Return the model's action for every agent slot (one batch of n_envs * n_agents rows)."""
        rows = {k: v.reshape(task.n_envs * task.n_agents, *v.shape[2:]) for k, v in obs.items()}
        if self.normalizer is not None:
            rows = self.normalizer.normalize_obs(rows)
        action, _ = self.model.predict(rows, deterministic=self.deterministic)
        return np.asarray(action, dtype=np.float64).reshape(task.n_envs, task.n_agents, *task.action_spec.shape)
