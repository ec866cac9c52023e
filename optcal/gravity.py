"""Local gravity: WGS84 normal gravity (Somigliana's closed form) with the free-air height correction.

Values in m/s²; the problem works in units of standard gravity G0 (docs/design.md §2).
Constants from NIMA TR8350.2 (WGS84), Table 3.4 and Eq. 4-1 / 4-3.
"""

from __future__ import annotations

import math

from .errors import InputError

G0 = 9.80665  # standard gravity, m/s² (the unit "g" throughout optcal)

# WGS84 defining and derived constants
A_WGS84 = 6378137.0  # semi-major axis, m
F_WGS84 = 1 / 298.257223563  # flattening
GM_WGS84 = 3.986004418e14  # m³/s²
OMEGA_E = 7.292115e-5  # Earth rotation rate, rad/s
GAMMA_E = 9.7803253359  # normal gravity at the equator, m/s²
K_SOMIGLIANA = 0.00193185265241
E2_WGS84 = 6.69437999014e-3  # first eccentricity squared
M_WGS84 = OMEGA_E**2 * A_WGS84**2 * (A_WGS84 * (1 - F_WGS84)) / GM_WGS84


def normal_gravity(latitude_deg: float, height_m: float = 0.0) -> float:
    """Normal gravity in m/s² at geodetic latitude and ellipsoidal height (TR8350.2 Eq. 4-1, 4-3)."""
    if not -90.0 <= latitude_deg <= 90.0:
        raise InputError(f"latitude {latitude_deg} is outside [-90, 90] degrees; give it in degrees")
    if not -12000.0 <= height_m <= 100000.0:
        raise InputError(f"height {height_m} m is implausible; give the ellipsoidal height in metres")
    s2 = math.sin(math.radians(latitude_deg)) ** 2
    gamma = GAMMA_E * (1 + K_SOMIGLIANA * s2) / math.sqrt(1 - E2_WGS84 * s2)
    # Second-order free-air correction (TR8350.2 Eq. 4-3)
    corr = 1 - 2 / A_WGS84 * (1 + F_WGS84 + M_WGS84 - 2 * F_WGS84 * s2) * height_m + 3 / A_WGS84**2 * height_m**2
    return gamma * corr


def local_gravity_g(gravity_ms2: float | None = None, latitude_deg: float | None = None,
                    height_m: float = 0.0) -> float:
    """g_local in units of G0: from a value in m/s², or from latitude and height, or 1.0."""
    if gravity_ms2 is not None and latitude_deg is not None:
        raise InputError("give either --gravity or --latitude/--height, not both")
    if gravity_ms2 is not None:
        if not 9.7 <= gravity_ms2 <= 9.9:
            raise InputError(
                f"--gravity {gravity_ms2} is not a plausible local gravity; give it in m/s² (about 9.78 to 9.83)"
            )
        return gravity_ms2 / G0
    if latitude_deg is not None:
        return normal_gravity(latitude_deg, height_m) / G0
    return 1.0
