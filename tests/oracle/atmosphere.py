"""Oracle: the ISA atmosphere and airspeed conversions as readable numpy array code.

The package computes these with scalar kernels (bluesky_gym.core.atmosphere); the tests compare
them with this form, operation by operation BlueSky's own numpy code, to the last bit.

Two forms exist in BlueSky and both are reproduced [docs/dynamics.md §1.6]:

* the *vector* ISA (``vatmos`` and the ``v*`` conversions), used by the kinematics and the
  performance model; its density exponent 4.256848030018761 differs slightly from the layered
  model's;
* the *scalar*, layered ISA (``atmos``, ``tas2cas``, ``cas2tas``), used only by ``creconfs``.
  Here it is vectorised over arrays, giving bit-identical results to BlueSky's scalar loops.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from bluesky_gym.core.units import CASMACH_THRESHOLD, G0, GAMMA, P0, R_AIR, RHO0, T_STRAT

Array = NDArray[np.float64]


def vtemp(h: ArrayLike) -> Array:
    """ISA temperature [K] at altitude ``h`` [m] (troposphere lapse, isothermal above)."""
    return np.maximum(288.15 - 0.0065 * h, T_STRAT)


def vatmos(h: ArrayLike) -> tuple[Array, Array, Array]:
    """Vector ISA: pressure [Pa], density [kg/m^3] and temperature [K] at ``h`` [m]."""
    t = vtemp(h)
    rhotrop = 1.225 * (t / 288.15) ** 4.256848030018761
    dhstrat = np.maximum(0.0, h - 11000.0)
    rho = rhotrop * np.exp(-dhstrat / 6341.552161)
    p = rho * R_AIR * t
    return p, rho, t


def vdensity(h: ArrayLike) -> Array:
    """Vector ISA density [kg/m^3]."""
    return vatmos(h)[1]


def vpressure(h: ArrayLike) -> Array:
    """Vector ISA pressure [Pa]."""
    return vatmos(h)[0]


def vvsound(h: ArrayLike) -> Array:
    """Speed of sound [m/s] at ``h`` [m]."""
    return np.sqrt(GAMMA * R_AIR * vtemp(h))


def vtas2mach(tas: ArrayLike, h: ArrayLike) -> Array:
    """True airspeed [m/s] to Mach number."""
    return tas / vvsound(h)


def vmach2tas(mach: ArrayLike, h: ArrayLike) -> Array:
    """Mach number to true airspeed [m/s]."""
    return mach * vvsound(h)


def tas2cas_from_atmos(tas: ArrayLike, p: ArrayLike, rho: ArrayLike) -> Array:
    """TAS to CAS [m/s] given the local pressure and density (vector form)."""
    qdyn = p * ((1.0 + rho * tas * tas / (7.0 * p)) ** 3.5 - 1.0)
    cas = np.sqrt(7.0 * P0 / RHO0 * ((qdyn / P0 + 1.0) ** (2.0 / 7.0) - 1.0))
    return np.where(tas < 0, -1 * cas, cas)


def cas2tas_from_atmos(cas: ArrayLike, p: ArrayLike, rho: ArrayLike) -> Array:
    """CAS to TAS [m/s] given the local pressure and density (vector form)."""
    qdyn = P0 * ((1.0 + RHO0 * cas * cas / (7.0 * P0)) ** 3.5 - 1.0)
    tas = np.sqrt(7.0 * p / rho * ((1.0 + qdyn / p) ** (2.0 / 7.0) - 1.0))
    return np.where(cas < 0, -1 * tas, tas)


def vtas2cas(tas: ArrayLike, h: ArrayLike) -> Array:
    """True to calibrated airspeed [m/s] at ``h`` [m] (vector ISA)."""
    p, rho, _ = vatmos(h)
    return tas2cas_from_atmos(tas, p, rho)


def vcas2tas(cas: ArrayLike, h: ArrayLike) -> Array:
    """Calibrated to true airspeed [m/s] at ``h`` [m] (vector ISA)."""
    p, rho, _ = vatmos(h)
    return cas2tas_from_atmos(cas, p, rho)


def is_mach(spd: ArrayLike) -> NDArray[np.bool_]:
    """BlueSky reads a speed as a Mach number when 0.1 < spd < 2 [docs/dynamics.md §1.6]."""
    spd = np.asarray(spd)
    return (spd > 0.1) & (spd < CASMACH_THRESHOLD)


def vcasormach(spd: ArrayLike, h: ArrayLike) -> tuple[Array, Array, Array]:
    """Interpret ``spd`` as CAS [m/s] or Mach; return (TAS, CAS, Mach)."""
    spd = np.asarray(spd, dtype=np.float64)
    ismach = is_mach(spd)
    tas = np.where(ismach, vmach2tas(spd, h), vcas2tas(spd, h))
    cas = np.where(ismach, vtas2cas(tas, h), spd)
    mach = np.where(ismach, spd, vtas2mach(tas, h))
    return tas, cas, mach


def vcasormach2tas(spd: ArrayLike, h: ArrayLike) -> Array:
    """Interpret ``spd`` as CAS [m/s] or Mach and return TAS [m/s]."""
    ismach = is_mach(spd)
    return np.where(ismach, vmach2tas(spd, h), vcas2tas(spd, h))


# --- BlueSky's scalar, layered ISA (used by creconfs), vectorised -------------------------------

_LAYER_H = np.array([0.0, 11000.0, 20000.0, 32000.0, 47000.0, 51000.0, 71000.0, 86852.0])
_LAYER_P = np.array([101325.0, 22631.7009099, 5474.71768857, 867.974468302, 110.898214043, 66.939, 3.9564])
_LAYER_T = np.array([288.15, 216.65, 216.65, 228.65, 270.65, 270.65, 214.65])
_LAYER_A = np.array([-0.0065, 0.0, 0.001, 0.0028, 0.0, -0.0028, -0.002])


def atmos(h: ArrayLike) -> tuple[Array, Array, Array]:
    """BlueSky's layered ISA (scalar ``aero.atmos``), element-wise: (p, rho, T)."""
    h = np.clip(np.asarray(h, dtype=np.float64), 0.0, _LAYER_H[-1])
    # Layer i is the first with h <= top of layer i (BlueSky's `while h > h0[i+1]` loop).
    i = np.minimum(np.searchsorted(_LAYER_H[1:], h, side="left"), len(_LAYER_T) - 1)
    a, t0, p0, h0 = _LAYER_A[i], _LAYER_T[i], _LAYER_P[i], _LAYER_H[i]
    with np.errstate(divide="ignore", invalid="ignore"):
        t_iso = t0
        p_iso = p0 * np.exp(-G0 / (R_AIR * t_iso) * (h - h0))
        t_grad = t0 + a * (h - h0)
        p_grad = p0 * ((t_grad / t0) ** (-G0 / (a * R_AIR)))
    iso = a == 0
    t = np.where(iso, t_iso, t_grad)
    p = np.where(iso, p_iso, p_grad)
    rho = p / (R_AIR * t)
    return p, rho, t


def tas2cas(tas: ArrayLike, h: ArrayLike) -> Array:
    """Scalar-ISA TAS to CAS [m/s] (BlueSky ``aero.tas2cas``), element-wise."""
    p, rho, _ = atmos(h)
    return tas2cas_from_atmos(np.asarray(tas, dtype=np.float64), p, rho)


def cas2tas(cas: ArrayLike, h: ArrayLike) -> Array:
    """Scalar-ISA CAS to TAS [m/s] (BlueSky ``aero.cas2tas``), element-wise."""
    p, rho, _ = atmos(h)
    return cas2tas_from_atmos(np.asarray(cas, dtype=np.float64), p, rho)


def casormach2tas(spd: ArrayLike, h: ArrayLike) -> Array:
    """Scalar-ISA CAS-or-Mach to TAS [m/s] (BlueSky ``aero.casormach2tas``), element-wise."""
    spd = np.asarray(spd, dtype=np.float64)
    _, _, t = atmos(h)
    mach_tas = spd * np.sqrt(GAMMA * R_AIR * t)
    return np.where(is_mach(spd), mach_tas, cas2tas(spd, h))
