"""The figures and numbers of docs/real_data.md for the recordings of the corpus that the ``--plot``
commands there do not draw: imucal's labelled session, imu_tk's Xsens MTi, Hassan & Bao's smartphone and
their 24- and 49-position sets, Mikov et al.'s five MPU-9150s, CK-Explorer's 160 one-second poses,
TWLogger's LSM303 tag and sensor-fusion's two MPU-6050 tumbles (the real corpus, each folder with its licence
and README; ``--real`` defaults to tests/corpus.py's folder: ``OPTCAL_CORPUS``, else the shared folder beside
the clone).

    .venv/bin/python docs/scripts/real_data_figures.py [--real DIR] [--figures docs/figures]

Prints, per recording, the positions found, the fitted parameters with standard errors (K in output units
per g, b in g, S in rad; docs/design.md §2, §3.1), the residual RMS and the noise floor (the RMS over
positions of the standard error of a position's mean, input-referred), and writes real_imucal_annotated.png,
real_imu_tk_xsens.png, real_hassan_bao_phone.png, real_hassan_bao_positions.png, real_mikov.png,
real_mikov_imu0.png, real_ck_explorer.png, real_twlogger.png and (when h5py is installed: it reads the MATLAB
v7.3 files, which optcal does not) real_sensor_fusion.png at 100 dpi. The default command's outcome on the
new recordings (the model it fits, or its one-line refusal) is printed as ``optcal.calibrate`` gives it.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from optcal.app import api
from optcal.app.fit import calibrate
from optcal.app.workflows.recording import choose_threshold
from optcal.core.errors import InputError
from optcal.core.plots import save_figure
from optcal.core.plots.recording import recording_figure
from optcal.core.recording import given_intervals, label_intervals, positions_from_recording, read_recording
from optcal.core.recording.positions import mat_positions

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tests"))
from corpus import corpus_root  # noqa: E402  tests/corpus.py: the real corpus's folder (OPTCAL_CORPUS or beside the clone)

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
        unit = (f"{units} per g" if n.startswith("K_") else f"{units} per g²" if n.startswith("K2_")
                else "g" if n.startswith("b_") else "rad")
        print(f"  {n:5s} {v:14.7g} ± {s:.3g} {unit}")
    off = cal.x[:3] * cal.x[3:6]
    print(f"  offsets K·b: {', '.join(f'{o:.6g}' for o in off)} {units}")
    fl = floor_g(data, cal.x[:3])
    print(f"  residual RMS {cal.fit.rms_g * 1e6:.1f} µg" + (f", noise floor {fl * 1e6:.1f} µg, ratio "
                                                          f"{cal.fit.rms_g / fl:.2f}" if fl else ", no noise floor"))


def raw_figure(name: str, rec, det, model: str, g_local: float, out: Path, force_weak: bool = False) -> None:
    data = positions_from_recording(rec, det)
    cal = calibrate(data, model, g_local=g_local, force_weak=force_weak)
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
    ap.add_argument("--real", type=Path, default=corpus_root())
    ap.add_argument("--figures", type=Path, default=ROOT / "docs" / "figures")
    a = ap.parse_args()
    real, figs = a.real, a.figures

    rec = read_recording(real / "imucal" / "annotated_session.csv", columns="acc_x,acc_y,acc_z", rate=204.8,
                         units="counts", labels="part")
    det = label_intervals(rec, ["x_p", "x_a", "y_p", "y_a", "z_p", "z_a"])
    # six poses, six parameters: an exact fit, which optcal writes only when forced
    raw_figure("imucal annotated_session", rec, det, "diag6", 9.81 / G0, figs / "real_imucal_annotated.png",
               force_weak=True)

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

    mikov_figures(real / "mikov", figs)
    ck_figure(real / "ck_explorer" / "acc_log.csv", figs / "real_ck_explorer.png")
    twlogger_figure(real / "twlogger", figs / "real_twlogger.png")
    sensor_fusion_figure(real / "sunsided", figs / "real_sensor_fusion.png")


def default_command(name: str, path: Path, **reading):
    """``optcal calibrate PATH --raw ...`` without --model: the calibration, or None and its refusal."""
    try:
        cal = api.calibrate(path, raw=True, **reading)
    except InputError as exc:
        print(f"== {name}: default command refused: {exc}")
        return None
    report(f"{name} (default command)", cal.problem.data, cal)
    return cal


def _sensitivity(p: dict):
    """Scale factors (row norms of diag(K)·T), output offsets K·b and the cosines of the angles between the
    sensitive axes (x,y), (x,z), (y,z): the gauge-free quantities tests/test_corpus_wild.py compares."""
    T = np.eye(3)
    T[1, 0], T[2, 0], T[2, 1] = p.get("S_yz", 0.0), p.get("S_zy", 0.0), p.get("S_zx", 0.0)
    K = np.array([p["K_x"], p["K_y"], p["K_z"]])
    M = K[:, None] * T
    n = np.linalg.norm(M, axis=1)
    C = (M / n[:, None]) @ (M / n[:, None]).T
    return n, K * np.array([p["b_x"], p["b_y"], p["b_z"]]), np.array([C[0, 1], C[0, 2], C[1, 2]])


# Mikov et al.'s table (the corpus's mikov/README.md): s (%), m_yz, m_xy, m_xz (°), b (m/s²) per IMU
MIKOV = [([0.363, 0.315, 0.647], [0.123, 0.02, 0.317], [0.103, 0.097, 0.344]),
         ([0.471, 0.482, 0.932], [-0.284, -0.01, 0.145], [0.09, 0.07, 0.338]),
         ([0.382, 0.355, 0.78], [0.26, -0.012, 0.282], [0.096, 0.008, -0.045]),
         ([0.263, 0.448, 0.721], [-0.009, -0.028, -0.104], [0.065, 0.092, -0.009]),
         ([0.251, 0.286, 0.804], [0.056, 0.0, 0.191], [0.07, 0.036, 0.182])]


def mikov_figures(folder: Path, figs: Path) -> None:
    """The default command on the five MPU-9150s against the source's table: scale errors (%), the angles
    between the sensitive axes as their table's m_yz, m_xy, m_xz (°, the arcsine of the cosines) and
    the biases (m/s²)."""
    from matplotlib.figure import Figure

    g = 9.81 / G0  # their code's |g|
    ours = []
    for i in range(5):
        cal = default_command(f"Mikov et al. imu{i}", folder / f"imu{i}.log.gz", units="m/s2", rate=100.0,
                              columns="ax=0,ay=1,az=2", g_local=g)
        p = dict(zip(cal.model.names, cal.x))
        scale, off, cos = _sensitivity(p)
        s = (scale / G0 - 1) * 100
        m = np.degrees(np.arcsin(cos[[2, 0, 1]]))  # (y,z), (x,y), (x,z): their m_yz, m_xy, m_xz
        ds, dm, db = s - MIKOV[i][0], m - MIKOV[i][1], off - MIKOV[i][2]
        print(f"  vs their table: scale {np.round(ds, 4)} %-points, angles {np.round(dm, 4)} °, "
              f"biases {np.round(db, 4)} m/s²")
        ours.append((s, m, off))
        if i == 0:
            det = cal.problem.data.extra["detection"]
            rec = read_recording(folder / "imu0.log.gz", units="m/s2", rate=100.0, columns="ax=0,ay=1,az=2")
            save_figure(recording_figure(rec, det, cal.problem.residuals_full(cal.x)[0]),
                        figs / "real_mikov_imu0.png", dpi=DPI)
            print(f"  wrote {figs / 'real_mikov_imu0.png'}")
    fig = Figure(figsize=(10, 2.8), layout="constrained")
    axes = fig.subplots(1, 3)
    titles = ("scale error s [%]", "non-orthogonality m_yz, m_xy, m_xz [°]", "bias b [m/s²]")
    for k, (ax, title) in enumerate(zip(axes, titles)):
        for j, c in enumerate(("tab:blue", "tab:orange", "tab:green")):
            x = np.arange(5) + (j - 1) * 0.2
            ax.plot(x, [MIKOV[i][k][j] for i in range(5)], "o", mfc="none", color=c, ms=7)
            ax.plot(x, [ours[i][k][j] for i in range(5)], ".", color=c, ms=6)
        ax.set_title(title, fontsize=9)
        ax.set_xticks(range(5), [f"#{i + 1}" for i in range(5)])
        ax.grid(alpha=0.3)
    axes[0].plot([], [], "ko", mfc="none", label="their table")
    axes[0].plot([], [], "k.", label="optcal, default command")
    axes[0].legend(fontsize=8)
    save_figure(fig, figs / "real_mikov.png", dpi=DPI)
    print(f"  wrote {figs / 'real_mikov.png'}")


def ck_figure(path: Path, out: Path) -> None:
    """The default command (rate assumed 100 Hz), then the reference: nonlinear12 on the 160 blocks of 100
    samples the logger wrote, drawn with those blocks as the intervals."""
    default_command("CK-Explorer acc_log (100 Hz assumed)", path, units="g", rate=100.0)
    rec = read_recording(path, units="g", rate=100.0)
    blocks = np.column_stack([np.arange(0, len(rec), 100), np.arange(100, len(rec) + 1, 100)])
    raw_figure("CK-Explorer, the 160 logger blocks (reference)", rec, given_intervals(rec, blocks), "nonlinear12",
               1.0, out)


def twlogger_figure(folder: Path, out: Path) -> None:
    """The tag's outputs in g (4080 counts per g) with the poses a linear9 threshold search holds, and each
    held pose's direction: the x component never leaves ±0.33."""
    from matplotlib.figure import Figure

    path = folder / "T1D0711-00.CSV.gz"
    cols = "t=Timestamp(Ms),ax=ACCELX,ay=ACCELY,az=ACCELZ"
    g = 9.81 / G0
    default_command("TWLogger (columns named)", path, units="counts", columns=cols, g_local=g)
    rec = read_recording(path, units="counts", columns=cols)
    det = choose_threshold(rec, "diag6", g_local=g)
    data = positions_from_recording(rec, det)
    u = data.N / np.linalg.norm(data.N, axis=1, keepdims=True)
    print(f"== TWLogger: {len(data)} held poses; direction components x {u[:, 0].min():+.2f}…{u[:, 0].max():+.2f}, "
          f"y {u[:, 1].min():+.2f}…{u[:, 1].max():+.2f}, z {u[:, 2].min():+.2f}…{u[:, 2].max():+.2f}")
    cal = np.genfromtxt(folder / "Tag1_LSM303cal.csv", delimiter=",", names=True)
    norms = np.linalg.norm(data.N * cal["AccPoly1"] + cal["AccPoly2"], axis=1)
    print(f"  the source's calibration on those poses: |a| = {norms.mean():.3f} ± {norms.std():.3f} m/s² "
          f"({norms.min():.2f} to {norms.max():.2f})")
    fig = Figure(figsize=(11, 4.6), layout="constrained")
    ax, bx = fig.subplots(2, 1, gridspec_kw={"height_ratios": [3, 2]})
    step = 10
    for j, c in enumerate("xyz"):
        ax.plot(rec.t[::step], rec.N[::step, j] / 4080.0, lw=0.5, label=f"a{c}")
    for s_, e_ in det.intervals:
        ax.axvspan(rec.t[s_], rec.t[e_ - 1], color="tab:green", alpha=0.15, lw=0)
    ax.set_ylim(-2, 2)
    ax.set_ylabel("output / 4080 [g]")
    ax.set_xlabel("time [s]")
    ax.legend(fontsize=8, ncol=3, loc="upper right")
    for j, c in enumerate("xyz"):
        bx.plot(np.arange(len(u)), u[:, j], "o", ms=4, label=f"u{c}")
    bx.axhspan(-0.33, 0.33, color="0.85", lw=0)
    bx.set_ylabel("held pose direction")
    bx.set_xlabel(f"held pose ({len(u)}, diag6 threshold search)")
    bx.legend(fontsize=8, ncol=3)
    save_figure(fig, out, dpi=DPI)
    print(f"  wrote {out}")


