"""ISA atmosphere and airspeed conversions exactly as BlueSky 1.1.1 computes them.

Two forms exist in BlueSky and both are reproduced [docs/dynamics.md §1.6]:

* the *vector* ISA (BlueSky's ``vatmos`` and the ``v*`` conversions), used by the kinematics and
  the performance model; its density exponent differs slightly from the layered model's;
* the *scalar*, layered ISA (``atmos``, ``tas2cas``, ``cas2tas``), used only by ``creconfs``.

The physics is written once, as scalar kernels (:func:`isa`, :func:`isa_layered`,
:func:`tas2cas_at`, :func:`cas2tas_at`, :func:`casormach`); the array functions below
(:func:`vcas2tas`, :func:`vcasormach`, :func:`tas2cas`, :func:`casormach2tas`) are loops over
them for the places that need arrays (aircraft creation, ``creconfs``, task set-up).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from bluesky_gym.core.jit import flat_float_args, grid_range, jit, shaped
from bluesky_gym.core.units import (
    CASMACH_THRESHOLD,
    G0,
    GAMMA,
    H_SCALE_STRAT,
    H_TROPOPAUSE,
    ISA_LAPSE,
    MACH_MIN,
    P0,
    R_AIR,
    RHO0,
    RHO_EXPONENT,
    T0,
    T_STRAT,
)

Array = NDArray[np.float64]

GAMMA_R = GAMMA * R_AIR  # J/(kg K): gamma * R, as BlueSky's vvsound evaluates it
_7P0_RHO0 = 7.0 * P0 / RHO0

# BlueSky's layered ISA: layer bottoms [m], base pressures [Pa], base temperatures [K], lapse [K/m].
LAYER_H = np.array([0.0, 11000.0, 20000.0, 32000.0, 47000.0, 51000.0, 71000.0, 86852.0])
LAYER_P = np.array([101325.0, 22631.7009099, 5474.71768857, 867.974468302, 110.898214043, 66.939, 3.9564])
LAYER_T = np.array([288.15, 216.65, 216.65, 228.65, 270.65, 270.65, 214.65])
LAYER_A = np.array([-0.0065, 0.0, 0.001, 0.0028, 0.0, -0.0028, -0.002])


# --- Scalar kernels ------------------------------------------------------------------------------
@jit
def isa(h: float) -> tuple[float, float, float]:
    """Vector ISA (BlueSky ``vatmos``): pressure [Pa], density [kg/m^3], temperature [K] at ``h`` [m]."""
    t = T0 - ISA_LAPSE * h
    if not t > T_STRAT:  # np.maximum(x, T_STRAT) propagates NaN
        t = T_STRAT if t == t else t
    rhotrop = RHO0 * math.pow(t / T0, RHO_EXPONENT)
    dh = h - H_TROPOPAUSE
    if not dh > 0.0:
        dh = 0.0 if dh == dh else dh
    rho = rhotrop * math.exp(-dh / H_SCALE_STRAT)
    p = rho * R_AIR * t
    return p, rho, t


@jit
def isa_layered(h: float) -> tuple[float, float, float]:
    """BlueSky's layered ISA (scalar ``aero.atmos``): (p [Pa], rho [kg/m^3], T [K]) at ``h`` [m]."""
    top = LAYER_H[LAYER_H.shape[0] - 1]
    if h < 0.0:
        h = 0.0
    if h > top:
        h = top
    # Layer i is the first with h <= top of layer i (BlueSky's `while h > h0[i+1]` loop).
    i = 0
    while i < LAYER_T.shape[0] - 1 and h > LAYER_H[i + 1]:
        i += 1
    a, t0, p0, h0 = LAYER_A[i], LAYER_T[i], LAYER_P[i], LAYER_H[i]
    if a == 0:
        t = t0
        p = p0 * math.exp(-G0 / (R_AIR * t) * (h - h0))
    else:
        t = t0 + a * (h - h0)
        p = p0 * math.pow(t / t0, -G0 / (a * R_AIR))
    rho = p / (R_AIR * t)
    return p, rho, t


@jit
def tas2cas_at(tas: float, p: float, rho: float) -> float:
    """TAS to CAS [m/s] given the local pressure [Pa] and density [kg/m^3]."""
    qdyn = p * (math.pow(1.0 + rho * tas * tas / (7.0 * p), 3.5) - 1.0)
    cas = math.sqrt(_7P0_RHO0 * (math.pow(qdyn / P0 + 1.0, 2.0 / 7.0) - 1.0))
    return -1 * cas if tas < 0 else cas


