"""Bad inputs, one table across every command (issue #13): each row is one command line that must end with exit
status 2, exactly one line on stderr (of at most 300 characters, issue #29) naming the problem (the row's
fragment), no traceback, and nothing written: the working folder holds the same files with the same bytes
afterwards (so no output appeared and no input was changed). A row for a case not yet handled is a strict
xfail naming the change that would fix it (none today)."""

import hashlib
import json
import shutil

import numpy as np
import pytest

from optcal.app.cli import main
from optcal.app.fit import calibrate
from optcal.core.model import get_model
from optcal.core.presets import PAPER_TRUTH
from optcal.core.schemes import random_orientations
from optcal.core.simulate import simulate

COUNTS = {"K_x": 16301.0, "K_y": 16452.0, "K_z": 16690.0, "b_x": 0.021, "b_y": -0.013, "b_z": 0.042,
          "S_yz": 2.0e-3, "S_zy": -1.5e-3, "S_zx": 1.0e-3}


def _csv(path, header, rows):
    path.write_text(",".join(header) + "\n" + "\n".join(",".join(str(v) for v in r) for r in rows) + "\n")


@pytest.fixture(scope="module")
def source(tmp_path_factory):
    """The files every row may read, made once: positions in g and in counts, calibrations fitted to them,
    raw recordings, broken positions files, truths, another tool's file and study specs."""
    d = tmp_path_factory.mktemp("inputs")
    m = get_model("nonlinear12")
    truth = {k: v for k, v in PAPER_TRUTH.items() if k in m.names}
    sim = simulate(m, truth, np.random.default_rng(1), scheme="24", noise_g=10e-6, times=True)
    sim.data.to_csv(d / "p.csv")
    (d / "truth.json").write_text(json.dumps(truth))
    (d / "empty.json").write_text("{}")
    (d / "word.json").write_text(json.dumps({**truth, "K_x": "one"}))
    fit = calibrate(sim.data, m)
    from optcal.core.calfile import write_calibration

    write_calibration(fit, d / "cal.json", units_out="g")
    lin = get_model("linear9")
    csim = simulate(lin, COUNTS, np.random.default_rng(2), scheme="24", noise_g=20e-6)
    from dataclasses import replace

    cdata = replace(csim.data, units="counts")
    cdata.to_csv(d / "pc.csv")
    write_calibration(calibrate(cdata, lin), d / "calc.json", units_out="counts")
    v3 = json.loads((d / "cal.json").read_text())
    (d / "v3.json").write_text(json.dumps({**v3, "format_version": 3}))
    # raw recordings in g: a sensor at rest in random attitudes (apply) and one long rest (noise)
    A = random_orientations(500, np.random.default_rng(3))
    np.savetxt(d / "raw_g.csv", np.column_stack([np.arange(500) / 100.0, A]), delimiter=",", header="t,ax,ay,az",
               comments="", fmt="%.10g")
    rest = np.array([0.0, 0.0, 1.0]) + 1e-4 * np.random.default_rng(4).standard_normal((6000, 3))
    np.savetxt(d / "rest.csv", np.column_stack([np.arange(6000) / 100.0, rest]), delimiter=",",
               header="t,ax,ay,az", comments="", fmt="%.10g")
    # broken positions files
    text = (d / "p.csv").read_text().splitlines()
    header, rows = text[0].split(","), [r.split(",") for r in text[1:]]
    huge = [list(r) for r in rows]
    huge[3][1] = "1e300"
    _csv(d / "huge.csv", header, huge)
    _csv(d / "zero_sd.csv", header + ["n", "sx", "sy", "sz"], [r + ["100", "0", "0", "0"] for r in rows])
    _csv(d / "neg_sd.csv", header + ["n", "sx", "sy", "sz"], [r + ["100", "-1e-4", "1e-4", "1e-4"] for r in rows])
    _csv(d / "dup.csv", header + ["ax"], [r + ["0.5"] for r in rows])
    _csv(d / "ident.csv", header, [rows[0]] * len(rows))
    nan = [list(r) for r in rows]
    nan[2][2] = "nan"
    _csv(d / "nan.csv", header, nan)
    (d / "imu_tk.txt").write_text("1 0 0\n0 1 0\n0 0 1\n\n1 0 0\n0 1 0\n0 0 1\n\n0\n0\n0\n")
    (d / "missing_key.toml").write_text('name = "x"\nruns = 2\nmodels = ["linear9"]\nschemes = ["24"]\nwhat = 1\n'
                                        '[[solvers]]\nname = "scipy-lm"\n')
    (d / "neg_seed.toml").write_text('name = "x"\nruns = 2\nseed = -1\nmodels = ["linear9"]\nschemes = ["24"]\n'
                                     '[[solvers]]\nname = "scipy-lm"\n')
    (d / "huge_runs.toml").write_text('name = "x"\nruns = 100000000\nmodels = ["linear9"]\nschemes = ["24"]\n'
                                      '[[solvers]]\nname = "scipy-lm"\n')
    (d / "notadir").mkdir()
    # data that do not determine a fit (issue #20, optcal.core.determination): 10 and 5 of the 24 positions, 12
    # random positions for nonlinear12's 12 parameters, linear9 from 10 random positions (one spare), and
    # positions of a sensor whose y axis is 10° off (a misalignment beyond ±5°)
    sim.data.subset(range(10)).to_csv(d / "p10.csv")
    sim.data.subset(range(5)).to_csv(d / "p5.csv")
    simulate(m, truth, np.random.default_rng(5), scheme="random:12", noise_g=10e-6).data.to_csv(d / "p12.csv")
    simulate(lin, {k: v for k, v in PAPER_TRUTH.items() if k in lin.names}, np.random.default_rng(6),
             scheme="random:10", noise_g=10e-6).data.to_csv(d / "l10.csv")
    simulate(lin, {**{k: v for k, v in PAPER_TRUTH.items() if k in lin.names}, "S_yz": np.radians(10.0)},
             np.random.default_rng(7), scheme="24", noise_g=10e-6).data.to_csv(d / "tilt10.csv")
    # MAT files optcal cannot read (issue #20): a compressed variable whose deflate stream is damaged (its zlib
    # checksum fails and it does not inflate in full; a checksum alone is read, with a warning), and v7.3 (HDF5)
    import io
    import struct

    from scipy.io import savemat

    buf = io.BytesIO()
    savemat(buf, {"V": sim.data.N}, do_compression=True)
    raw = bytearray(buf.getvalue())
    end = 136 + struct.unpack("<II", raw[128:136])[1]
    raw[150:end] = bytes(end - 150)
    (d / "damaged.mat").write_bytes(bytes(raw))
    # a slow continuous tumble (3 °/s for 60 s, no rest): no pose was held still (optcal.core.synthetic_recording)
    from optcal.core.synthetic_recording import tumble_recording

    tumble = tumble_recording(np.random.default_rng(8), duration_s=60.0, turn_rate_dps=3.0).recording
    np.savetxt(d / "tumble.csv", np.column_stack([tumble.t, tumble.N]), delimiter=",", header="t,ax,ay,az",
               comments="", fmt="%.10g")
    # layouts that do not say which columns are ax, ay, az: a header of other names; a positions file of five
    # columns and a recording of six without one
    np.savetxt(d / "uvw.csv", np.column_stack([np.arange(500) / 100.0, A]), delimiter=",", header="time,u,v,w",
               comments="", fmt="%.10g")
    np.savetxt(d / "five.csv", np.column_stack([np.arange(24), sim.data.N, np.ones(24)]), delimiter=",", fmt="%.10g")
    np.savetxt(d / "six_raw.csv", np.column_stack([np.arange(6000) / 100.0, rest, rest[:, :2]]), delimiter=",",
               fmt="%.10g")
    (d / "v73.mat").write_bytes(b"MATLAB 7.3 MAT-file, Platform: GLNXA64, HDF5 schema 1.00 .".ljust(116) + bytes(8)
                                + b"\x00\x02IM" + b"\x89HDF\r\n\x1a\n" + bytes(64))
    # IMU files (optcal imu's layout, issue #23): gyroscope blocks beside the accelerometer's record; a
    # gyroscope's samples whose times are half a step off the recordings'; Kalibr noise without the gyroscope's
    _imu_files(d)
    _reader_files(d, A)
    _robot_files(d)
    _new_user_files(d)
    return d


