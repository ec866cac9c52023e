"""imucal's Ferraris calibration, gyroscope half (Ferraris, Grimaldi & Parvis, Sensors and Materials 7(5),
1995, as the ``imucal`` package implements it; the accelerometer half is :mod:`optcal.exchange.imucal`).

imucal corrects gyroscope samples as ω = R_g⁻¹·K_g⁻¹·(u − K_ga·a − b_g): ω in ``gyr_unit`` (deg/s), u in
``from_gyr_unit``, a the calibrated acceleration in m/s², K_g diagonal, R_g with the sensitive axes' unit
vectors as rows, K_ga the acceleration sensitivity, b_g the offset in raw units. From optcal's gyroscope
u = diag(K)·(T·ω_rad + b + G·f), f = a/g0 in g and ω_rad = (π/180)·ω: K_g·R_g = (π/180)·diag(K)·T, so K_g
holds the row norms and R_g the unit rows; K_ga = diag(K)·G/g0; b_g = K·b, or the rests' offset.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..gravity import G0
from ..gyro.calfile import CALIBRATED, GYRO_UNITS, GyroCalibration
from ..gyro.model import GSENS, MISALIGNMENT, get_gyro_model, param_units
from .common import matrix3

RAD_PER_DEG = np.pi / 180.0


def gyro_to_imucal(cal: GyroCalibration) -> dict:
    """imucal's gyroscope fields (K_g, R_g, K_ga, b_g as nested lists; gyr_unit deg/s)."""
    K, T, _, G = (a[0] for a in cal.model.matrices(cal.x[None]))
    C = RAD_PER_DEG * K[:, None] * T
    k = np.linalg.norm(C, axis=1)
    b_g = cal.output_offset()
    return {"K_g": np.diag(k).tolist(), "R_g": (C / k[:, None]).tolist(), "K_ga": (K[:, None] * G / G0).tolist(),
            "b_g": [float(v) for v in b_g], "gyr_unit": "deg/s"}


def gyro_from_imucal(d: dict, units: str, path) -> dict:
    """The ``gyroscope`` block of the gyroscope fields of an imucal file ``d`` (raw samples in ``units``):
    gyro21 when K_ga is not zero, else gyro12."""
    if units not in GYRO_UNITS:
        raise InputError(f"unknown gyroscope units {units!r}; use one of {', '.join(GYRO_UNITS)}")
    if d.get("gyr_unit", "deg/s") != "deg/s":
        raise InputError(f"{path}: gyr_unit {d.get('gyr_unit')!r}; optcal reads imucal gyroscopes calibrated to deg/s")
    KR = matrix3(d.get("K_g"), "K_g", path) @ matrix3(d.get("R_g"), "R_g", path)
    K_ga = matrix3(d.get("K_ga"), "K_ga", path)
    b_g = np.asarray(d.get("b_g"), float).reshape(3)
    C = KR / RAD_PER_DEG  # diag(K)·T
    K = np.diag(C).copy()
    if np.any(K == 0):
        raise InputError(f"{path}: a gyroscope axis does not sense its own rate (a zero diagonal of K_g·R_g)")
    T = C / K[:, None]
    model = get_gyro_model(bool(np.any(K_ga != 0)))
    v = {f"K_{a}": float(K[i]) for i, a in enumerate("xyz")}
    v.update({n: float(T["xyz".index(n[2]), "xyz".index(n[3])]) for n in MISALIGNMENT})
    v.update({f"b_{a}": float(b_g[i] / K[i]) for i, a in enumerate("xyz")})
    G = K_ga * G0 / K[:, None]
    v.update({n: float(G["xyz".index(n[2]), "xyz".index(n[3])]) for n in GSENS})
    return {"model": model.name, "terms": list(model.terms), "bias_mode": "fit",
            "parameters": {n: v[n] for n in model.names},
            "units": {"raw": units, "calibrated": CALIBRATED,
                      "parameters": {n: u for n, u in param_units(units).items() if n in model.names}}}
