"""Physical constants, unit conversions and model constants, with the exact values BlueSky 1.1.1 uses.

Everything inside the core is SI (m, s, kg, Pa, K) with angles in degrees for headings and
positions. Aviation units only appear at the edges (commands, observations). Every constant of the
physics is declared here once and imported where it is used.
"""

from __future__ import annotations

# --- Units -------------------------------------------------------------------------------------
KTS = 0.514444  # m/s per knot
FT = 0.3048  # m per foot
FL = 100 * FT  # m per flight level (FL350 = 350 * FL = 10668 m)
FPM = FT / 60.0  # m/s per foot-per-minute (== 0.00508, OpenAP's literal)
NM = 1852.0  # m per nautical mile
DEG2RAD = 0.017453292519943295  # rad per deg, BlueSky's compiled geo module's constant (== np.radians(1))
RAD2DEG = 57.29577951308232  # deg per rad
M2NM = 0.0005399568034557236  # NM per m, 1/1852 as written in BlueSky's compiled geo module

# The gym environments' own conversion factors (reference bluesky-gym 0.2.0).
NM2KM = 1.852  # km per NM
MPS2KT = 1.94384  # kt per m/s
KM = 1000.0  # m per km

# --- Earth -------------------------------------------------------------------------------------
G0 = 9.80665  # m/s^2, standard gravity
R_EARTH = 6371000.0  # m, mean Earth radius (kinematics, kwik geometry)
WGS84_A = 6378137.0  # m, WGS-84 major semi-axis
WGS84_B = 6356752.314245  # m, WGS-84 minor semi-axis

# --- ISA atmosphere [docs/dynamics.md §1.6] ----------------------------------------------------------
R_AIR = 287.05287  # J/(kg K), specific gas constant used by BlueSky
GAMMA = 1.40  # -, cp/cv for air
P0 = 101325.0  # Pa, ISA sea-level pressure
RHO0 = 1.225  # kg/m^3, ISA sea-level density
T0 = 288.15  # K, ISA sea-level temperature
T_STRAT = 216.65  # K, ISA tropopause temperature
ISA_LAPSE = 0.0065  # K/m, tropospheric temperature lapse rate
H_TROPOPAUSE = 11000.0  # m
RHO_EXPONENT = 4.256848030018761  # -, density exponent of BlueSky's vector ISA (g0 / (R lapse) - 1, rounded)
H_SCALE_STRAT = 6341.552161  # m, density scale height above the tropopause (vector ISA)
MACH_MIN = 0.1  # -: a speed MACH_MIN < v < CASMACH_THRESHOLD is a Mach number, otherwise CAS
CASMACH_THRESHOLD = 2.0  # m/s: a speed 0.1 < v < 2 is a Mach number, otherwise CAS [docs/dynamics.md §1.6]

# --- Autopilot and kinematics [docs/dynamics.md §2] --------------------------------------------------
BANK_DEFAULT = 0.4363323129985824  # rad (25 deg), BlueSky's default bank angle
VS_DEFAULT = 1500 * FPM  # m/s (7.62): used when |selvs| <= VS_SELECT_EPS [docs/dynamics.md §2.3]
VS_SELECT_EPS = 0.1  # m/s
VS_RAMP = 300 * FPM  # m/s per s: vertical acceleration, threshold NOT scaled by dt (quirk 9.6)
WIND_MIN_ALT = 50.0 * FT  # m: wind only acts above this altitude [docs/dynamics.md §1.7]
TAS_EPS = 0.01  # m/s, BlueSky's traf.eps: floor of TAS in the turn-rate formula
PERFORMANCE_INTERVAL = 1.0  # s, BlueSky's performance_dt timer
ASAS_INTERVAL = 1.0  # s, BlueSky's conflict detection and resolution update interval (asas_dt)
NO_VALUE = -999.0  # BlueSky's marker for "not set"
