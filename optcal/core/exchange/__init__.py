"""Calibration files other tools read and write: imu_tk, imucal, Kalibr and a plain affine matrix
(docs/exchange.md). Each format module converts optcal's linear part (scale, bias, misalignment; see
:mod:`optcal.core.exchange.common`) to the tool's matrices and units exactly, and back; the ``gyro_*`` modules
do the same for the gyroscope of an IMU file (``optcal imu``, :mod:`optcal.core.gyro.calfile`). What a format
cannot hold is refused, never dropped.

:func:`export_files` renders a calibration (an :class:`optcal.core.calfile.CalibrationFile`) in a format: one
text, and imu_tk's second file for the gyroscope (:func:`export_text` when there is one file);
:func:`import_calibration` reads a tool's file (and imu_tk's gyroscope file) into the dictionary of an
optcal calibration file (docs/design.md, "Calibration file"). None writes anything; the commands ``optcal export`` and
``optcal import`` do.
"""

from __future__ import annotations

from pathlib import Path

from optcal.core.errors import InputError

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


def _gyroscope(cal, source, accelerometer_only: bool):
    """The calibration's gyroscope (:class:`optcal.core.gyro.calfile.GyroCalibration`), or None without one (or
    when the caller exports the accelerometer alone)."""
    if accelerometer_only or not isinstance(cal.meta.get("gyroscope"), dict):
        return None
    from optcal.core.gyro.calfile import read_gyro_block

    return read_gyro_block(cal.meta, source)


def export_files(cal, fmt: str, *, calibrated: str | None = None, bias_online: bool = False, source=None,
                 noise: dict | None = None, accelerometer_only: bool = False) -> tuple[str, str | None, list[str]]:
    """The text of ``cal`` (a CalibrationFile) in format ``fmt``; the text of imu_tk's gyroscope file when
    ``cal`` has a gyroscope and ``fmt`` is imu_tk (else None); and notes for the user. The gyroscope of an IMU
    file goes with it (imucal and Kalibr hold both sensors in one file) unless ``accelerometer_only``; the
    matrix format, which holds one affine map, refuses it. ``noise``: Kalibr's noise fields
    (:func:`optcal.core.exchange.kalibr.load_noise`), kalibr only."""
    from optcal.core.exchange import common

    _check_format(fmt)
    unit = _calibrated(fmt, calibrated)
    src = "the calibration" if source is None else str(source)
    if noise is not None and fmt != "kalibr":
        raise InputError(f"`noise` fields belong to Kalibr's imu.yaml; the {fmt} format has none: drop `noise`")
    lin = common.linear_part(cal, fmt, src)
    gyro = _gyroscope(cal, src, accelerometer_only)
    origin = f"exported by optcal from {Path(src).name} (model {cal.model.name}, g_local {cal.g_local!r} g)"
    notes: list[str] = []
    if fmt == "imu_tk":
        from optcal.core.exchange import imu_tk

        T, K, B = imu_tk.to_imu_tk(lin, unit)
        notes.append(f"imu_tk's file states no units: raw X in {lin.units}, calibrated X' = T·K·(X − B) in {unit}")
        gyro_text = None
        if gyro is not None:
            from optcal.core.exchange.gyro_imu_tk import gyro_to_imu_tk

            gyro_text = imu_tk.dumps(*gyro_to_imu_tk(gyro))
            notes.append(f"imu_tk's gyroscope file states no units: raw W in {gyro.units_raw}, calibrated "
                         "ω = T·K·(W − B) in rad/s")
        return imu_tk.dumps(T, K, B), gyro_text, notes
    if fmt == "imucal":
        from optcal.core.exchange import imucal

        if gyro is None:
            fields = None
            comment = origin + ("; accelerometer only: the gyroscope terms are the identity (K_g = R_g = I, "
                                "K_ga = 0, b_g = 0, deg/s to deg/s)")
            notes.append("the gyroscope terms are the identity (" + ("--accelerometer-only)"
                         if accelerometer_only else "the calibration has no gyroscope)"))
        else:
            from optcal.core.exchange.gyro_imucal import gyro_to_imucal

            fields = gyro_to_imucal(gyro)
            comment = origin + f"; gyroscope model {gyro.model.name}, raw in {gyro.units_raw}, calibrated to deg/s"
        return imucal.dumps(imucal.to_imucal(lin, comment=comment, gyro=fields)), None, notes
    if fmt == "kalibr":
        from optcal.core.exchange import kalibr

        M, bias = kalibr.to_kalibr(lin, bias_online=bias_online)
        comment = [origin, "Kalibr's scale-misalignment model a_m = M·a + b(t), a_m and a in m/s^2"]
        if any(bias):
            comment.append("the calibration's constant bias, left to Kalibr's online estimate: "
                           + ", ".join(repr(float(v)) for v in bias) + " m/s^2")
            notes.append("the bias is not in the file (--bias-online): Kalibr estimates it online")
        intrinsics = None
        if gyro is None:
            comment.append("the gyroscope terms are the identity (the calibration has no gyroscope" +
                           (", or it was left out)" if accelerometer_only else ")"))
        else:
            from optcal.core.exchange.gyro_kalibr import RAD_PER_UNIT, gyro_to_kalibr

            intrinsics = gyro_to_kalibr(gyro, bias_online=bias_online)
            comment.append(f"gyroscope (model {gyro.model.name}, raw in {gyro.units_raw}): w_m = M·C_gyro_i·w + "
                           "A·a + b_g(t), w_m and w in rad/s, A in (rad/s)/(m/s^2)")
            offset = RAD_PER_UNIT[gyro.units_raw] * gyro.output_offset()
            if any(offset):
                comment.append("the gyroscope's constant offset, left to Kalibr's online estimate: "
                               + ", ".join(repr(float(v)) for v in offset) + " rad/s")
                notes.append("the gyroscope's offset is not in the file (--bias-online): Kalibr estimates it online")
        if noise is None:
            notes.append("Kalibr's imu.yaml also needs the noise densities (`noise`: optcal noise --kalibr-yaml) "
                         "and rostopic")
        else:
            comment.append("noise densities from optcal noise (white noise density and bias random walk, SI)")
            notes.append("Kalibr's imu.yaml also needs rostopic")
        return kalibr.dumps(M, comment, gyro=intrinsics, noise=noise), None, notes
    if gyro is not None:
        raise InputError(f"{src} has a gyroscope, and the matrix format holds one affine map (the accelerometer's); "
                         "export both sensors with imu_tk, imucal or kalibr, or pass `accelerometer_only`")
    from optcal.core.exchange import matrix

    C, d = matrix.to_matrix(lin, unit)
    return matrix.dumps(C, d, lin.units, unit, cal.g_local, src), None, notes


