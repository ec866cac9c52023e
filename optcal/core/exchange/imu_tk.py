"""imu_tk's calibration file (Tedaldi, Pretto & Menegatti, ICRA 2014, as imu_tk implements its sensor model;
docs/exchange.md, "imu_tk").

imu_tk corrects a raw reading X as X' = T·K·(X − B): T a misalignment matrix with unit diagonal, K a
diagonal scale matrix (calibrated units per raw unit), B the bias in raw units. Its ``CalibratedTriad::save``
writes the three as text, T (3 rows of 3), a blank line, K (3 rows of 3), a blank line, B (3 rows of 1);
``load`` reads the 21 numbers back in that order. imu_tk's accelerometer fit keeps T upper triangular (its
"body frame" gauge); the file holds any T, and the loader applies it as written.

From optcal's N = M·A + o (A in g): T·K = f·M⁻¹ with f the calibrated units per g (1 for g, g0 for m/s²,
imu_tk's default as its g_mag is 9.81 m/s²), so K_j = (f·M⁻¹)_jj, T = f·M⁻¹·K⁻¹, and B = o. The file does not
state units: the raw units and the calibrated unit are given on import.
"""

from __future__ import annotations

import numpy as np

from optcal.core.errors import InputError
from optcal.core.exchange.common import CALIBRATED_UNITS, LinearPart, inverse

FORMAT = "imu_tk"
DEFAULT_CALIBRATED = "m/s2"


def to_imu_tk(lin: LinearPart, calibrated: str = DEFAULT_CALIBRATED) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(T, K, B) of imu_tk's X' = T·K·(X − B) for optcal's linear part, X' in ``calibrated`` units."""
    C = CALIBRATED_UNITS[calibrated] * inverse(lin.M)
    k = np.diag(C).copy()
    if np.any(k == 0):
        raise InputError("an axis's calibrated output does not depend on its own raw output (a zero diagonal "
                         "cell); imu_tk's T·K with a unit-diagonal T cannot hold it")
    return C / k[None, :], np.diag(k), np.asarray(lin.o, float).copy()


def from_imu_tk(T, K, B, units: str, calibrated: str = DEFAULT_CALIBRATED) -> LinearPart:
    """optcal's linear part of imu_tk's X' = T·K·(X − B) (X in ``units``, X' in ``calibrated`` units):
    M = f·(T·K)⁻¹, o = B. T and K are used as the product imu_tk applies, whatever their structure."""
    C = np.asarray(T, float) @ np.asarray(K, float)
    return LinearPart(CALIBRATED_UNITS[calibrated] * inverse(C), np.asarray(B, float).reshape(3).copy(), units)


def dumps(T, K, B) -> str:
    """The text ``CalibratedTriad::save`` writes (at full precision: imu_tk's stream gives 6 digits)."""
    def block(M):
        return "\n".join(" ".join(repr(float(v)) for v in row) for row in np.atleast_2d(M)) + "\n"

    return block(T) + "\n" + block(K) + "\n" + block(np.asarray(B, float).reshape(3, 1)) + "\n"


def loads(text: str, path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(T, K, B) from the text of an imu_tk calibration file: exactly 21 numbers, row by row."""
    tokens = text.split()
    try:
        values = np.array([float(t) for t in tokens])
    except ValueError:
        bad = next(t for t in tokens if not _is_float(t))
        raise InputError(f"{path}: {bad!r} is not a number; an imu_tk calibration file holds 21 numbers "
                         "(T 3×3, K 3×3, B 3×1)") from None
    if values.size != 21:
        raise InputError(f"{path}: an imu_tk calibration file holds 21 numbers (T 3×3, K 3×3, B 3×1); this one "
                         f"has {values.size}")
    if not np.all(np.isfinite(values)):
        raise InputError(f"{path}: a value is not finite")
    T, K, B = values[:9].reshape(3, 3), values[9:18].reshape(3, 3), values[18:]
    off = K[~np.eye(3, dtype=bool)]
    if np.any(off != 0):
        raise InputError(f"{path}: imu_tk's scale matrix K is diagonal, but this file's second block has "
                         "off-diagonal entries; is it an imu_tk file?")
    return T, K, B


def _is_float(s: str) -> bool:
    try:
        float(s)
    except ValueError:
        return False
    return True
