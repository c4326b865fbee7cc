"""HorizontalCREnv-v0."""

from __future__ import annotations

from bluesky_gym.environments.horizontal_cr.task import HorizontalCRTask
from bluesky_gym.envs.shell import BlueSkyEnv, BlueSkyVectorEnv


class HorizontalCREnv(BlueSkyEnv):
    """Horizontal conflict resolution: reach a waypoint while avoiding crossing traffic.

    Animation: ``docs/gifs/HorizontalCREnv-v0.gif`` (made with ``bluesky-gym render HorizontalCREnv-v0 --policy classical``).

    ## Description
    An A320 starts at 52°N 4°E heading north and must reach a waypoint due north of it, 100 to
    150 km away. Five intruders, created with BlueSky's `creconfs`, fly straight towards
    conflicts with it, each set up to come within 5 NM after a random time. Every 50 s
    (10 sub-steps of 5 s) the agent changes the heading by up to ±45°.

    As in the reference, no altitude is given when the aircraft are created, so they are at
    0 m, in OpenAP's ground phase: they decelerate from 150 to **89 m/s** and fly at that speed
    (BlueSky physics, kept), which keeps the conflict geometry but stretches it in time. Wind
    never acts below 50 ft, so wind wrappers have no effect on this environment.

    ## Observation Space
    A `Dict` of `Box(-inf, inf, shape, float64)`. The intruder entries have shape (5,), one
    value per intruder **in creation order** (no sorting, as the reference); the waypoint
    entries have shape (1,):

    | Key | Value |
    |---|---|
    | `intruder_distance` | kwik-distance ownship → intruder [km] / 150 |
    | `cos_difference_pos`, `sin_difference_pos` | cos / sin of wrap180(hdg_own − qdr_own→int); positive: intruder to the left |
    | `x_difference_speed` | −cos(hdg_own − hdg_int)·gs_int / 150 |
    | `y_difference_speed` | (gs_own − sin(hdg_own − hdg_int)·gs_int) / 150 |
    | `waypoint_distance` | kwik-distance to the waypoint [km] / 150 |
    | `cos_drift`, `sin_drift` | cos / sin of drift = wrap180(hdg_own − qdr_own→waypoint) |

    ## Action Space
    `Box(-1, 1, (1,), float64)`: heading command (BlueSky `HDG`) to h + 45·a degrees, where h is
    the ownship heading **at the last observation**. The target may fall outside [0, 360) and is
    used as such. At 89 m/s the turn rate is about 2.9°/s, so a 45° change completes within the
    step. Actions outside [-1, 1] are clipped; NaN, infinite values or a wrong shape raise
    `ValueError`.

    ## Rewards
    Evaluated after the 10 sub-steps, on the state of the returned observation; the reward is
    the sum of:
    * +1 the first time the waypoint is within 5 km (kwik distance) (component `reach`);
    * −0.1·|drift| with the drift in radians (`drift`);
    * −1 for every intruder within 5 NM (kwik distance, horizontal only) (`intrusion`).

    As in the reference, the waypoint's reach flag is updated after the observation is built
    (a one-step lag visible only in the rendered waypoint colour, since reaching the waypoint
    ends the episode).

    ## Starting State
    Ownship: 52°N 4°E, heading 0°, altitude 0 m, CAS 150 m/s. Then, for each of the five
    intruders, in this order: track offset dpsi integer in [45, 315) deg, dcpa integer in [0, 5)
    NM, tlosh integer in [100, 1000) s; each is created by `creconfs` at the ownship's altitude
    and ground speed. Finally the waypoint distance, an integer in [100, 150) km, placed due north
    on the great circle. The initial drift is 0.

    ## Episode End
    Termination when the waypoint is reached. Truncation after 300 steps (15000 s).

    ## Info
    `total_reward`, `total_intrusions` (intruder-steps within 5 NM), `average_drift` (mean
    |drift| in radians over the steps so far; **0.0 at reset**, where the reference reports the
    NaN mean of an empty array), `reward_<component>` every step, and at the end of an episode
    the KPIs `kpi_*` (losses of separation within 5 NM, minimum separation, mean drift, success =
    waypoint reached, time to goal, extra track = distance flown − (initial distance to the
    waypoint − the 5 km capture radius), ...).

    ## KPIs
    At the end of an episode `info` (`final_info` in batched environments) carries these keys.
    Some are not finite by design; average them over the finite values (see the note on averaging
    on the environment's documentation page).

    | key | meaning | not finite when |
    |---|---|---|
    | `kpi_success` | 1.0 if the waypoint was reached, else 0.0 | never |
    | `kpi_time_to_goal_s` | simulated time until the waypoint was reached [s] | `NaN` when the goal was not reached |
    | `kpi_extra_track_km` | distance flown minus (initial distance to the waypoint − the 5 km capture radius) [km] | never |
    | `kpi_los_count` | new losses of separation: intruders coming within 5 NM | never |
    | `kpi_los_steps` | decision steps with the ownship in a loss of separation | never |
    | `kpi_min_separation_nm` | smallest distance to an intruder [NM] | never |
    | `kpi_mean_abs_drift_deg` | mean absolute drift from the heading to the waypoint [deg], over the decision steps | never |
    | `kpi_track_distance_km` | distance flown [km] | never |
    | `kpi_fuel_kg` | fuel burned by the ownship [kg]: its fuel flow (BlueSky's OpenAP model) summed over the physics steps | never |
    | `kpi_episode_time_s` | simulated time of the episode [s] | never |

    ## Arguments
    `gym.make("HorizontalCREnv-v0", render_mode=None, backend="native", num_intruders=5,
    dpsi_min=45, dpsi_max=315, dcpa_min=0, dcpa_max=5, tlosh_min=100, tlosh_max=1000,
    waypoint_distance_min=100, waypoint_distance_max=150)`. Integer draws are uniform over
    [min, max). The observation's 150 km distance normalisation does not change with the options.

    **Aircraft types.** `intruder_types` and `ownship_types` (default `("A320",)`, the paper's
    fleet) set the intruders' and the ownship's types: one name, names drawn with equal probability,
    e.g. `intruder_types=("A320", "B744", "E190")`, or weights, e.g. `intruder_types={"A320": 0.5,
    "B744": 0.5}`. Any type BlueSky 1.1.1 flies with its own OpenAP data is accepted
    (`bluesky_gym.core.aircraft.supported_types()`); another name is refused with the list. Types
    are drawn from the episode's generator after all other draws of the scenario, so a seed gives
    the same geometry whatever the mix; a one-type mix draws nothing, so the default episodes are
    the `-v0` ones. This environment also accepts BlueSky's rotorcraft (helicopters and drones,
    `bluesky_gym.core.aircraft.ROTORCRAFT_TYPES`, e.g. `intruder_types={"A320": 0.7, "EC35": 0.3}`),
    which fly BlueSky's rotor model (a fixed TAS envelope, e.g. at most 71.95 m/s for the EC35 and
    18 m/s for the M600); it is the one paper task whose actions (headings) and traffic (at the
    ownship's altitude) suit them. They burn no fuel in BlueSky's model, so a rotorcraft ownship
    ends its episodes with `kpi_fuel_kg` 0. With `airborne_start` (`-v1`) a rotorcraft must reach
    FL100 (the M100, M200 and the drones with a 2500 m ceiling are refused).

    ## Version History
    * v0: the paper's MDP (bluesky-gym 0.2.0). Fixed software defects: seeded generator,
      `terminated` is a bool, `average_drift` is a number at reset, rgb_array frames, correct
      north-up pictures. The reference's deletion of (every other) aircraft on termination is
      not reproduced: every reset starts a clean scenario, so it has no effect.
    * v1 (`-v1` ids; the same task with these configuration fields set, selected by the registry):
      float32 observation and action spaces with finite bounds that the observations keep (SB3 and
      `check_env` warned about float64 and infinite bounds; the bounds are in
      docs/environments-v1.md);
      every aircraft starts at FL100 (`airborne_start`): at altitude 0 they were in BlueSky's ground
      phase, capped at 89 m/s, which also stretched the conflict geometry in time.
    """

    task_class = HorizontalCRTask


class HorizontalCRVectorEnv(BlueSkyVectorEnv):
    """Natively batched :class:`HorizontalCREnv`."""

    task_class = HorizontalCRTask