def _new_user_files(d):
    """Layouts other labs' files had (issue #29, the new users' third and fourth rounds): a headerless IMU table
    with the gyroscope first; relative stamps in ns at 1 kHz (1 Hz in µs); two files without times of different
    lengths; a recording at half the rate of another."""
    rng = np.random.default_rng(11)
    W = 0.01 * rng.standard_normal((500, 3))
    W[100:140, 0] += 1.5  # turns between the rests
    W[300:340, 1] -= 1.5
    A = np.array([0.0, 0.0, 1.0]) + 1e-3 * rng.standard_normal((500, 3))  # samples of one pose, not positions
    t = np.arange(500) / 100.0
    np.savetxt(d / "gyro_first.csv", np.column_stack([t, W, A]), delimiter=",", fmt="%.10g")
    np.savetxt(d / "rel_ns.csv", np.column_stack([np.arange(500) * 999_936.0, A]), delimiter=",",
               header="t,ax,ay,az", comments="", fmt="%.0f")
    np.savetxt(d / "acc_norate.csv", A, delimiter=",", fmt="%.10g")
    np.savetxt(d / "gyr_norate.csv", W[:300], delimiter=",", fmt="%.10g")
    np.savetxt(d / "raw_half.csv", np.column_stack([np.arange(500) / 50.0, A]), delimiter=",", header="t,ax,ay,az",
               comments="", fmt="%.10g")


