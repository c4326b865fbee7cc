"""Multi-agent real traffic: every recorded aircraft of a window is an agent (PettingZoo ``ParallelEnv``).

The episode is a window of RealTrafficCREnv-v0 (the same windows, splits and options); every
aircraft of it, named by its recorded flight id, is an agent from the step its recording starts
until the step it ends. Each agent has the single-agent observation, action and reward from its
own point of view (:func:`bluesky_gym.environments.real_traffic.task.measure`, :func:`~bluesky_gym.environments.real_traffic.task.observation`,
:func:`~bluesky_gym.environments.real_traffic.task.reward` and :func:`~bluesky_gym.environments.real_traffic.task.steer`
applied to its own slot): heading, speed (and optionally altitude) relative to its own recorded
path, so that all-zero actions replay the recording.

* ``possible_agents`` are the flight ids of every aircraft of the windows an episode can play
  (both splits with ``split="auto"``), known from construction; ``agents`` are those flying now.
* ``agents`` grow when recorded aircraft appear and shrink when their recordings end (those agents
  are truncated in that step, with an all-zero final observation: their aircraft is gone); at the
  end of the window every agent is truncated.
* The dicts ``step`` returns hold the agents that acted in it and the agents that appeared in it:
  an appearing agent gets its first observation (reward 0, neither terminated nor truncated, an
  empty info), so that its first action is based on what it saw. An aircraft that appears in the
  last step of the window is not an agent.
* ``step(actions)``: an agent missing from the dict flies its recording (action 0); names that
  are not current agents are ignored. An action that is not an array of real numbers of the
  action shape, or has NaN or infinite values, raises ``ValueError`` naming the agent; ``actions``
  other than a dict raise ``TypeError``.
* ``reset(seed=s)``: seeds of the evaluation range (``2**31`` and above) draw from the test split
  with ``split="auto"``.
* ``state()``: per aircraft slot (active, lat, lon, altitude, heading, ground speed), its Box is
  ``state_space``.

The step is :meth:`bluesky_gym.tasks.base.Task.step`, laid out by
:class:`RealTrafficMultiAgentTask` (a :class:`~bluesky_gym.multiagent.base.MultiAgentTask`) over
the rows (episode, aircraft slot) of the recorded aircraft; :class:`RealTrafficParallelEnv` is the
PettingZoo shell of the other multi-agent environments
(:class:`~bluesky_gym.multiagent.parallel.BlueSkyParallelEnv`) with agents named by flight id.

Example::

    from bluesky_gym.environments.real_traffic.multiagent import RealTrafficParallelEnv

    env = RealTrafficParallelEnv()
    obs, infos = env.reset(seed=0)
    while env.agents:
        obs, rew, term, trunc, infos = env.step({a: env.action_space(a).sample() for a in env.agents})
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces

from bluesky_gym.environments.real_traffic import task as rt
from bluesky_gym.envs.seeds import is_eval_seed
from bluesky_gym.multiagent import require_pettingzoo
from bluesky_gym.multiagent.base import IntArray, MultiAgentStepResult, MultiAgentTask
from bluesky_gym.multiagent.parallel import BlueSkyParallelEnv, agent_observation_space, box
from bluesky_gym.tasks.base import Array, BoolArray, BoxSpec, StepGeometry

require_pettingzoo()

#: The names of the environment and the configuration each adds to the options (RealTrafficCREnv-v0's, -v1's).
NAMES: dict[str, tuple[tuple[str, Any], ...]] = {"real_traffic_cr_v0": (), "real_traffic_cr_v1": (("float32_spaces", True),)}

#: Columns of one aircraft slot in :meth:`RealTrafficParallelEnv.state`.
STATE_COLUMNS = ("active", "lat", "lon", "altitude", "heading", "ground_speed")


class RealTrafficMultiAgentTask(MultiAgentTask):
    """The multi-agent layout of the real-traffic step: every recorded aircraft of the window is an agent.

    The scenario is :class:`~bluesky_gym.environments.real_traffic.task.RealTrafficAllAgentsTask` (no aircraft
    flies the recorded profile on its own). Beyond the common layout: an aircraft whose recording
    starts during a step *appears* (it did not act; the step's result holds its first observation);
    an acting agent whose recording ends in the step is truncated with an all-zero observation,
    reward 0 and no per-agent info (its aircraft is gone); at the time limit (the window's end)
    every agent is truncated, the aircraft that appeared in that step are not agents, and the
    aircraft stay where the window left them (:meth:`state`).

    Per-agent infos: the common ones (``return``, ``completed``, ``reward_route``,
    ``reward_intrusion``), ``route_deviation_nm`` and ``intrusions`` (aircraft within 5 NM and
    1000 ft after the step); the PettingZoo environment shows the last two.
    """

    name: ClassVar[str] = "real_traffic_cr_v0"
    env_id: ClassVar[str] = "RealTrafficCREnv-v0"
    scenario_class = rt.RealTrafficAllAgentsTask
    intrusion_distance: ClassVar[float] = rt.INTRUSION_NM
    completion: ClassVar[str] = "none"
    scenario: rt.RealTrafficAllAgentsTask
    _route_nm: Array  # (n_envs, n_agents) route deviation [NM] of the rows measured in the step

    def build_observation_spec(self) -> dict[str, BoxSpec]:
        """RealTrafficCREnv-v0's observation (-v1's with ``float32_spaces``), without the wind's entries (see :meth:`add_wind`)."""
        return self.scenario.build_observation_spec()

    def build_action_spec(self) -> BoxSpec:
        """RealTrafficCREnv-v0's action."""
        return self.scenario.action_spec

    def apply_action(self, action: Array) -> None:
        """Steer every acting aircraft relative to its own recorded path (:func:`~bluesky_gym.environments.real_traffic.task.steer`)."""
        e, k = np.nonzero(self.acting)
        rt.steer(self.scenario, e, k, action[e, k])

    def measure(self, envs: IntArray | None = None, own: IntArray | None = None) -> StepGeometry:
        """The geometry of the rows; without rows, of the acting agents whose aircraft is still recorded (the step's)."""
        if envs is None or own is None:
            envs, own = np.nonzero(self.acting & self.sim.active)
        return self.measure_rows(np.asarray(envs, dtype=np.int64), np.asarray(own, dtype=np.int64))

    def measure_rows(self, envs: IntArray, own: IntArray) -> rt.RealTrafficGeometry:
        """:func:`bluesky_gym.environments.real_traffic.task.measure` of the rows."""
        return rt.measure(self.scenario, envs, own)

    def observe_rows(self, g: StepGeometry) -> dict[str, Array]:
        """:func:`bluesky_gym.environments.real_traffic.task.observation` of the rows."""
        assert isinstance(g, rt.RealTrafficGeometry)
        return rt.observation(self.scenario, g)

    def reward_rows(self, g: StepGeometry) -> tuple[Array, BoolArray, dict[str, Array]]:
        """Route and intrusion penalties (:func:`bluesky_gym.environments.real_traffic.task.reward`); no agent terminates."""
        assert isinstance(g, rt.RealTrafficGeometry)
        r, parts = rt.reward(g)
        self._route_nm = self._rows_to_slots(g, g.route_nm, 0.0)
        return r, np.zeros(len(g.envs), bool), parts

    def targets(self) -> tuple[Array, Array]:
        """Each aircraft's heading reference: its recorded position ``CARROT_S`` ahead (lat, lon [deg]; empty slots: its last slot's flight)."""
        player = self.scenario.player
        now = np.broadcast_to(player.now()[:, None], player.flight.shape)
        carrot = self.scenario.flights.at(np.maximum(player.flight, 0), now + rt.CARROT_S)
        return carrot["lat"], carrot["lon"]

    def truncate(self, g: StepGeometry) -> BoolArray:
        """The acting agents whose recording ended in this step."""
        return self.acting & ~self.sim.active

    def remove(self, done: BoolArray) -> BoolArray:
        """No aircraft to delete: those whose recording ended are gone, and at the time limit the last step's aircraft stay (in :meth:`state`).

        Returns:
            The running episodes at the time limit or without aircraft.
        """
        running = ~self.finished
        return running & ((self.stats.steps >= self.time_limit) | ~self.sim.active.any(axis=1))

    def step_result(
        self, obs: dict[str, Array], reward: Array, terminated: BoolArray, truncated: BoolArray, ended: BoolArray, info: dict[str, Array]
    ) -> MultiAgentStepResult:
        """The common result, with the first observation of the agents that appeared and the per-agent infos."""
        appeared = self.sim.active & ~self.acting & ~ended[:, None]  # at the time limit they are not agents
        if appeared.any():
            e, k = np.nonzero(appeared)
            first = self.with_observation_terms(self.observe_rows(self.measure_rows(e, k)))
            for key, v in first.items():
                obs[key][e, k] = v
        agent_info: dict[str, Any] = dict(super().step_result(obs, reward, terminated, truncated, ended, info).agent_info)
        agent_info.update(route_deviation_nm=self._route_nm, intrusions=self.intrusion_counts.copy())  # intrusions of this step
        measured = self.acting & self.sim.active
        return MultiAgentStepResult(obs, reward, terminated, truncated, self.acting, ended, info, agent_info, appeared, measured)

    def state_rows(self) -> Array:
        """Per aircraft slot :data:`STATE_COLUMNS`: active, lat, lon [deg], altitude [m], heading [deg], ground speed [m/s]; (n_envs, n_agents, 6)."""
        s = self.sim
        return np.stack([s.active.astype(float), s.lat, s.lon, s.alt, s.hdg, s.gs], axis=-1)

    @property
    def state_size(self) -> int:
        """Length of one episode's state vector."""
        return self.n_agents * len(STATE_COLUMNS)


class RealTrafficParallelEnv(BlueSkyParallelEnv):
    """Every recorded aircraft of a real-traffic window is an agent, named by its flight id.

    Args:
        max_episode_steps: Time limit in decision steps (default: the window).
        name: ``"real_traffic_cr_v0"`` (default) or ``"real_traffic_cr_v1"``: RealTrafficCREnv-v1's
            configuration (float32 spaces with finite bounds, ``intruders`` as one vector).
        **options: Options of RealTrafficCREnv-v0 (collections, split, window_s, ...).
    """

    task_class = RealTrafficMultiAgentTask
    metadata: dict[str, Any] = {"name": "real_traffic_cr_v0", "render_modes": [], "is_parallelizable": True}  # noqa: RUF012 - per instance: the name (_v0 or _v1) is set by __init__
    kpis_in_infos: ClassVar[bool] = False
    agent_info_keys: ClassVar[tuple[str, ...] | None] = ("route_deviation_nm", "intrusions")
    task: RealTrafficMultiAgentTask

    def __init__(self, max_episode_steps: int | None = None, name: str = "real_traffic_cr_v0", **options: Any) -> None:
        super().__init__(None, max_episode_steps, name, **options)

    def make_task(self, name: str, max_episode_steps: int | None, options: dict[str, Any]) -> RealTrafficMultiAgentTask:
        """The layout with the configuration of ``name`` and ``options`` on top."""
        if name not in NAMES:
            raise ValueError(f"name must be one of {list(NAMES)}, got {name!r}")
        config = RealTrafficMultiAgentTask.make_config({**dict(NAMES[name]), **options})
        task = RealTrafficMultiAgentTask(1, config, max_episode_steps=max_episode_steps)
        task.name = task.id = name  # type: ignore[misc]  # the instance's name: _v0 or _v1
        return task

    def all_agents(self) -> list[str]:
        """Flight ids of every aircraft of the windows this environment's split can draw."""
        data, split = self.task.scenario.data, self.task.scenario.config.split
        pools = (data.train,) if split == "train" else (data.test,) if split == "test" else (data.train, data.test)
        flights = sorted({f for pool in pools for w in pool for f in w.flights})
        return [str(self.task.scenario.flights.flight_id[f]) for f in flights]

    def _build_spaces(self) -> None:
        self._slots_of: list[str] | None = None
        self._slots: dict[str, int] = {}
        self._obs_space = agent_observation_space(self.task)
        self._act_space = box(self.task.action_spec, self._dtype)

    def observation_space(self, agent: str) -> spaces.Dict:
        """Every agent's observation space (RealTrafficCREnv-v0's)."""
        return self._obs_space

    def action_space(self, agent: str) -> spaces.Box:
        """Every agent's action space (RealTrafficCREnv-v0's)."""
        return self._act_space

    def agent_names(self, slots: np.ndarray) -> list[str]:
        """The flight ids of the aircraft in ``slots``."""
        scenario = self.task.scenario
        return [str(scenario.flights.flight_id[scenario.player.flight[0, s]]) for s in slots]

    def action_slot(self, agent: Any) -> int | None:
        """The slot of a current agent; other names are ignored."""
        if self._slots_of is not self.agents:  # the agents are the aircraft flying now, in slot order
            self._slots = dict(zip(self.agents, np.flatnonzero(self.task.sim.active[0]).tolist(), strict=True))
            self._slots_of = self.agents
        return self._slots.get(agent) if isinstance(agent, str) else None

    def seed_episode(self, seed: int | None) -> None:
        """The split of the episode (the test split for evaluation-range seeds with ``split="auto"``), then its generator."""
        self.task.scenario.set_test_split(np.array([0]), np.array([seed is not None and is_eval_seed(int(seed))]))
        super().seed_episode(seed)
