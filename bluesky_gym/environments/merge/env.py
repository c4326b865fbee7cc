"""MergeEnv-v0."""

from __future__ import annotations

from bluesky_gym.environments.merge.task import MergeTask
from bluesky_gym.envs.shell import BlueSkyEnv, BlueSkyVectorEnv


class MergeEnv(BlueSkyEnv):
    """Arrival merging: join a stream of 19 arrivals through a final approach fix to the runway.

    Animation: ``docs/gifs/MergeEnv-v0.gif`` (made with ``bluesky-gym render MergeEnv-v0 --policy classical``).

    ## Description
    A final approach fix (FAF) lies 200 km due north of the Schiphol runway threshold
    (52.3624°N 4.7132°E), at 54.1610°N 4.7132°E; the reference's comment says NM, the value is used
    in km. The ownship and 19 intruders fly at 10000 m, created at CAS 100 m/s (TAS ≈ 167.5 m/s,
    M ≈ 0.56). The intruders fly BlueSky's LNAV: direct to the FAF, then (fly-by turn) to the runway
    as their destination, then straight on; VNAV stays off, so nobody descends. The agent commands
    heading and speed changes of the ownship every 50 s; it should fly to the FAF and then towards
    the runway while keeping 4 NM from the intruders.

    ## Observation Space
    A `Dict` of float64 `Box`es: `cos(drift)`, `sin(drift)` are `Box(-1, 1, (1,))`; `airspeed` and
    `waypoint_dist` `Box(-inf, inf, (1,))`; `faf_reached` `Box(0, 1, (1,))`; the others
    `Box(-inf, inf, (5,))` over the 5 intruders closest to the ownship by kwik distance, ascending.

    | Key | Value |
    |---|---|
    | `cos(drift)`, `sin(drift)` | drift = wrap180(heading − kwik bearing to the target): the FAF until it is reached, then the runway |
    | `airspeed` | TAS [m/s], **not normalised** (reference) |
    | `waypoint_dist` | kwik distance to the target [NM] / 250 |
    | `faf_reached` | 0 before, 1 after the FAF was reached; set by the reward, so it shows one step late |
    | `x_r`, `y_r` | d·1852·cos(qdr), d·1852·sin(qdr) [m] / 1e6 (north / east); d, qdr: kwik distance [NM], bearing |
    | `vx_r`, `vy_r` | intruder minus ownship TAS vector (from headings), north / east [m/s] / 150 |
    | `cos(track)`, `sin(track)` | of atan2(Δv_east, Δv_north), the relative-velocity direction |
    | `distances` | kwik distance [NM] / 250 |

    ## Action Space
    `Box(-1, 1, (2,), float64)`:
    * heading: HDG wrap180(heading + 15·a0) [deg];
    * speed: SPD (CAS [m/s] + 20·a1) · 1.94384 kt, i.e. ±20 m/s of CAS per step. BlueSky limits
      it to 67–163 m/s CAS and M0.80 (≈ 139 m/s CAS at 10000 m).
    Actions outside [-1, 1] are clipped; NaN, infinite values or a wrong shape raise `ValueError`.

    ## Rewards
    Every step, after the observation (so with the observation's target distance):
    * reach (`reach`): +1 when the FAF distance is below 10 (NM; commented km in the reference) and
      the FAF was not reached before. The target then switches to the runway;
    * runway: once the FAF was reached, a runway distance below 20 NM ends the episode (no reward);
    * drift (`drift`): −0.1 · |drift| [rad];
    * intrusion (`intrusion`): −1 per intruder (all 19) within 4 NM kwik distance; there is no
      altitude test, all aircraft share one altitude.

    ## Starting State
    Ownship: bearing b ~ U(−15°, 15°) and distance d ~ U(50, 200) km from the FAF (great circle),
    heading b − 180° (towards the FAF; stored unwrapped, e.g. −170°, as BlueSky does until the first
    step). Intruders: b ~ U(−15°, 15°), d ~ U(20, 500) km from the FAF, heading b − 180°, route
    FAF → runway. Same speed and altitude for all.

    ## Episode End
    Termination 20 NM before the runway after the FAF (info `faf_reach` = 2). Truncation after 50
    steps (2500 s). Aircraft are never deleted.

    ## Info
    `total_reward`, `faf_reach` (0, 1 after the FAF, 2 at the end), `average_drift` (mean |drift|
    [rad] over the steps; 0.0 at reset, where the reference gives NaN), `total_intrusions`,
    `reward_<component>` every step, and at the end of an episode the KPIs `kpi_*` (success =
    `faf_reach` 2, time to goal, extra track against start → FAF → 20 NM before the runway, ...).

    ## KPIs
    At the end of an episode `info` (`final_info` in batched environments) carries these keys.
    Some are not finite by design; average them over the finite values (see the note on averaging
    on the environment's documentation page).

    | key | meaning | not finite when |
    |---|---|---|
    | `kpi_success` | 1.0 if the aircraft passed the FAF and came within 20 NM of the runway (`faf_reach` 2), else 0.0 | never |
    | `kpi_time_to_goal_s` | simulated time until then [s] | `NaN` when the goal was not reached |
    | `kpi_extra_track_km` | distance flown minus the nominal route start → FAF → 20 NM before the runway [km] | never |
    | `kpi_los_count` | new losses of separation: aircraft coming within 4 NM of the ownship | never |
    | `kpi_los_steps` | decision steps with the ownship in a loss of separation | never |
    | `kpi_min_separation_nm` | smallest distance to another aircraft [NM] | never |
    | `kpi_mean_abs_drift_deg` | mean absolute drift (from the bearing to the FAF, then the runway) [deg], over the decision steps | never |
    | `kpi_track_distance_km` | distance flown [km] | never |
    | `kpi_fuel_kg` | fuel burned by the ownship [kg]: its fuel flow (BlueSky's OpenAP model) summed over the physics steps | never |
    | `kpi_episode_time_s` | simulated time of the episode [s] | never |

    ## Arguments
    `gym.make("MergeEnv-v0", render_mode=None, backend="native", num_aircraft=20,
    spawn_distance_km=(50.0, 200.0), intruder_distance_km=(20.0, 500.0), spawn_bearing_deg=15.0,
    ac_speed=100.0, altitude=10000.0)`. `num_aircraft` includes the ownship (6–200); `ac_speed` is
    the creation CAS [m/s] (the paper's training logs were recorded with 150, which BlueSky
    limits to M0.80), `altitude` in metres.

    **Aircraft types.** `intruder_types` and `ownship_types` (default `("A320",)`, the paper's
    fleet) set the intruders' and the ownship's types: one name, names drawn with equal probability,
    e.g. `intruder_types=("A320", "B744", "E190")`, or weights, e.g. `intruder_types={"A320": 0.5,
    "B744": 0.5}`. Any type BlueSky 1.1.1 flies with its own OpenAP data is accepted
    (`bluesky_gym.core.aircraft.supported_types()`); another name is refused with the list. Types
    are drawn from the episode's generator after the spawn points, so a seed gives the same geometry
    whatever the mix (the speed and altitude normalisation stays the A320's); a one-type mix draws
    nothing, so the default episodes are the `-v0` ones. BlueSky's rotorcraft are refused with a
    one-line error: the traffic flies at 10,000 m by default, above their ceilings, with fixed-wing
    speed actions (HorizontalCREnv accepts them).

    ## Version History
    * v0: the paper's MDP (bluesky-gym 0.2.0). Fixed software defects: the scenario draws come from
      the episode generator (the reference uses Python's global `random`), `average_drift` is 0.0
      at reset, `terminated` is a bool and `faf_reached` a float, rgb_array frames, many
      environments per process. Kept: the one-step lag of `faf_reached`, the raw airspeed, the
      km/NM mix in the FAF distance and the margins.
    * The reference's intruder sort uses `kwikdist_matrix`, which with BlueSky 1.1.1's compiled
      geometry (its default) returns a single 0 and makes the reference crash at reset; v0
      implements the specified sort by kwik distance to each intruder.
    * v1 (`-v1` ids; the same task with these configuration fields set, selected by the registry):
      float32 observation and action spaces with finite bounds that the observations keep (SB3 and
      `check_env` warned about float64 and infinite bounds; the bounds are in
      docs/environments-v1.md);
      the FAF reached in a step shows in that step's observation, with the runway as the new target
      (`faf_same_step`, bluesky-gym #13);
      the FAF is 200 NM north of the runway (`faf_distance_in_nm`), the unit the reference's comment
      gives (it was 200 km); the episode limit is 100 steps so that the runway stays within reach;
      the FAF capture radius is 10 km and the runway goal 20 km (`margins_in_km`): the "km" were
      compared with NM;
      `airspeed` is (TAS − 150)/150 (`normalise_airspeed`): it was the raw TAS, about 168 m/s.
    """

    task_class = MergeTask


class MergeVectorEnv(BlueSkyVectorEnv):
    """Natively batched :class:`MergeEnv`."""

    task_class = MergeTask
