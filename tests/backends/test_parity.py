"""Parity of the native core with the real BlueSky 1.1.1, state by state and episode by episode.

Needs the ``bluesky`` extra (numpy < 2.4); skipped when BlueSky cannot be imported.

Core level: random scenarios (creation states, HDG/SPD/ALT/VS commands, gym-style selalt/selvs and
heading writes, creconfs, LNAV routes with destinations, constant and 2-D wind, deletions) are
stepped on :class:`~bluesky_gym.core.Simulator` (and on the numpy oracle of its step) and on
:class:`~bluesky_gym.backends.bluesky_sim.BlueSkyPhysics` side by side. Every state array of every
aircraft must be bit-identical after every event and every step until a route or a multi-point
wind field appears (the known sources of last-bit differences below), and agree within 1e-9
(scaled, see ``parity.py``) from then on.

Env level: every registered environment runs 20 seeded episodes with seeded random actions on both
backends side by side; observations, rewards, terminated/truncated and infos must be bit-identical
under the same rule, and agree within 1e-6 at every step once a route or wind field exists
(MergeEnv's LNAV routes). Descent and SectorCR also run with the wind wrapper.

Known, bounded differences (all far below the tolerances; see docs/backends.md):

* BlueSky stores a waypoint as ``(lat + 90) % 180 - 90``, ``(lon + 180) % 360 - 180``, which can
  move it by one ulp (~1e-14 deg); route geometry (bearings, turn distances) then differs by
  ~1e-12 relative, and headings under LNAV by ~1e-10 deg after 10 minutes of flight.
* BlueSky computes 2-D wind weights with matrix products, the core with sums: ~1 ulp.
* BlueSky's compiled and Python geo functions differ in the last bits; which set LNAV uses depends
  on whether ``bluesky.tools.geo`` was imported before ``bs.init()``. The core tests build the
  native core with the same set (``BlueSkyPhysics.geo``); the environments use the compiled set,
  so with the Python set MergeEnv differs by a few ulps more.
* A destination that is a route's only waypoint switches BlueSky's VNAV on; the core has no VNAV,
  so the random scenarios set a destination only after a waypoint (as MergeEnv does).
* The 1 s performance timer of BlueSky is process-global: for dt < 1 s its phase depends on the
  process history. Every environment uses dt >= 1 s, where it runs every step; dt < 1 is not tested.
"""

from __future__ import annotations

import pytest

pytest.importorskip("bluesky")

from bluesky_gym.backends.bluesky_sim import BlueSkyPhysics
from bluesky_gym.core import Simulator
from bluesky_gym.registration import available_envs
from tests.oracle.simulator import OracleSimulator

from .parity import CORE_TOL, ENV_TOL, compare_states, random_core_scenario, run_core_scenario, run_env_episodes

pytestmark = pytest.mark.bluesky

KERNELS = {"kernel": Simulator, "oracle": OracleSimulator}
CORE_SEEDS = list(range(20))


def _natives(max_aircraft: int, dt: float, geo: str, max_waypoints: int = 4) -> dict[str, Simulator]:
    """The native core and its numpy oracle, using the geo functions BlueSky uses here."""
    return {k: cls(1, max_aircraft, dt=dt, max_waypoints=max_waypoints, geo=geo) for k, cls in KERNELS.items()}


@pytest.mark.parametrize("seed", CORE_SEEDS)
def test_core_random_scenario(seed: int) -> None:
    sc = random_core_scenario(seed)
    bs = BlueSkyPhysics(sc.max_aircraft, dt=sc.dt, max_waypoints=4)
    try:
        dev = run_core_scenario(sc, _natives(sc.max_aircraft, sc.dt, bs.geo), bs, CORE_TOL)
    finally:
        bs.close()
    print(f"seed {seed} dt {sc.dt} geo {bs.geo}: largest scaled deviation {dev.max:.2e}: {dev.summary()}")


def test_core_scenarios_cover_every_event_kind() -> None:
    kinds = {label for s in CORE_SEEDS for evs in random_core_scenario(s).events.values() for label, _ in evs}
    assert kinds >= {"create", "hdg", "spd", "alt", "vs", "write_v", "write_h", "creconfs", "route", "dest", "wind", "delete"}


def test_core_reference_like_scenario_is_bit_identical_without_routes() -> None:
    """Straight flight, HDG/SPD/ALT/VS commands, gym writes, creconfs and constant wind: to the last bit."""
    bs = BlueSkyPhysics(5, dt=1.0)
    natives = _natives(5, 1.0, bs.geo)
    sims = [*natives.values(), bs]
    try:
        for s in sims:
            s.create(0, [0, 1], [52.0, 51.5], [4.0, 3.0], [45.0, 300.0], [6096.0, 3000.0], [128.6, 150.0])
            s.creconfs(0, 0, 2, 90.0, 1.0, 120.0)
            s.creconfs(0, 0, 3, 200.0, 0.0, 150.0, spd=200 * 0.514444)
            s.creconfs(0, 0, 4, 300.0, 2.0, 100.0, dh=500.0, tlosv=90.0)
            s.cmd_heading(0, 0, 90.0)
            s.cmd_speed(0, 1, 250 * 0.514444)
            s.set_autopilot(0, 1, selalt=0.0, selvs=-12.5)
        for t in range(400):
            if t == 100:
                for s in sims:
                    s.wind.add_points(0, [52.0], [4.0], [-10.0], [15.0])
                    s.cmd_altitude(0, 0, 3048.0)
                    s.cmd_vertical_speed(0, 2, 5.0)
                    s.cmd_altitude(0, 2, 7000.0)
            for s in sims:
                s.step()
            for nat in natives.values():
                compare_states(nat, bs, f"t={t + 1}", 0.0)
    finally:
        bs.close()


