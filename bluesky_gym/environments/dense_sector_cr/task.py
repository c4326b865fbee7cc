"""DenseSectorCREnv-v0: SectorCR with traffic that keeps entering the sector, at a rate that rises through the episode.

The sector, the ownship, its observation, action and reward are SectorCREnv's
(:mod:`bluesky_gym.environments.sector_cr.task`); the scenario adds a traffic flow. After every decision
step's physics sub-steps, other aircraft that left the sector are removed and new ones enter:
their number in the step is Poisson distributed with the expected count of the spawn rate over the
step, a rate [aircraft/h] that rises linearly from ``spawn_rate_start`` to ``spawn_rate_end`` over
``rise_time_s`` and then stays at ``spawn_rate_end``. Training at a rate rising above the one a
policy is tested at is the stress curriculum (train denser than you test).

A new aircraft enters at a point drawn uniformly along the sector's perimeter, set
:data:`ENTRY_INSET_NM` inside towards the sector centre, and flies straight at CAS 150 m/s towards
its exit point, drawn on the perimeter between a quarter and three quarters of the perimeter
further along (so it crosses the sector); it is removed once it is outside the sector. Slots are
not reused within an episode: an episode holds at most ``max_spawned`` new aircraft; an entry
beyond that is dropped (counted in ``spawns_dropped``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from bluesky_gym.core.jit import grid_range, jit
from bluesky_gym.environments.sector_cr import task as sc
from bluesky_gym.tasks.base import StepGeometry, TaskConfig, check_int, check_range, check_type_mix, draw_types, typed
from bluesky_gym.tasks.compiled import polygon_contains
from bluesky_gym.tasks.geometry import initial_bearing

SPAWN_RATE_START = 90.0  # aircraft / h entering the sector at the start of an episode
SPAWN_RATE_END = 360.0  # aircraft / h at the end of the rise
RISE_TIME_S = 600.0  # s over which the rate rises linearly from start to end
MAX_SPAWNED = 120  # new aircraft (slots) per episode
MAX_SPAWN_RATE = 3600.0  # aircraft / h: at most one entry per simulated second on average
ENTRY_INSET_NM = 0.5  # NM: an entry point lies this far inside the perimeter, towards the sector centre
EXIT_ARC = (0.25, 0.75)  # fraction of the perimeter from the entry to the exit point (uniform)
S_PER_H = 3600.0  # s / h


# --- kernels (the CPU task and the device step run these) ------------------------------------------
@jit
def outside_sector(lat, lon, active, poly_lat, poly_lon, n_vertices, out):
    """``out[e, k]``: aircraft ``k`` (not the ownship, slot 0) of episode ``e`` is active and outside the episode's sector.

    The even-odd test of :func:`~bluesky_gym.tasks.compiled.polygon_contains` against the
    episode's polygon (``poly_*`` (n, V), ``n_vertices`` (n,)); ``out`` (n, m).
    """
    for e in grid_range(out.shape[0]):
        out[e, 0] = False
        for k in range(1, out.shape[1]):
            out[e, k] = active[e, k] and not polygon_contains(lat[e, k], lon[e, k], poly_lat[e], poly_lon[e], n_vertices[e])


@jit
def first_loss(envs, stepped, los_count, steps, dt, action_frequency, los_at_start, first_los_s):
    """The first-loss clock of episodes ``envs``: the episode time [s] of the first loss of separation that starts in the episode.

    At a reset (not ``stepped``) the losses of separation present (``los_count``) are noted in
    ``los_at_start``; after a step, the first time ``los_count`` exceeds them is kept in
    ``first_los_s`` (NaN until then): ``steps`` decision steps of ``dt`` x ``action_frequency`` s.
    """
    for r in grid_range(envs.shape[0]):
        e = envs[r]
        if not stepped:
            los_at_start[e] = los_count[e]
        elif math.isnan(first_los_s[e]) and los_count[e] > los_at_start[e]:
            first_los_s[e] = steps[e] * dt * action_frequency


@jit
def per_flight_hour(count, steps, dt, action_frequency, out):
    """``count`` per flight-hour of ``steps`` decision steps (``dt`` x ``action_frequency`` s each); NaN without a step."""
    for e in grid_range(out.shape[0]):
        hours = steps[e] * dt * action_frequency / S_PER_H
        out[e] = count[e] / hours if hours > 0 else math.nan


@dataclass(frozen=True)
class DenseSectorCRConfig(sc.SectorCRConfig):
    """Options of the dense sector task: SectorCREnv's (the initial traffic, the sector) and the traffic flow.

    Attributes:
        spawn_rate_start: Rate at which aircraft enter the sector at the start of an episode [aircraft/h].
        spawn_rate_end: Rate at the end of the rise [aircraft/h], at least ``spawn_rate_start``.
        rise_time_s: Time over which the rate rises linearly from start to end [s]; afterwards it
            stays at ``spawn_rate_end``.
        max_spawned: Most aircraft that enter in one episode (their slots); later entries are dropped.
    """

    spawn_rate_start: float = SPAWN_RATE_START
    spawn_rate_end: float = SPAWN_RATE_END
    rise_time_s: float = RISE_TIME_S
    max_spawned: int = MAX_SPAWNED

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first invalid option."""
        super().validate()
        check_range("spawn_rate_start", self.spawn_rate_start, 0.0, MAX_SPAWN_RATE)
        check_range("spawn_rate_end", self.spawn_rate_end, 0.0, MAX_SPAWN_RATE)
        if self.spawn_rate_end < self.spawn_rate_start:
            raise ValueError(f"spawn_rate_end must be >= spawn_rate_start (the rate rises), got {self.spawn_rate_end} < {self.spawn_rate_start}")
        check_range("rise_time_s", self.rise_time_s, 0.0, strict_low=True)
        check_int("max_spawned", self.max_spawned, 0, sc.MAX_AIRCRAFT_LIMIT - sc.worst_case_aircraft(self))


