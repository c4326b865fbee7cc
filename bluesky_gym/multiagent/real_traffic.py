"""Multi-agent real traffic: every recorded aircraft of a window is an agent (PettingZoo ``ParallelEnv``).

The episode is a window of RealTrafficCREnv-v0 (the same windows, splits and options); every
aircraft of it, named by its recorded flight id, is an agent from the step its recording starts
until the step it ends. Each agent has the single-agent observation, action and reward from its
own point of view (:func:`bluesky_gym.tasks.real_traffic.measure`, :func:`~bluesky_gym.tasks.real_traffic.observation`,
:func:`~bluesky_gym.tasks.real_traffic.reward` and :func:`~bluesky_gym.tasks.real_traffic.steer`
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

Example::

    from bluesky_gym.multiagent.real_traffic import RealTrafficParallelEnv

    env = RealTrafficParallelEnv()
    obs, infos = env.reset(seed=0)
    while env.agents:
        obs, rew, term, trunc, infos = env.step({a: env.action_space(a).sample() for a in env.agents})
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding

from bluesky_gym.envs.seeds import is_eval_seed
from bluesky_gym.multiagent import require_pettingzoo
from bluesky_gym.multiagent.base import agent_action, agent_actions
from bluesky_gym.multiagent.parallel import box
from bluesky_gym.tasks import real_traffic as rt

require_pettingzoo()  # a clear error naming the extra when PettingZoo is missing
from pettingzoo import ParallelEnv  # noqa: E402

#: The names of the environment and the configuration each adds to the options (RealTrafficCREnv-v0's, -v1's).
NAMES: dict[str, tuple[tuple[str, Any], ...]] = {"real_traffic_cr_v0": (), "real_traffic_cr_v1": (("float32_spaces", True),)}

#: Columns of one aircraft slot in :meth:`RealTrafficParallelEnv.state`.
STATE_COLUMNS = ("active", "lat", "lon", "altitude", "heading", "ground_speed")


class RealTrafficParallelEnv(ParallelEnv):
    """Every recorded aircraft of a real-traffic window is an agent.

    Args:
        max_episode_steps: Time limit in decision steps (default: the window).
        name: ``"real_traffic_cr_v0"`` (default) or ``"real_traffic_cr_v1"``: RealTrafficCREnv-v1's
            configuration (float32 spaces with finite bounds, ``intruders`` as one vector).
        **options: Options of RealTrafficCREnv-v0 (collections, split, window_s, ...).
    """

    metadata: dict[str, Any] = {"name": "real_traffic_cr_v0", "render_modes": [], "is_parallelizable": True}  # noqa: RUF012 - per instance: the name (_v0 or _v1) is set by __init__

    def __init__(self, max_episode_steps: int | None = None, name: str = "real_traffic_cr_v0", **options: Any) -> None:
        if name not in NAMES:
            raise ValueError(f"name must be one of {list(NAMES)}, got {name!r}")
        config = rt.RealTrafficTask.make_config({**dict(NAMES[name]), **options})
        self.task = rt.RealTrafficAllAgentsTask(1, config, max_episode_steps=max_episode_steps)
        self.metadata = {**self.metadata, "name": name}
        self._dtype = self.task.space_dtype
        spec = self.task.observation_spec
        self._obs_space = spaces.Dict({k: box(v, self._dtype) for k, v in spec.items()})
        self._act_space = box(self.task.action_spec, self._dtype)
        self.state_space = spaces.Box(-np.inf, np.inf, (self.task.sim.max_aircraft * len(STATE_COLUMNS),), np.float64)
        self.possible_agents: list[str] = self._possible_agents()
        self.agents: list[str] = []
        self._slot: dict[str, int] = {}
        self._np_random, _ = seeding.np_random(None)
        self._steps = 0

    def _possible_agents(self) -> list[str]:
        """Flight ids of every aircraft of the windows this environment's split can draw."""
        data, split = self.task.data, self.task.config.split
        pools = (data.train,) if split == "train" else (data.test,) if split == "test" else (data.train, data.test)
        flights = sorted({f for pool in pools for w in pool for f in w.flights})
        return [str(self.task.flights.flight_id[f]) for f in flights]

    def observation_space(self, agent: str) -> spaces.Space[Any]:
        """Every agent's observation space (RealTrafficCREnv-v0's)."""
        return self._obs_space

    def action_space(self, agent: str) -> spaces.Space[Any]:
        """Every agent's action space (RealTrafficCREnv-v0's)."""
        return self._act_space

    def _names(self) -> dict[str, int]:
        task = self.task
        active = np.flatnonzero(task.sim.active[0])
        return {str(task.flights.flight_id[task.player.flight[0, s]]): int(s) for s in active}

    def _observe(self, names: dict[str, int]) -> tuple[dict[str, dict[str, np.ndarray]], np.ndarray, rt.RealTrafficGeometry | None]:
        if not names:
            return {}, np.zeros(0), None
        slots = np.fromiter(names.values(), dtype=np.int64)
        g = rt.measure(self.task, np.zeros(len(slots), np.int64), slots)
        obs = self.task.with_observation_terms(rt.observation(self.task, g), np.zeros(len(slots), np.int64))  # -v1: clipped to the bounds
        reward, _ = rt.reward(g)
        return {a: {k: v[i].astype(self._dtype) for k, v in obs.items()} for i, a in enumerate(names)}, reward, g

    def reset(self, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[dict[str, Any], dict[str, Any]]:
        """Start an episode (seeded: the window of that seed)."""
        if seed is not None:
            self._np_random, _ = seeding.np_random(seed)
        self.task.set_test_split(np.array([0]), np.array([seed is not None and is_eval_seed(int(seed))]))
        self.task.seed(np.array([0]), [self._np_random])
        self.task.reset()
        self._steps = 0
        self._slot = self._names()
        self.agents = list(self._slot)
        obs, _, _ = self._observe(self._slot)
        return obs, {a: {} for a in self.agents}

    def step(self, actions: dict[str, Any]) -> tuple[dict[str, Any], dict[str, float], dict[str, bool], dict[str, bool], dict[str, Any]]:
        """Apply the agents' actions, fly 10 s, and report every agent that acted or appeared."""
        if not self.agents:
            raise RuntimeError("step() called before reset() or after the episode ended; call reset() first")
        given = agent_actions(actions)
        shape = self._act_space.shape
        acting = dict(self._slot)
        slots = np.fromiter(acting.values(), dtype=np.int64)
        a = np.zeros((len(slots), *shape))
        for i, name in enumerate(acting):
            if name in given:
                a[i] = np.clip(agent_action(name, given[name], shape), self._act_space.low, self._act_space.high)
        rt.steer(self.task, np.zeros(len(slots), np.int64), slots, a)
        self.task.advance()
        self._steps += 1
        end = self._steps >= self.task.time_limit
        now = self._names()
        # flying after the step: those that acted and are still recorded, then (unless the window ends) those that appeared
        flying = {n: s for n, s in now.items() if n in acting or not end}
        obs, reward, g = self._observe(flying)
        blank = {k: np.zeros(spec.shape, self._dtype) for k, spec in self.task.observation_spec.items()}
        for n in acting:
            if n not in flying:
                obs[n] = {k: v.copy() for k, v in blank.items()}
        rewards = dict.fromkeys(obs, 0.0)
        infos: dict[str, Any] = {n: {} for n in obs}
        if g is not None:
            for i, n in enumerate(flying):
                if n in acting:
                    rewards[n] = float(reward[i])
                    infos[n] = {"route_deviation_nm": float(g.route_nm[i]), "intrusions": int(g.los[i].sum())}
        terminations = dict.fromkeys(obs, False)
        truncations = {n: n in acting and (end or n not in now) for n in obs}
        self._slot = {} if end else flying
        self.agents = list(self._slot)
        return obs, rewards, terminations, truncations, infos

    def state(self) -> np.ndarray:
        """Global state: per aircraft slot (active, lat, lon, altitude [m], heading [deg], ground speed [m/s]); see ``state_space``."""
        sim = self.task.sim
        return np.stack([sim.active[0].astype(float), sim.lat[0], sim.lon[0], sim.alt[0], sim.hdg[0], sim.gs[0]], axis=1).ravel()