@jit
def cas2tas_at(cas: float, p: float, rho: float) -> float:
    """CAS to TAS [m/s] given the local pressure [Pa] and density [kg/m^3]."""
    qdyn = P0 * (math.pow(1.0 + RHO0 * cas * cas / (7.0 * P0), 3.5) - 1.0)
    tas = math.sqrt(7.0 * p / rho * (math.pow(1.0 + qdyn / p, 2.0 / 7.0) - 1.0))
    return -1 * tas if cas < 0 else tas


@jit
def is_mach(spd: float) -> bool:
    """BlueSky reads a speed as a Mach number when 0.1 < spd < 2 [docs/dynamics.md §1.6]."""
    return spd > MACH_MIN and spd < CASMACH_THRESHOLD


@jit
def casormach(spd: float, h: float) -> tuple[float, float, float]:
    """Interpret ``spd`` as CAS [m/s] or Mach at ``h`` [m] (vector ISA); return (TAS, CAS, Mach)."""
    p, rho, t = isa(h)
    sound = math.sqrt(GAMMA_R * t)
    if is_mach(spd):
        tas = spd * sound
        return tas, tas2cas_at(tas, p, rho), spd
    tas = cas2tas_at(spd, p, rho)
    return tas, spd, tas / sound


# --- Array functions (loops over the kernels) ----------------------------------------------------
@jit
def _vcasormach_loop(spd, h, tas, cas, mach):  # type: ignore[no-untyped-def]
    for i in grid_range(spd.shape[0]):
        tas[i], cas[i], mach[i] = casormach(spd[i], h[i])


@jit
def _vcas2tas_loop(cas, h, out):  # type: ignore[no-untyped-def]
    for i in grid_range(cas.shape[0]):
        p, rho, _ = isa(h[i])
        out[i] = cas2tas_at(cas[i], p, rho)


@jit
def _layered_loop(spd, h, out, to_cas):  # type: ignore[no-untyped-def]
    for i in grid_range(spd.shape[0]):
        p, rho, t = isa_layered(h[i])
        if to_cas:
            out[i] = tas2cas_at(spd[i], p, rho)
        elif is_mach(spd[i]):
            out[i] = spd[i] * math.sqrt(GAMMA_R * t)
        else:
            out[i] = cas2tas_at(spd[i], p, rho)


def vcasormach(spd: ArrayLike, h: ArrayLike) -> tuple[Array, Array, Array]:
    """Interpret ``spd`` as CAS [m/s] or Mach at ``h`` [m] (vector ISA); return (TAS, CAS, Mach)."""
    shape, (s, hh) = flat_float_args(spd, h)
    tas, cas, mach = np.empty(s.size), np.empty(s.size), np.empty(s.size)
    _vcasormach_loop(s, hh, tas, cas, mach)
    return shaped(tas, shape), shaped(cas, shape), shaped(mach, shape)


def vcas2tas(cas: ArrayLike, h: ArrayLike) -> Array:
    """Calibrated to true airspeed [m/s] at ``h`` [m] (vector ISA)."""
    shape, (c, hh) = flat_float_args(cas, h)
    out = np.empty(c.size)
    _vcas2tas_loop(c, hh, out)
    return shaped(out, shape)  # type: ignore[no-any-return]


def tas2cas(tas: ArrayLike, h: ArrayLike) -> Array:
    """Layered-ISA TAS to CAS [m/s] (BlueSky ``aero.tas2cas``), element-wise."""
    shape, (v, hh) = flat_float_args(tas, h)
    out = np.empty(v.size)
    _layered_loop(v, hh, out, True)
    return shaped(out, shape)  # type: ignore[no-any-return]


def casormach2tas(spd: ArrayLike, h: ArrayLike) -> Array:
    """Layered-ISA CAS-or-Mach to TAS [m/s] (BlueSky ``aero.casormach2tas``), element-wise."""
    shape, (v, hh) = flat_float_args(spd, h)
    out = np.empty(v.size)
    _layered_loop(v, hh, out, False)
    return shaped(out, shape)  # type: ignore[no-any-return]