def export_text(cal, fmt: str, **options) -> tuple[str, list[str]]:
    """The text of ``cal`` in format ``fmt`` and notes (:func:`export_files`'s options), when it is one file:
    imu_tk's second file for a gyroscope is refused here (use :func:`export_files`)."""
    text, gyro_text, notes = export_files(cal, fmt, **options)
    if gyro_text is not None:
        raise InputError("the calibration has a gyroscope, which imu_tk keeps in a second file: use export_files "
                         "(optcal export --gyro-output), or pass `accelerometer_only`")
    return text, notes


def import_calibration(path, fmt: str, *, units: str | None = None, calibrated: str | None = None,
                       model: str | None = None, g_local: float | None = None, gyro=None,
                       gyro_units: str | None = None) -> tuple[dict, list[str]]:
    """The optcal calibration-file dictionary of a tool's file, and notes for the user. ``units``: the raw
    units where the file does not state them (imu_tk), states a label optcal does not know (imucal), or
    are Kalibr's m/s² converted from g or mg; ``calibrated``: imu_tk's calibrated unit (its file does not say);
    ``model``: the optcal model to hold the result (default: the smallest exact one); ``g_local`` in g (default: the
    file's, else 1). The gyroscope:
    imucal and Kalibr files hold it (imported unless it is the identity optcal writes without one), imu_tk
    keeps it in a second file, ``gyro``; ``gyro_units`` its raw units (imu_tk: required; imucal: where its
    label is unknown; Kalibr: rad/s by default, deg/s if Kalibr's rad/s were converted from those). The
    gyroscope's bias is its whole output offset (b = offset / K, no ``offset_raw``)."""
    from optcal.core.data import UNITS
    from optcal.core.exchange import common
    from optcal.core.gyro.calfile import GYRO_UNITS

    _check_format(fmt)
    if units is not None and units not in UNITS:
        raise InputError(f"unknown units {units!r}; use one of {', '.join(UNITS)}")
    if gyro_units is not None and gyro_units not in GYRO_UNITS:
        raise InputError(f"unknown gyroscope units {gyro_units!r}; use one of {', '.join(GYRO_UNITS)}")
    if gyro is not None and fmt != "imu_tk":
        raise InputError(f"`gyro` names imu_tk's second file; the {fmt} format "
                         + ("holds the gyroscope in its one file" if fmt != "matrix" else "has no gyroscope")
                         + ": drop `gyro`")
    if gyro_units is not None and (fmt == "matrix" or (fmt == "imu_tk" and gyro is None)):
        raise InputError("`gyro_units` applies to a gyroscope, and " + ("the matrix format has none"
                         if fmt == "matrix" else "no imu_tk gyroscope file is given (`gyro`)") + "; drop it")
    notes: list[str] = []
    g_file = None
    block = None
    if fmt == "imu_tk":
        from optcal.core.exchange import imu_tk

        if units is None:
            raise InputError("an imu_tk file does not state its raw units; give them with --units (g, m/s2, counts, "
                             "volts, mg)")
        T, K, B = imu_tk.loads(common.read_text(path, "imu_tk calibration"), path)
        lin = imu_tk.from_imu_tk(T, K, B, units, _calibrated(fmt, calibrated))
        if gyro is not None:
            from optcal.core.exchange.gyro_imu_tk import gyro_from_imu_tk

            if gyro_units is None:
                raise InputError("an imu_tk gyroscope file does not state its raw units; give them with `gyro_units` "
                                 f"({', '.join(GYRO_UNITS)})")
            block = gyro_from_imu_tk(*imu_tk.loads(common.read_text(gyro, "imu_tk gyroscope calibration"), gyro),
                                     gyro_units, source=gyro)
    elif fmt == "imucal":
        from optcal.core.exchange import gyro_imucal, imucal

        if calibrated is not None:
            raise InputError("an imucal file states its calibrated unit (acc_unit); drop --calibrated-units")
        info = common.read_json(path, "imucal calibration")
        lin, notes = imucal.from_imucal(info, path, units)
        if not gyro_imucal.is_identity(info):
            block = gyro_imucal.gyro_from_imucal(info, gyro_imucal.gyro_units_of(info, gyro_units, path), path)
        elif gyro_units is not None:
            raise InputError(f"{path}: the gyroscope terms are the identity (no gyroscope calibration); drop "
                             "`gyro_units`")
    elif fmt == "kalibr":
        from optcal.core.exchange import gyro_kalibr, kalibr

        _calibrated(fmt, calibrated)
        entry = kalibr.load_entry(common.read_text(path, "Kalibr imu yaml"), path)
        lin = kalibr.from_kalibr(kalibr.acc_loads(entry, path), units or "m/s2")
        notes.append("Kalibr's file holds no accelerometer bias (Kalibr estimates it online): the biases are 0")
        intrinsics = kalibr.gyro_loads(entry, path)
        if intrinsics is not None and not gyro_kalibr.is_identity(*intrinsics):
            block = gyro_kalibr.gyro_from_kalibr(*intrinsics, gyro_units or "rad/s", source=path)
            notes.append("nor any gyroscope bias: the gyroscope's biases are 0")
        elif gyro_units is not None:
            raise InputError(f"{path}: the gyroscope is the identity (no gyroscope calibration); drop `gyro_units`")
        kept = [k for k in kalibr.NOISE_FIELDS if k in entry]
        if kept:
            notes.append(f"the file's noise fields ({', '.join(kept)}) are not kept: an optcal calibration file "
                         "holds no noise model")
    else:
        from optcal.core.exchange import matrix

        C, d, raw, cal_units, g_file = matrix.loads(common.read_json(path, "affine-matrix"), path)
        if units is not None and units != raw:
            raise InputError(f"{path} states raw units {raw!r}; drop --units {units}")
        if calibrated is not None and calibrated != cal_units:
            raise InputError(f"{path} states calibrated units {cal_units!r}; drop --calibrated-units")
        lin = matrix.from_matrix(C, d, raw, cal_units)
    g = g_local if g_local is not None else (g_file if g_file is not None else 1.0)
    doc = common.calibration_dict(lin, fmt=fmt, source=path, g_local=g, model=model)
    if block is not None:
        doc["gyroscope"] = block
        notes.append(f"the gyroscope is imported as {block['model']} (raw in {block['units']['raw']}, calibrated "
                     "rad/s; its bias is the whole output offset)")
    return doc, notes
