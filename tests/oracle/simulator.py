"""Oracle: the simulator step as readable numpy array code, in BlueSky 1.1.1's update order.

:class:`OracleSimulator` is a :class:`~bluesky_gym.core.Simulator` (same state, same commands)
whose :meth:`step` advances every airspace with whole-array numpy operations written like
BlueSky's own code [docs/dynamics.md §2], instead of the compiled kernels. The tests compare both to the
last bit (with numpy's AVX-512 math off, so that numpy and the kernels call the same C library
functions). Inactive slots are computed too (their values are meaningless).
"""

from __future__ import annotations

import dataclasses
from types import SimpleNamespace

import numpy as np
from numpy.typing import NDArray

from bluesky_gym.core import Simulator
from bluesky_gym.core.aircraft import aircraft_performance
from bluesky_gym.core.performance import AXMAX_ROTOR, PHASE_NA, AircraftPerformance
from bluesky_gym.core.units import (
    BANK_DEFAULT,
    G0,
    NM,
    NO_VALUE,
    R_EARTH,
    TAS_EPS,
    VS_DEFAULT,
    VS_RAMP,
    VS_SELECT_EPS,
    WIND_MIN_ALT,
)

from . import atmosphere as isa
from . import conflicts as oconf
from . import geo as ogeo
from . import performance as pf

Array = NDArray[np.float64]
IntArray = NDArray[np.int64]

BANK = np.float64(BANK_DEFAULT)
# ``turnphi`` after a waypoint activation: deg2rad(rad2deg(bankdef)), which may differ by one ulp.
BANK_LNAV = np.deg2rad(np.rad2deg(BANK))


