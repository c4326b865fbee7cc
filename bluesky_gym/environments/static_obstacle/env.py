"""StaticObstacleEnv-v0."""

from __future__ import annotations

from bluesky_gym.environments.static_obstacle.task import StaticObstacleTask
from bluesky_gym.envs.shell import BlueSkyEnv, BlueSkyVectorEnv


class StaticObstacleEnv(BlueSkyEnv):
    """Horizontal control: reach a waypoint while avoiding ten polygonal restricted areas.

    Animation: ``docs/gifs/StaticObstacleEnv-v0.gif`` (made with ``bluesky-gym render StaticObstacleEnv-v0 --policy classical``).

    ## Description
    An A320 at 350 m (the reference's `ALTITUDE = 350` is meant as FL350 but used as metres;
    kept) starts at 52°N 4°E with CAS 150 m/s (TAS about 152 m/s), pointing at a waypoint
    100–169 km away. Ten convex polygonal restricted areas lie 20–149 km around the start. Every
    10 s the agent changes heading and speed. Entering any area ends the episode. The turn rate
    is about 1.7°/s, so about 17° of turn fits in one step. Many goals cannot be reached within
    the 100-step limit (1000 s at about 152 m/s is about 152 km). Nothing checks that the start
    position is outside the obstacles, so some episodes end on the first step.

    ## Observation Space
    A `Dict` of seven float64 `Box`es. Obstacles are in fixed creation order. With drift =
    wrap180(hdg − kwik-bearing to the waypoint) and, per obstacle, bearing = wrap180(hdg −
    kwik-bearing to its centre):

    | Key | Shape | Bounds | Value |
    |---|---|---|---|
    | `destination_waypoint_distance` | (1,) | ±inf | kwik-distance to the waypoint [km] / 170 |
    | `destination_waypoint_cos_drift` | (1,) | ±inf | cos(drift) |
    | `destination_waypoint_sin_drift` | (1,) | ±inf | sin(drift) |
    | `restricted_area_radius` | (10,) | [0, 1] | radius of the circle the polygon was drawn on [NM] / 50 (0.11–0.36) |
    | `restricted_area_distance` | (10,) | ±inf | kwik-distance to the obstacle centre [km] / 170 |
    | `cos_difference_restricted_area_pos` | (10,) | ±inf | cos(bearing) |
    | `sin_difference_restricted_area_pos` | (10,) | ±inf | sin(bearing) |

    An obstacle is described by its centre and enclosing circle, not by its polygon.

    ## Action Space
    `Box(-1, 1, (2,), float64)`: heading target wrap180(hdg + 45·a0) degrees, and speed target
    (CAS [m/s] + a1·20/3)·1.94384 knots, i.e. CAS ± 6.67 m/s: the reference's "20/3 kts" step is
    added in m/s (kept). OpenAP clamps CAS to 67–163 m/s. Actions outside [-1, 1] are clipped;
    NaN, infinite values or a wrong shape raise `ValueError`.

    ## Rewards
    Evaluated after each of the 10 one-second sub-steps, from the waypoint distance and drift of
    the **previous observation** (stale) and the **live** position:
    * `reach`: +1 the first time the stale waypoint distance is below 5 km;
    * `drift`: −0.01·|drift| [rad] (stale drift);
    * `intrusion`: −5 per restricted area containing the aircraft (even-odd test on the polygon
      in (lat, lon), BlueSky's 2-D `checkInside`).

    When an episode ends at sub-step k (waypoint reached or intrusion), the step returns at once
    with the observation and reward of sub-step k. Otherwise the step returns the reward of the
    last sub-step only: the sub-steps' drift penalties are not summed, so a normal step's reward
    is −0.01·|drift at the previous observation|. Because the reward uses the previous
    observation's distance, a waypoint capture is detected one step late, at sub-step 1 of the
    next step. In a vector environment, an episode that ends at sub-step k returns sub-step k's
    observation while the other episodes complete their sub-steps.

    ## Starting State
    A clean airspace with one aircraft at 52°N 4°E, 350 m, CAS 150 m/s. Then, in this order:
    1. ten obstacle centres, each at an integer distance uniform in [20, 150) km and an integer
       bearing uniform in [0, 360) degrees from the aircraft (spherical destination formula);
    2. for each obstacle, a circle area A integer uniform in [100, 1000) NM², radius
       R = sqrt(A/π) NM, and a polygon of points drawn uniformly on that circle: three points,
       sorted clockwise, then one more at a time until the shoelace area is at least 50 NM²
       (so the polygon area is only guaranteed to be ≥ 50 NM²); vertices converted from
       (north, east) NM offsets to (lat, lon) around the centre at 60 NM per degree;
    3. the waypoint, rejection-sampled: integer distance uniform in [100, 170) km, integer
       bearing uniform in [0, 360) degrees, redrawn while inside any obstacle; a
       `RuntimeError` is raised at the 1001st try;
    4. heading and autopilot track set to the kwik-bearing from the aircraft to the waypoint.

    ## Episode End
    Termination when the waypoint is reached or an obstacle is entered. Truncation after 100
    steps (1000 s).

    ## Info
    `total_reward`, `waypoint_reached` (0/1), `crashed` (0/1), `average_drift` (mean of the
    per-sub-step |drift| samples [rad]; 0.0 before the first step, where the reference gives
    NaN), `reward_reach`, `reward_drift`, `reward_intrusion` every step, and at the end of an
    episode the KPIs `kpi_*`: success = waypoint reached, time to goal, mean |drift| per step,
    extra track = distance flown minus the start-to-waypoint kwik-distance, and
    `kpi_obstacle_intrusions`, the number of restricted areas the aircraft was inside when the
    episode ended (0 without a crash; overlapping areas count separately). There is no
    traffic, so the separation KPIs are trivial.

    ## KPIs
    At the end of an episode `info` (`final_info` in batched environments) carries these keys.
    Some are not finite by design; average them over the finite values (see the note on averaging
    on the environment's documentation page).

    | key | meaning | not finite when |
    |---|---|---|
    | `kpi_success` | 1.0 if the waypoint was reached, else 0.0 | never |
    | `kpi_time_to_goal_s` | simulated time until the waypoint was reached [s] | `NaN` when the goal was not reached |
    | `kpi_extra_track_km` | distance flown minus the start-to-waypoint kwik-distance [km] | never |
    | `kpi_los_count` | losses of separation; always 0, there is no other aircraft | never |
    | `kpi_los_steps` | decision steps with the ownship in a loss of separation | never |
    | `kpi_min_separation_nm` | smallest distance to another aircraft [NM] | always `inf`: there is no other aircraft |
    | `kpi_mean_abs_drift_deg` | mean absolute drift from the heading to the waypoint [deg], over the decision steps | never |
    | `kpi_track_distance_km` | distance flown [km] | never |
    | `kpi_fuel_kg` | fuel burned by the ownship [kg]: its fuel flow (BlueSky's OpenAP model) summed over the physics steps | never |
    | `kpi_episode_time_s` | simulated time of the episode [s] | never |
    | `kpi_obstacle_intrusions` | restricted areas the aircraft was inside at the end (0 without a crash) | never |

    ## Arguments
    `gym.make("StaticObstacleEnv-v0", render_mode=None, backend="native", num_obstacles=10,
    obstacle_distance_min=20, obstacle_distance_max=150, obstacle_area_min=50,
    obstacle_area_max=1000, waypoint_distance_min=100, waypoint_distance_max=170,
    distance_margin_km=5.0)`. The circle-area draw is [2·obstacle_area_min, obstacle_area_max),
    as in the reference; distances are normalised by `waypoint_distance_max`; the radius scale
    is fixed at 50 NM, so `obstacle_area_max` is at most π·50² NM².

    ## Version History
    * v0: the paper's MDP (bluesky-gym 0.2.0). Fixed software defects: seeded generator,
      `terminated` is a bool, `average_drift` is 0.0 (not NaN) at reset, rgb_array frames. Not
      reproduced: the paper's training logs were recorded with an uncommitted variant without
      the drift penalty.
    * v1 (`-v1` ids; the same task with these configuration fields set, selected by the registry):
      float32 observation and action spaces with finite bounds that the observations keep (SB3 and
      `check_env` warned about float64 and infinite bounds; the bounds are in
      docs/environments-v1.md);
      the aircraft flies at FL350 (`flight_level_altitude`): "FL350" was 350 m; at FL350 (TAS 237 m/s)
      the farthest waypoint (169 km) is reachable in the 100 steps, at 152 m/s many were not;
      the speed action changes CAS by 20/3 kt per unit (`speed_step_in_knots`): the "kts" were added
      as m/s;
      the reward is evaluated once per decision step on the state after it (`step_reward`): it was
      evaluated per sub-step with the previous observation's waypoint distance and drift and only the
      last sub-step's value returned, so the waypoint was detected a step late;
      an obstacle whose circle comes within 5 km of the start is redrawn (`clear_start`): about 6% of
      the episodes started inside or at the edge of an obstacle.
    """

    task_class = StaticObstacleTask


class StaticObstacleVectorEnv(BlueSkyVectorEnv):
    """Natively batched :class:`StaticObstacleEnv`."""

    task_class = StaticObstacleTask
