"""The table of docs/noise.md, "The noise floor of a position": each raw recording of the real corpus
(tests/corpus.py: ``OPTCAL_CORPUS``, else the shared folder beside the clone; each folder with its licence and
README) calibrated by the default path of ``optcal calibrate --raw``
(optcal.app.workflows.recording.positions_from_raw: the default segmentation, positions; optcal.app.fit.calibrate), its
verdicts against the white-noise floor σ/√n (the old one) and against the noise floor of optcal.core.recording.floor
(the new one).

    .venv/bin/python docs/scripts/noise_floor_corpus.py [--simulate SEEDS]

With ``--simulate`` it prints instead the false-alarm table: SEEDS simulated recordings per noise (linear9
truth, scheme 24, poses of 5 s with 3 s between, 100 Hz, optcal.core.noise.colored_noise), each calibrated with the
true model through positions_from_recording and optcal.app.fit.calibrate, and the share of χ² tests that reject at
5 % against σ/√n, against the model's Allan deviation at τ = each interval's length (never below σ/√n; the
χ² test) and against the new floor (about 15 s per 200 seeds and noise).

Otherwise it prints one markdown row per recording: positions, residual RMS, the two floors (RMS over positions of each
residual's σ, input-referred, µg), residual / floor, χ²/dof with its p-value (χ² test against σ/√n; F test
against the estimated floor), the positions flagged as outliers, and the Allan deviation at τ = each
interval's length (the model's, RMS) for comparison.
"""

from __future__ import annotations

import gzip
import sys
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np
from scipy.io import loadmat

from optcal.app.fit import calibrate
from optcal.app.workflows.recording import choose_threshold, positions_from_raw
from optcal.core.analysis import goodness_of_fit, position_diagnostics
from optcal.core.errors import InputError
from optcal.core.problem import CalibrationProblem
from optcal.core.recording import positions_from_recording, read_recording

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tests"))
from corpus import corpus_root  # noqa: E402  tests/corpus.py: the real corpus's folder (OPTCAL_CORPUS or beside the clone)

DATA = corpus_root()
G0 = 9.80665


def recordings(tmp: Path):
    """(name, path, reading options, model, g_local): the corpus's raw recordings as tests/test_real_data.py and
    tests/test_corpus.py read them."""
    xsens = tmp / "xsens_acc.mat"
    xsens.write_bytes(gzip.decompress((DATA / "imu_tk" / "xsens_acc.mat.gz").read_bytes()))
    yield "imu_tk Xsens MTi", xsens, dict(units="counts", saturation=65535), "linear9", 9.81744 / G0
    yield ("imu_tk Xsens MTi, variance detector", xsens, dict(units="counts", saturation=65535), "linear9",
           9.81744 / G0)
    m = loadmat(DATA / "hassan_bao" / "MobileAccData30orientationRawSample01.mat")
    (a,) = [v for k, v in m.items() if not k.startswith("__")]
    phone = tmp / "phone.csv"
    np.savetxt(phone, a.T if a.shape[0] == 3 else a, delimiter=",", header="ax,ay,az", comments="", fmt="%.17g")
    yield "Hassan & Bao phone", phone, dict(rate=50.0, units="m/s2"), "linear9", 1.0
    yield ("ImuCalibration MPU-6050", DATA / "mpu6050" / "example_data_calibration.csv", dict(units="counts"),
           "diag6", 1.0)
    yield ("imucal Ferraris session", DATA / "imucal" / "example_ferraris_session.csv",
           dict(rate=102.4, units="m/s2"), "diag6", 1.0)


def fit(data, model, g_local):
    """The default fit; a fit the refusal rules call weak is forced (and said so) to show its verdicts."""
    try:
        return calibrate(data, model, g_local=g_local), ""
    except InputError as exc:
        return calibrate(data, model, g_local=g_local, force_weak=True), f" (weak, forced: {str(exc)[:40]}…)"


