"""SectorCREnv-v0."""

from __future__ import annotations

from bluesky_gym.environments.sector_cr.task import SectorCRTask
from bluesky_gym.envs.shell import BlueSkyEnv, BlueSkyVectorEnv


class SectorCREnv(BlueSkyEnv):
    """Horizontal conflict resolution: cross a sector towards an exit point through random traffic.

    Animation: ``docs/gifs/SectorCREnv-v0.gif`` (made with ``bluesky-gym render SectorCREnv-v0 --policy classical``).

    ## Description
    Every episode draws a convex sector (airspace polygon) around 51.9904°N 4.3761°E: points are
    drawn uniformly on the circle of area 3750 NM² (radius 34.55 NM) until their polygon, sorted
    clockwise by bearing, has an area of at least 2400 NM². The sector is filled with
    `num_ac = max(ceil(density · area), 5)` A320s (agent included), usually 12–19, each flying
    straight at CAS 150 m/s from a random point inside the sector towards its own point on the
    sector boundary. The agent (aircraft 0) commands heading and speed changes every 5 s; it should
    keep flying towards its exit point while staying 5 NM away from the other aircraft. The
    other aircraft have no routes and never react: they fly straight on, also after leaving the
    sector. All aircraft are at 350 m: the reference's `ALTITUDE = 350` (commented "FL") is passed
    to BlueSky in metres, so TAS ≈ 152.4 m/s (kept in v0; the vertical dimension plays no role).

    ## Observation Space
    A `Dict` of float64 `Box`es. `cos(drift)`, `sin(drift)` and `airspeed` are `Box(-1, 1, (1,))`;
    the others are `Box(-inf, inf, (4,))` over the 4 intruders closest to the agent, sorted by
    ascending flat distance. Positions are projected flat around the sector centre
    (north = Δlat·60 NM, east = Δlon·60·cos(51.99°) NM, × 1852 m). The `airspeed` bound and
    values are the reference's: changing either would change what a trained policy sees.

    | Key | Value |
    |---|---|
    | `cos(drift)`, `sin(drift)` | drift = wrap180(heading − kwik bearing to the agent's exit point) |
    | `airspeed` | (TAS [m/s] − 150) / 6; **leaves the declared [−1, 1]** beyond 144–156 m/s TAS (kept, see below) |
    | `x_r`, `y_r` | intruder minus agent position, north / east [m] / 13000 |
    | `vx_r`, `vy_r` | intruder minus agent TAS vector (from headings), north / 32, east / 66 [m/s] |
    | `cos(track)`, `sin(track)` | of atan2(Δv_east, Δv_north), the relative-velocity direction |
    | `distances` | (flat distance [m] − 50000) / 15000 |

    ## Action Space
    `Box(-1, 1, (2,), float64)`:
    * heading: HDG wrap180(heading + 22.5·a0) [deg];
    * speed: SPD (CAS [m/s] + (20/3)·a1) · 1.94384 kt. The reference calls the 20/3 step "kts"
      but adds it to the CAS in m/s, so the CAS target moves by up to ±6.67 m/s per step (kept in
      v0); BlueSky limits the CAS to 67–163 m/s.
    At ~1.72°/s a single 5 s step turns at most ~8.6°. Actions outside [-1, 1] are clipped; NaN,
    infinite values or a wrong shape raise `ValueError`.

    ## Rewards
    Every step, after the observation:
    * drift: −0.1 · |drift| [rad] (component `drift`);
    * intrusion: −1 per other aircraft within 5 NM kwik distance, horizontal only (`intrusion`).
    There is no reward for reaching the exit point and no terminal reward.

    ## Starting State
    Sector and traffic as in the description. Density [aircraft/NM²] ~ N(0.005, 0.001) in the
    default `ac_density_mode="normal"` (a draw above mean + 5 σ is clipped to it, which happens with
    probability 2.9e-7 and bounds the aircraft count), or ~ U(0.003, 0.007) in `"uniform"` mode.
    Exit points: `num_ac` uniform positions along the perimeter, sorted along it from vertex 0;
    the agent gets the first. Start points: uniform in the sector (rejection sampling in its
    bounding box). Headings: great-circle initial bearing to the own exit point.

    ## Episode End
    `terminated` is always False. The episode is truncated when the agent is no longer inside the
    sector (the reference truncates rather than terminates so that the agent does not learn to
    leave quickly), and after 200 steps (1000 s).

    ## Info
    `total_reward`, `total_intrusions` (intruder-steps within 5 NM), `average_drift` (mean |drift|
    [rad] over the steps; 0.0 at reset, where the reference gives NaN), `reward_<component>` every
    step, and at the end of an episode the KPIs `kpi_*` (losses of separation, minimum separation,
    mean drift, track distance; the task has no goal, so there is no success KPI).

    ## KPIs
    At the end of an episode `info` (`final_info` in batched environments) carries these keys.
    Some are not finite by design; average them over the finite values (see the note on averaging
    on the environment's documentation page).

    | key | meaning | not finite when |
    |---|---|---|
    | `kpi_los_count` | new losses of separation: aircraft coming within 5 NM of the ownship | never |
    | `kpi_los_steps` | decision steps with the ownship in a loss of separation | never |
    | `kpi_min_separation_nm` | smallest distance to another aircraft [NM] | never |
    | `kpi_mean_abs_drift_deg` | mean absolute drift from the heading to the exit point [deg], over the decision steps | never |
    | `kpi_track_distance_km` | distance flown [km] | never |
    | `kpi_fuel_kg` | fuel burned by the ownship [kg]: its fuel flow (BlueSky's OpenAP model) summed over the physics steps | never |
    | `kpi_episode_time_s` | simulated time of the episode [s] | never |

    ## Arguments
    `gym.make("SectorCREnv-v0", render_mode=None, backend="native", ac_density_mode="normal",
    ac_density_range=(0.003, 0.007), ac_density_mu=0.005, ac_density_sigma=0.001,
    poly_area_range=(2400, 3750))`. Densities are in aircraft/NM²; `poly_area_range` is the minimum
    polygon area and the area of the circle the vertices lie on [NM²] (minimum ≤ 0.9 × maximum).

    **Aircraft types.** `intruder_types` and `ownship_types` (default `("A320",)`, the paper's
    fleet) set the other traffic's and the agent's types: one name, names drawn with equal
    probability, e.g. `intruder_types=("A320", "B744", "E190")`, or weights, e.g.
    `intruder_types={"A320": 0.5, "B744": 0.5}`. Any type BlueSky 1.1.1 flies with its own OpenAP
    data is accepted (`bluesky_gym.core.aircraft.supported_types()`); another name is refused with
    the list. Types are drawn from the episode's generator after the start points, so a seed gives
    the same geometry whatever the mix; a one-type mix draws nothing, so the default episodes are
    the `-v0` ones. BlueSky's rotorcraft are refused with a one-line error: the speed actions and the
    airspeed observation are scaled for fixed-wing speeds (HorizontalCREnv accepts them).

    ## Version History
    * v0: the paper's MDP (bluesky-gym 0.2.0, after its 2025-01 fixes of the drift computation,
      the intruder altitude and the CAS-based speed action). Fixed software defects: seeded
      generator, `average_drift` is 0.0 at reset, rgb_array frames, many environments per process.
    * v1 (`-v1` ids; the same task with these configuration fields set, selected by the registry):
      float32 observation and action spaces with finite bounds that the observations keep (SB3 and
      `check_env` warned about float64 and infinite bounds; the bounds are in
      docs/environments-v1.md);
      traffic at FL350 (`flight_level_altitude`): the reference's "FL350" was used as 350 m; at FL350
      BlueSky caps the CAS 150 m/s at M0.80 (TAS 237 m/s), and `airspeed` is (TAS − 180)/80 so that it
      stays in [−1, 1];
      the speed action changes CAS by 20/3 kt per unit (`speed_step_in_knots`): the "kts" were added
      as m/s;
      leaving the sector terminates the episode; within 5 NM of the own waypoint it is the exit,
      elsewhere it costs 1 per decision step left (`exit_ends_episode`): leaving early used to
      truncate without penalty, so it escaped the drift and intrusion penalties (bluesky-gym #44).
    """

    task_class = SectorCRTask


class SectorCRVectorEnv(BlueSkyVectorEnv):
    """Natively batched :class:`SectorCREnv`."""

    task_class = SectorCRTask