def spawn_rate(config: DenseSectorCRConfig, t_s: ArrayLike) -> NDArray[np.float64]:
    """The spawn rate [aircraft/h] at episode time ``t_s`` [s]."""
    c = config
    t = np.asarray(t_s, dtype=np.float64)
    rate: NDArray[np.float64] = c.spawn_rate_start + (c.spawn_rate_end - c.spawn_rate_start) * np.minimum(t / c.rise_time_s, 1.0)
    return rate


def expected_entries(config: DenseSectorCRConfig, t_s: ArrayLike) -> NDArray[np.float64]:
    """Expected number of aircraft entering from episode time 0 to ``t_s`` [s]: the integral of :func:`spawn_rate`."""
    c = config
    t = np.asarray(t_s, dtype=np.float64)
    rising = np.minimum(t, c.rise_time_s)
    slope = (c.spawn_rate_end - c.spawn_rate_start) / c.rise_time_s  # aircraft / h / s
    count: NDArray[np.float64] = c.spawn_rate_start * rising + 0.5 * slope * rising * rising + c.spawn_rate_end * np.maximum(t - c.rise_time_s, 0.0)
    return count / S_PER_H


class DenseSectorCRTask(sc.SectorCRTask):
    """Batched dense sector CR task; see :class:`bluesky_gym.environments.dense_sector_cr.env.DenseSectorCREnv` for the MDP."""

    env_id: ClassVar[str] = "DenseSectorCREnv-v0"
    config_class: ClassVar[type[TaskConfig]] = DenseSectorCRConfig
    info_keys: ClassVar[tuple[str, ...]] = ("total_reward", "total_intrusions", "average_drift", "traffic", "spawned", "spawns_dropped")
    config: DenseSectorCRConfig

    def max_aircraft(self) -> int:
        """Slots for the worst-case initial traffic and the most aircraft that may enter."""
        return sc.worst_case_aircraft(self.config) + int(self.config.max_spawned)

    def allocate(self) -> None:
        """SectorCR's arrays and the flow's counters."""
        super().allocate()
        n = self.n_envs
        self.flow_steps = np.zeros(n, np.int64)  # decision steps of the episode's traffic flow
        self.next_slot = np.zeros(n, np.int64)  # first slot never used in the episode
        self.spawned = np.zeros(n, np.int64)  # aircraft that entered
        self.spawns_dropped = np.zeros(n, np.int64)  # entries dropped: no slot left
        self.first_los_s = np.full(n, np.nan)  # s: episode time of the ownship's first loss of separation
        self.los_at_start = np.zeros(n, np.int64)  # the ownship's losses of separation present at the start

    def generate(self, envs: NDArray[np.int64]) -> None:
        """SectorCR's scenario (the initial traffic); the flow starts empty."""
        super().generate(envs)
        self.flow_steps[envs] = 0
        self.next_slot[envs] = self.num_ac[envs]
        self.spawned[envs] = 0
        self.spawns_dropped[envs] = 0
        self.first_los_s[envs] = np.nan

    # --- the traffic flow ---------------------------------------------------------------------------
    def advance(self) -> None:
        """The physics sub-steps, then the traffic flow of every episode (exited traffic removed, new traffic entered)."""
        super().advance()
        self.remove_exited()
        self.spawn(self.all_envs)

    def remove_exited(self) -> None:
        """Delete the other aircraft (not the ownship, slot 0) that are outside their sector (:func:`outside_sector`)."""
        outside = np.empty((self.n_envs, self.sim.max_aircraft), bool)
        outside_sector(self.sim.lat, self.sim.lon, self.sim.active, self.poly_lat, self.poly_lon, self.n_vertices, outside)
        e, k = np.nonzero(outside)
        if e.size:
            self.sim.delete(e, k)

    def spawn(self, envs: NDArray[np.int64]) -> NDArray[np.int64]:
        """Advance the flow clock of episodes ``envs`` by one decision step and create the aircraft entering in it.

        Each episode draws from its own generator: the count (Poisson), then per aircraft its entry
        and exit perimeter positions and its type.

        Returns:
            (n_envs,) the number of aircraft created in each episode.
        """
        c = self.config
        step_s = self.dt * self.action_frequency
        t0 = self.flow_steps[envs] * step_s
        self.flow_steps[envs] += 1
        expected = expected_entries(c, t0 + step_s) - expected_entries(c, t0)
        imix = check_type_mix("intruder_types", c.intruder_types)
        created = np.zeros(self.n_envs, np.int64)
        cre_env: list[int] = []
        cre_slot: list[int] = []
        starts: list[NDArray[np.float64]] = []
        exits: list[NDArray[np.float64]] = []
        types: list[str] = []
        for e, lam in zip(envs.tolist(), expected.tolist(), strict=True):
            rng = self.rngs[e]
            k = int(rng.poisson(lam))
            if k == 0:
                continue
            nv = int(self.n_vertices[e])
            poly = self.poly_nm[e, :nv]
            cum = self._perimeter(poly)
            perimeter = cum[-1]
            entry_d = rng.uniform(0.0, perimeter, k)
            exit_d = (entry_d + rng.uniform(*EXIT_ARC, k) * perimeter) % perimeter
            kinds = draw_types(rng, imix, k)
            n_new = min(k, int(c.max_spawned - self.spawned[e]))  # next_slot = num_ac + spawned stays within the slots
            self.spawns_dropped[e] += k - n_new
            if n_new == 0:
                continue
            entry = self._perimeter_points(poly, entry_d[:n_new], cum)
            radius = np.hypot(entry[:, 0], entry[:, 1])
            starts.append(entry * (1.0 - ENTRY_INSET_NM / radius)[:, None])  # towards the centre: inside (the sector is convex around it)
            exits.append(self._perimeter_points(poly, exit_d[:n_new], cum))
            first = int(self.next_slot[e])
            cre_env += [e] * n_new
            cre_slot += list(range(first, first + n_new))
            types += kinds[:n_new]
            self.next_slot[e] += n_new
            self.spawned[e] += n_new
            created[e] = n_new
        if cre_env:
            env_a, slot_a = np.asarray(cre_env, np.int64), np.asarray(cre_slot, np.int64)
            lat0, lon0 = self._latlon(np.concatenate(starts))
            exit_nm = np.concatenate(exits)
            wlat, wlon = self._latlon(exit_nm)
            self.wpt_nm[env_a, slot_a] = exit_nm
            self.wpt_lat[env_a, slot_a] = wlat
            self.wpt_lon[env_a, slot_a] = wlon
            hdg0 = initial_bearing(lat0, lon0, wlat, wlon)
            alt = sc.FLIGHT_LEVEL_ALTITUDE if c.flight_level_altitude else sc.ALTITUDE
            self.sim.create(env_a, slot_a, lat0, lon0, hdg0, alt, sc.AC_SPD, **typed(types))
        return created

    def spawn_rate_now(self) -> NDArray[np.float64]:
        """(n_envs,) the spawn rate [aircraft/h] of each episode's next decision step."""
        return spawn_rate(self.config, self.flow_steps * self.dt * self.action_frequency)

    # --- statistics and KPIs ------------------------------------------------------------------------
    def record(self, g: StepGeometry, reward: NDArray[np.float64] | None) -> None:
        """The common statistics, and the time of the ownship's first loss of separation that starts during the episode.

        The losses present at the start do not count: SectorCR places its initial traffic without
        a separation check, so an episode may start in a loss of separation.
        """
        super().record(g, reward)
        st = self.stats
        first_loss(g.envs, reward is not None, st.los_count, st.steps, self.dt, self.action_frequency, self.los_at_start, self.first_los_s)

    def episode_info(self) -> dict[str, NDArray[np.float64]]:
        """SectorCR's info keys, the other aircraft in the sector now, and the flow's counts."""
        return {
            **super().episode_info(),
            "traffic": self.sim.active[:, 1:].sum(axis=1),
            "spawned": self.spawned.copy(),
            "spawns_dropped": self.spawns_dropped.copy(),
        }

    def kpis(self) -> dict[str, NDArray[np.float64]]:
        """The common KPIs, the time to the first loss of separation, losses per flight-hour and the aircraft that entered."""
        out = super().kpis()
        out["kpi_los_per_flight_hour"] = np.empty(self.n_envs)
        per_flight_hour(self.stats.los_count, self.stats.steps, self.dt, self.action_frequency, out["kpi_los_per_flight_hour"])
        out["kpi_time_to_first_los_s"] = self.first_los_s.copy()
        out["kpi_aircraft_spawned"] = self.spawned.astype(np.float64)
        return out
