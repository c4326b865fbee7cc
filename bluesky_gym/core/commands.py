"""Autopilot commands of one aircraft, as scalar kernels: the native core's commands and the device steps' write the same fields.

:meth:`bluesky_gym.core.Simulator.cmd_altitude` is :func:`altitude_commands`; a task's device
step, which writes the autopilot state on the device without the host, calls the same scalar
functions (:func:`select_altitude`, :func:`select_speed`, :func:`select_track`). The HDG and SPD
forms are what :meth:`~bluesky_gym.core.Simulator.cmd_heading` (in an airspace without wind) and
:meth:`~bluesky_gym.core.Simulator.cmd_speed` do; the tests hold them equal bit for bit.
"""

from __future__ import annotations

from bluesky_gym.core.jit import grid_range, jit, jit_inline

#: |selected vertical speed| [m/s] above which an ALT command without a speed cancels one pointing away from the new altitude
#: (BlueSky's ``selaltcmd``).
OPPOSITE_VS_MIN = 0.01


@jit_inline
def select_altitude(e, s, target, vs, alt, selalt, swvnav, selvs):  # type: ignore[no-untyped-def]
    """``ALT`` of aircraft ``(e, s)``: altitude ``target`` [m], vertical speed ``vs`` [m/s] (0: none given), VNAV off (BlueSky's ``ap.selaltcmd``).

    Without a vertical speed, a selected one that points away from the new altitude is cancelled.
    """
    selalt[e, s] = target
    swvnav[e, s] = False
    if vs != 0.0:
        selvs[e, s] = vs
    else:
        v = selvs[e, s]
        if v * (target - alt[e, s]) < 0.0 and abs(v) > OPPOSITE_VS_MIN:
            selvs[e, s] = 0.0


@jit_inline
def select_speed(e, s, casmach, selspd, swvnavspd):  # type: ignore[no-untyped-def]
    """``SPD`` of aircraft ``(e, s)``: CAS [m/s] or Mach ``casmach``, VNAV speed off."""
    selspd[e, s] = casmach
    swvnavspd[e, s] = False


@jit_inline
def select_track(e, s, hdg, ap_trk, swlnav):  # type: ignore[no-untyped-def]
    """``HDG`` of aircraft ``(e, s)`` in an airspace without wind: the track selected is ``hdg`` [deg], LNAV off."""
    ap_trk[e, s] = hdg
    swlnav[e, s] = False


@jit
def altitude_commands(env, slot, target, vs, alt, selalt, swvnav, selvs):  # type: ignore[no-untyped-def]
    """:func:`select_altitude` of aircraft ``(env[i], slot[i])`` (each at most once), with ``target[i]`` and ``vs[i]``."""
    for i in grid_range(env.shape[0]):
        select_altitude(env[i], slot[i], target[i], vs[i], alt, selalt, swvnav, selvs)
