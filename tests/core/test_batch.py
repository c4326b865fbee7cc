"""Batch invariance: an airspace's trajectory does not depend on what the other airspaces do."""

from __future__ import annotations

import numpy as np
import pytest

from bluesky_gym.core import Simulator

from .reference_scenarios import SCENARIOS, run, run_alone

N_OTHERS = 1000


def _random_traffic(sim: Simulator, envs: np.ndarray, rng: np.random.Generator) -> None:
    """Fill airspaces with different traffic: speeds, altitudes, turns, climbs, routes, wind."""
    n = sim.max_aircraft
    for slot in range(n):
        sim.create(
            envs,
            slot,
            rng.uniform(-60, 60, envs.size),
            rng.uniform(-179, 179, envs.size),
            rng.uniform(0, 360, envs.size),
            rng.choice([0.0, 300.0, 3000.0, 9000.0, 12000.0], envs.size),
            rng.choice([80.0, 130.0, 160.0, 0.78], envs.size),
        )
    sim.cmd_heading(envs, 0, rng.uniform(-400, 400, envs.size))
    sim.cmd_speed(envs, 1, rng.uniform(60, 200, envs.size))
    sim.cmd_altitude(envs, 2, rng.uniform(0, 12000, envs.size), rng.uniform(-20, 20, envs.size))
    lnav = envs[: envs.size // 3]
    sim.add_waypoint(lnav, 3, sim.lat[lnav, 3] + 0.3, sim.lon[lnav, 3] + 0.2)
    sim.add_waypoint(lnav, 3, sim.lat[lnav, 3] - 0.1, sim.lon[lnav, 3] + 0.5)
    for e in envs[envs.size // 2 : envs.size // 2 + 50]:
        sim.wind.add_points(e, rng.uniform(40, 60, 3), rng.uniform(0, 8, 3), rng.normal(0, 15, 3), rng.normal(0, 15, 3))


@pytest.mark.parametrize(
    "name", ["s2_hdg_turns_fl200", "s7_route_lnav", "s9_creconfs", "s10_gym_horizontal_alt0_dt5", "s12_wind_constant_gymwrapper"]
)
def test_scenario_in_large_batch_is_bit_identical(name: str) -> None:
    scenario = SCENARIOS[name]
    sim = Simulator(N_OTHERS + 1, 4, dt=scenario.dt)
    target = N_OTHERS // 2
    others = np.delete(np.arange(N_OTHERS + 1), target)
    _random_traffic(sim, others, np.random.default_rng(7))
    scenario.setup(sim, target)
    batched = run(scenario, sim, target)
    alone = run_alone(scenario)
    for col in batched:
        np.testing.assert_array_equal(batched[col], alone[col], err_msg=f"{name}: column {col} differs in a batch")
    # The others really did fly different things.
    assert np.unique(np.round(sim.lat[others, 0], 6)).size > N_OTHERS // 2
