"""Multi-agent SectorCR: every aircraft crossing the sector is an agent (adapted from spec section 5).

The scenario is SectorCREnv-v0's (:class:`~bluesky_gym.tasks.sector_cr.SectorCRTask` generates
it): a random convex sector with ``max(ceil(density * area), 5)`` aircraft, each flying from a
random point inside towards its own exit point on the boundary. Here every aircraft is an agent
with the single-agent observation, action and reward, seen from its own point of view.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from bluesky_gym.core import geo
from bluesky_gym.multiagent.base import Array, BoolArray, IntArray, MultiAgentTask, nearest_neighbours, of_neighbours, pick
from bluesky_gym.tasks import sector_cr as sc
from bluesky_gym.tasks.base import BoxSpec, wrap180
from bluesky_gym.tasks.geometry import points_in_polygons

STATE_SCALE_NM = 40.0  # NM: positions in the global state (the sector's circle has a 34.5 NM radius)


class SectorCRMultiAgentTask(MultiAgentTask):
    """Batched multi-agent sector conflict resolution.

    Per agent (every aircraft of the sector):

    * observation: ``cos(drift)``, ``sin(drift)`` (drift = wrap180(heading - kwik bearing to its own
      exit point)), ``airspeed`` = (TAS - 150) / 6, and its 4 nearest other aircraft by flat
      distance, in ascending order: ``x_r``, ``y_r`` (their position minus its own, north / east
      [m] / 13000), ``vx_r`` / 32, ``vy_r`` / 66 (TAS-vector difference, north / east [m/s]),
      ``cos(track)``, ``sin(track)`` of the relative velocity, ``distances`` = (d [m] - 50000) /
      15000, and ``traffic_mask`` (1 for a real neighbour, 0 for padding: when fewer than 4 other
      aircraft are left, the missing entries are zeros). The constants and key names are
      SectorCREnv-v0's; ``airspeed`` is declared unbounded here (its values leave [-1, 1]);
    * action: ``Box(-1, 1, (2,))``: HDG wrap180(heading + 22.5 a0), SPD (CAS + 20/3 a1) kt-converted
      exactly as SectorCREnv-v0 (a CAS step of up to 6.67 m/s);
    * reward: -0.1 |drift| [rad] - 1 per other aircraft within 5 NM (kwik distance), every step;
    * the agent leaves (``truncated``, as the single-agent episode's end) when it is outside the
      sector; its aircraft is removed. All agents are truncated at the time limit (200 steps).
    """

    name: ClassVar[str] = "sector_cr_v0"
    env_id: ClassVar[str] = "SectorCR multi-agent"
    scenario_class = sc.SectorCRTask
    intrusion_distance: ClassVar[float] = sc.INTRUSION_DISTANCE
    state_origin: ClassVar[tuple[float, float]] = sc.CENTER
    state_scale_nm: ClassVar[float] = STATE_SCALE_NM
    completion: ClassVar[str] = "exit"
    num_neighbours: ClassVar[int] = sc.NUM_AC_STATE
    scenario: sc.SectorCRTask

    def build_observation_spec(self) -> dict[str, BoxSpec]:
        """SectorCREnv-v0's keys, from each agent's point of view, plus ``traffic_mask``."""
        k = self.num_neighbours
        spec = {key: BoxSpec((1,), -1.0, 1.0) for key in ("cos(drift)", "sin(drift)")}
        spec["airspeed"] = BoxSpec((1,))
        spec.update({key: BoxSpec((k,)) for key in ("x_r", "y_r", "vx_r", "vy_r")})
        spec.update({key: BoxSpec((k,), -1.0, 1.0) for key in ("cos(track)", "sin(track)")})
        spec["distances"] = BoxSpec((k,))
        spec["traffic_mask"] = BoxSpec((k,), 0.0, 1.0)
        return spec

    def build_action_spec(self) -> BoxSpec:
        """Heading change and speed change, each in [-1, 1]."""
        return BoxSpec((2,), -1.0, 1.0)

    def apply_action(self, action: Array, acting: BoolArray) -> None:
        """HDG wrap180(hdg + 22.5 a0); SPD (CAS + 20/3 a1) * 1.94384 kt, for every acting agent."""
        self.command_heading_and_speed(action, acting, sc.D_HEADING, sc.D_VELOCITY)

    def targets(self) -> tuple[Array, Array]:
        """Each aircraft's exit point."""
        return self.scenario.wpt_lat, self.scenario.wpt_lon

    def allocate(self) -> None:
        """Per-agent drift at the last observation."""
        self.drift = np.zeros((self.n_envs, self.n_agents))  # deg

    def on_reset(self, envs: IntArray) -> None:
        """Drift of the new agents (zero: they start heading to their exit points)."""
        self.drift[envs] = self._drift()[envs]

    def _drift(self) -> Array:
        s = self.sim
        qdr, _ = geo.kwikqdrdist(s.lat, s.lon, self.scenario.wpt_lat, self.scenario.wpt_lon)
        return wrap180(s.hdg - qdr)

    def agent_drift(self) -> Array:
        """wrap180(heading - kwik bearing to the own exit point) [deg] at the last observation."""
        return self.drift

    def observe(self) -> dict[str, Array]:
        """Own drift and airspeed, and the 4 nearest other aircraft by flat distance."""
        s = self.sim
        drift = self._drift()
        self.drift = drift
        loc = self.scenario.flat_positions_m()  # (n, m, 2) north / east [m]
        north, east = loc[..., 0], loc[..., 1]
        dn = north[:, None, :] - north[:, :, None]  # [e, i, j]: aircraft j minus aircraft i
        de = east[:, None, :] - east[:, :, None]
        dist = np.sqrt(dn**2 + de**2)
        order, valid = nearest_neighbours(dist, s.active, self.num_neighbours)
        vx = np.cos(np.deg2rad(s.hdg)) * s.tas
        vy = np.sin(np.deg2rad(s.hdg)) * s.tas
        vx_r = np.where(valid, of_neighbours(vx, order) - vx[..., None], 0.0)
        vy_r = np.where(valid, of_neighbours(vy, order) - vy[..., None], 0.0)
        track = np.arctan2(vy_r, vx_r)
        return {
            "cos(drift)": np.cos(np.deg2rad(drift))[..., None],
            "sin(drift)": np.sin(np.deg2rad(drift))[..., None],
            "airspeed": ((s.tas - sc.AIRSPEED_MEAN) / sc.AIRSPEED_STD)[..., None],
            "x_r": pick(dn, order, valid) / sc.POSITION_SCALE,
            "y_r": pick(de, order, valid) / sc.POSITION_SCALE,
            "vx_r": vx_r / sc.VX_SCALE,
            "vy_r": vy_r / sc.VY_SCALE,
            "cos(track)": np.where(valid, np.cos(track), 0.0),
            "sin(track)": np.where(valid, np.sin(track), 0.0),
            "distances": np.where(valid, (pick(dist, order, valid) - sc.DISTANCE_MEAN) / sc.DISTANCE_STD, 0.0),
            "traffic_mask": valid.astype(np.float64),
        }

    def evaluate(self, acting: BoolArray) -> tuple[Array, BoolArray, dict[str, Array]]:
        """Drift and intrusion penalties; no agent terminates (leaving the sector truncates it)."""
        drift_reward = np.abs(np.deg2rad(self.drift)) * sc.DRIFT_PENALTY
        intrusion = self.intrusion_counts * sc.INTRUSION_PENALTY + 0.0
        return drift_reward + intrusion, np.zeros_like(acting), {"drift": drift_reward, "intrusion": intrusion}

    def inside(self) -> BoolArray:
        """(n_envs, n_agents) aircraft inside their episode's sector (2-D even-odd test on lat/lon)."""
        s, scn = self.sim, self.scenario
        return points_in_polygons(s.lat, s.lon, scn.poly_lat[:, None], scn.poly_lon[:, None], scn.n_vertices[:, None])[..., 0]

    def leaving(self, acting: BoolArray) -> BoolArray:
        """Agents outside the sector leave (the single-agent episode's truncation)."""
        return acting & ~self.inside()
