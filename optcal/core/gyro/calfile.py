"""The IMU calibration file: the accelerometer's calibration record (:mod:`optcal.core.calfile`, docs/design.md,
"Calibration file") with a ``gyroscope`` block beside it.

The block: ``model`` (``gyro9``: scale and misalignment, bias from the rests; ``gyro12`` with the bias;
``gyro21`` with g-sensitivity), ``terms``, ``bias_mode`` (``rests`` or ``fit``), ``parameters`` and
``stderr`` {name: value}, ``units`` {``raw``: the gyroscope's output units, ``calibrated``: ``rad/s``,
``parameters``: {name: unit}}, ``offset_raw`` (the rests' mean output per axis, raw units, which
:meth:`GyroCalibration.apply` subtracts before the model: the bias parameters, when fitted, are the rate
bias beyond it; with the bias from the rests ``offset_spread_raw`` is its SD across the rests, the drift
the file cannot follow), ``data`` {``n_rests``, ``n_motions``, ``rms_motion_angle_rad``,
``chi2_per_dof``}, ``solver``, ``observability`` and, when it was run, ``g_sensitivity_test``. A fit kept with
``force_weak`` although the gates refused it (:func:`optcal.core.gyro.analysis.plausibility`) has ``forced`` (true) and
``forced_reasons``, as the accelerometer's record.

A block imported from another tool's file (``optcal import``, :func:`imported_block`) holds ``model``
(gyro12, or gyro21 with g-sensitivity), ``terms``, ``bias_mode`` ``fit``, ``parameters``, ``stderr`` (all
null: nothing was fitted), ``units``, ``solver`` ``import:FORMAT`` and ``source``; no ``offset_raw`` (the
bias parameters hold the whole output offset, b = offset / K), no ``data`` and no ``observability``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from optcal.core.errors import InputError
from optcal.core.gyro.model import AXES, BIAS, GSENS, MISALIGNMENT, SCALE, GyroModel, get_gyro_model, param_units
from optcal.core.ranges import range_means

GYRO_UNITS = ("counts", "deg/s", "rad/s", "volts")
CALIBRATED = "rad/s"
# deg/s or rad/s outputs have a known nominal scale (output units per rad/s); counts and volts do not. A fit more
# than 10 % from it is said in a note, beyond 10 times refused (optcal.core.gyro.analysis, docs/gyroscope.md, "The
# gates: fits refused, scales noted (issue #29)").
NOMINAL_SCALE = {"deg/s": 180.0 / math.pi, "rad/s": 1.0}


def _num(v) -> float | None:
    v = float(v)
    return v if math.isfinite(v) else None


def gyro_block(problem, x, stderr, *, solver: str, observability: dict, g_test: dict | None = None,
               forced: list | None = None) -> dict:
    """The ``gyroscope`` block of a fitted :class:`optcal.core.gyro.GyroProblem` at ``x`` with ``stderr``; ``forced``:
    the reasons a fit kept with ``force_weak`` would have been refused for (:attr:`GyroFit.forced`)."""
    model: GyroModel = problem.model
    d = problem.data
    angles = problem.motion_angles(x)
    dof = problem.n_residuals - model.n_params
    cost = float(np.sum(problem.residuals_full(x)[0] ** 2))
    out = {
        "model": model.name,
        "terms": list(model.terms),
        "bias_mode": problem.bias_mode,
        "parameters": {n: float(v) for n, v in zip(model.names, x, strict=True)},
        "stderr": {n: _num(s) for n, s in zip(model.names, stderr, strict=True)},
        "units": {"raw": d.units, "calibrated": CALIBRATED, "parameters": param_units(d.units)},
        "data": {"n_rests": d.n_rests, "n_motions": d.n_motions,
                 "rms_motion_angle_rad": float(np.sqrt(np.mean(angles**2))),
                 "chi2_per_dof": cost / dof if dof > 0 else None},
        "solver": str(solver),
        "observability": observability,
    }
    out["units"]["parameters"] = {n: out["units"]["parameters"][n] for n in model.names}
    out["offset_raw"] = [float(v) for v in problem.data.extra["offset_raw"]]
    if problem.bias_mode == "rests":
        out["offset_spread_raw"] = [float(v) for v in np.std(problem.data.rest_W + _offsets(problem), axis=0)]
    if g_test is not None:
        out["g_sensitivity_test"] = g_test
    if forced:  # written only then, so that the blocks of plausible fits read as before
        out["forced"] = True
        out["forced_reasons"] = [str(r) for r in forced]
    return out


def _offsets(problem) -> np.ndarray:
    """The rests' mean raw outputs (the debiased data hold them subtracted: add them back)."""
    off = problem.data.extra["bias_from_rests"]
    return range_means(off, problem.data.rests)