class OracleSimulator(Simulator):
    """A :class:`~bluesky_gym.core.Simulator` stepped by the numpy oracle."""

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self._oracle_qdrdist = ogeo.qdrdist if self.geo == "compiled" else ogeo.qdrdist_python

    def creconfs(self, env, target, slot, dpsi, dcpa, tlosh, dh=None, tlosv=None, spd=None, actype=None) -> None:
        """``creconfs`` through the numpy oracle of the conflict geometry."""
        oconf.create_conflicts(self, env, target, slot, dpsi, dcpa, tlosh, dh, tlosv, spd, actype=actype)

    def _perf_of_every_aircraft(self) -> SimpleNamespace:
        """The performance data with every field an (n_envs, max_aircraft) array of each aircraft's type's value."""
        rows = [self.perf] + [aircraft_performance(n) for n in self.aircraft_types[1:]]
        fields = [f.name for f in dataclasses.fields(AircraftPerformance) if f.name != "name"]
        out = SimpleNamespace(**{f: np.array([getattr(p, f) for p in rows])[self.type_index] for f in fields})
        out.static_thrust = out.engine_count * out.engine_max_thrust
        return out

    def _run(self, n_steps: int, trace: bool) -> Array | None:
        track = np.empty((n_steps, 2, self.n_envs, self.max_aircraft)) if trace else None
        for k in range(n_steps):
            self.step()
            if track is not None:
                track[k, 0], track[k, 1] = self.lat, self.lon
        return track

    def step(self) -> None:
        """Advance every airspace by ``dt`` seconds (numpy)."""
        with np.errstate(all="ignore"):
            if self._performance_due():
                self._update_performance()
            self.simt += self.dt
            self._update_autopilot()
            trk_t, tas_t, alt_t, vs_t = self.ap_trk, self.ap_tas, self.ap_alt, np.abs(self.ap_vs)
            any_wind = self.wind.any
            if any_wind:
                wn, we = self.wind.at_all(self.lat, self.lon)
                vw = np.sqrt(wn * wn + we * we)
                winddir = np.arctan2(we, wn)
                drift = np.radians(trk_t) - winddir
                steer = np.arcsin(np.minimum(1.0, np.maximum(-1.0, vw * np.sin(drift) / np.maximum(0.001, self.tas))))
                hdg_t = (trk_t + np.degrees(steer)) % 360.0
            else:
                hdg_t = trk_t % 360.0
            perf = self._perf_of_every_aircraft()
            tas_t, vs_t, alt_t = pf.apply_limits(tas_t, vs_t, alt_t, self.ax, self.tas, self.phase, self.vmin, self.vmax, self.axmax, perf)
            self._update_airspeed(tas_t, hdg_t, alt_t, vs_t)
            self._update_groundspeed(any_wind)
            self._update_position(alt_t)

    def _update_performance(self) -> None:
        """OpenAP update from the start-of-step state [docs/dynamics.md §1.3-1.4]."""
        perf = self._perf_of_every_aircraft()
        rotor = perf.rotor  # BlueSky's rotor model: phase NA, a fixed envelope, axmax 3.5, no outputs [§1.2b]
        self.phase[...] = np.where(rotor, PHASE_NA, pf.flight_phase(self.tas, self.vs, self.alt))
        vmin, vmax = pf.speed_envelope(self.phase, perf)
        self.vmin, self.vmax = np.where(rotor, perf.vmin_enroute, vmin), np.where(rotor, perf.vmax_enroute, vmax)
        self.axmax = np.where(rotor, AXMAX_ROTOR, pf.max_acceleration(self.phase, self.tas, self.alt, self.vs, perf))
        drag = pf.drag(self.phase, self.tas, self.alt, perf)  # outputs [docs/dynamics.md §1.4a]
        thrust, fuelflow = pf.thrust_and_fuel_flow(drag, self.ax, perf)
        self.drag = np.where(rotor, self.drag, drag)
        self.thrust = np.where(rotor, self.thrust, thrust)
        self.fuelflow = np.where(rotor, self.fuelflow, fuelflow)

    def _update_autopilot(self) -> None:
        """Autopilot targets [docs/dynamics.md §2.3]; LNAV waypoint logic [docs/dynamics.md §2.6]."""
        if np.any(self.swlnav):
            self._update_lnav()
        self.ap_vs = np.where(np.abs(self.selvs) > VS_SELECT_EPS, self.selvs, VS_DEFAULT)
        self.ap_alt = self.selalt.copy()
        self.ap_tas = isa.vcasormach2tas(self.selspd, self.alt)

    def _oracle_next_leg_qdr(self, env: IntArray, slot: IntArray, iact: IntArray) -> Array:
        nxt = (iact > -1) & (iact < self.nwp[env, slot] - 1)
        i0 = np.clip(iact, 0, self.max_waypoints - 1)
        i1 = np.clip(iact + 1, 0, self.max_waypoints - 1)
        qdr, _ = self._oracle_qdrdist(
            self.route_lat[env, slot, i0], self.route_lon[env, slot, i0], self.route_lat[env, slot, i1], self.route_lon[env, slot, i1]
        )
        return np.where(nxt, qdr, NO_VALUE)

    @staticmethod
    def _oracle_turn_distance(tas: Array, qdr: Array, next_qdr: Array) -> Array:
        """Fly-by turn anticipation distance [m] (``actwp.calcturn`` with default turn data)."""
        local_next = np.where(next_qdr < -900.0, qdr, next_qdr)
        turnbank = np.rad2deg(BANK)
        turnrad = tas**2 / (G0 * np.tan(np.deg2rad(turnbank)))
        return np.abs(turnrad * np.tan(np.radians(0.5 * np.abs(ogeo.degto180(qdr % 360.0 - local_next % 360.0)))))

    def _update_lnav(self) -> None:
        qdr, distnm = self._oracle_qdrdist(self.lat, self.lon, self.actwp_lat, self.actwp_lon)
        dist = distnm * NM
        # actwp.reached [docs/dynamics.md §2.6]; all waypoints here are fly-by.
        close2wp = dist / (np.maximum(0.0001, np.abs(self.gs))) < 4.0
        tooclose2turn = close2wp * (np.abs(ogeo.degto180(self.trk % 360.0 - qdr % 360.0)) > 90.0)
        awayorpassed = np.logical_or(tooclose2turn, np.abs(ogeo.degto180(qdr - self.curlegdir)) > 90.0)
        reached = self.swlnav & self.active & np.logical_or(awayorpassed, dist < self.turndist)
        if np.any(reached):
            env, slot = np.nonzero(reached)
            last = self.swlastwp[env, slot]
            if np.any(last):
                e, s = env[last], slot[last]
                self.swlnav[e, s] = False
                self.swvnav[e, s] = False
                self.swvnavspd[e, s] = False
            env, slot = env[~last], slot[~last]
            if env.size:
                nwp = self.nwp[env, slot]
                lnavon = self.iactwp[env, slot] < nwp - 1
                iact = np.where(lnavon, self.iactwp[env, slot] + 1, self.iactwp[env, slot])
                self.iactwp[env, slot] = iact
                self.swlastwp[env, slot] = iact == nwp - 1
                self.next_qdr[env, slot] = self._oracle_next_leg_qdr(env, slot, iact)
                off = ~lnavon & self.swlnav[env, slot]
                self.swlnav[env[off], slot[off]] = False
                self.swvnav[env, slot] &= self.swlnav[env, slot]
                wlat = self.route_lat[env, slot, iact]
                wlon = self.route_lon[env, slot, iact]
                self.actwp_lat[env, slot] = wlat
                self.actwp_lon[env, slot] = wlon
                q, _ = self._oracle_qdrdist(self.lat[env, slot], self.lon[env, slot], wlat, wlon)
                qdr[env, slot] = q
                self.curlegdir[env, slot] = q
                self.turndist[env, slot] = self._oracle_turn_distance(self.tas[env, slot], q, self.next_qdr[env, slot])
                self.turnphi[env, slot] = BANK_LNAV
        self.ap_trk = np.where(self.swlnav, qdr % 360.0, self.ap_trk)

    def _update_airspeed(self, tas_t: Array, hdg_t: Array, alt_t: Array, vs_t: Array) -> None:
        """Speed ramp, heading turn and vertical-speed ramp [docs/dynamics.md §2.2 steps 6-8]."""
        dt = self.dt
        delta_spd = tas_t - self.tas
        need_ax = np.abs(delta_spd) > np.abs(dt * self.axmax)
        self.ax = need_ax * np.sign(delta_spd) * self.axmax
        self.tas = np.where(need_ax, self.tas + self.ax * dt, tas_t)
        p, rho, t = isa.vatmos(self.alt)
        self.cas = isa.tas2cas_from_atmos(self.tas, p, rho)
        self.mach = self.tas / np.sqrt(isa.GAMMA * isa.R_AIR * t)

        bank = np.where(self.turnphi > TAS_EPS * TAS_EPS, self.turnphi, BANK)
        turnrate = np.degrees(G0 * np.tan(bank) / np.maximum(self.tas, TAS_EPS))
        delhdg = (hdg_t - self.hdg + 180) % 360 - 180
        swhdgsel = np.abs(delhdg) > np.abs(dt * turnrate)
        self.hdg = np.where(swhdgsel, self.hdg + dt * turnrate * np.sign(delhdg), hdg_t) % 360.0

        delta_alt = alt_t - self.alt
        self._swaltsel = np.abs(delta_alt) > 1.05 * np.maximum(np.abs(dt * vs_t), np.abs(dt * self.vs))
        target_vs = self._swaltsel * np.sign(delta_alt) * np.abs(vs_t)
        delta_vs = target_vs - self.vs
        need_az = np.abs(delta_vs) > VS_RAMP
        az = need_az * np.sign(delta_vs) * VS_RAMP
        vs = np.where(need_az, self.vs + az * dt, target_vs)
        self.vs = np.where(np.isfinite(vs), vs, 0)

    def _update_groundspeed(self, any_wind: bool) -> None:
        """Ground velocity from TAS, heading and wind [docs/dynamics.md §1.7]."""
        hdgrad = np.radians(self.hdg)
        if not any_wind:
            self.gsnorth = self.tas * np.cos(hdgrad)
            self.gseast = self.tas * np.sin(hdgrad)
            self.gs = self.tas
            self.trk = self.hdg
            self.windnorth[:] = 0.0
            self.windeast[:] = 0.0
            return
        wn, we = self.wind.at_all(self.lat, self.lon)
        self.windnorth = wn
        self.windeast = we
        applywind = self.wind.has_wind[:, None] & (self.alt > WIND_MIN_ALT)
        self.gsnorth = self.tas * np.cos(hdgrad) + wn * applywind
        self.gseast = self.tas * np.sin(hdgrad) + we * applywind
        gs_wind = np.sqrt(self.gsnorth**2 + self.gseast**2)
        trk_wind = np.degrees(np.arctan2(self.gseast, self.gsnorth)) % 360.0
        self.gs = np.where(applywind, gs_wind, self.tas)
        self.trk = np.where(applywind, trk_wind, self.hdg)

    def _update_position(self, alt_t: Array) -> None:
        """Semi-implicit Euler position update on the sphere [docs/dynamics.md §2.2 step 10]."""
        dt = self.dt
        self.alt = np.where(self._swaltsel, np.round(self.alt + self.vs * dt, 6), alt_t)
        self.lat = self.lat + np.degrees(dt * self.gsnorth / R_EARTH)
        coslat = np.cos(np.deg2rad(self.lat))
        self.lon = self.lon + np.degrees(dt * self.gseast / coslat / R_EARTH)
        self.distflown = self.distflown + self.gs * dt
        self.fuelburn = self.fuelburn + self.fuelflow * dt