def _robot_files(d):
    """Robot and drone logs optcal refuses (issue #33), written by rosbags' writer (tests/robot_logs_files.py): a
    bag without IMU messages, one with two IMU topics, one cut in half, and a ULog."""
    import robot_logs_files as R

    t_ns = R.EPOCH_NS + np.arange(300) * 10_000_000
    acc, gyro = np.tile([0.0, 0.0, 9.81], (300, 1)), np.zeros((300, 3))
    ts = R.typestore("ros1")
    chatter = [(int(s), R.serialise(ts, "ros1", ts.types["std_msgs/msg/String"](data="hi"), "std_msgs/msg/String"))
               for s in t_ns[::10]]
    R.write_bag(d / "noimu", "ros1", {"/chatter": ("std_msgs/msg/String", chatter)})
    imu1 = [(int(s), R.serialise(ts, "ros1", R.imu_message(ts, "ros1", int(s), a, g), R.IMU))
            for s, a, g in zip(t_ns, acc, gyro)]
    full = R.imu_bag(d / "two_imu", "ros1", t_ns, acc, gyro, topic="/imu0", extra={"/imu1": (R.IMU, imu1)})
    (d / "cut.bag").write_bytes(full.read_bytes()[:full.stat().st_size // 2])
    R.write_ulog(d / "x.ulg", {("sensor_combined", 0): {"timestamp": np.arange(300) * 10_000,
                                                      "accelerometer_m_s2": acc.astype(np.float32)}})


def _reader_files(d, A):
    """Files the readers refuse (issue #29, item 6): 62 columns of names no alias matches; two columns either of
    which could be ax; intervals in seconds outside the recording, and of an unknown unit; a MATLAB v7.3
    (HDF5) file holding text only."""
    names = ["time_utc", "counter"] + [f"imu{k}_ch{c}" for k in range(1, 7) for c in range(10)]
    np.savetxt(d / "wide62.csv", np.column_stack([np.arange(500) / 100.0, np.arange(500),
                                                  np.tile(A, (1, 20))]), delimiter=",", header=",".join(names),
               comments="", fmt="%.10g")
    np.savetxt(d / "two_ax.csv", np.column_stack([np.arange(500) / 100.0, A[:, :1], A]), delimiter=",",
               header="t,ax,acc_x,ay,az", comments="", fmt="%.10g")
    (d / "iv_outside.json").write_text(json.dumps({"intervals": [[0.0, 1.0], [50.0, 70.0]]}))  # rest.csv: 60 s
    (d / "iv_unit.json").write_text(json.dumps({"intervals": [[0, 100]], "unit": "ms"}))
    import h5py

    with h5py.File(d / "text73.mat", "w", userblock_size=512) as f:
        ds = f.create_dataset("note", data=np.frombuffer("hand-held".encode("utf-16-le"), np.uint16)[:, None])
        ds.attrs["MATLAB_class"] = np.bytes_("char")
    with open(d / "text73.mat", "r+b") as fh:
        fh.write((b"MATLAB 7.3 MAT-file, Platform: GLNXA64, HDF5 schema 1.00 .".ljust(116) + bytes(8)
                  + b"\x00\x02IM").ljust(512, b"\x00"))


def _imu_files(d):
    from optcal.core.exchange.common import LinearPart, calibration_dict
    from optcal.core.gyro.model import get_gyro_model

    def block(g_sensitivity, units, k):
        m = get_gyro_model(g_sensitivity)
        x = np.zeros(m.n_params)
        x[:3], x[3:9] = k, [0.01, -0.01, 0.005, 0.0, 0.002, -0.003]
        if g_sensitivity:
            x[12:] = 1e-3
        return {"model": m.name, "terms": list(m.terms), "bias_mode": "fit",
                "parameters": dict(zip(m.names, x.tolist())), "units": {"raw": units, "calibrated": "rad/s"}}

    def imu(src, name, gyro):
        (d / name).write_text(json.dumps({**json.loads(src.read_text()), "gyroscope": gyro}))

    imu(d / "cal.json", "imu_g.json", block(False, "deg/s", 180 / np.pi))  # nonlinear12 in g, deg/s gyroscope
    imu(d / "calc.json", "imu_c.json", block(False, "counts", 16.4 * 180 / np.pi))  # linear9 in counts
    imu(d / "calc.json", "imu_gs.json", block(True, "counts", 16.4 * 180 / np.pi))  # with g-sensitivity
    lin_g = d / "lin_g.json"
    lin_g.write_text(json.dumps(calibration_dict(LinearPart(np.eye(3), np.zeros(3), "g"), fmt="test", source="t")))
    imu(lin_g, "imu_lin_gc.json", block(False, "counts", 16.4 * 180 / np.pi))  # Kalibr-ready but for counts
    t = np.arange(500) / 100.0
    np.savetxt(d / "gyro_shifted.csv", np.column_stack([t + 0.005, np.zeros((500, 3))]), delimiter=",", fmt="%.10g")
    np.savetxt(d / "gyro_late.csv", np.column_stack([t + 100.0, np.zeros((500, 3))]), delimiter=",", fmt="%.10g")
    t = np.arange(6000) / 100.0
    np.savetxt(d / "rest_gyro_shifted.csv", np.column_stack([t + 0.005, np.zeros((6000, 3))]), delimiter=",",
               fmt="%.10g")
    (d / "acc_noise.yaml").write_text("accelerometer_noise_density: 1e-3\naccelerometer_random_walk: 1e-4\n")
    (d / "imu_tk_gyro.txt").write_text((d / "imu_tk.txt").read_text())
    # WitMotion-like exports (issue #29): a time-of-day column that stands still over two samples (a PC's clock),
    # and rates whose names say rad/s
    A = np.array([0.0, 0.0, 1.0]) + 1e-3 * np.random.default_rng(9).standard_normal((500, 3))  # at rest, in g
    clock = [f"12:00:{(i // 2) * 0.02:06.3f}" for i in range(500)]
    (d / "wit_clock.csv").write_text("Time,ax(g),ay(g),az(g)\n" + "".join(
        f"{c},{a[0]:.6f},{a[1]:.6f},{a[2]:.6f}\n" for c, a in zip(clock, A)))
    (d / "wit_two.csv").write_text("time,DeviceName,AccX(g),AccY(g),AccZ(g)\n" + "".join(
        f"{i / 100.0:.2f},WT901({'AB'[i % 2]}),{a[0]:.6f},{a[1]:.6f},{a[2]:.6f}\n" for i, a in enumerate(A)))
    np.savetxt(d / "wit_rad.csv", np.column_stack([np.arange(500) / 100.0, A, np.zeros((500, 3))]), delimiter=",",
               comments="", header="time,AccX(g),AccY(g),AccZ(g),gx(rad/s),gy(rad/s),gz(rad/s)", fmt="%.10g")


def row(name, argv, fragment, xfail=None):
    """One case; ``xfail`` names the change that would make it pass (a strict xfail until then)."""
    marks = () if xfail is None else pytest.mark.xfail(strict=True, reason=xfail)
    return pytest.param(argv, fragment, id=name, marks=marks)


SIM = ["simulate", "-o", "new.csv"]
CAL = ["calibrate", "p.csv"]
APPLY = ["apply", "cal.json", "raw_g.csv", "-o", "out.csv"]
INFO = ["info"]
DISC = ["discover", "p.csv", "--base", "linear9"]
NAV = ["nav", "cal.json", "--truth", "truth.json"]
NOISE = ["noise", "rest.csv"]
CASES = [
    # simulate: seeds, noise, dwell, tilt, gravity, temperatures, sizes, folders, outputs that are inputs
    row("simulate-negative-seed", SIM + ["--seed", "-1"], "--seed -1 is negative"),
    row("simulate-negative-noise", SIM + ["--noise-ug", "-5"], "--noise-ug -5"),
    row("simulate-nan-noise", SIM + ["--noise-ug", "nan"], "--noise-ug nan"),
    row("simulate-absurd-noise", SIM + ["--noise-ug", "1e7"], "noisier than gravity"),
    row("simulate-noise-in-g", SIM + ["--noise-ug", "1e-5"], "looks like a value in g"),
    row("simulate-negative-dwell", SIM + ["--dwell-s", "-10"], "--dwell-s -10"),
    row("simulate-zero-dwell", SIM + ["--dwell-s", "0"], "--dwell-s 0"),
    row("simulate-negative-tilt", SIM + ["--tilt-deg", "-1"], "--tilt-deg -1"),
    row("simulate-gravity-in-ms2", SIM + ["--gravity-g", "9.81"], "looks like m/s²"),
    row("simulate-infinite-temperature", SIM + ["--temp", "20:inf"], "°C"),
    row("simulate-memory-exhausting-scheme", SIM + ["--scheme", "random:100000000"], "more than optcal handles"),
    row("simulate-zero-positions", SIM + ["--scheme", "random:0"], "number of orientations"),
    row("simulate-unknown-scheme", SIM + ["--scheme", "25"], "unknown scheme"),
    row("simulate-missing-folder", ["simulate", "-o", "missing/x.csv"], "does not exist"),
    row("simulate-existing-output", ["simulate", "-o", "p.csv"], "--force"),
    row("simulate-output-is-truth", ["simulate", "--truth", "truth.json", "-o", "truth.json", "--force"],
        "is also an input"),
    row("simulate-two-outputs-one-file", SIM + ["--truth-out", "new.csv"], "is also an input"),
    row("simulate-arcsec-without-reference", SIM + ["--reference-error-arcsec", "5"], "with --reference"),
    row("simulate-unknown-effect-parameter", SIM + ["--effect", "cubic:K3_q=1"], "not a parameter of cubic"),
    row("simulate-empty-truth", SIM + ["--truth", "empty.json"], "truth lacks parameter"),
    row("simulate-word-in-truth", SIM + ["--truth", "word.json"], "finite numbers"),
    row("simulate-unknown-model", SIM + ["--model", "seed99"], "unknown model"),
    # calibrate: broken positions files, units, gravity, seeds, outputs, plots
    row("calibrate-huge-value", ["calibrate", "huge.csv"], "position(s) 3"),
    row("calibrate-huge-value-diag6", ["calibrate", "huge.csv", "--model", "diag6"], "position(s) 3"),
    row("calibrate-zero-sample-sds", ["calibrate", "zero_sd.csv"], "all zero"),
    row("calibrate-negative-sample-sd", ["calibrate", "neg_sd.csv"], "negative standard deviation"),
    row("calibrate-duplicate-column", ["calibrate", "dup.csv"], "'ax' 2 times"),
    row("calibrate-identical-positions", ["calibrate", "ident.csv"], "unobservable"),
    row("calibrate-nan-cell", ["calibrate", "nan.csv"], "line 4, column 'ay'"),
    row("calibrate-negative-seed", CAL + ["--seed", "-1"], "--seed -1"),
    row("calibrate-gravity-ms2-looks-like-g", CAL + ["--gravity-ms2", "1.0"], "looks like g"),
    row("calibrate-height-zero-without-latitude", CAL + ["--height", "0"], "without a latitude"),
    row("calibrate-height-without-latitude", CAL + ["--height", "100"], "without a latitude"),
    row("calibrate-latitude-out-of-range", CAL + ["--latitude", "95"], "latitude 95"),
    row("calibrate-output-is-input", CAL + ["-o", "p.csv", "--force"], "is also an input"),
    row("calibrate-missing-folder", CAL + ["-o", "missing/cal.json"], "does not exist"),
    row("calibrate-existing-output", CAL + ["-o", "cal.json"], "--force"),
    row("calibrate-plot-unknown-format-positions", CAL + ["--plot", "fig.xyz"], "suffix"),
    row("calibrate-plot-unknown-format", ["calibrate", "raw_g.csv", "--raw", "--plot", "fig.xyz"], "suffix"),
    row("calibrate-plot-missing-folder", ["calibrate", "raw_g.csv", "--raw", "--plot", "missing/fig.png"],
        "does not exist"),
    row("calibrate-counts-declared-mg", ["calibrate", "pc.csv", "--model", "linear9", "--units", "mg"],
        "looks like counts"),
    row("calibrate-unknown-units", CAL + ["--units", "furlongs"], "unknown units"),
    row("calibrate-zero-budget", CAL + ["--budget", "0"], "--budget 0"),
    row("calibrate-dwell-without-noise", CAL + ["--dwell-s", "10"], "--noise-from"),
    row("calibrate-option-without-value", CAL + ["--option", "ftol"], "KEY=VALUE"),
    row("calibrate-unknown-solver", CAL + ["--solver", "no-such-solver"], "no-such-solver"),
    # calibrate: data that do not determine the fit (issue #20), nothing written even with -o
    row("calibrate-too-few-positions-for-the-model", ["calibrate", "p10.csv", "--model", "nonlinear12", "-o",
                                                      "new.json"], "fewer than the 12 parameters of nonlinear12"),
    row("calibrate-too-few-positions-for-any-model", ["calibrate", "p5.csv", "-o", "new.json"],
        "nor any smaller model of"),
    row("calibrate-exact-fit", ["calibrate", "p12.csv", "--model", "nonlinear12", "-o", "new.json"],
        "an exact fit"),
    row("calibrate-fewer-than-3-degrees-of-freedom", ["calibrate", "l10.csv", "--model", "linear9", "-o",
                                                     "new.json"], "only 1 residual degree(s) of freedom"),
    row("calibrate-implausible-result", ["calibrate", "tilt10.csv", "--model", "linear9", "-o", "new.json"],
        "(10°) is beyond ±5°"),
    row("calibrate-mat-damaged-compressed-variable", ["calibrate", "damaged.mat", "-o", "new.json"],
        "a compressed variable is damaged"),
    row("calibrate-raw-mat-damaged-compressed-variable", ["calibrate", "damaged.mat", "--raw", "--rate", "100"],
        "a compressed variable is damaged"),
    row("calibrate-mat-v7.3", ["calibrate", "v73.mat"], "MATLAB v7.3 (HDF5)"),
    row("calibrate-continuous-motion", ["calibrate", "tumble.csv", "--raw", "-o", "new.json"],
        "a continuous motion, not held poses"),
    row("calibrate-continuous-motion-named-model", ["calibrate", "tumble.csv", "--raw", "--model", "linear9"],
        "a continuous motion, not held poses"),
    row("calibrate-raw-ambiguous-column-names", ["calibrate", "uvw.csv", "--raw"],
        "cannot tell which columns are ax, ay, az"),
    row("calibrate-raw-six-columns-without-header", ["calibrate", "six_raw.csv", "--raw"],
        "6 columns and no header; name them with --columns"),
    row("calibrate-positions-five-columns-without-header", ["calibrate", "five.csv"], "5 columns and no header"),
    # readers and messages (issue #29): long lists cut, a column or role given twice, intervals in seconds,
    # names two columns could hold, MATLAB v7.3 without a numeric matrix
    row("calibrate-raw-62-columns-not-recognised", ["calibrate", "wide62.csv", "--raw"], "… (54 more)); name them "
        "with --columns"),
    row("calibrate-raw-columns-one-column-twice", ["calibrate", "rest.csv", "--raw", "--columns", "ax=ax,ay=ax,az=az"],
        "gives column 'ax' for both ax and ay"),
    row("calibrate-raw-columns-positional-column-twice", ["calibrate", "rest.csv", "--raw", "--columns",
                                                         "t,ax,ax,az"], "gives column 'ax' for both ax and ay"),
    row("calibrate-raw-columns-one-role-twice", ["calibrate", "rest.csv", "--raw", "--columns",
                                                "ax=ax,ax=ay,ay=ay,az=az"], "gives ax more than once (ax, ay)"),
    row("calibrate-raw-two-columns-for-ax", ["calibrate", "two_ax.csv", "--raw"], "columns ax, acc_x could each be ax"),
    row("calibrate-raw-intervals-seconds-outside", ["calibrate", "rest.csv", "--raw", "--intervals", "iv_outside.json",
                                                   "-o", "new.json"], "interval 1 (50 s to 70 s) is empty or outside"),
    row("calibrate-raw-intervals-unknown-unit", ["calibrate", "rest.csv", "--raw", "--intervals", "iv_unit.json"],
        "\"unit\" 'ms' is not one of s, samples"),
    row("calibrate-raw-mat-v7.3-text-only", ["calibrate", "text73.mat", "--raw", "--rate", "100"],
        "holds no numeric matrix (variables: note)"),
    # apply: units against the calibration, options that do nothing, outputs
    row("apply-counts-calibration-to-g-data", ["apply", "calc.json", "raw_g.csv", "-o", "out.csv"], "counts"),
    row("apply-declared-units-disagree", APPLY + ["--units", "counts"], "fitted to outputs in 'g'"),
    row("apply-output-is-calibration", ["apply", "cal.json", "raw_g.csv", "-o", "cal.json", "--force"],
        "is also an input"),
    row("apply-output-is-data", ["apply", "cal.json", "raw_g.csv", "-o", "raw_g.csv", "--force"],
        "is also an input"),
    row("apply-missing-folder", ["apply", "cal.json", "raw_g.csv", "-o", "missing/out.csv"], "does not exist"),
    row("apply-existing-output", ["apply", "cal.json", "raw_g.csv", "-o", "p.csv"], "--force"),
    row("apply-detector-intervals", APPLY + ["--intervals", "truth.json"], "--intervals select static intervals"),
    row("apply-detector-window", APPLY + ["--window", "2"], "--window select static intervals"),
    row("apply-detector-threshold", APPLY + ["--threshold-k", "3"], "--threshold-k"),
    row("apply-height-without-latitude", APPLY + ["--height", "100"], "without a latitude"),
    row("apply-unknown-version", ["apply", "v3.json", "raw_g.csv", "-o", "out.csv"], "format_version 3"),
    # apply with the gyroscope (issue #23): asked for without a gyroscope block, columns missing, times disagree
    row("apply-gyro-units-contradict-names", ["apply", "imu_g.json", "wit_rad.csv", "-o", "out.csv"],
        "wit_rad.csv: the gyroscope's columns are in rad/s (gx(rad/s), gy(rad/s), gz(rad/s)), the calibration's "
        "gyroscope in deg/s"),
    row("apply-named-gyro-columns-contradict-units", ["apply", "imu_g.json", "wit_rad.csv", "-o", "out.csv",
                                                      "--gyro-columns", "gx(rad/s),gy(rad/s),gz(rad/s)"],
        "the calibration's gyroscope in deg/s; give its rates in deg/s, or calibrate in rad/s"),
    row("imu-gyro-units-contradict-names", ["imu", "wit_rad.csv", "--gyro-units", "deg/s", "-o", "i.json"],
        "are in rad/s (gx(rad/s), gy(rad/s), gz(rad/s)); give --gyro-units rad/s, or drop it"),
    # a gyroscope file at its own times (issue #29): interpolated when they overlap, refused when they do not
    row("imu-gyro-file-times-do-not-overlap", ["imu", "rest.csv", "--gyro", "gyro_late.csv", "--gyro-units",
                                               "deg/s", "-o", "i.json"],
        "do not overlap: give both files' times in one clock"),
    row("calibrate-gyro-without-raw", ["calibrate", "rest.csv", "--gyro", "gyro_shifted.csv", "-o", "c.json"],
        "--gyro judges the rests of a raw recording on its gyroscope too: give --raw"),
    row("calibrate-rows-of-two-devices", ["calibrate", "wit_two.csv", "--raw"],
        "its rows come from 2 devices (column DeviceName: WT901(A), WT901(B))"),
    row("calibrate-clock-stands-still", ["calibrate", "wit_clock.csv", "--raw"],
        "give the sample rate with --rate (the clock column is then not read)"),
    row("apply-gyro-columns-without-gyroscope", APPLY + ["--gyro-columns", "gx,gy,gz"], "has no gyroscope block"),
    row("apply-gyro-file-without-gyroscope", APPLY + ["--gyro", "gyro_shifted.csv"], "has no gyroscope block"),
    row("apply-gyro-columns-missing", ["apply", "imu_g.json", "raw_g.csv", "-o", "out.csv", "--gyro-columns",
                                       "gx,gy,gz"], "no column 'gx'"),
    row("apply-gyro-times-disagree", ["apply", "imu_g.json", "raw_g.csv", "-o", "out.csv", "--gyro",
                                      "gyro_shifted.csv"], "times disagree"),
    row("apply-gyro-columns-wrong-count", ["apply", "imu_g.json", "raw_g.csv", "-o", "out.csv", "--gyro-columns",
                                           "gx,gy"], "must name 3 columns"),
    # robot and drone logs (issue #33): no IMU messages, two IMU topics, a bag cut short, another message type, an
    # output apply cannot write
    row("calibrate-raw-bag-without-imu", ["calibrate", "noimu.bag", "--raw"], "holds no IMU messages"),
    row("calibrate-raw-bag-two-imu-topics", ["calibrate", "two_imu.bag", "--raw"],
        "holds 2 IMU topics (/imu0, /imu1); pick one with --topic"),
    row("calibrate-raw-bag-cut-short", ["calibrate", "cut.bag", "--raw"], "as a ROS 1 bag"),
    row("noise-bag-topic-not-imu", ["noise", "noimu.bag", "--topic", "/chatter"],
        "carries std_msgs/msg/String, not an IMU's message"),
    row("apply-ulog-to-ulog", ["apply", "cal.json", "x.ulg", "-o", "y.ulg"], "as a table, not a ULog"),
    # info
    row("info-zero-noise", INFO + ["--noise-ug", "0"], "--noise-ug 0"),
    row("info-negative-noise", INFO + ["--noise-ug", "-1"], "--noise-ug -1"),
    row("info-negative-seed", INFO + ["--seed", "-1"], "--seed -1"),
    row("info-memory-exhausting-scheme", INFO + ["--scheme", "random:100000000"], "more than optcal handles"),
    row("info-dwell-without-noise-from", INFO + ["--dwell-s", "5"], "--noise-from"),
    row("info-unknown-model", INFO + ["--model", "nope"], "unknown model"),
    # discover
    row("discover-identical-positions", ["discover", "ident.csv"], "same outputs"),
    row("discover-zero-noise", DISC + ["--noise-ug", "0"], "--noise-ug 0"),
    row("discover-noise-in-g", DISC + ["--noise-ug", "1e-5"], "looks like a value in g"),
    row("discover-duplicate-column", ["discover", "dup.csv"], "'ax' 2 times"),
    row("discover-plot-unknown-format", DISC + ["--plot", "fig.xyz"], ".png, .pdf or .svg"),
    row("discover-plot-missing-folder", DISC + ["--plot", "missing/fig.png"], "does not exist"),
    row("discover-plot-is-input", DISC + ["--plot", "p.csv", "--force"], "is also an input"),
    row("discover-existing-plot", DISC + ["--plot", "p.csv"], "is also an input"),
    row("discover-gravity-looks-like-g", DISC + ["--gravity-ms2", "1.0"], "looks like g"),
    # nav
    row("nav-counts-calibration-g-truth", ["nav", "calc.json", "--truth", "truth.json"], "looks like outputs in g"),
    row("nav-empty-truth", ["nav", "cal.json", "--truth", "empty.json"], "is empty"),
    row("nav-plot-unknown-format", NAV + ["--plot", "n.xyz"], "suffix"),
    row("nav-plot-missing-folder", NAV + ["--plot", "missing/n.png"], "does not exist"),
    row("nav-plot-is-input", NAV + ["--plot", "truth.json", "--force"], "is also an input"),
    row("nav-zero-hours", NAV + ["--hours", "0"], "run length"),
    row("nav-latitude-out-of-range", NAV + ["--latitude", "95"], "latitude 95"),
    row("nav-bad-gyro-bias", NAV + ["--gyro-bias-dph", "1,x,2"], "--gyro-bias-dph"),
    # noise
    row("noise-confidence-above-one", NOISE + ["--ci", "1.5"], "--ci 1.5"),
    row("noise-plot-is-input", NOISE + ["--plot", "rest.csv", "--force"], "is also an input"),
    row("noise-plot-missing-folder", NOISE + ["--plot", "missing/n.png"], "does not exist"),
    row("noise-plot-unknown-format", NOISE + ["--plot", "n.xyz"], "cannot write .xyz"),
    row("noise-negative-tau", NOISE + ["--tau-max", "-1"], "--tau-max -1"),
    row("noise-negative-scale", NOISE + ["--scale", "-2"], "--scale -2"),
    row("noise-unknown-units", NOISE + ["--units", "furlongs"], "furlongs"),
    row("noise-bad-interval", NOISE + ["--interval", "5-9"], "START:END"),
    row("noise-gyro-columns-without-units", NOISE + ["--gyro-columns", "gx,gy,gz"], "give --gyro-units"),
    row("noise-gyro-counts-without-scale", NOISE + ["--gyro-units", "counts", "--gyro-columns", "1,2,3"],
        "give --gyro-scale"),
    row("noise-gyro-columns-missing", NOISE + ["--gyro-units", "deg/s", "--kalibr-yaml", "k.yaml"],
        "names no gyroscope columns"),
    row("noise-gyro-times-disagree", NOISE + ["--gyro", "rest_gyro_shifted.csv", "--gyro-units", "deg/s",
                                              "--kalibr-yaml", "k.yaml"], "times disagree"),
    # export and import
    row("export-output-is-input", ["export", "cal.json", "--format", "matrix", "-o", "cal.json", "--force"],
        "is also an input"),
    row("export-missing-folder", ["export", "cal.json", "--format", "matrix", "-o", "missing/m.json"],
        "does not exist"),
    row("export-bias-online-not-kalibr", ["export", "cal.json", "--format", "imucal", "-o", "i.json",
                                          "--bias-online"], "kalibr only"),
    row("export-missing-calibration", ["export", "none.json", "--format", "matrix", "-o", "m.json"],
        "does not exist"),
    row("export-unknown-version", ["export", "v3.json", "--format", "matrix", "-o", "m.json"], "format_version 3"),
    row("export-imu-file-to-matrix", ["export", "imu_c.json", "--format", "matrix", "-o", "m.json"],
        "holds one affine map"),
    row("export-imu-tk-without-gyro-output", ["export", "imu_c.json", "--format", "imu_tk", "-o", "a.calib"],
        "--gyro-output FILE"),
    row("export-imu-tk-g-sensitivity", ["export", "imu_gs.json", "--format", "imu_tk", "-o", "a.calib",
                                        "--gyro-output", "g.calib"], "no g-sensitivity"),
    row("export-kalibr-gyroscope-in-counts", ["export", "imu_lin_gc.json", "--format", "kalibr", "-o", "k.yaml"],
        "gyroscope outputs are in counts"),
    row("export-kalibr-noise-without-gyroscope", ["export", "imu_lin_gc.json", "--format", "kalibr", "-o", "k.yaml",
                                                  "--noise", "acc_noise.yaml"], "lacks gyroscope_noise_density"),
    row("export-gyro-output-not-imu-tk", ["export", "imu_c.json", "--format", "imucal", "-o", "i.json",
                                          "--gyro-output", "g.calib"], "imu_tk only"),
    row("export-gyro-output-without-gyroscope", ["export", "calc.json", "--format", "imu_tk", "-o", "a.calib",
                                                 "--gyro-output", "g.calib"], "has no gyroscope block"),
    row("export-noise-not-kalibr", ["export", "imu_c.json", "--format", "imucal", "-o", "i.json", "--noise",
                                    "acc_noise.yaml"], "kalibr only"),
    row("import-imu-tk-gyro-without-units", ["import", "imu_tk.txt", "--format", "imu_tk", "--units", "g", "--gyro",
                                             "imu_tk_gyro.txt", "-o", "i.json"], "give them with --gyro-units"),
    row("import-gyro-units-without-gyro-file", ["import", "imu_tk.txt", "--format", "imu_tk", "--units", "g",
                                                "--gyro-units", "counts", "-o", "i.json"], "(--gyro)"),
    row("import-gyro-file-not-imu-tk", ["import", "imu_tk.txt", "--format", "kalibr", "--gyro", "imu_tk_gyro.txt",
                                        "-o", "i.json"], "imu_tk's second file"),
    row("import-imu-tk-without-units", ["import", "imu_tk.txt", "--format", "imu_tk", "-o", "i.json"], "--units"),
    row("import-missing-folder", ["import", "imu_tk.txt", "--format", "imu_tk", "--units", "g", "-o",
                                  "missing/i.json"], "does not exist"),
    row("import-output-is-input", ["import", "imu_tk.txt", "--format", "imu_tk", "--units", "g", "-o",
                                   "imu_tk.txt", "--force"], "is also an input"),
    row("import-gravity-looks-like-g", ["import", "imu_tk.txt", "--format", "imu_tk", "--units", "g", "-o",
                                        "i.json", "--gravity-ms2", "1.0"], "looks like g"),
    row("import-height-without-latitude", ["import", "imu_tk.txt", "--format", "imu_tk", "--units", "g", "-o",
                                           "i.json", "--height", "100"], "without a latitude"),
    # solvers, study, demo
    row("solvers-unknown", ["solvers", "no-such-solver"], "unknown solver"),
    row("study-run-missing-spec", ["study", "run", "nothing.toml", "--out", "st"], "nothing.toml"),
    row("study-run-unknown-key", ["study", "run", "missing_key.toml", "--out", "st"], "what"),
    row("study-run-negative-seed", ["study", "run", "neg_seed.toml", "--out", "st"], "seed"),
    row("study-run-memory-exhausting-runs", ["study", "run", "huge_runs.toml", "--out", "st"], "runs"),
    row("study-report-missing-folder", ["study", "report", "nowhere"], "nowhere"),
    row("study-report-not-a-study", ["study", "report", "notadir"], "study.sqlite"),
    row("study-export-missing-folder", ["study", "export", "nowhere", "-o", "ioh"], "nowhere"),
    row("raw-gyroscope-first-headerless", ["calibrate", "gyro_first.csv", "--raw"],
        "vary as a gyroscope's rates do"),
    row("raw-time-unit-ambiguous", ["calibrate", "rel_ns.csv", "--raw"], "or 1000 Hz in ns; set --time-unit"),
    row("imu-two-files-without-times-of-other-lengths", ["imu", "acc_norate.csv", "--gyro", "gyr_norate.csv",
                                                         "--rate", "100", "--gyro-units", "rad/s"],
        "neither has a time column"),
    row("calibrate-raw-option-on-positions", [*CAL, "--columns", "ax=1,ay=2,az=3"], "reads a raw recording: add --raw"),
    row("calibrate-several-files-not-raw", [*CAL, "p.csv"], "files are read as one raw recording: give --raw"),
    row("calibrate-several-files-other-rate", ["calibrate", "rest.csv", "raw_half.csv", "--raw"], "at one rate"),
    row("calibrate-gyro-columns-not-raw", [*CAL, "--gyro-columns", "4,5,6"], "judges the rests of a raw recording"),
    row("imu-several-files-and-a-gyro-file", ["imu", "rest.csv", "raw_half.csv", "--gyro", "rest_gyro_shifted.csv",
                                              "--gyro-units", "rad/s"], "--gyro is one second file"),
    row("demo-negative-seed", ["demo", "--seed", "-1"], "--seed -1"),
    row("demo-negative-noise", ["demo", "--noise-ug", "-1"], "--noise-ug -1"),
    row("demo-zero-noise", ["demo", "--noise-ug", "0"], "--noise-ug 0"),
    row("demo-memory-exhausting-scheme", ["demo", "--scheme", "random:100000000"], "more than optcal handles"),
]


def _snapshot(folder) -> dict:
    return {p.relative_to(folder).as_posix(): (hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else "dir")
            for p in sorted(folder.rglob("*"))}


def test_the_table_covers_every_command_and_is_large():
    commands = {argv.values[0][0] for argv in CASES}
    assert {"simulate", "calibrate", "apply", "info", "discover", "nav", "noise", "export", "import", "solvers",
            "study", "demo"} <= commands
    assert {c.values[0][1] for c in CASES if c.values[0][0] == "study"} == {"run", "report", "export"}
    assert len(CASES) >= 60


@pytest.mark.parametrize("argv, fragment", CASES)
def test_bad_input_is_one_line_exit_2_and_writes_nothing(argv, fragment, source, tmp_path, monkeypatch, capsys):
    work = tmp_path / "w"
    shutil.copytree(source, work)
    monkeypatch.chdir(work)
    before = _snapshot(work)
    try:
        code = main(list(argv))
    except SystemExit as exc:  # argparse's own errors
        code = exc.code
    out, err = capsys.readouterr()
    lines = err.strip().splitlines()
    assert code == 2, (code, out, err)
    assert "Traceback" not in err
    assert len(lines) == 1, err
    assert len(lines[0]) <= 300, (len(lines[0]), lines[0])  # issue #29: long lists cut, a backstop in the CLI
    assert fragment in lines[0], lines[0]
    assert _snapshot(work) == before, "a file was written, removed or changed"
