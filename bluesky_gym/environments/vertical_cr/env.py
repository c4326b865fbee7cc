"""VerticalCREnv-v0."""

from __future__ import annotations

from bluesky_gym.environments.vertical_cr.task import VerticalCRTask
from bluesky_gym.envs.shell import BlueSkyEnv, BlueSkyVectorEnv


class VerticalCREnv(BlueSkyEnv):
    """Vertical conflict resolution: the descent task with level intruders crossing the path.

    Animation: ``docs/gifs/VerticalCREnv-v0.gif`` (made with ``bluesky-gym render VerticalCREnv-v0 --policy classical``).

    ## Description
    An A320 flies north from 52°N 4°E at CAS 150 m/s towards a runway 200 km ahead (measured
    from the start point), exactly as in `DescentEnv-v0`: it should hold a target altitude and
    descend to the runway in time. Five intruders, created with BlueSky's `creconfs`, fly
    straight and level at the ownship's initial ground speed on tracks that cross its path, each
    set up to come within 5 NM after a random time. The agent only controls the vertical speed
    (every 30 s) and must pass above or below the intruders. An intruder met late in the flight
    (after the average top of descent) flies between 500 m above the ground and 100 m above the
    target altitude; one met earlier flies within ±500 m of the target altitude.

    ## Observation Space
    A `Dict` of `Box(-inf, inf, shape, float64)`. The four descent entries have shape (1,); the
    seven intruder entries have shape (5,), one value per intruder **in creation order** (no
    sorting, as the reference):

    | Key | Value |
    |---|---|
    | `altitude` | (alt [m] − 1500) / 3000 |
    | `vz` | vertical speed [m/s] / 5 |
    | `target_altitude` | (target altitude [m] − 1500) / 3000 |
    | `runway_distance` | (rd [km] − 100) / 200, rd = 200 − kwik-distance from the start point |
    | `intruder_distance` | kwik-distance ownship → intruder [km] / 200 |
    | `cos_difference_pos`, `sin_difference_pos` | cos / sin of wrap180(hdg_own − qdr_own→int); positive: intruder to the left |
    | `altitude_difference` | (alt_int − alt_own) [m] / 3000 |
    | `x_difference_speed` | −cos(hdg_own − hdg_int)·gs_int / 150 |
    | `y_difference_speed` | (gs_own − sin(hdg_own − hdg_int)·gs_int) / 150 |
    | `z_difference_speed` | vs_int − vs_own [m/s], **not normalised** (reference quirk, kept) |

    ## Action Space
    `Box(-1, 1, (1,), float64)`, as in `DescentEnv-v0`: vertical speed v = 12.5·a m/s. For
    v ≥ 0 the selected altitude is 1e6 m (clipped to the 11060 m ceiling), otherwise 0 m;
    `selvs = v`. As in BlueSky, |v| ≤ 0.1 m/s (|a| ≤ 0.008) selects the default 7.62 m/s, so
    a = 0 climbs. Actions outside [-1, 1] are clipped; NaN, infinite values or a wrong shape
    raise `ValueError`.

    ## Rewards
    Evaluated after the 30 sub-steps; the reward is the sum of:
    * the descent terms, in this order: runway ahead and alt > 0: −(5/3000)·|target − alt|
      (component `altitude`); alt ≤ 0: −100 and the episode terminates (`crash`); runway
      reached: −(50/3000)·alt and the episode terminates (`runway`);
    * −50 for every intruder within 5 NM (kwik distance) **and** 1000 ft (304.8 m) of the
      ownship (`intrusion`).

    ## Starting State
    Ownship as in `DescentEnv-v0`: initial altitude integer uniform in [2000, 4000) m, target =
    initial + integer uniform in [−500, 500) m, heading 0°, CAS 150 m/s, VNAV off. Then, for each
    of the five intruders, in this order: track offset dpsi integer in [45, 315) deg, dcpa integer
    in [0, 5) NM, tlosh integer in [100, int(180 km / gs_own)) s, and the altitude offset dH:
    if tlosh > 200 km / gs_own − 2·target / 12.5 (the "average top of descent"), integer in
    [int(500 − alt), int(target − alt + 100)), otherwise in [int(target − alt − 500),
    int(target − alt + 500)) m. The intruder is created by `creconfs` with that dH (added in
    metres, as BlueSky does) and a vertical time to loss of separation of 1e11 s, then forced to
    alt + dH and given an altitude command to that level, so it holds level.

    ## Episode End
    Termination on crash or at the runway. Truncation after 300 steps (9000 s).

    ## Info
    `total_reward`, `total_intrusions` (intruder-steps inside the intrusion cylinder),
    `final_altitude` (0 until the end, −100 after a crash), `reward_<component>` every step, and
    at the end of an episode the KPIs `kpi_*` (losses of separation counted with the same
    5 NM / 1000 ft cylinder, minimum separation, success = runway reached, time to goal, extra
    track, ...).

    ## KPIs
    At the end of an episode `info` (`final_info` in batched environments) carries these keys.
    Some are not finite by design; average them over the finite values (see the note on averaging
    on the environment's documentation page).

    | key | meaning | not finite when |
    |---|---|---|
    | `kpi_success` | 1.0 if the runway was reached (no crash), else 0.0 | never |
    | `kpi_time_to_goal_s` | simulated time until the runway was reached [s] | `NaN` when the goal was not reached |
    | `kpi_extra_track_km` | distance flown minus the runway leg [km]; negative before the runway | never |
    | `kpi_los_count` | new losses of separation: intruders entering the 5 NM / 1000 ft cylinder | never |
    | `kpi_los_steps` | decision steps with the ownship in a loss of separation | never |
    | `kpi_min_separation_nm` | smallest horizontal distance to an intruder [NM] | never |
    | `kpi_mean_abs_drift_deg` | mean absolute drift from the goal heading [deg] | always `NaN`: the task has no heading goal |
    | `kpi_track_distance_km` | distance flown [km] | never |
    | `kpi_fuel_kg` | fuel burned by the ownship [kg]: its fuel flow (BlueSky's OpenAP model) summed over the physics steps | never |
    | `kpi_episode_time_s` | simulated time of the episode [s] | never |

    ## Arguments
    `gym.make("VerticalCREnv-v0", render_mode=None, backend="native", alt_min=2000,
    alt_max=4000, target_alt_dif=500, runway_distance_km=200.0, num_intruders=5, dpsi_min=45,
    dpsi_max=315, dcpa_min=0, dcpa_max=5, tlosh_min=100, tlosh_runway_fraction=0.9,
    late_dh_floor=500, late_dh_above_target=100, early_dh_band=500)`. Integer draws are uniform
    over [min, max). The observation's normalisation constants do not change with the options.

    **Aircraft types.** `intruder_types` and `ownship_types` (default `("A320",)`, the paper's
    fleet) set the intruders' and the ownship's types: one name, names drawn with equal probability,
    e.g. `intruder_types=("A320", "B744", "E190")`, or weights, e.g. `intruder_types={"A320": 0.5,
    "B744": 0.5}`. Any type BlueSky 1.1.1 flies with its own OpenAP data is accepted
    (`bluesky_gym.core.aircraft.supported_types()`); another name is refused with the list. Types
    are drawn from the episode's generator (the ownship's after the altitudes, the intruders' after
    their conflict draws); a one-type mix draws nothing, so the default episodes are the `-v0` ones.
    BlueSky's rotorcraft are refused with a one-line error: the task's start altitudes (2000-4000 m),
    speeds (CAS 150 m/s) and vertical-speed actions are beyond their envelopes (HorizontalCREnv
    accepts them).

    ## Version History
    * v0: the paper's MDP (bluesky-gym 0.2.0, where `NUM_INTRUDERS` is defined twice and the
      second value, 5, applies). Fixed software defects: seeded generator, `terminated` is a
      bool, rgb_array frames. The reference's deletion of (every other) aircraft on termination
      is not reproduced: every reset starts a clean scenario, so it has no effect.
    * v1 (`-v1` ids; the same task with these configuration fields set, selected by the registry):
      float32 observation and action spaces with finite bounds that the observations keep (SB3 and
      `check_env` warned about float64 and infinite bounds; the bounds are in
      docs/environments-v1.md);
      |a| ≤ 0.008 holds the current altitude (`hold_altitude_at_zero`, bluesky-gym #59: a = 0 climbed
      at 7.62 m/s);
      `z_difference_speed` is divided by 5 m/s as `vz` is (`normalise_vertical_speed`): it was raw
      m/s.
    """

    task_class = VerticalCRTask


class VerticalCRVectorEnv(BlueSkyVectorEnv):
    """Natively batched :class:`VerticalCREnv`."""

    task_class = VerticalCRTask
