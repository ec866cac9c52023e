"""The table of docs/noise.md, "The noise floor of a position": each raw recording of the real corpus
(tests/data/, each folder with its licence and README) calibrated by the default path (the threshold search of
optcal.recording, positions, optcal.fit.calibrate), its verdicts against the white-noise floor σ/√n (the old
one) and against the noise floor of optcal.noise.floor (the new one).

    .venv/bin/python docs/scripts/noise_floor_corpus.py

Prints one markdown row per recording: positions, residual RMS, the two floors (RMS over positions of each
residual's σ, input-referred, µg), residual / floor, χ²/dof with its p-value (χ² test against σ/√n; F test
against the estimated floor), the positions flagged as outliers, and the Allan deviation at τ = each
interval's length (the model's, RMS) for comparison.
"""

from __future__ import annotations

import gzip
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np
from scipy.io import loadmat

from optcal.analysis import goodness_of_fit, position_diagnostics
from optcal.errors import InputError
from optcal.fit import calibrate
from optcal.problem import CalibrationProblem
from optcal.recording import choose_threshold, positions_from_recording, read_recording

DATA = Path(__file__).resolve().parents[2] / "tests" / "data"
G0 = 9.80665


def recordings(tmp: Path):
    """(name, recording, model, g_local): the corpus's raw recordings as tests/test_real_data.py and
    tests/test_corpus.py read them."""
    xsens = tmp / "xsens_acc.mat"
    xsens.write_bytes(gzip.decompress((DATA / "imu_tk" / "xsens_acc.mat.gz").read_bytes()))
    yield ("imu_tk Xsens MTi", read_recording(xsens, units="counts", saturation=65535), "linear9", 9.81744 / G0)
    m = loadmat(DATA / "hassan_bao" / "MobileAccData30orientationRawSample01.mat")
    (a,) = [v for k, v in m.items() if not k.startswith("__")]
    phone = tmp / "phone.csv"
    np.savetxt(phone, a.T if a.shape[0] == 3 else a, delimiter=",", header="ax,ay,az", comments="", fmt="%.17g")
    yield "Hassan & Bao phone", read_recording(phone, rate=50.0, units="m/s2"), "linear9", 1.0
    yield ("ImuCalibration MPU-6050", read_recording(DATA / "mpu6050" / "example_data_calibration.csv",
                                                     units="counts"), "diag6", 1.0)
    yield ("imucal Ferraris session", read_recording(DATA / "imucal" / "example_ferraris_session.csv", rate=102.4,
                                                     units="m/s2"), "diag6", 1.0)


def fit(data, model, g_local):
    """The default fit; a fit the refusal rules call weak is forced (and said so) to show its verdicts."""
    try:
        return calibrate(data, model, g_local=g_local), ""
    except InputError as exc:
        return calibrate(data, model, g_local=g_local, force_weak=True), f" (weak, forced: {str(exc)[:40]}…)"


def row(name, rec, model, g_local) -> str:
    det = choose_threshold(rec, model, g_local=g_local)
    data = positions_from_recording(rec, det)
    cal, weak = fit(data, model, g_local)
    new = cal.fit
    old_problem = CalibrationProblem(model, replace(data, sem=None), g_local=g_local)
    old = goodness_of_fit(old_problem, cal.x)
    out_old = np.flatnonzero(position_diagnostics(old_problem, cal.x).outlier).tolist()
    out_new = np.flatnonzero(cal.diagnostics.outlier).tolist()
    floor = data.extra["noise_floor"]
    K = np.abs(cal.x[cal.model.groups()["scale"]])
    at_T = float(np.sqrt(np.mean((floor.adev_at_interval / K) ** 2))) if floor.adev_at_interval is not None else None
    U = 1e6

    def verdict(g):
        return "—" if g.chi2 is None else f"{g.chi2 / g.dof:.3g} (p = {g.p_value:.2g})"

    return (f"| {name}, {model}{weak} | {len(data)} | {new.rms_g * U:.4g} | {old.noise_g * U:.4g} | "
            f"{new.noise_g * U:.4g} | {new.rms_g / old.noise_g:.3g} | {new.rms_g / new.noise_g:.3g} | "
            f"{verdict(old)} | {verdict(new)} (ν = {new.floor_dof or float('inf'):.3g}) | "
            f"{out_old or '—'} | {out_new or '—'} | {'—' if at_T is None else f'{at_T * U:.4g}'} |")


def main() -> None:
    print("| recording, model | positions | residual RMS µg | old floor σ/√n µg | new floor µg | residual / old | "
          "residual / new | χ²/dof old | χ²/dof new | outliers old | outliers new | ADEV(τ = T) µg |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for rec in recordings(Path(tmp)):
            print(row(*rec), flush=True)


if __name__ == "__main__":
    main()
