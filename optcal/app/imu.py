"""The whole IMU from one recording (application layer: it runs registered solvers): the accelerometer's fit,
then the gyroscope's over the same rests and the rotations between them (``optcal imu``, ``optcal.calibrate_imu``;
docs/gyroscope.md, "The command")."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from optcal.app.workflows.gyro import GyroFit, calibrate_gyro
from optcal.core.errors import InputError
from optcal.core.gyro.analysis import GyroRefused
from optcal.core.gyro.data import GyroData


def check_imu_options(*, gyro_scale=None, gyro_bias: str = "rests", g_sensitivity: bool = False) -> None:
    """Refuse options of :func:`calibrate_imu` that cannot hold, before anything is read."""
    if g_sensitivity and gyro_bias != "fit":
        raise InputError("`g_sensitivity` needs `gyro_bias` fit: the rests' outputs hold both the bias and G")
    if gyro_scale is not None and not (np.isfinite(gyro_scale) and gyro_scale > 0):
        raise InputError(f"`gyro_scale` {gyro_scale} must be a positive number of output units per rad/s")


@dataclass
class ImuCalibration:
    """An IMU's accelerometer and gyroscope calibrated from one recording (``optcal imu``, docs/gyroscope.md, "The
    command"):
    the accelerometer's :class:`optcal.core.calibration.Calibration`, the gyroscope's :class:`GyroFit`, the gyroscope's
    rests and motions (:class:`GyroData`), the accelerometer's raw ``units`` and the notes of both fits."""

    accelerometer: object
    gyroscope: GyroFit
    data: GyroData
    units: str
    solver: str
    notes: list = field(default_factory=list)

    def gyro_block(self) -> dict:
        """The file's ``gyroscope`` block (docs/gyroscope.md, "The command")."""
        from optcal.core.gyro.calfile import gyro_block

        fit = self.gyroscope
        return gyro_block(fit.problem, fit.x, fit.stderr, solver=self.solver,
                          observability=fit.observability.to_dict(), g_test=fit.g_test, forced=fit.forced)

    def to_dict(self, source: str | None = None) -> dict:
        """The IMU calibration file's content: the accelerometer's record with the gyroscope block."""
        from optcal.core.calfile import calibration_to_dict

        return {**calibration_to_dict(self.accelerometer, units_in="g", units_out=self.units, source=source),
                "gyroscope": self.gyro_block()}

    def write(self, path, *, overwrite: bool = False, source: str | None = None) -> None:
        """Write the IMU calibration file (``optcal apply`` and ``optcal export`` read it); an existing file is
        kept unless ``overwrite``."""
        from optcal.core.jsonfile import write_json_object

        write_json_object(self.to_dict(source), path, overwrite=overwrite)


def _spans(times: np.ndarray, most: int = 6) -> str:
    """Spans (k, 2) of shown times (s) for a note: the first ``most``, "…" after them."""
    return ", ".join(f"{a:.1f}-{b:.1f} s" for a, b in times[:most]) + (" …" if len(times) > most else "")


