"""imu_tk's calibration file for the gyroscope (Tedaldi, Pretto & Menegatti, ICRA 2014; imu_tk writes the
gyroscope's ``CalibratedTriad`` to its own file, ``test_imu_gyro.calib`` in its example program).

The text is the accelerometer's (:mod:`optcal.core.exchange.imu_tk`: T 3×3, K 3×3, B 3×1) and so is the model,
ω = T·K·(W − B) with T of unit diagonal, K diagonal in rad/s per raw unit, B in raw units. optcal's
gyroscope (:mod:`optcal.core.gyro.model`) without g-sensitivity is the same map: T·K = M = T_o⁻¹·diag(1/K_o), and
B the output offset, K_o·b (bias fitted) or the rests' mean output (bias from the rests). A calibration with
g-sensitivity is refused: imu_tk's file cannot hold it. Both tools' misalignments are relative to their own
accelerometer frame (docs/gyroscope.md, "imu_tk's Xsens recording, against imu_tk"), so a file moved between them
keeps the frame it was made in.
"""

from __future__ import annotations

import numpy as np

from optcal.core.errors import InputError
from optcal.core.exchange.imu_tk import dumps, loads
from optcal.core.gyro.calfile import GyroCalibration, imported_block

__all__ = ["dumps", "gyro_from_imu_tk", "gyro_to_imu_tk", "loads"]


def gyro_to_imu_tk(cal: GyroCalibration) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(T, K, B) of imu_tk's ω = T·K·(W − B) for a gyroscope calibration read from an optcal IMU file."""
    if cal.model.g_sensitivity:
        raise InputError("imu_tk's gyroscope file has no g-sensitivity, and this calibration's gyroscope has it; "
                         "export to imucal or kalibr, which hold it, or calibrate without --g-sensitivity")
    Ko, To, _, _ = (a[0] for a in cal.model.matrices(cal.x[None]))
    M = np.linalg.inv(To) / Ko[None, :]
    k = np.diag(M).copy()
    if np.any(k == 0):
        raise InputError("a gyroscope axis's calibrated rate does not depend on its own output (a zero diagonal "
                         "cell); imu_tk's T·K with a unit-diagonal T cannot hold it")
    return M / k[None, :], np.diag(k), cal.output_offset()


def gyro_from_imu_tk(T, K, B, units: str, source=None) -> dict:
    """The ``gyroscope`` block (:func:`optcal.core.gyro.calfile.imported_block`) of imu_tk's ω = T·K·(W − B), ω in
    rad/s and W in ``units``: gyro12 with K_o = diag((T·K)⁻¹), T_o = diag(1/K_o)·(T·K)⁻¹, b = B/K_o."""
    C = np.asarray(T, float) @ np.asarray(K, float)
    try:
        Ci = np.linalg.inv(C)
    except np.linalg.LinAlgError:
        raise InputError("imu_tk's gyroscope T·K is singular: the file cannot be a gyroscope calibration") from None
    Ko = np.diag(Ci).copy()
    if np.any(Ko == 0) or not np.all(np.isfinite(Ci)):
        raise InputError("imu_tk's gyroscope T·K has an axis that does not sense its own rate; the file cannot be "
                         "a gyroscope calibration")
    return imported_block(Ko, Ci / Ko[:, None], np.asarray(B, float).reshape(3) / Ko, None, units, fmt="imu_tk",
                          source=source)
