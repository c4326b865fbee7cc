"""Multi-agent Merge: every arrival is an agent merging via the FAF to the runway (adapted from spec section 7).

The scenario is MergeEnv-v0's (:class:`~bluesky_gym.tasks.merge.MergeTask` generates it): 20
aircraft at 10000 m north of the final approach fix, within +-15 deg of the approach radial. In
the single-agent environment aircraft 0 is controlled and the others fly LNAV via the FAF to the
runway; here every aircraft is an agent with MergeEnv-v0's observation, action and reward from
its own point of view (an aircraft's LNAV route is switched off by its first heading command).
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from bluesky_gym.core import geo
from bluesky_gym.core.units import NM2KM
from bluesky_gym.multiagent.base import Array, BoolArray, IntArray, MultiAgentTask, nearest_neighbours, of_neighbours
from bluesky_gym.tasks import merge as mg
from bluesky_gym.tasks.base import BoxSpec, wrap180


class MergeMultiAgentTask(MultiAgentTask):
    """Batched multi-agent merge.

    Per agent (every aircraft):

    * observation: MergeEnv-v0's keys from its own point of view: ``cos(drift)``, ``sin(drift)``
      to its current target (the FAF, then the runway once the FAF was reached), ``airspeed``
      (TAS [m/s], not normalised, as MergeEnv-v0), ``waypoint_dist`` (kwik NM to the target / 250),
      ``faf_reached`` (0/1, with MergeEnv-v0's one-step lag), and its 5 nearest other aircraft by
      kwik distance: ``x_r``, ``y_r`` (north / east [m] / 1e6), ``vx_r``, ``vy_r`` (TAS-vector
      difference / 150), ``cos(track)``, ``sin(track)``, ``distances`` (NM / 250) and
      ``traffic_mask`` (0 for padding when fewer than 5 other aircraft are left);
    * action: ``Box(-1, 1, (2,))``: HDG wrap180(heading + 15 a0), SPD (CAS + 20 a1) kt-converted;
    * reward: +1 when it first comes within 10 NM of the FAF, -0.1 |drift| [rad], -1 per other
      aircraft within 4 NM;
    * the agent terminates (arrives) when, after the FAF, it is within 20 NM of the runway; its
      aircraft is removed. All agents are truncated at the time limit (50 steps of 50 s).
    """

    name: ClassVar[str] = "merge_v0"
    env_id: ClassVar[str] = "Merge multi-agent"
    scenario_class = mg.MergeTask
    intrusion_distance: ClassVar[float] = mg.INTRUSION_DISTANCE
    state_origin: ClassVar[tuple[float, float]] = (mg.FAF_LAT, mg.FAF_LON)
    state_scale_nm: ClassVar[float] = mg.WAYPOINT_DIST_SCALE
    completion: ClassVar[str] = "arrival"
    num_neighbours: ClassVar[int] = mg.NUM_AC_STATE
    scenario: mg.MergeTask

    def build_observation_spec(self) -> dict[str, BoxSpec]:
        """MergeEnv-v0's keys and bounds, plus ``traffic_mask``."""
        k = self.num_neighbours
        spec = {key: BoxSpec((1,), -1.0, 1.0) for key in ("cos(drift)", "sin(drift)")}
        spec.update({key: BoxSpec((1,)) for key in ("airspeed", "waypoint_dist")})
        spec["faf_reached"] = BoxSpec((1,), 0.0, 1.0)
        spec.update({key: BoxSpec((k,)) for key in ("x_r", "y_r", "vx_r", "vy_r")})
        spec.update({key: BoxSpec((k,), -1.0, 1.0) for key in ("cos(track)", "sin(track)")})
        spec["distances"] = BoxSpec((k,))
        spec["traffic_mask"] = BoxSpec((k,), 0.0, 1.0)
        return spec

    def build_action_spec(self) -> BoxSpec:
        """Heading change and speed change, each in [-1, 1]."""
        return BoxSpec((2,), -1.0, 1.0)

    def allocate(self) -> None:
        """Per-agent target state."""
        shape = (self.n_envs, self.n_agents)
        self.wpt_reach = np.zeros(shape, np.int64)  # 0 before the FAF, 1 after (the observed flag)
        self.faf_reached = np.zeros(shape, np.int64)  # 0, 1 (FAF) or 2 (near the runway)
        self.drift = np.zeros(shape)  # deg, to the current target at the last observation
        self.waypoint_dist = np.zeros(shape)  # NM, to the current target at the last observation

    def on_reset(self, envs: IntArray) -> None:
        """Every agent starts towards the FAF."""
        self.wpt_reach[envs] = 0
        self.faf_reached[envs] = 0
        drift, dist = self._target_geometry()
        self.drift[envs] = drift[envs]
        self.waypoint_dist[envs] = dist[envs]

    def apply_action(self, action: Array, acting: BoolArray) -> None:
        """HDG wrap180(hdg + 15 a0); SPD (CAS + 20 a1) * 1.94384 kt, for every acting agent."""
        self.command_heading_and_speed(action, acting, mg.D_HEADING, mg.D_SPEED)

    def targets(self) -> tuple[Array, Array]:
        """Return the FAF, or the runway for agents that reached the FAF."""
        after = self.wpt_reach != 0
        return np.where(after, mg.RWY_LAT, mg.FAF_LAT), np.where(after, mg.RWY_LON, mg.FAF_LON)

    def _target_geometry(self) -> tuple[Array, Array]:
        s = self.sim
        tlat, tlon = self.targets()
        qdr, dist = geo.kwikqdrdist(s.lat, s.lon, tlat, tlon)
        return wrap180(s.hdg - qdr), dist

    def agent_drift(self) -> Array:
        """Drift [deg] to the current target at the last observation."""
        return self.drift

    def observe(self) -> dict[str, Array]:
        """Own drift, airspeed and target distance, and the 5 nearest other aircraft by kwik distance."""
        s = self.sim
        drift, dist = self._target_geometry()
        self.drift = drift
        self.waypoint_dist = dist
        # Neighbours by kwik distance (the pair distance matrix is MergeEnv-v0's kwik distance).
        order, valid = nearest_neighbours(self.pair_dist, s.active, self.num_neighbours)
        brg, d = geo.kwikqdrdist(s.lat[..., None], s.lon[..., None], of_neighbours(s.lat, order), of_neighbours(s.lon, order))
        vx = np.cos(np.deg2rad(s.hdg)) * s.tas
        vy = np.sin(np.deg2rad(s.hdg)) * s.tas
        vx_r = np.where(valid, of_neighbours(vx, order) - vx[..., None], 0.0)
        vy_r = np.where(valid, of_neighbours(vy, order) - vy[..., None], 0.0)
        track = np.arctan2(vy_r, vx_r)
        d_m = d * NM2KM * mg.M_PER_KM
        return {
            "cos(drift)": np.cos(np.deg2rad(drift))[..., None],
            "sin(drift)": np.sin(np.deg2rad(drift))[..., None],
            "airspeed": s.tas[..., None].copy(),
            "waypoint_dist": (dist / mg.WAYPOINT_DIST_SCALE)[..., None],
            "faf_reached": self.wpt_reach[..., None].astype(np.float64),
            "x_r": np.where(valid, d_m * np.cos(np.deg2rad(brg)), 0.0) / mg.POSITION_SCALE,
            "y_r": np.where(valid, d_m * np.sin(np.deg2rad(brg)), 0.0) / mg.POSITION_SCALE,
            "vx_r": vx_r / mg.SPEED_SCALE,
            "vy_r": vy_r / mg.SPEED_SCALE,
            "cos(track)": np.where(valid, np.cos(track), 0.0),
            "sin(track)": np.where(valid, np.sin(track), 0.0),
            "distances": np.where(valid, d, 0.0) / mg.WAYPOINT_DIST_SCALE,
            "traffic_mask": valid.astype(np.float64),
        }

    def evaluate(self, acting: BoolArray) -> tuple[Array, BoolArray, dict[str, Array]]:
        """FAF reach reward, runway arrival, drift and intrusion penalties (MergeEnv-v0's, per agent)."""
        reach_faf = acting & (self.waypoint_dist < mg.DISTANCE_MARGIN) & (self.wpt_reach != 1)
        near_runway = acting & ~reach_faf & (self.waypoint_dist < mg.GOAL_MARGIN) & (self.wpt_reach == 1)
        self.wpt_reach = np.where(reach_faf, 1, self.wpt_reach)
        self.faf_reached = np.where(reach_faf, 1, np.where(near_runway, 2, self.faf_reached))
        reach = np.where(reach_faf, mg.REACH_REWARD, 0.0)
        drift_reward = np.abs(np.deg2rad(self.drift)) * mg.DRIFT_PENALTY
        intrusion = self.intrusion_counts * mg.INTRUSION_PENALTY + 0.0
        return reach + drift_reward + intrusion, near_runway, {"reach": reach, "drift": drift_reward, "intrusion": intrusion}
