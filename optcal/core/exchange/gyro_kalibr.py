"""Kalibr's gyroscope intrinsics, model ``scale-misalignment`` (Rehder, Nikolic, Schneider, Hinzmann &
Siegwart, ICRA 2016, Eq. 3; docs/exchange.md, "Kalibr" for the accelerometer's half).

Kalibr predicts a gyroscope measurement as ω_m = M·C_gyro_i·ω + A·a + b(t): M lower triangular, C_gyro_i
the rotation from the IMU frame to the gyroscope's, A the g-sensitivity in (rad/s)/(m/s²) and b a bias
Kalibr estimates online as a random walk, all in rad/s. optcal's gyroscope (:mod:`optcal.core.gyro.model`) in
output units u with s rad/s per u is s·W = s·diag(K)·(T·ω + b + G·f), f in g: so M·C_gyro_i =
s·diag(K)·T, split by an RQ decomposition with M's diagonal positive; A = s·diag(K)·G/g0; and the bias
s·K·b (or the rests' offset) is refused unless Kalibr is to estimate it online (``bias_online``), as for
the accelerometer. Counts and volts, with no fixed value in rad/s, are refused. An import
(:func:`gyro_from_kalibr`) inverts the product M·C_gyro_i (the split into M and C is not needed back).
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import rq

from optcal.core.errors import InputError
from optcal.core.gravity import G0
from optcal.core.gyro.calfile import GyroCalibration, imported_block

RAD_PER_UNIT = {"rad/s": 1.0, "deg/s": np.pi / 180.0}
_FLIP = np.eye(3)[::-1]


def gyro_to_kalibr(cal: GyroCalibration, *, bias_online: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(M, A, C_gyro_i) of Kalibr's ω_m = M·C_gyro_i·ω + A·a + b for a gyroscope calibration."""
    if cal.units_raw not in RAD_PER_UNIT:
        raise InputError("Kalibr's gyroscope measurements are in rad/s, and this calibration's gyroscope outputs "
                         f"are in {cal.units_raw}, which have no fixed value in rad/s; use the imu_tk or imucal format")
    s = RAD_PER_UNIT[cal.units_raw]
    K, T, _, G = (a[0] for a in cal.model.matrices(cal.x[None]))
    offset = cal.output_offset()
    if np.any(offset != 0) and not bias_online:
        raise InputError("Kalibr's gyroscope model has no constant bias (it estimates one online as a random walk), "
                         "and this calibration's gyroscope offset is "
                         + ", ".join(f"{v:.6g}" for v in offset) + f" {cal.units_raw}; pass `bias_online` to leave "
                         "it to Kalibr, or choose the imu_tk or imucal format")
    B = s * K[:, None] * T
    if np.linalg.det(B) <= 0:
        raise InputError("this gyroscope's axes form a left-handed set (negative determinant): Kalibr's "
                         "M·C_gyro_i with a rotation C cannot hold it")
    U, Q = rq(_FLIP @ B @ _FLIP)  # B = L·C with L = P·U·P lower triangular and C = P·Q·P (P the flip)
    L, C = _FLIP @ U @ _FLIP, _FLIP @ Q @ _FLIP
    D = np.diag(np.sign(np.diag(L)))
    L, C = L @ D, D @ C  # positive diagonal of M; C stays a rotation (det B > 0 and det L > 0)
    A = s * K[:, None] * G / G0
    return L, A, C


def is_identity(M, A, C) -> bool:
    """True for the gyroscope intrinsics optcal writes for a calibration without a gyroscope (M = C = I,
    A = 0): no gyroscope calibration to import."""
    return bool(np.array_equal(M, np.eye(3)) and np.array_equal(C, np.eye(3)) and not np.any(A))


def gyro_from_kalibr(M, A, C, units: str = "rad/s", source=None) -> dict:
    """The ``gyroscope`` block of Kalibr's ω_m = M·C_gyro_i·ω + A·a + b, raw outputs in ``units`` (rad/s, or
    deg/s when Kalibr's rad/s were converted from those): s·diag(K)·T = M·C_gyro_i, so K = diag(M·C)/s and
    T = diag(1/K)·M·C/s; G = g0·diag(1/K)·A/s; no bias (Kalibr estimates it online), b = 0."""
    if units not in RAD_PER_UNIT:
        raise InputError(f"Kalibr's gyroscope measurements are in rad/s; raw units {units!r} have no fixed value "
                         f"in rad/s (use {' or '.join(RAD_PER_UNIT)})")
    s = RAD_PER_UNIT[units]
    B = np.asarray(M, float) @ np.asarray(C, float) / s
    K = np.diag(B).copy()
    if np.any(K == 0):
        raise InputError("Kalibr's gyroscope M·C_gyro_i has a zero diagonal cell: an axis that does not sense its "
                         "own rate")
    return imported_block(K, B / K[:, None], np.zeros(3), np.asarray(A, float) * G0 / (s * K[:, None]), units,
                          fmt="kalibr", source=source)
