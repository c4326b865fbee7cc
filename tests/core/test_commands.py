"""The autopilot commands as scalar kernels (:mod:`bluesky_gym.core.commands`): what the native core's commands write, bit for bit.

The device steps write the autopilot state with :func:`select_track`, :func:`select_speed` and
:func:`select_altitude`; :meth:`Simulator.cmd_altitude` is :func:`altitude_commands`. Here each
is held against the readable numpy form of BlueSky's command (``ap.selaltcmd``) and against the
simulator's own HDG and SPD commands in an airspace without wind.
"""

from __future__ import annotations

import numpy as np

from bluesky_gym.core import Simulator
from bluesky_gym.core.commands import OPPOSITE_VS_MIN, select_altitude, select_speed, select_track
from bluesky_gym.core.jit import grid_range, jit

_FIELDS = ("selalt", "selvs", "selspd", "ap_trk", "swvnav", "swvnavspd", "swlnav")


@jit
def _direct(env, slot, hdg, spd, alt_cmd, vs_cmd, alt, ap_trk, swlnav, selspd, swvnavspd, selalt, swvnav, selvs):  # type: ignore[no-untyped-def]
    for i in grid_range(env.shape[0]):
        select_track(env[i], slot[i], hdg[i], ap_trk, swlnav)
        select_speed(env[i], slot[i], spd[i], selspd, swvnavspd)
        select_altitude(env[i], slot[i], alt_cmd[i], vs_cmd[i], alt, selalt, swvnav, selvs)


def _traffic() -> Simulator:
    sim = Simulator(3, 4, dt=1.0)
    sim.create([0, 0, 1, 1, 2, 2], [0, 1, 0, 2, 1, 3], 52.0, 4.0, 90.0, [3000.0, 5000.0, 8000.0, 1000.0, 4000.0, 6000.0], 150.0)
    sim.selvs[...] = np.array([[2.0, -3.0, 0.005, 0.0], [-0.005, 4.0, -6.0, 1.0], [0.0, -2.0, 3.0, -0.02]])
    sim.swlnav[...] = True
    sim.swvnav[...] = True
    sim.swvnavspd[...] = True
    return sim


def test_the_scalar_commands_write_what_the_simulator_commands_write() -> None:
    """HDG (no wind), SPD and ALT with and without a vertical speed: the same fields, bit for bit."""
    env, slot = np.array([0, 0, 1, 1, 2, 2]), np.array([0, 1, 0, 2, 1, 3])
    hdg = np.array([10.0, 359.5, 180.25, 0.0, 91.0, 270.0])
    spd = np.array([150.0, 0.78, 120.5, 200.0, 0.5, 180.0])
    alt_cmd = np.array([2000.0, 6000.0, 8000.0, 300.0, 5000.0, 7000.0])
    vs_cmd = np.array([0.0, 0.0, 0.0, -4.0, 0.0, 2.5])
    sim = _traffic()
    sim.cmd_heading(env, slot, hdg)
    sim.cmd_speed(env, slot, spd)
    sim.cmd_altitude(env, slot, alt_cmd, vs_cmd)
    direct = _traffic()
    fields = {k: np.ascontiguousarray(getattr(direct, k)) for k in _FIELDS}
    _direct(
        env, slot, hdg, spd, alt_cmd, vs_cmd, np.ascontiguousarray(direct.alt), fields["ap_trk"], fields["swlnav"], fields["selspd"],
        fields["swvnavspd"], fields["selalt"], fields["swvnav"], fields["selvs"],
    )  # fmt: skip
    for k in _FIELDS:
        np.testing.assert_array_equal(fields[k], getattr(sim, k), err_msg=k)


def test_cmd_altitude_is_bluesky_selaltcmd() -> None:
    """``ALT`` as BlueSky's ``selaltcmd`` reads in numpy: a given rate is set; without one, a rate pointing away (above 0.01 m/s) is cancelled."""
    env, slot = np.array([0, 0, 1, 1, 2, 2]), np.array([0, 1, 0, 2, 1, 3])
    for vs in (None, np.array([0.0, 1.5, 0.0, -2.0, np.nan, 0.0])):
        sim = _traffic()
        selvs = sim.selvs.copy()
        target = np.array([2000.0, 6000.0, 8000.0, 300.0, 5000.0, 7000.0])
        alt = sim.alt[env, slot]
        given = np.zeros(env.shape, bool) if vs is None else vs != 0
        expected = selvs[env, slot].copy()
        if vs is not None:
            expected[given] = vs[given]
        keep = ~given
        opposite = keep & (expected * (target - alt) < 0.0) & (np.abs(expected) > OPPOSITE_VS_MIN)
        expected[opposite] = 0.0
        sim.cmd_altitude(env, slot, target, vs)
        np.testing.assert_array_equal(sim.selvs[env, slot], expected)
        np.testing.assert_array_equal(sim.selalt[env, slot], target)
        assert not sim.swvnav[env, slot].any() and sim.swvnav[0, 2]
        assert opposite.any() and (keep & ~opposite & (expected != 0)).any()