def imported_block(K, T, b, G, units: str, *, fmt: str, source=None) -> dict:
    """The gyroscope block of another tool's calibration (:mod:`optcal.core.exchange`), from the model's
    matrices (:mod:`optcal.core.gyro.model`): scale ``K`` (3,) in output units per rad/s, misalignment ``T``
    (3, 3) with unit diagonal, bias ``b`` (3,) in rad/s (the whole output offset over K) and g-sensitivity
    ``G`` (3, 3) in (rad/s)/g or None; gyro21 when G has a non-zero cell, else gyro12."""
    if units not in GYRO_UNITS:
        raise InputError(f"unknown gyroscope units {units!r}; use one of {', '.join(GYRO_UNITS)}")
    K, T, b = np.asarray(K, float).reshape(3), np.asarray(T, float).reshape(3, 3), np.asarray(b, float).reshape(3)
    G = np.zeros((3, 3)) if G is None else np.asarray(G, float).reshape(3, 3)
    if not (np.all(np.isfinite(K)) and np.all(np.isfinite(T)) and np.all(np.isfinite(b)) and np.all(np.isfinite(G))):
        raise InputError(f"the {fmt} file's gyroscope has a non-finite entry")
    model = get_gyro_model(bool(np.any(G != 0)))
    values = {n: float(K[i]) for i, n in enumerate(SCALE)}
    values.update({n: float(T[AXES.index(n[2]), AXES.index(n[3])]) for n in MISALIGNMENT})
    values.update({n: float(b[i]) for i, n in enumerate(BIAS)})
    values.update({n: float(G[AXES.index(n[2]), AXES.index(n[3])]) for n in GSENS})
    block = {"model": model.name, "terms": list(model.terms), "bias_mode": "fit",
             "parameters": {n: values[n] for n in model.names}, "stderr": {n: None for n in model.names},
             "units": {"raw": units, "calibrated": CALIBRATED,
                       "parameters": {n: u for n, u in param_units(units).items() if n in model.names}},
             "solver": f"import:{fmt}"}
    if source is not None:
        block["source"] = str(source)
    return block


def write_imu_calibration(acc_record: dict, gyro: dict, path, *, overwrite: bool = False) -> None:
    """Write the accelerometer's record (:func:`optcal.core.calfile.calibration_to_dict`) with the gyroscope block;
    an existing file is kept unless ``overwrite``."""
    from optcal.core.jsonfile import write_json_object

    write_json_object({**acc_record, "gyroscope": gyro}, path, overwrite=overwrite)


@dataclass
class GyroCalibration:
    """A gyroscope calibration read back from an IMU file; :meth:`apply` gives body rates in rad/s."""

    model: GyroModel
    x: np.ndarray
    units_raw: str
    offset_raw: np.ndarray | None  # raw units, subtracted before the model
    meta: dict

    def output_offset(self) -> np.ndarray:
        """The raw output (3,) at zero rate and zero specific force: the offset plus K·b."""
        K, _, b, _ = (a[0] for a in self.model.matrices(self.x[None]))
        return (0.0 if self.offset_raw is None else self.offset_raw) + K * b

    def apply(self, W: np.ndarray, F: np.ndarray | None = None) -> np.ndarray:
        """Body rates (n, 3) in rad/s of raw outputs ``W`` (n, 3), under specific force ``F`` (n, 3, g; needed
        with g-sensitivity)."""
        W = np.asarray(W, float)
        if self.model.g_sensitivity and F is None:
            raise InputError("this gyroscope calibration has g-sensitivity: give the accelerometer's samples too")
        F = np.zeros_like(W) if F is None else np.asarray(F, float)
        if self.offset_raw is not None:
            W = W - self.offset_raw
        return self.model.inverse(self.x, W, F)


def read_gyro_block(d: dict, path) -> GyroCalibration:
    """The gyroscope block of an IMU file's content ``d`` (already parsed); one-line InputErrors naming the
    field that is wrong."""
    g = d.get("gyroscope")
    if not isinstance(g, dict):
        raise InputError(f"{path} has no gyroscope block; calibrate the IMU with optcal imu -o")
    terms = g.get("terms")
    if not isinstance(terms, list) or not set(terms) <= {"scale", "misalignment", "bias", "g_sensitivity"}:
        raise InputError(f"{path}: gyroscope.terms {terms!r} is not a gyroscope model's terms; re-create the file "
                         "with optcal imu -o")
    model = get_gyro_model("g_sensitivity" in terms, bias="bias" in terms)
    if list(model.terms) != terms or g.get("model") != model.name:
        raise InputError(f"{path}: gyroscope.model {g.get('model')!r} does not match its terms; re-create the file")
    params = g.get("parameters")
    if not isinstance(params, dict):
        raise InputError(f"{path}: gyroscope.parameters is missing; re-create the file with optcal imu -o")
    missing = [n for n in model.names if n not in params]
    if missing:
        raise InputError(f"{path}: gyroscope parameter(s) {', '.join(missing)} are missing; re-create the file")
    x = model.vector(params)
    if not np.all(np.isfinite(x)) or np.any(x[:3] == 0):
        raise InputError(f"{path}: a gyroscope parameter is not finite or a scale factor is zero; re-create the file")
    units = g.get("units", {})
    if units.get("raw") not in GYRO_UNITS or units.get("calibrated") != CALIBRATED:
        raise InputError(f"{path}: gyroscope.units must have raw in {', '.join(GYRO_UNITS)} and calibrated "
                         f"{CALIBRATED}; re-create the file")
    offset = None
    if "offset_raw" in g or not model.bias:
        offset = np.asarray(g.get("offset_raw", []), float)
        if offset.shape != (3,) or not np.all(np.isfinite(offset)):
            raise InputError(f"{path}: gyroscope.offset_raw must be three numbers; re-create the file")
    return GyroCalibration(model, x, units["raw"], offset, g)
