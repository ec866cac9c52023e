"""Calibration files other tools read and write: imu_tk, imucal, Kalibr and a plain affine matrix
(docs/exchange.md). Each format module converts optcal's linear part (scale, bias, misalignment; see
:mod:`optcal.exchange.common`) to the tool's matrices and units exactly, and back; what a format cannot hold
is refused, never dropped.

:func:`export_text` renders a calibration (an :class:`optcal.calfile.CalibrationFile`) in a format;
:func:`import_calibration` reads a tool's file into the dictionary of an optcal calibration file
(docs/design.md §9.3). Neither writes anything; the commands ``optcal export`` and ``optcal import`` do.
"""

from __future__ import annotations

from pathlib import Path

from ..errors import InputError

FORMATS = ("imucal", "imu_tk", "kalibr", "matrix")
# calibrated units each format can hold (the first is the default)
CALIBRATED = {"imu_tk": ("m/s2", "g"), "matrix": ("g", "m/s2"), "imucal": ("m/s2",), "kalibr": ("m/s2",)}


def _check_format(fmt: str) -> None:
    if fmt not in FORMATS:
        raise InputError(f"unknown format {fmt!r}; choose one of {', '.join(FORMATS)}")


def _calibrated(fmt: str, calibrated: str | None) -> str:
    allowed = CALIBRATED[fmt]
    if calibrated is None:
        return allowed[0]
    if calibrated not in allowed:
        raise InputError(f"the {fmt} format's calibrated output is in {' or '.join(allowed)}, not {calibrated}; "
                         "drop --calibrated-units")
    return calibrated


def export_text(cal, fmt: str, *, calibrated: str | None = None, bias_online: bool = False,
                source=None) -> tuple[str, list[str]]:
    """The text of ``cal`` (a CalibrationFile) in format ``fmt``, and notes for the user."""
    from . import common

    _check_format(fmt)
    unit = _calibrated(fmt, calibrated)
    src = "the calibration" if source is None else str(source)
    lin = common.linear_part(cal, fmt, src)
    origin = f"exported by optcal from {Path(src).name} (model {cal.model.name}, g_local {cal.g_local!r} g)"
    notes: list[str] = []
    if fmt == "imu_tk":
        from . import imu_tk

        T, K, B = imu_tk.to_imu_tk(lin, unit)
        notes.append(f"imu_tk's file states no units: raw X in {lin.units}, calibrated X' = T·K·(X − B) in {unit}")
        return imu_tk.dumps(T, K, B), notes
    if fmt == "imucal":
        from . import imucal

        info = imucal.to_imucal(lin, comment=origin + "; accelerometer only: the gyroscope terms are the identity "
                                "(K_g = R_g = I, K_ga = 0, b_g = 0, deg/s to deg/s)")
        notes.append("the gyroscope terms are the identity (optcal calibrates the accelerometer only)")
        return imucal.dumps(info), notes
    if fmt == "kalibr":
        from . import kalibr

        M, bias = kalibr.to_kalibr(lin, bias_online=bias_online)
        comment = [origin, "Kalibr's scale-misalignment model a_m = M·a + b(t), a_m and a in m/s^2; the gyroscope "
                   "terms are the identity (optcal calibrates the accelerometer only)"]
        if any(bias):
            comment.append("the calibration's constant bias, left to Kalibr's online estimate: "
                           + ", ".join(repr(float(v)) for v in bias) + " m/s^2")
            notes.append("the bias is not in the file (--bias-online): Kalibr estimates it online")
        return kalibr.dumps(M, comment), notes
    from . import matrix

    C, d = matrix.to_matrix(lin, unit)
    return matrix.dumps(C, d, lin.units, unit, cal.g_local, src), notes


def import_calibration(path, fmt: str, *, units: str | None = None, calibrated: str | None = None,
                       model: str | None = None, g_local: float | None = None) -> tuple[dict, list[str]]:
    """The optcal calibration-file dictionary of a tool's file, and notes for the user. ``units``: the raw
    units where the file does not state them (imu_tk), states a label optcal does not know (imucal), or
    are Kalibr's m/s² converted from g or mg;
    ``calibrated``: imu_tk's calibrated unit (its file does not say); ``model``: the optcal model to hold the
    result (default: the smallest exact one); ``g_local`` in g (default: the file's, else 1)."""
    from ..data import UNITS
    from . import common

    _check_format(fmt)
    if units is not None and units not in UNITS:
        raise InputError(f"unknown units {units!r}; use one of {', '.join(UNITS)}")
    notes: list[str] = []
    g_file = None
    if fmt == "imu_tk":
        from . import imu_tk

        if units is None:
            raise InputError("an imu_tk file does not state its raw units; give them with --units (g, m/s2, counts, "
                             "volts, mg)")
        T, K, B = imu_tk.loads(common.read_text(path, "imu_tk calibration"), path)
        lin = imu_tk.from_imu_tk(T, K, B, units, _calibrated(fmt, calibrated))
    elif fmt == "imucal":
        from . import imucal

        if calibrated is not None:
            raise InputError("an imucal file states its calibrated unit (acc_unit); drop --calibrated-units")
        lin, notes = imucal.from_imucal(common.read_json(path, "imucal calibration"), path, units)
    elif fmt == "kalibr":
        from . import kalibr

        _calibrated(fmt, calibrated)
        M = kalibr.loads(common.read_text(path, "Kalibr imu yaml"), path)
        lin = kalibr.from_kalibr(M, units or "m/s2")
        notes.append("Kalibr's file holds no accelerometer bias (Kalibr estimates it online): the biases are 0")
    else:
        from . import matrix

        C, d, raw, cal_units, g_file = matrix.loads(common.read_json(path, "affine-matrix"), path)
        if units is not None and units != raw:
            raise InputError(f"{path} states raw units {raw!r}; drop --units {units}")
        if calibrated is not None and calibrated != cal_units:
            raise InputError(f"{path} states calibrated units {cal_units!r}; drop --calibrated-units")
        lin = matrix.from_matrix(C, d, raw, cal_units)
    g = g_local if g_local is not None else (g_file if g_file is not None else 1.0)
    return common.calibration_dict(lin, fmt=fmt, source=path, g_local=g, model=model), notes
