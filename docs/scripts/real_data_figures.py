"""The figures and numbers of docs/real_data.md for the recordings of the corpus that the ``--plot``
commands there do not draw: imucal's labelled session, imu_tk's Xsens MTi, Hassan & Bao's smartphone and
their 24- and 49-position sets (tests/data/, each folder with its licence and README).

    .venv/bin/python docs/scripts/real_data_figures.py [--real tests/data] [--figures docs/figures]

Prints, per recording, the positions found, the fitted parameters with standard errors (K in output units
per g, b in g, S in rad; docs/design.md §2, §3.1), the residual RMS and the noise floor (the RMS over
positions of the standard error of a position's mean, input-referred), and writes real_imucal_annotated.png,
real_imu_tk_xsens.png, real_hassan_bao_phone.png and real_hassan_bao_positions.png at 100 dpi.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from optcal.fit import calibrate
from optcal.plots import save_figure
from optcal.plots.recording import recording_figure
from optcal.recording import choose_threshold, label_intervals, positions_from_recording, read_recording
from optcal.recording.positions import mat_positions

ROOT = Path(__file__).resolve().parents[2]
G0 = 9.80665
DPI = 100


def floor_g(data, K) -> float | None:
    se = data.noise_of_mean()
    return None if se is None else float(np.sqrt(np.mean((se / K) ** 2)))


def report(name: str, data, cal) -> None:
    """The numbers the page quotes: positions, parameters ± SE with units, residual against the floor."""
    units = data.units
    print(f"== {name}: {len(data)} positions, model {cal.model.name}, g_local {cal.problem.g_local:.6f} g")
    for n, v, s in zip(cal.model.names, cal.x, cal.stderr):
        unit = f"{units} per g" if n.startswith("K_") else ("g" if n.startswith("b_") else "rad")
        print(f"  {n:5s} {v:14.7g} ± {s:.3g} {unit}")
    off = cal.x[:3] * cal.x[3:6]
    print(f"  offsets K·b: {', '.join(f'{o:.6g}' for o in off)} {units}")
    fl = floor_g(data, cal.x[:3])
    print(f"  residual RMS {cal.fit.rms_g * 1e6:.1f} µg" + (f", noise floor {fl * 1e6:.1f} µg, ratio "
                                                          f"{cal.fit.rms_g / fl:.2f}" if fl else ", no noise floor"))


def raw_figure(name: str, rec, det, model: str, g_local: float, out: Path) -> None:
    data = positions_from_recording(rec, det)
    cal = calibrate(data, model, g_local=g_local)
    report(name, data, cal)
    save_figure(recording_figure(rec, det, cal.problem.residuals_full(cal.x)[0]), out, dpi=DPI)
    print(f"  wrote {out}")


def positions_figure(sets: dict, out: Path) -> None:
    from matplotlib.figure import Figure

    fig = Figure(figsize=(10, 2.4 * len(sets)), layout="constrained")
    axes = fig.subplots(len(sets), 1)
    for ax, (name, data) in zip(np.atleast_1d(axes), sets.items()):
        cal = calibrate(data, "linear9")
        report(name, data, cal)
        r = cal.problem.residuals_full(cal.x)[0]
        ax.bar(np.arange(1, len(r) + 1), r * 1e6, color="tab:blue")
        ax.axhline(0, color="k", lw=0.5)
        ax.set_ylabel("residual [µg]")
        ax.set_title(f"{name}: linear9, {len(r)} positions, residual RMS {cal.fit.rms_g * 1e6:.0f} µg", fontsize=9)
    np.atleast_1d(axes)[-1].set_xlabel("position (file order)")
    save_figure(fig, out, dpi=DPI)
    print(f"  wrote {out}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--real", type=Path, default=ROOT / "tests" / "data")
    ap.add_argument("--figures", type=Path, default=ROOT / "docs" / "figures")
    a = ap.parse_args()
    real, figs = a.real, a.figures

    rec = read_recording(real / "imucal" / "annotated_session.csv", columns="acc_x,acc_y,acc_z", rate=204.8,
                         units="counts", labels="part")
    det = label_intervals(rec, ["x_p", "x_a", "y_p", "y_a", "z_p", "z_a"])
    raw_figure("imucal annotated_session", rec, det, "diag6", 9.81 / G0, figs / "real_imucal_annotated.png")

    g_xsens = 9.81744 / G0  # imu_tk's test_imu_calib.cpp sets this gravity for the recording
    rec = read_recording(real / "imu_tk" / "xsens_acc.mat.gz", units="counts")
    raw_figure("imu_tk Xsens MTi", rec, choose_threshold(rec, "linear9", g_local=g_xsens), "linear9", g_xsens,
               figs / "real_imu_tk_xsens.png")

    rec = read_recording(real / "hassan_bao" / "MobileAccData30orientationRawSample01.mat", rate=50.0,
                         units="m/s2")
    raw_figure("Hassan & Bao smartphone (50 Hz assumed)", rec, choose_threshold(rec, "linear9"), "linear9", 1.0,
               figs / "real_hassan_bao_phone.png")

    hb = real / "hassan_bao"
    sets = {f"Hassan & Bao, {n} positions": mat_positions(hb / f"CalibrationOfLowCostTriaxialInertialSensors{s}.mat")
            for n, s in ((24, ""), (49, "50"))}
    positions_figure(sets, figs / "real_hassan_bao_positions.png")


if __name__ == "__main__":
    main()