def row(name, path, reading, model, g_local) -> str:
    if name.endswith("variance detector"):  # Tedaldi's detector and the threshold search, as tests/test_noise_floor.py
        rec = read_recording(path, **reading)
        data = positions_from_recording(rec, choose_threshold(rec, model, g_local=g_local))
    else:
        data = positions_from_raw(path, **reading, model=model, g_local=g_local)
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


# (name, N in g/√Hz, B in g); flicker dominates beyond τ = N²/(0.664·B)²
NOISES = (("white only", 100e-6, 0.0), ("flicker beyond τ = 14 s", 100e-6, 40e-6),
          ("flicker beyond τ = 4 s", 100e-6, 75e-6), ("MEMS: flicker beyond τ = 1 s", 100e-6, 150e-6),
          ("flicker beyond τ = 0.09 s", 60e-6, 300e-6))


def simulated(seed: int, white: float, flicker: float):
    """One simulated recording calibrated with the true linear9 model: the new fit and the old χ² test."""
    from optcal.core.model import get_model
    from optcal.core.noise.colored import colored_noise
    from optcal.core.presets import PAPER_TRUTH
    from optcal.core.recording import given_intervals
    from optcal.core.recording.reading import Recording
    from optcal.core.schemes import scheme

    model = get_model("linear9")
    truth = model.from_dict({k: v for k, v in PAPER_TRUTH.items() if k in model.names})
    rng = np.random.default_rng(seed)
    A = scheme("24", rng)
    rate, ns, ng = 100.0, 500, 300
    n = len(A) * (ns + ng)
    K = np.abs(truth[model.groups()["scale"]])
    N = np.repeat(model.forward(truth, A)[0], ns + ng, axis=0) + K * colored_noise(n, rate, rng, white=white,
                                                                                   flicker=flicker)
    rec = Recording(t=np.arange(n) / rate, N=N, temp=None, units="g", rate=rate, saturated=np.zeros(n, bool))
    start = np.arange(len(A)) * (ns + ng)
    data = positions_from_recording(rec, given_intervals(rec, np.column_stack([start, start + ns])))
    cal = calibrate(data, model)
    old = goodness_of_fit(CalibrationProblem(model, replace(data, sem=None)), cal.x)
    fl = data.extra["noise_floor"]
    adev = goodness_of_fit(CalibrationProblem(model, replace(data, sem=np.maximum(fl.adev_at_interval, fl.white),
                                                             extra={})), cal.x)
    return cal.fit, old, fl, adev


def false_alarms(seeds: int) -> None:
    print("| noise (N µg/√Hz, B µg) | floor / (σ/√n) | rejected at 5 %: σ/√n | rejected at 5 %: σ_A(τ = T) | "
          "rejected at 5 %: new floor |")
    print("|---|---|---|---|---|")
    for name, white, flicker in NOISES:
        runs = [simulated(s, white, flicker) for s in range(seeds)]
        old = sum(o.p_value < 0.05 for _, o, _, _ in runs)
        adev = sum(a.p_value < 0.05 for _, _, _, a in runs)
        new = sum(f.p_value < 0.05 for f, _, _, _ in runs)
        ratio = np.mean([fl.ratio for _, _, fl, _ in runs])
        print(f"| {name} ({white * 1e6:g}, {flicker * 1e6:g}) | {ratio:.3g} | {old}/{seeds} | {adev}/{seeds} | "
              f"{new}/{seeds} |", flush=True)


def main() -> None:
    import argparse

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--simulate", type=int, metavar="SEEDS", help="the false-alarm table over SEEDS seeds per noise")
    args = ap.parse_args()
    if args.simulate:
        false_alarms(args.simulate)
        return
    print("| recording, model | positions | residual RMS µg | old floor σ/√n µg | new floor µg | residual / old | "
          "residual / new | χ²/dof old | χ²/dof new | outliers old | outliers new | ADEV(τ = T) µg |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for rec in recordings(Path(tmp)):
            print(row(*rec), flush=True)


if __name__ == "__main__":
    main()
