"""Local gravity: WGS84 normal gravity (Somigliana's closed form) with the free-air height correction.

Values in m/s²; the problem works in units of standard gravity G0 (docs/design.md, "Units and frames").
Constants from NIMA TR8350.2 (WGS84), Table 3.4 and Eq. 4-1 / 4-3.
"""

from __future__ import annotations

import math

from optcal.core.errors import InputError

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
    if not math.isfinite(latitude_deg) or not -90.0 <= latitude_deg <= 90.0:
        raise InputError(f"latitude {latitude_deg} is outside [-90, 90] degrees; give it in degrees")
    if not math.isfinite(height_m) or not -12000.0 <= height_m <= 100000.0:
        raise InputError(f"height {height_m} m is implausible; give the ellipsoidal height in metres")
    s2 = math.sin(math.radians(latitude_deg)) ** 2
    gamma = GAMMA_E * (1 + K_SOMIGLIANA * s2) / math.sqrt(1 - E2_WGS84 * s2)
    # Second-order free-air correction (TR8350.2 Eq. 4-3)
    corr = 1 - 2 / A_WGS84 * (1 + F_WGS84 + M_WGS84 - 2 * F_WGS84 * s2) * height_m + 3 / A_WGS84**2 * height_m**2
    return gamma * corr


# Local gravity on the Earth's surface, m/s²: 9.78 at the equator to 9.83 at the poles, a little less on
# mountains; the check leaves a margin around it.
PLAUSIBLE_MS2 = (9.76, 9.84)


def local_gravity_g(gravity_ms2: float | None = None, latitude_deg: float | None = None,
                    height_m: float | None = 0.0) -> float:
    """g_local in units of G0 (docs/design.md, "Units and frames"): from ``gravity_ms2`` in m/s², or from
    ``latitude_deg`` and ``height_m`` (WGS84 normal gravity), or 1.0. A value that looks like g instead of m/s², or a
    height without a latitude (it would be ignored), is refused."""
    if gravity_ms2 is not None and latitude_deg is not None:
        raise InputError("give the local gravity either in m/s² or as a latitude (and height), not both")
    if latitude_deg is None and height_m not in (None, 0.0):
        raise InputError(f"a height ({height_m:g} m) without a latitude says nothing about local gravity; "
                         "give the latitude too, or leave the height out")
    if gravity_ms2 is not None:
        lo, hi = PLAUSIBLE_MS2
        if not math.isfinite(gravity_ms2) or not lo <= gravity_ms2 <= hi:
            looks = ""
            if math.isfinite(gravity_ms2) and 0.99 <= gravity_ms2 <= 1.01:
                looks = " looks like g, not m/s²:"
            elif math.isfinite(gravity_ms2) and 976 <= gravity_ms2 <= 984:
                looks = " looks like cm/s² (Gal), not m/s²:"
            raise InputError(f"local gravity {gravity_ms2:g} m/s²{looks} give it in m/s², {lo:g} to {hi:g} "
                             "(9.80665 is standard gravity)")
        return gravity_ms2 / G0
    if latitude_deg is not None:
        return normal_gravity(latitude_deg, height_m or 0.0) / G0
    return 1.0


def check_gravity_g(g_local: float) -> float:
    """A local gravity given in g (simulate's): about 1; a value near 9.8 looks like m/s²."""
    if not math.isfinite(g_local) or not 0.99 <= g_local <= 1.01:
        looks = " looks like m/s², not g:" if math.isfinite(g_local) and 9.7 <= g_local <= 9.9 else ""
        raise InputError(f"local gravity {g_local:g} g{looks} give it in g, 0.99 to 1.01 (Earth's surface)")
    return float(g_local)
