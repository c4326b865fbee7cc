"""Physical constants and unit conversions, with the exact values BlueSky 1.1.1 uses.

Everything inside the core is SI (m, s, kg, Pa, K) with angles in degrees for headings and
positions. Aviation units only appear at the edges (commands, observations).
"""

from __future__ import annotations

KTS = 0.514444  # m/s per knot
FT = 0.3048  # m per foot
FPM = FT / 60.0  # m/s per foot-per-minute
NM = 1852.0  # m per nautical mile
G0 = 9.80665  # m/s^2, standard gravity
R_AIR = 287.05287  # J/(kg K), specific gas constant used by BlueSky
P0 = 101325.0  # Pa, ISA sea-level pressure
RHO0 = 1.225  # kg/m^3, ISA sea-level density
T0 = 288.15  # K, ISA sea-level temperature
T_STRAT = 216.65  # K, ISA tropopause temperature
GAMMA = 1.40  # cp/cv for air
R_EARTH = 6371000.0  # m, mean Earth radius (kinematics, kwik geometry)
WGS84_A = 6378137.0  # m, WGS-84 major semi-axis
WGS84_B = 6356752.314245  # m, WGS-84 minor semi-axis

DEG2RAD = 0.017453292519943295  # the compiled geo module's constant (== np.radians(1))
RAD2DEG = 57.29577951308232
M2NM = 0.0005399568034557236  # 1/1852 as written in BlueSky's compiled geo module

# The gym environments' own conversion factors (reference bluesky-gym 0.2.0).
NM2KM = 1.852
MPS2KT = 1.94384

CASMACH_THRESHOLD = 2.0  # m/s: a speed 0.1 < v < 2 is a Mach number, otherwise CAS [dynamics.md 1.6]
