"""DescentEnv-v0."""

from __future__ import annotations

from bluesky_gym.environments.descent.task import DescentTask
from bluesky_gym.envs.shell import BlueSkyEnv, BlueSkyVectorEnv


class DescentEnv(BlueSkyEnv):
    """Vertical control: hold a target altitude, then descend to the runway in time.

    Animation: ``docs/gifs/DescentEnv-v0.gif`` (made with ``bluesky-gym render DescentEnv-v0 --policy classical``).

    ## Description
    An A320 flies north from 52°N 4°E at CAS 150 m/s towards a runway 200 km ahead (measured
    from the start point). The agent commands a vertical speed every 30 s. It should hold the
    target altitude while the runway is far and start its descent late enough to stay near the
    target, yet early enough to be low over the runway. There is no horizontal control. Below
    1000 ft while descending OpenAP's approach phase caps CAS at 77 m/s, so a late dive slows the
    aircraft (BlueSky physics, kept).

    ## Observation Space
    A `Dict` of four `Box(-inf, inf, (1,), float64)`:

    | Key | Value |
    |---|---|
    | `altitude` | (alt [m] − 1500) / 3000 |
    | `vz` | vertical speed [m/s] / 5 |
    | `target_altitude` | (target altitude [m] − 1500) / 3000 |
    | `runway_distance` | (rd [km] − 100) / 200, rd = 200 − kwik-distance from the start point |

    ## Action Space
    `Box(-1, 1, (1,), float64)`: vertical speed v = 12.5·a m/s. For v ≥ 0 the selected
    altitude is 1e6 m (clipped to the 11060 m ceiling), otherwise 0 m; `selvs = v`. As in BlueSky,
    |v| ≤ 0.1 m/s (|a| ≤ 0.008) selects the default 7.62 m/s, so a = 0 climbs. Actions outside
    [-1, 1] are clipped; NaN, infinite values or a wrong shape raise `ValueError`.

    ## Rewards
    Evaluated after the 30 sub-steps, in this order:
    1. runway ahead and alt > 0: −(5/3000)·|target − alt| (component `altitude`);
    2. alt ≤ 0: −100 and the episode terminates (`crash`);
    3. runway reached: −(50/3000)·alt, and the episode terminates (`runway`).

    ## Starting State
    Initial altitude: integer uniform in [2000, 4000) m; target: initial + integer uniform in
    [−500, 500) m; heading 0°, CAS 150 m/s, VNAV off.

    ## Episode End
    Termination on crash or at the runway. Truncation after 300 steps (9000 s).

    ## Info
    `total_reward`, `final_altitude` (0 until the end, −100 after a crash), `reward_<component>`
    every step, and at the end of an episode the KPIs `kpi_*` (success = runway reached,
    time to goal, extra track, ...).

    ## KPIs
    At the end of an episode `info` (`final_info` in batched environments) carries these keys.
    Some are not finite by design; average them over the finite values (see the note on averaging
    on the environment's documentation page).

    | key | meaning | not finite when |
    |---|---|---|
    | `kpi_success` | 1.0 if the runway was reached (no crash), else 0.0 | never |
    | `kpi_time_to_goal_s` | simulated time until the runway was reached [s] | `NaN` when the goal was not reached |
    | `kpi_extra_track_km` | distance flown minus the runway leg (`runway_distance_km`) [km]; negative before the runway | never |
    | `kpi_los_count` | losses of separation; always 0, there is no other aircraft | never |
    | `kpi_los_steps` | decision steps with the ownship in a loss of separation | never |
    | `kpi_min_separation_nm` | smallest distance to another aircraft [NM] | always `inf`: there is no other aircraft |
    | `kpi_mean_abs_drift_deg` | mean absolute drift from the goal heading [deg] | always `NaN`: the task has no heading goal |
    | `kpi_track_distance_km` | distance flown [km] | never |
    | `kpi_fuel_kg` | fuel burned by the ownship [kg]: its fuel flow (BlueSky's OpenAP model) summed over the physics steps | never |
    | `kpi_episode_time_s` | simulated time of the episode [s] | never |

    ## Arguments
    `gym.make("DescentEnv-v0", render_mode=None, backend="native", alt_min=2000, alt_max=4000,
    target_alt_dif=500, runway_distance_km=200.0)`.

    ## Version History
    * v0: the paper's MDP (bluesky-gym 0.2.0). Fixed software defects: seeded generator, clean
      reset (no aircraft carried over after truncation), `terminated` is a bool, rgb_array frames.
    * v1 (`-v1` ids; the same task with these configuration fields set, selected by the registry):
      float32 observation and action spaces with finite bounds that the observations keep (SB3 and
      `check_env` warned about float64 and infinite bounds; the bounds are in
      docs/environments-v1.md);
      |a| ≤ 0.008 (|v| ≤ 0.1 m/s) holds the current altitude (`hold_altitude_at_zero`): BlueSky
      replaces such a vertical speed by its default 7.62 m/s, so a = 0 climbed (bluesky-gym #59).
    """

    task_class = DescentTask


class DescentVectorEnv(BlueSkyVectorEnv):
    """Natively batched :class:`DescentEnv`."""

    task_class = DescentTask
