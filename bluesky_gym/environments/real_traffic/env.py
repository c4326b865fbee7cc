"""RealTrafficCREnv-v0 and -v1: conflict resolution in recorded air traffic."""

from __future__ import annotations

from typing import Any

import numpy as np

from bluesky_gym.environments.real_traffic.task import RealTrafficTask
from bluesky_gym.envs.seeds import is_eval_seed
from bluesky_gym.envs.shell import BlueSkyEnv, BlueSkyVectorEnv, episode_seeds


def _test_flags(seeds: list[int | None]) -> np.ndarray:
    return np.array([s is not None and is_eval_seed(int(s)) for s in seeds], dtype=bool)


class RealTrafficCREnv(BlueSkyEnv):
    """Fly a recorded flight through the recorded traffic around it without losing separation.

    ## Description
    Every episode is a window (10 minutes by default) of real ADS-B traffic from the sample
    collections of the `traffic` library (Switzerland, 2018-08-01, and the Paris region,
    2021-10-07), cleaned once, at the first reset, into a cache directory (`cache_dir` option;
    see `docs/realtraffic.md`). One flight recorded over the whole window is the ownship (aircraft 0);
    up to 24 recorded aircraft that come within 30 NM of it during the window fly their recorded
    routes (route points from a Douglas-Peucker simplification of the track, flown with LNAV) and
    their recorded altitude and speed profiles; they appear and disappear when their recordings do.
    Every aircraft flies with the performance of its recorded aircraft type (BlueSky's OpenAP data;
    BlueSky's fallback, the B744, where the recording has no type or one BlueSky does not fly as a
    fixed-wing aircraft). With a zero action the ownship follows its
    own recording too, so an episode with zero actions replays the recorded traffic.

    ## Observation Space
    A `Dict` of float64 `Box`es (float32 with finite bounds in `-v1`, see the version history):

    * `ownship` (6,): signed distance from the recorded route / 5 NM (clipped to ±10, positive:
      right of it); cos and sin of the heading minus the bearing to the recorded position 60 s
      ahead; (CAS − recorded CAS) / 20 m/s; (altitude − recorded altitude) / 3000 m; vertical
      speed / 10 m/s.
    * `intruders` (5, 7) (`-v1`: (35,), the same rows one after the other), the 5 closest
      aircraft: east and north offset / 20 NM, relative ground velocity east and north / 250 m/s,
      relative altitude / 3000 m, distance / 20 NM, present (1; an empty row is all zeros).

    ## Action Space
    `Box(-1, 1, (2,))` (or `(3,)` with `altitude_action=True`), every 10 s:
    * heading: HDG = bearing to the ownship's recorded position 60 s ahead + 30° · a0;
    * speed: CAS target = recorded speed (ground speed as TAS, 20 s ahead) + 10 m/s · a1;
    * altitude (optional): altitude target = recorded altitude 60 s ahead + 1000 ft · a2.

    ## Rewards
    Every step: route −0.1 per NM of distance from the recorded route (capped at 20 NM,
    component `route`); intrusion −1 per aircraft within 5 NM and 1000 ft (`intrusion`).

    ## Starting State
    A window drawn uniformly, with the episode's generator, from the windows of the episode's
    split: windows start every 60 s; the ownship is any flight recorded over the whole window with
    at least `min_traffic` aircraft within `radius_nm`. Aircraft present at the window start are
    created at their recorded state, the others at their first recorded sample.

    ## Splits
    `split_by="time"` (default): the last `test_fraction` (30 %) of every collection's recorded
    time is the test part, windows of the training part end before it. `split_by="collection"`:
    `test_collections` are held out. With `split="auto"` (default) an episode reset with a seed of
    the evaluation range (`2**31` and above, what `bluesky-gym eval` uses) is drawn from the test
    part, every other episode from the training part; `split="train"` or `"test"` fixes it.

    ## Episode End
    Never terminated; truncated when the window ends (60 steps by default).

    ## Info
    `total_reward`, `total_intrusions`, `average_route_deviation_nm`, `reward_route`,
    `reward_intrusion`; at the end the KPIs `kpi_*`, with `kpi_mean_route_deviation_nm`.

    ## KPIs
    At the end of an episode `info` (`final_info` in batched environments) carries these keys.
    Some are not finite by design; average them over the finite values (see the note on averaging
    on the environment's documentation page).

    | key | meaning | not finite when |
    |---|---|---|
    | `kpi_los_count` | new losses of separation: recorded aircraft coming within 5 NM and 1000 ft | never |
    | `kpi_los_steps` | decision steps with the ownship in a loss of separation | never |
    | `kpi_min_separation_nm` | smallest horizontal distance to another aircraft [NM] | `inf` with no other aircraft |
    | `kpi_mean_abs_drift_deg` | mean absolute drift from the heading to the recorded position 60 s ahead [deg], over the decision steps | never |
    | `kpi_mean_route_deviation_nm` | mean lateral distance from the recorded route [NM] | `NaN` without a decision step |
    | `kpi_track_distance_km` | distance flown [km] | never |
    | `kpi_fuel_kg` | fuel burned by the ownship [kg]: its fuel flow (BlueSky's OpenAP model) summed over the physics steps | never |
    | `kpi_episode_time_s` | simulated time of the episode [s] | never |

    ## Arguments
    `gym.make("RealTrafficCREnv-v0", collections=("switzerland", "quickstart"), split="auto",
    split_by="time", test_fraction=0.3, test_collections=("quickstart",), window_s=600,
    radius_nm=30, min_traffic=2, max_traffic=24, altitude_action=False, cache_dir=None)`.
    A collection is a `traffic` sample name or a `.npz` file from `bluesky-gym realtraffic prepare`.

    ## Version History
    * v0: initial version. Collections named twice are refused (they played every window twice).
      The id is listed and described (`bluesky-gym list`, `info`) before its data are prepared;
      `gym.make` needs none, the first reset cleans the sample collections not in the cache yet.
    * v1 (`RealTrafficCREnv-v1`; the same task with `float32_spaces=True`, selected by the
      registry): float32 observation and action spaces with finite bounds that the observations
      keep (`check_env` warned about the infinite bounds of v0); `intruders` is one vector of 35
      values, the 5 rows of 7 one after the other (SB3's checker warns about a 2-D entry). The
      bounds are in docs/environments-v1.md.
    """

    task_class = RealTrafficTask
    task: RealTrafficTask

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """Start a new episode; a seed of the evaluation range draws it from the test split (``split="auto"``)."""
        self.task.set_test_split(np.array([0]), _test_flags([seed]))
        return super().reset(seed=seed, options=options)


class RealTrafficCRVectorEnv(BlueSkyVectorEnv):
    """Natively batched :class:`RealTrafficCREnv`."""

    task_class = RealTrafficTask
    task: RealTrafficTask

    def reset(
        self, *, seed: int | list[int | None] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """Reset every episode; episodes seeded in the evaluation range are drawn from the test split (``split="auto"``)."""
        with self._errors:
            seeds = episode_seeds(seed, self.num_envs)
        self.task.set_test_split(self.task.all_envs, _test_flags(seeds))
        return super().reset(seed=seed, options=options)
