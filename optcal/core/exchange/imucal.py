"""imucal's Ferraris calibration file (Ferraris, Grimaldi & Parvis, Sensors and Materials 7(5), 1995, as the
``imucal`` package implements it; docs/exchange.md, "imucal").

imucal's ``FerrarisCalibrationInfo`` corrects accelerometer samples as a = R_a⁻¹·K_a⁻¹·(u − b_a), a in
``acc_unit`` (m/s² for a Ferraris fit), u in ``from_acc_unit``: K_a diagonal (raw units per m/s²), R_a the
matrix whose rows are the sensitive axes' unit vectors, b_a the offset in raw units. It also holds the
gyroscope's K_g, R_g, K_ga (acceleration sensitivity) and b_g. Its JSON file (``to_json_file``, format 2.0.0)
has those arrays as nested lists plus ``cal_type`` and ``_format_version``.

From optcal's N = M·A + o (A in g): K_a·R_a = M/g0 (raw units per m/s²), so K_a = diag of the row norms of
M/g0, R_a = K_a⁻¹·M/g0 (unit rows, as imucal's own fit gives them), b_a = o. The gyroscope's fields are
:mod:`optcal.core.exchange.gyro_imucal`'s for an IMU calibration (``optcal imu``); a calibration without a
gyroscope is written with the identity (K_g = R_g = I, K_ga = 0, b_g = 0, deg/s to deg/s), which an import
reads as no gyroscope.
"""

from __future__ import annotations

import json

import numpy as np

from optcal.core.errors import InputError
from optcal.core.exchange.common import CALIBRATED_UNITS, LinearPart, matrix3, rows

FORMAT = "imucal"
CAL_TYPES = ("Ferraris", "Turntable")  # imucal's two Ferraris-equation classes
FORMAT_VERSION = "2.0.0"
# optcal's output units and imucal's unit labels (imucal's own example files call counts "a.u.").
UNIT_LABELS = {"counts": "a.u.", "m/s2": "m/s^2", "g": "g", "mg": "mg", "volts": "V"}
LABEL_UNITS = {**{v: k for k, v in UNIT_LABELS.items()}, "m/s2": "m/s2", "counts": "counts"}
ACC_UNITS = {"m/s^2": "m/s2", "g": "g"}  # imucal's calibrated acc_unit -> optcal's calibrated unit


def to_imucal(lin: LinearPart, comment: str | None = None, gyro: dict | None = None) -> dict:
    """The fields of a ``FerrarisCalibrationInfo`` for optcal's linear part (calibrated output in m/s²);
    ``gyro``: the gyroscope's fields (:func:`optcal.core.exchange.gyro_imucal.gyro_to_imucal`), else the identity."""
    Msi = np.asarray(lin.M, float) / CALIBRATED_UNITS["m/s2"]
    k = np.linalg.norm(Msi, axis=1)
    info = {
        "acc_unit": "m/s^2",
        "gyr_unit": "deg/s",
        "from_acc_unit": UNIT_LABELS[lin.units],
        "from_gyr_unit": "deg/s",
        "comment": comment,
        "K_a": rows(np.diag(k)),
        "R_a": rows(Msi / k[:, None]),
        "b_a": rows(lin.o),
        "K_g": rows(np.eye(3)),
        "R_g": rows(np.eye(3)),
        "K_ga": rows(np.zeros((3, 3))),
        "b_g": rows(np.zeros(3)),
        "cal_type": "Ferraris",
        "_format_version": FORMAT_VERSION,
    }
    if gyro is not None:
        info.update(gyro)
    return info


def dumps(info: dict) -> str:
    return json.dumps(info, indent=4) + "\n"


def from_imucal(info: dict, path, units: str | None = None) -> tuple[LinearPart, list[str]]:
    """optcal's linear part of an imucal Ferraris calibration (M = f·K_a·R_a, o = b_a, f the calibrated
    units per g of its ``acc_unit``), and notes for the user (none today; the gyroscope's fields are
    :func:`optcal.core.exchange.gyro_imucal.gyro_from_imucal`'s).
    ``units`` names the raw units when the file's ``from_acc_unit`` is missing or not one optcal knows."""
    cal_type = info.get("cal_type")
    if cal_type not in CAL_TYPES:
        raise InputError(f"{path}: cal_type {cal_type!r} is not an imucal Ferraris calibration "
                         f"({' or '.join(CAL_TYPES)})")
    version = str(info.get("_format_version") or "1")
    if version.split(".")[0] != FORMAT_VERSION.split(".")[0]:
        raise InputError(f"{path}: imucal format version {version}; optcal reads version 2 files (convert older "
                         "ones with imucal.legacy)")
    for key in ("K_a", "R_a", "b_a"):
        if info.get(key) is None:
            raise InputError(f"{path}: the accelerometer field {key} is missing")
    K = matrix3(info["K_a"], "K_a", path)
    R = matrix3(info["R_a"], "R_a", path)
    b = matrix3(info["b_a"], "b_a", path, (3,))
    acc_unit = info.get("acc_unit", "m/s^2")
    if acc_unit not in ACC_UNITS:
        raise InputError(f"{path}: acc_unit {acc_unit!r} is not one optcal converts (m/s^2 or g)")
    label = info.get("from_acc_unit")
    if units is None:
        if label not in LABEL_UNITS:
            raise InputError(f"{path}: from_acc_unit {label!r} is not a unit optcal knows; give the raw units "
                             "with --units (g, m/s2, counts, volts, mg)")
        units = LABEL_UNITS[label]
    elif label in LABEL_UNITS and LABEL_UNITS[label] != units:
        raise InputError(f"{path}: the file's raw unit is {label!r} but --units says {units!r}; drop --units")
    notes: list[str] = []
    M = CALIBRATED_UNITS[ACC_UNITS[acc_unit]] * (K @ R)
    return LinearPart(M, b, units), notes
