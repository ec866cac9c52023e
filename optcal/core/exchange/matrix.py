"""The plain affine form, a JSON file any tool can apply (docs/exchange.md, "The affine matrix").

    a = C·u + d        u: raw outputs (3-vector, raw units), a: calibrated specific force (calibrated units)

MATLAB's ``accelcal`` writes the same map for row vectors, C_matlab = U·A + b (U an N×3 block of raw rows):
A = Cᵀ and b = dᵀ. From optcal's u = M·A_g + o (A_g in g): C = f·M⁻¹, d = −C·o, f the calibrated units per g
(1 for g, g0 = 9.80665 m/s² for m/s²). The file states both units; optcal's raw units and g_local travel with it.
"""

from __future__ import annotations

import json

import numpy as np

from optcal.core.data import UNITS
from optcal.core.errors import InputError
from optcal.core.exchange.common import CALIBRATED_UNITS, LinearPart, inverse, matrix3, rows

FORMAT = "matrix"
FILE_FORMAT = "optcal-affine-matrix"
FILE_VERSION = 1
EQUATION = "calibrated = C @ raw + d"
DEFAULT_CALIBRATED = "g"


def to_matrix(lin: LinearPart, calibrated: str = DEFAULT_CALIBRATED) -> tuple[np.ndarray, np.ndarray]:
    """(C, d) of a = C·u + d for optcal's linear part, a in ``calibrated`` units."""
    C = CALIBRATED_UNITS[calibrated] * inverse(lin.M)
    return C, -(C @ np.asarray(lin.o, float))


def from_matrix(C, d, units: str, calibrated: str) -> LinearPart:
    """optcal's linear part of a = C·u + d: M = f·C⁻¹, o = −C⁻¹·d."""
    Ci = inverse(C)
    return LinearPart(CALIBRATED_UNITS[calibrated] * Ci, -(Ci @ np.asarray(d, float)), units)


def dumps(C, d, units: str, calibrated: str, g_local: float | None = None, source=None) -> str:
    doc = {
        "format": FILE_FORMAT,
        "format_version": FILE_VERSION,
        "equation": EQUATION,
        "C": rows(C),
        "d": rows(d),
        "units": {"raw": units, "calibrated": calibrated},
        "g_local_g": None if g_local is None else float(g_local),
        "source": None if source is None else str(source),
    }
    return json.dumps(doc, indent=2) + "\n"


def loads(doc: dict, path) -> tuple[np.ndarray, np.ndarray, str, str, float | None]:
    """(C, d, raw units, calibrated units, g_local in g or None) from the file's JSON object."""
    if doc.get("format") != FILE_FORMAT:
        raise InputError(f"{path} is not an affine-matrix file (no \"format\": \"{FILE_FORMAT}\")")
    if doc.get("format_version") != FILE_VERSION:
        raise InputError(f"{path}: format_version {doc.get('format_version')!r}; optcal reads version {FILE_VERSION}")
    if doc.get("equation", EQUATION) != EQUATION:
        raise InputError(f"{path}: equation {doc['equation']!r}; this format is {EQUATION!r}")
    units = doc.get("units")
    if not isinstance(units, dict) or units.get("raw") not in UNITS or units.get("calibrated") not in CALIBRATED_UNITS:
        raise InputError(f"{path}: units must name the raw units ({', '.join(UNITS)}) and the calibrated units "
                         f"({', '.join(CALIBRATED_UNITS)})")
    g = doc.get("g_local_g")
    if g is not None and not (isinstance(g, int | float) and 0.5 < g < 2.0):
        raise InputError(f"{path}: g_local_g {g!r} is not a local gravity in g")
    return (matrix3(doc.get("C"), "C", path), matrix3(doc.get("d"), "d", path, (3,)), units["raw"],
            units["calibrated"], None if g is None else float(g))