def calibrate_imu(positions, gyro, *, model=None, solver: str = "lm", options: dict | None = None,
                  g_local: float = 1.0, seed: int = 0, budget: int | None = None, gyro_units: str,
                  gyro_scale: float | None = None, gyro_bias: str = "rests",
                  g_sensitivity: bool = False, force_weak: bool = False) -> ImuCalibration:
    """Calibrate the accelerometer from ``positions`` (found in a raw recording: their ``extra["detection"]``
    holds its rests and samples), then the gyroscope from ``gyro`` (a :class:`~optcal.core.recording.Recording`
    whose ``N`` holds the rates, at the same times) over the same rests and the rotations between them, the
    calibrated accelerometer giving each rest's gravity direction (Tedaldi et al., ICRA 2014). Poses the
    accelerometer's detection took for motion are found by the gyroscope (:func:`missed_rests`) and used for
    it, with a note. ``model`` None: the accelerometer's default with its fallback (as ``optcal calibrate``);
    ``gyro_scale``: nominal output units per rad/s (exact for deg/s and rad/s, searched for otherwise when
    None). A motion during which the gyroscope sits at a rail is left out, with a note; too few motions left
    is refused by the gyroscope's fit. ``force_weak`` keeps fits the data do not determine (either sensor),
    marked as forced, as ``optcal calibrate --force-weak`` does."""
    from optcal.app.fit import calibrate
    from optcal.core.gyro.calfile import NOMINAL_SCALE
    from optcal.core.gyro.data import MISSED_REST_MIN_S, missed_rests
    from optcal.core.gyro.recording import join_times

    check_imu_options(gyro_scale=gyro_scale, gyro_bias=gyro_bias, g_sensitivity=g_sensitivity)
    det = positions.extra.get("detection") if positions.extra else None
    if det is None:
        raise InputError("the IMU calibration needs the positions of a raw recording (its rests and samples); "
                         "read the recording as a raw one")
    acc = det.recording
    cal = calibrate(positions, model, solver=solver, options=options, g_local=g_local, seed=seed, budget=budget,
                    force_weak=force_weak)
    join_times(acc.t, gyro.t)
    F = cal.model.inverse(np.asarray(cal.x, float)[None], acc.N)[0]
    # a second file's gaps (optcal.core.gyro.recording.on_times_of), and the sample between two joined files
    # (optcal.core.recording.join), where neither sensor has one
    missing = ~np.isfinite(gyro.N).all(axis=1) | ~np.isfinite(F).all(axis=1)
    data = GyroData(acc.t, gyro.N, F, det.intervals, units=gyro_units, saturated=gyro.saturated,
                    missing=missing if missing.any() else None)
    found = missed_rests(data)
    notes = list(cal.notes)
    if len(found):  # poses the accelerometer's detection took for motion: the gyroscope is still there
        data = data.with_rests(found)
        notes.append(f"{len(found)} rest(s) the accelerometer's detection left inside motions were found by the "
                     f"gyroscope (still for {MISSED_REST_MIN_S:g} s or more) and used for the gyroscope only, at t = "
                     + _spans(np.column_stack([acc.shown_t[found[:, 0]], acc.shown_t[found[:, 1] - 1]])))
    if len(data.dropped_motions):
        notes.append(f"{len(data.dropped_motions)} motion(s) during which the gyroscope reached a rail left out of "
                     f"its fit ({data.n_motions} used), at t = {_spans(data.dropped_motions - acc.origin)}; turn "
                     "more slowly to keep them")
    if gyro.reading.get("gyro_joined"):
        notes.append(f"the gyroscope's file has its own times: {gyro.reading['gyro_joined']}")
    if len(data.gapped_motions):
        notes.append(f"{len(data.gapped_motions)} motion(s) across a gap in the samples left out of the gyroscope's "
                     f"fit ({data.n_motions} used), at t = {_spans(data.gapped_motions - acc.origin)}: a rotation "
                     "cannot be integrated over samples that are not there")
    scale = gyro_scale if gyro_scale is not None else NOMINAL_SCALE.get(gyro_units)
    try:
        fit = calibrate_gyro(data, bias=gyro_bias, g_sensitivity=g_sensitivity, scale=scale, solver=solver,
                             options=options, seed=seed, budget=budget, force_weak=force_weak)
    except InputError as exc:
        if not (len(data.dropped_motions) or len(data.gapped_motions)):
            raise
        n_out = len(data.dropped_motions) + len(data.gapped_motions)
        why = " and ".join(w for n, w in ((len(data.dropped_motions), "reach the gyroscope's rail"),
                                          (len(data.gapped_motions), "cross a gap in the samples")) if n)
        way = "; ".join(w for n, w in ((len(data.dropped_motions), "turn more slowly, or record with a wider "
                                        "gyroscope range"),
                                       (len(data.gapped_motions), "record without gaps")) if n)
        # the gates' first reason, without their way out (the motions left out are the cause)
        first = exc.refusals[0].reason if isinstance(exc, GyroRefused) else str(exc)
        raise InputError(f"{n_out} of {n_out + data.n_motions} motions {why} and are left out, and the "
                         f"{data.n_motions} left do not determine the gyroscope ({first}); {way}") from None
    return ImuCalibration(cal, fit, data, positions.units, solver, notes + fit.notes)
