"""PlanWaypointEnv-v0."""

from __future__ import annotations

from bluesky_gym.environments.plan_waypoint.task import PlanWaypointTask
from bluesky_gym.envs.shell import BlueSkyEnv, BlueSkyVectorEnv


class PlanWaypointEnv(BlueSkyEnv):
    """Horizontal control: fly over five scattered waypoints, in any order.

    Animation: ``docs/gifs/PlanWaypointEnv-v0.gif`` (made with ``bluesky-gym render PlanWaypointEnv-v0 --policy classical``).

    ## Description
    An A320 is created at 52°N 4°E, heading north, with a requested CAS of 150 m/s but at
    altitude 0 m. BlueSky therefore treats it as being on the ground: OpenAP's ground phase caps
    its speed at 89 m/s, it decelerates to that within a few seconds and never takes off, and wind
    has no effect on it (all BlueSky physics, kept in v0). Five waypoints are scattered within
    75 km. Every 10 s the agent changes the heading; each waypoint that comes within 5 km scores
    a point. It is a travelling-salesman problem without explicit planning: the turn rate at
    89 m/s is about 2.9°/s, so at most about 29° of turn fits in one step.

    ## Observation Space
    A `Dict` of four `Box`es of shape `(5,)`, float64, one entry per waypoint in fixed creation
    order. With drift = wrap180(hdg − kwik-bearing to the waypoint) and the mask m = 1 − reached:

    | Key | Bounds | Value |
    |---|---|---|
    | `waypoint_distance` | ±inf | m · kwik-distance [km] / 75 |
    | `cos_difference` | ±inf | m · cos(drift) |
    | `sin_difference` | ±inf | m · sin(drift) |
    | `waypoint_reached` | [0, 1] | 1.0 once the waypoint has been reached, else 0.0 |

    Masked entries are 0.0 times the value, so they can be −0.0. The reach flags are updated
    after the observation is built: a waypoint reached in a step still shows as unreached (and
    unmasked) in that step's observation, and as reached from the next one on.

    ## Action Space
    `Box(-1, 1, (1,), float64)`: the autopilot heading target becomes hdg + 45·a degrees (as
    the reference's "HDG" command; not wrapped, BlueSky takes it modulo 360). Actions outside
    [-1, 1] are clipped; NaN, infinite values or a wrong shape raise `ValueError`.

    ## Rewards
    +1 for every waypoint that newly comes within 5 km (kwik-distance) at the end of a step
    (component `reach`). There are no other terms.

    ## Starting State
    A clean airspace with one aircraft at 52°N 4°E, heading 0°, altitude 0 m, CAS 150 m/s
    requested. Waypoint i (i = 0..4, distance then bearing for each): distance integer uniform in
    [0, 75) km, bearing integer uniform in [0, 359) degrees (the reference's `randint(0, 359)`, so
    359° is never drawn; kept), placed from the aircraft's position with the spherical
    destination formula (R = 6371 km). A waypoint can therefore start within the capture radius;
    it is then collected at the end of the first step.

    ## Episode End
    Termination when all waypoints have been reached. Truncation after 300 steps (3000 s).

    ## Info
    `total_reward`, `waypoints_completed` (number reached), `reward_reach` every step, and at
    the end of an episode the KPIs `kpi_*`: success = all waypoints reached, time to goal, and
    extra track = distance flown minus the shortest polyline from the start through all waypoint
    centres (negative values are possible, since a waypoint counts within 5 km). There is no
    traffic, so the separation KPIs are trivial, and no single heading goal, so the drift KPI is
    NaN.

    ## KPIs
    At the end of an episode `info` (`final_info` in batched environments) carries these keys.
    Some are not finite by design; average them over the finite values (see the note on averaging
    on the environment's documentation page).

    | key | meaning | not finite when |
    |---|---|---|
    | `kpi_success` | 1.0 if every waypoint was reached, else 0.0 | never |
    | `kpi_time_to_goal_s` | simulated time until the last waypoint was reached [s] | `NaN` when the goal was not reached |
    | `kpi_extra_track_km` | distance flown minus the shortest polyline through all waypoint centres [km]; can be negative | never |
    | `kpi_los_count` | losses of separation; always 0, there is no other aircraft | never |
    | `kpi_los_steps` | decision steps with the ownship in a loss of separation | never |
    | `kpi_min_separation_nm` | smallest distance to another aircraft [NM] | always `inf`: there is no other aircraft |
    | `kpi_mean_abs_drift_deg` | mean absolute drift [deg] | always `NaN`: there is no single heading goal |
    | `kpi_track_distance_km` | distance flown [km] | never |
    | `kpi_fuel_kg` | fuel burned by the ownship [kg]: its fuel flow (BlueSky's OpenAP model) summed over the physics steps | never |
    | `kpi_episode_time_s` | simulated time of the episode [s] | never |

    ## Arguments
    `gym.make("PlanWaypointEnv-v0", render_mode=None, backend="native", num_waypoints=5,
    waypoint_distance_min=0, waypoint_distance_max=75, distance_margin_km=5.0)`. The waypoint
    distance normalisation follows `waypoint_distance_max`; `num_waypoints` (1 to 8) sets the
    length of the observation vectors.

    ## Version History
    * v0: the paper's MDP (bluesky-gym 0.2.0). Fixed software defects: seeded generator; clean
      reset (the reference keeps a truncated episode's aircraft, so the next episode continued
      from its position, heading and speed; here every episode starts at 52°N 4°E);
      `terminated` is a bool; the reach flags are float64; rgb_array frames.
    * v1 (`-v1` ids; the same task with these configuration fields set, selected by the registry):
      float32 observation and action spaces with finite bounds that the observations keep (SB3 and
      `check_env` warned about float64 and infinite bounds; the bounds are in
      docs/environments-v1.md);
      the aircraft starts at FL100 (`airborne_start`): at altitude 0 it was in BlueSky's ground phase,
      capped at 89 m/s instead of the scenario's CAS 150 m/s;
      a waypoint reached in a step shows as reached in that step's observation (`reach_same_step`):
      the flags lagged one step.
    """

    task_class = PlanWaypointTask


class PlanWaypointVectorEnv(BlueSkyVectorEnv):
    """Natively batched :class:`PlanWaypointEnv`."""

    task_class = PlanWaypointTask