# The -v1 versions with their own physics or geometry (FL350 traffic, the FAF at 200 NM, per-step
# obstacle reward); the other -v1 versions differ from their -v0 only in the task layer.
PARITY_V1 = ("SectorCREnv-v1", "StaticObstacleEnv-v1", "MergeEnv-v1")
# RealTrafficCREnv-v0 flies recorded traffic prepared from the 'traffic' package's samples; its
# parity with BlueSky is not part of this plan (the BlueSky environment has no 'traffic').
NO_PARITY = ("RealTrafficCREnv-v0",)
ENVS = [e for e in available_envs() if (e.endswith("-v0") or e in PARITY_V1) and e not in NO_PARITY]
EPISODES = 20
CHUNKS = 2  # each env's episodes run as two tests (contiguous halves), for pytest-xdist
# env id -> (time limit, number of full episodes, length of the others). Full episodes run to
# termination or the time limit (with random actions Descent and VerticalCR end at the runway after
# 38-42 steps; HorizontalCR, SectorCR and StaticObstacle end or truncate in several episodes); the
# others are abandoned after a few steps and the env is reset mid-episode. The numbers keep the
# suite within a few minutes on 2 cores.
EPISODE_PLAN = {
    "DescentEnv-v0": (45, 6, 8),
    "VerticalCREnv-v0": (45, 6, 8),
    "PlanWaypointEnv-v0": (40, 6, 10),
    "HorizontalCREnv-v0": (50, 8, 10),
    "SectorCREnv-v0": (80, 8, 15),
    "StaticObstacleEnv-v0": (50, 8, 15),
    "MergeEnv-v0": (25, 6, 8),
    "SectorCREnv-v1": (60, 6, 10),
    "StaticObstacleEnv-v1": (50, 6, 10),
    "MergeEnv-v1": (25, 6, 8),
    "DenseSectorCREnv-v0": (80, 6, 15),  # about 20 entries expected in a full episode, and exits
}


def _episodes(env_id: str) -> tuple[list[tuple[int, int]], int]:
    """(seed, steps) of every episode (full ones evenly spread), and the time limit."""
    limit, n_full, short = EPISODE_PLAN.get(env_id, (40, 6, 10))
    full = {round(i * EPISODES / n_full) for i in range(n_full)}
    return [(1000 * (k + 1) + 17, limit if k in full else short) for k in range(EPISODES)], limit


@pytest.mark.parametrize("chunk", range(CHUNKS))
@pytest.mark.parametrize("env_id", ENVS)
def test_env_episodes_match(env_id: str, chunk: int) -> None:
    episodes, limit = _episodes(env_id)
    size = EPISODES // CHUNKS
    mine = episodes[chunk * size : (chunk + 1) * size]
    dev, steps = run_env_episodes(env_id, mine, limit, ENV_TOL)
    assert steps >= len(mine)
    print(f"{env_id} chunk {chunk}: {len(mine)} episodes, {steps} steps; largest scaled deviation {dev.max:.2e}: {dev.summary()}")


WINDS = {
    "constant": ([52.0], [4.0], [-10.0], [15.0]),
    "field": ([51.5, 52.5, 52.0], [3.5, 4.5, 5.0], [-10.0, 5.0, 0.0], [15.0, 2.0, -8.0]),
}


@pytest.mark.parametrize("wind", sorted(WINDS))
@pytest.mark.parametrize("env_id", [e for e in ("DescentEnv-v0", "SectorCREnv-v0") if e in ENVS])
def test_env_episodes_with_wind_match(env_id: str, wind: str) -> None:
    """The wind option (wind points added at every reset, wind in the observation) on both backends."""
    from bluesky_gym.core.wind import Wind

    episodes = [(100 * k + 3, 30 if k == 0 else 6) for k in range(4)]
    dev, steps = run_env_episodes(env_id, episodes, 30, ENV_TOL, options={"wind": Wind(*WINDS[wind], observe=True)})
    assert steps >= len(episodes)
    print(f"{env_id} with {wind} wind: {steps} steps; largest scaled deviation {dev.max:.2e}: {dev.summary()}")


def test_every_registered_env_is_planned_with_20_episodes() -> None:
    assert set(ENVS) <= set(EPISODE_PLAN)
    assert EPISODES >= 20 and EPISODES % CHUNKS == 0
    for env_id in EPISODE_PLAN:
        episodes, limit = _episodes(env_id)
        assert len(episodes) == EPISODES and len({s for s, _ in episodes}) == EPISODES
        assert sum(n == limit for _, n in episodes) == EPISODE_PLAN[env_id][1]
