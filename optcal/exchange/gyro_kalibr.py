"""Kalibr's gyroscope intrinsics, model ``scale-misalignment`` (Rehder, Nikolic, Schneider, Hinzmann &
Siegwart, ICRA 2016, Eq. 3; docs/exchange.md §4 for the accelerometer's half).

Kalibr predicts a gyroscope measurement as ω_m = M·C_gyro_i·ω + A·a + b(t): M lower triangular, C_gyro_i
the rotation from the IMU frame to the gyroscope's, A the g-sensitivity in (rad/s)/(m/s²) and b a bias
Kalibr estimates online as a random walk, all in rad/s. optcal's gyroscope (:mod:`optcal.gyro.model`) in
output units u with s rad/s per u is s·W = s·diag(K)·(T·ω + b + G·f), f in g: so M·C_gyro_i =
s·diag(K)·T, split by an RQ decomposition with M's diagonal positive; A = s·diag(K)·G/g0; and the bias
s·K·b (or the rests' offset) is refused unless Kalibr is to estimate it online (``bias_online``), as for
the accelerometer. Counts and volts, with no fixed value in rad/s, are refused.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import rq

from ..errors import InputError
from ..gravity import G0
from ..gyro.calfile import GyroCalibration

RAD_PER_UNIT = {"rad/s": 1.0, "deg/s": np.pi / 180.0}
_FLIP = np.eye(3)[::-1]


def gyro_to_kalibr(cal: GyroCalibration, *, bias_online: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(M, A, C_gyro_i) of Kalibr's ω_m = M·C_gyro_i·ω + A·a + b for a gyroscope calibration."""
    if cal.units_raw not in RAD_PER_UNIT:
        raise InputError(f"Kalibr's gyroscope measurements are in rad/s, and this calibration's outputs are in "
                         f"{cal.units_raw}, which have no fixed value in rad/s; use the imu_tk format")
    s = RAD_PER_UNIT[cal.units_raw]
    K, T, _, G = (a[0] for a in cal.model.matrices(cal.x[None]))
    offset = cal.output_offset()
    if np.any(offset != 0) and not bias_online:
        raise InputError("Kalibr's gyroscope model has no constant bias (it estimates one online); pass "
                         "bias_online to leave this calibration's bias to Kalibr, or use the imu_tk format")
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
