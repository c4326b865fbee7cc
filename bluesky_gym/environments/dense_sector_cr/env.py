"""DenseSectorCREnv-v0."""

from __future__ import annotations

from bluesky_gym.environments.dense_sector_cr.task import DenseSectorCRTask
from bluesky_gym.envs.shell import BlueSkyEnv, BlueSkyVectorEnv


class DenseSectorCREnv(BlueSkyEnv):
    """Dense-traffic stress test: cross a sector while traffic keeps entering it at a rising rate.

    Animation: ``docs/gifs/DenseSectorCREnv-v0.gif`` (made with ``bluesky-gym render DenseSectorCREnv-v0 --policy classical``).

    ## Description
    SectorCREnv-v0 under a traffic flow. Each episode draws SectorCREnv's convex sector around
    51.9904°N 4.3761°E, its initial traffic (`max(ceil(density · area), 5)` aircraft, agent
    included) and the agent's start and exit points, with the same draws. Then, after every
    decision step, the other aircraft that are outside the sector are removed and new ones enter:
    their number in the step is Poisson distributed with the expected count of the spawn rate over
    the step. The rate [aircraft/h] rises linearly from `spawn_rate_start` (90) to `spawn_rate_end`
    (360) over `rise_time_s` (600 s) and stays there, so the traffic in the sector grows from
    about 15 to about 50 aircraft: a stress curriculum within every episode, and the options make
    a training setting denser than a test setting (see Arguments). A new aircraft enters at a point
    drawn uniformly along the perimeter, set 0.5 NM inside towards the sector centre, and flies
    straight at CAS 150 m/s towards its exit point, drawn on the perimeter a quarter to three
    quarters of the perimeter further along, so it crosses the sector. The other aircraft never
    react. The agent (aircraft 0) commands heading and speed changes every 5 s, as in SectorCREnv:
    it should keep flying towards its exit point while staying 5 NM away from the other aircraft.

    Aircraft slots are not reused within an episode: at most `max_spawned` (120) aircraft enter
    in one episode; an entry beyond that is dropped and counted in the info's `spawns_dropped`
    (with the defaults about 80 enter in a full episode). All aircraft fly at 350 m, as in
    SectorCREnv-v0 (FL350 in `-v1`).

    ## Observation Space
    SectorCREnv-v0's: a `Dict` of float64 `Box`es. `cos(drift)`, `sin(drift)` and `airspeed` are
    `Box(-1, 1, (1,))`; the others are `Box(-inf, inf, (4,))` over the 4 aircraft closest to the
    agent, sorted by ascending flat distance (positions projected flat around the sector centre).
    A policy trained on SectorCREnv-v0 runs here unchanged.

    | Key | Value |
    |---|---|
    | `cos(drift)`, `sin(drift)` | drift = wrap180(heading − kwik bearing to the agent's exit point) |
    | `airspeed` | (TAS [m/s] − 150) / 6; leaves the declared [−1, 1] beyond 144–156 m/s TAS (as in SectorCREnv-v0) |
    | `x_r`, `y_r` | intruder minus agent position, north / east [m] / 13000 |
    | `vx_r`, `vy_r` | intruder minus agent TAS vector (from headings), north / 32, east / 66 [m/s] |
    | `cos(track)`, `sin(track)` | of atan2(Δv_east, Δv_north), the relative-velocity direction |
    | `distances` | (flat distance [m] − 50000) / 15000 |

    ## Action Space
    `Box(-1, 1, (2,), float64)`, SectorCREnv-v0's:
    * heading: HDG wrap180(heading + 22.5·a0) [deg];
    * speed: SPD (CAS [m/s] + (20/3)·a1) · 1.94384 kt (a CAS step of up to 6.67 m/s; 20/3 kt in `-v1`).
    Actions outside [-1, 1] are clipped; NaN, infinite values or a wrong shape raise `ValueError`.

    ## Rewards
    Every step, after the observation (SectorCREnv's):
    * drift: −0.1 · |drift| [rad] (component `drift`);
    * intrusion: −1 per other aircraft within 5 NM kwik distance, horizontal only (`intrusion`).
    There is no reward for reaching the exit point and no terminal reward (`-v1`: see Version History).

    ## Starting State
    SectorCREnv-v0's: the sector, the initial traffic at a density ~ N(0.005, 0.001) aircraft/NM²
    (or uniform with `ac_density_mode="uniform"`), start points uniform in the sector, headings at
    the own exit points. The initial traffic is placed without a separation check, so an episode
    may start in a loss of separation (those are not counted by `kpi_time_to_first_los_s`). The
    traffic flow starts at the episode's start, at `spawn_rate_start`.

    ## Episode End
    `terminated` is always False in `-v0`. The episode is truncated when the agent is no longer
    inside the sector, and after 200 steps (1000 s).

    ## Info
    SectorCREnv's `total_reward`, `total_intrusions` and `average_drift`; `traffic` (other
    aircraft now), `spawned` (aircraft that entered so far), `spawns_dropped` (entries dropped for
    want of a slot), `reward_<component>` every step, and at the end of an episode the KPIs `kpi_*`.

    ## KPIs
    At the end of an episode `info` (`final_info` in batched environments) carries these keys.
    Some are not finite by design; average them over the finite values (see the note on averaging
    on the environment's documentation page).

    | key | meaning | not finite when |
    |---|---|---|
    | `kpi_los_count` | new losses of separation: aircraft coming within 5 NM of the ownship (those present at the start included) | never |
    | `kpi_los_steps` | decision steps with the ownship in a loss of separation | never |
    | `kpi_los_per_flight_hour` | `kpi_los_count` per hour flown by the ownship | never |
    | `kpi_time_to_first_los_s` | episode time of the ownship's first loss of separation that starts during the episode [s] | NaN when none starts |
    | `kpi_min_separation_nm` | smallest distance to another aircraft [NM] | never |
    | `kpi_mean_abs_drift_deg` | mean absolute drift from the heading to the exit point [deg], over the decision steps | never |
    | `kpi_track_distance_km` | distance flown [km] | never |
    | `kpi_fuel_kg` | fuel burned by the ownship [kg]: its fuel flow (BlueSky's OpenAP model) summed over the physics steps | never |
    | `kpi_aircraft_spawned` | aircraft that entered the sector during the episode | never |
    | `kpi_episode_time_s` | simulated time of the episode [s] | never |

    ## Arguments
    `gym.make("DenseSectorCREnv-v0", render_mode=None, backend="native", spawn_rate_start=90.0,
    spawn_rate_end=360.0, rise_time_s=600.0, max_spawned=120, ...)` and SectorCREnv-v0's options
    (`ac_density_mode`, `ac_density_mu`, ..., `poly_area_range`, `intruder_types`,
    `ownship_types`): rates in aircraft/h (at most 3600, `spawn_rate_end` at least
    `spawn_rate_start`), `rise_time_s` > 0, and `max_spawned` such that the slots (worst-case
    initial traffic plus `max_spawned`) stay at most 500. A bad value is refused with a one-line
    error naming the option. On a GPU (`gym.make_vec(..., device="cuda")`) the whole step runs on
    the device, the entering aircraft drawn on the host (docs/backends.md); an airspace there holds
    at most 161 aircraft, so `max_spawned` is at most 123 with the default sector (the default
    slots, 158, fit; more are refused with an error saying so).

    **Train denser than you test.** Train under a rate that rises beyond the test traffic and
    test at a constant rate, e.g.
    `gym.make("DenseSectorCREnv-v1", spawn_rate_start=120.0, spawn_rate_end=480.0)` for training
    and `gym.make("DenseSectorCREnv-v1", spawn_rate_start=240.0, spawn_rate_end=240.0)` for the
    test (`spawn_rate_start == spawn_rate_end`: a constant rate).

    **Reference policies.** `random`, `classical` (SectorCREnv's controller: steer to the exit
    point, turn away from the most urgent conflict) and `mvp` (BlueSky's MVP resolution with
    SectorCREnv's mapping): `bluesky-gym eval --env DenseSectorCREnv-v0 --model mvp`.

    **Multi-agent.** `dense_sector_cr_v0` / `_v1` (PettingZoo) and `DenseSectorCRCentralised-v0`:
    every aircraft is an agent, and the aircraft that enter during the episode are agents that
    appear mid-episode (see `bluesky_gym.environments.dense_sector_cr.multiagent`).

    ## Version History
    * v0: new in this release: SectorCREnv-v0's MDP (its defects included, so that its policies
      transfer) with the traffic flow.
    * v1 (`-v1` ids): SectorCREnv-v1's fixes: float32 observation and action spaces with finite
      bounds, traffic at FL350 (`flight_level_altitude`, `airspeed` = (TAS − 180)/80), the speed
      action in knots (`speed_step_in_knots`), and leaving the sector terminates the episode,
      with a penalty of 1 per decision step left unless within 5 NM of the own exit point
      (`exit_ends_episode`).
    """

    task_class = DenseSectorCRTask


class DenseSectorCRVectorEnv(BlueSkyVectorEnv):
    """Natively batched :class:`DenseSectorCREnv`."""

    task_class = DenseSectorCRTask
