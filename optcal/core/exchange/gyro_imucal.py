"""imucal's Ferraris calibration, gyroscope half (Ferraris, Grimaldi & Parvis, Sensors and Materials 7(5),
1995, as the ``imucal`` package implements it; the accelerometer half is :mod:`optcal.core.exchange.imucal`).

imucal corrects gyroscope samples as ω = R_g⁻¹·K_g⁻¹·(u − K_ga·a − b_g): ω in ``gyr_unit`` (deg/s), u in
``from_gyr_unit``, a the calibrated acceleration in m/s², K_g diagonal, R_g with the sensitive axes' unit
vectors as rows, K_ga the acceleration sensitivity, b_g the offset in raw units. From optcal's gyroscope
u = diag(K)·(T·ω_rad + b + G·f), f = a/g0 in g and ω_rad = (π/180)·ω: K_g·R_g = (π/180)·diag(K)·T, so K_g
holds the row norms and R_g the unit rows; K_ga = diag(K)·G/g0; b_g = K·b, or the rests' offset.
"""

from __future__ import annotations

import numpy as np

from optcal.core.errors import InputError
from optcal.core.exchange.common import matrix3
from optcal.core.gravity import G0
from optcal.core.gyro.calfile import GYRO_UNITS, GyroCalibration, imported_block

RAD_PER_DEG = np.pi / 180.0


# optcal's gyroscope output units and imucal's labels for them (its example files call counts "a.u.")
GYRO_LABELS = {"counts": "a.u.", "deg/s": "deg/s", "rad/s": "rad/s", "volts": "V"}
LABEL_GYRO_UNITS = {**{v: k for k, v in GYRO_LABELS.items()}, "counts": "counts", "volts": "volts"}
# what optcal writes for a calibration without a gyroscope: the identity, deg/s to deg/s
IDENTITY = {"K_g": np.eye(3), "R_g": np.eye(3), "K_ga": np.zeros((3, 3)), "b_g": np.zeros(3)}


def gyro_to_imucal(cal: GyroCalibration) -> dict:
    """imucal's gyroscope fields (K_g, R_g, K_ga, b_g as nested lists; ``gyr_unit`` deg/s and
    ``from_gyr_unit`` the raw units' label)."""
    K, T, _, G = (a[0] for a in cal.model.matrices(cal.x[None]))
    C = RAD_PER_DEG * K[:, None] * T
    k = np.linalg.norm(C, axis=1)
    b_g = cal.output_offset()
    return {"K_g": np.diag(k).tolist(), "R_g": (C / k[:, None]).tolist(), "K_ga": (K[:, None] * G / G0).tolist(),
            "b_g": [float(v) for v in b_g], "gyr_unit": "deg/s", "from_gyr_unit": GYRO_LABELS[cal.units_raw]}


def is_identity(d: dict) -> bool:
    """True when an imucal file's gyroscope fields are absent or the identity optcal writes for a calibration
    without a gyroscope (K_g = R_g = I, K_ga = 0, b_g = 0): no gyroscope calibration to import."""
    return all(d.get(k) is None or np.array_equal(np.asarray(d[k], float), v) for k, v in IDENTITY.items())


def gyro_units_of(d: dict, units: str | None, path) -> str:
    """The gyroscope's raw units: ``units`` (given), else the file's ``from_gyr_unit``; a given unit that
    contradicts the file's label is refused."""
    label = d.get("from_gyr_unit")
    if units is None:
        if label not in LABEL_GYRO_UNITS:
            raise InputError(f"{path}: from_gyr_unit {label!r} is not a unit optcal knows; give the gyroscope's raw "
                             f"units with --gyro-units ({', '.join(GYRO_UNITS)})")
        return LABEL_GYRO_UNITS[label]
    if label in LABEL_GYRO_UNITS and LABEL_GYRO_UNITS[label] != units:
        raise InputError(f"{path}: the file's gyroscope raw unit is {label!r} but --gyro-units says {units!r}; "
                         "drop --gyro-units")
    return units


def gyro_from_imucal(d: dict, units: str, path) -> dict:
    """The ``gyroscope`` block of the gyroscope fields of an imucal file ``d`` (raw samples in ``units``):
    gyro21 when K_ga is not zero, else gyro12."""
    if units not in GYRO_UNITS:
        raise InputError(f"unknown gyroscope units {units!r}; use one of {', '.join(GYRO_UNITS)}")
    if d.get("gyr_unit", "deg/s") != "deg/s":
        raise InputError(f"{path}: gyr_unit {d.get('gyr_unit')!r}; optcal reads imucal gyroscopes calibrated to deg/s")
    KR = matrix3(d.get("K_g"), "K_g", path) @ matrix3(d.get("R_g"), "R_g", path)
    K_ga = matrix3(d.get("K_ga"), "K_ga", path)
    b_g = matrix3(d.get("b_g"), "b_g", path, (3,))
    C = KR / RAD_PER_DEG  # diag(K)·T
    K = np.diag(C).copy()
    if np.any(K == 0):
        raise InputError(f"{path}: a gyroscope axis does not sense its own rate (a zero diagonal of K_g·R_g)")
    return imported_block(K, C / K[:, None], b_g / K, K_ga * G0 / K[:, None], units, fmt="imucal", source=path)