def sensor_fusion_figure(folder: Path, out: Path) -> None:
    """The two tumbles, read with h5py (MATLAB v7.3 is HDF5), outputs and norm in g against time."""
    try:
        import h5py
    except ImportError:
        print(f"== sensor-fusion: h5py is not installed; {out.name} not drawn")
        return
    from matplotlib.figure import Figure

    fig = Figure(figsize=(11, 4.8), layout="constrained")
    axes = fig.subplots(2, 1)
    for ax, name in zip(axes, ("full_sphere", "tilt_sphere")):
        with h5py.File(folder / f"{name}_accelerometer.mat", "r") as f:
            a = np.asarray(f["accelBuffer"]).T  # t, x, y, z
        for j, c in enumerate("xyz"):
            ax.plot(a[:, 0], a[:, j + 1], lw=0.5, label=f"a{c}")
        ax.plot(a[:, 0], np.linalg.norm(a[:, 1:], axis=1), "k", lw=0.5, label="|a|")
        ax.set_title(f"{name}_accelerometer.mat: {len(a)} samples, {a[-1, 0] - a[0, 0]:.0f} s", fontsize=9)
        ax.set_ylabel("output [g]")
        ax.legend(fontsize=8, ncol=4, loc="lower right")
    axes[-1].set_xlabel("time [s]")
    save_figure(fig, out, dpi=DPI)
    print(f"  wrote {out}")


if __name__ == "__main__":
    main()
