"""Multi-agent DenseSectorCR: every aircraft in the sector is an agent, and new agents keep entering.

The scenario is DenseSectorCREnv-v0's (:class:`~bluesky_gym.environments.dense_sector_cr.task.DenseSectorCRTask`):
SectorCR's sector and initial traffic, and a traffic flow whose spawn rate rises through the
episode. Each agent has SectorCR's multi-agent observation, action and reward
(:class:`~bluesky_gym.environments.sector_cr.multiagent.SectorCRMultiAgentTask`); it leaves (truncated) when it
is outside the sector.

Agents that appear mid-episode: an aircraft that enters the sector during a step did not act in
it; the step's result holds its first observation (reward 0, neither terminated nor truncated, an
empty info in the PettingZoo environment), and it acts from the next step on. Its name is the
slot's, ``aircraft_k``; slots are not reused within an episode, so a name is one aircraft. An
aircraft that enters in the last step (the time limit) is not an agent. The episode ends at the
time limit, or earlier when no aircraft is left.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from bluesky_gym.environments.dense_sector_cr import task as dsc
from bluesky_gym.environments.sector_cr.multiagent import SectorCRMultiAgentTask
from bluesky_gym.multiagent.base import Array, BoolArray, IntArray, MultiAgentStepResult
from bluesky_gym.multiagent.centralised import CentralisedEnv
from bluesky_gym.tasks.base import StepGeometry, Task


class DenseSectorCRMultiAgentTask(SectorCRMultiAgentTask):
    """Batched multi-agent dense sector conflict resolution.

    Per agent, SectorCR's multi-agent observation, action and reward (see
    :class:`~bluesky_gym.environments.sector_cr.multiagent.SectorCRMultiAgentTask`); the agents are the aircraft
    of the sector at the start and those that enter during the episode (see the module docstring).

    KPIs beyond the common ones: ``kpi_time_to_first_los_s`` (episode time of the first loss of
    separation between two aircraft that starts during the episode; NaN without one),
    ``kpi_los_per_flight_hour`` (new losses of separation per hour flown by the agents together)
    and ``kpi_aircraft_spawned`` (aircraft that entered). ``kpi_agents`` counts every agent of the
    episode, those that entered included.
    """

    name: ClassVar[str] = "dense_sector_cr_v0"
    env_id: ClassVar[str] = "DenseSectorCR multi-agent"
    scenario_class = dsc.DenseSectorCRTask
    scenario: dsc.DenseSectorCRTask
    config: dsc.DenseSectorCRConfig

    def allocate(self) -> None:
        """The first-loss clock: per episode, the time of its first new loss of separation and the losses present at its start."""
        self.first_los_s = np.full(self.n_envs, np.nan)  # s
        self.los_at_start = np.zeros(self.n_envs, np.int64)

    def on_reset(self, envs: IntArray) -> None:
        """The first-loss clock of the new episodes."""
        self.first_los_s[envs] = np.nan

    def reset(self, envs: IntArray | None = None) -> None:
        """Start new episodes; the losses of separation present at their start are not counted by the first-loss clock."""
        super().reset(envs)
        envs = self.all_envs if envs is None else np.asarray(envs, dtype=np.int64)
        self.los_at_start[envs] = self.stats.los_count[envs]

    def advance(self) -> None:
        """The physics sub-steps, then the aircraft that enter the running episodes (they appear as agents).

        The aircraft that left the sector are removed by the layout (:meth:`leaving`), not by the scenario.
        """
        Task.advance(self)
        created = self.scenario.spawn(np.flatnonzero(~self.finished))
        self.stats.n_start += created

    def record(self, g: StepGeometry, reward: Array | None) -> None:
        """The common statistics, and the time of the first loss of separation that starts during the episode."""
        super().record(g, reward)
        st = self.stats
        running = np.flatnonzero(~self.finished)
        dsc.first_loss(running, True, st.los_count, st.steps, self.dt, self.action_frequency, self.los_at_start, self.first_los_s)

    def remove(self, done: BoolArray) -> BoolArray:
        """Delete the aircraft of the agents that left; the running episodes end at the time limit or when no aircraft is left."""
        no_aircraft_left = super().remove(done)
        return no_aircraft_left | (~self.finished & (self.stats.steps >= self.time_limit))

    def step_result(
        self, obs: dict[str, Array], reward: Array, terminated: BoolArray, truncated: BoolArray, ended: BoolArray, info: dict[str, Array]
    ) -> MultiAgentStepResult:
        """The common result, with the first observation of the agents that entered in this step."""
        res = super().step_result(obs, reward, terminated, truncated, ended, info)
        appeared = self.sim.active & ~self.acting & ~ended[:, None]  # at the episode's end they are not agents
        if appeared.any():
            e, k = np.nonzero(appeared)
            first = self.with_observation_terms(self.observe_rows(self.measure_rows(e, k)))
            for key, v in first.items():
                res.observation[key][e, k] = v
        res.appeared = appeared
        return res

    def episode_info(self) -> dict[str, Array]:
        """The common per-episode values and the aircraft that entered."""
        info: dict[str, Any] = {
            **super().episode_info(),
            "spawned": self.scenario.spawned.copy(),
            "spawns_dropped": self.scenario.spawns_dropped.copy(),
        }
        return info

    def kpis(self) -> dict[str, Array]:
        """The common KPIs, the time to the first loss of separation, losses per flight-hour and the aircraft that entered."""
        out = super().kpis()
        out["kpi_los_per_flight_hour"] = np.empty(self.n_envs)
        dsc.per_flight_hour(self.stats.los_count, self.agent_steps.sum(axis=1), self.dt, self.action_frequency, out["kpi_los_per_flight_hour"])
        out["kpi_time_to_first_los_s"] = self.first_los_s.copy()
        out["kpi_aircraft_spawned"] = self.scenario.spawned.astype(np.float64)
        return out


class DenseSectorCRCentralisedEnv(CentralisedEnv):
    """DenseSectorCRCentralised-v0: one agent steers every aircraft of the sector, those that enter during the episode included."""

    task_class = DenseSectorCRMultiAgentTask
