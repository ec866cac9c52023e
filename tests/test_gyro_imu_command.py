"""optcal imu (issue #23): both sensors from one recording or two files into one calibration file; imucal's
Ferraris session end to end; bad input refused in one line with exit status 2 and nothing written."""

from __future__ import annotations

import gzip
import json

import numpy as np
import pytest
from conftest import run_cli
from corpus import corpus_root
from scipy.spatial.transform import Rotation

from optcal.core.errors import InputError
from optcal.core.gyro import draw_truth, get_gyro_model, simulate_imu
from optcal.core.gyro.calfile import read_gyro_block

IMUCAL = corpus_root() / "imucal" / "example_ferraris_session.csv"  # the real corpus (tests/corpus.py)
IMUCAL_ARGS = ["--columns", "ax=acc_x,ay=acc_y,az=acc_z", "--rate", "102.4", "--units", "m/s2",
               "--gyro-columns", "gyr_x,gyr_y,gyr_z", "--gyro-units", "deg/s", "--model", "diag6"]


def _write(path, t, F, W):
    head = "t,ax,ay,az,gx,gy,gz"
    np.savetxt(path, np.column_stack([t, F, W]), delimiter=",", header=head, comments="", fmt="%.9g")
    return path


def _recording(tmp_path, seed=0, attitudes=None, name="imu.csv", **kw):
    rng = np.random.default_rng(seed)
    model = get_gyro_model(False)
    x = draw_truth(model, rng, 1000.0)
    x[9:12] += 32768 / 1000.0  # an unsigned ADC's mid-scale offset
    sim = simulate_imu(model, x, poses=24, rest_s=3.0, attitudes=attitudes, rng=rng, **kw)
    d = sim.data
    return _write(tmp_path / name, d.t, d.F, np.round(d.W)), x, sim


ARGS = ["--gyro-columns", "gx,gy,gz", "--gyro-units", "counts", "--gyro-scale", "1000", "--model", "linear9"]


def test_one_file_gives_one_calibration_file_with_both_sensors(tmp_path, capsys):
    path, x, _ = _recording(tmp_path)
    out = tmp_path / "imu.json"
    code, text, err = run_cli(["imu", str(path), *ARGS, "-o", str(out)], capsys)
    assert code == 0, err
    d = json.loads(out.read_text())
    assert d["format"] == "optcal-calibration" and d["model"] == "linear9"
    g = d["gyroscope"]
    assert g["model"] == "gyro9" and g["bias_mode"] == "rests"
    assert g["units"] == {"raw": "counts", "calibrated": "rad/s", "parameters": {
        **{f"K_{a}": "counts/(rad/s)" for a in "xyz"}, **{n: "rad" for n in ("T_xy", "T_xz", "T_yx", "T_yz",
                                                                            "T_zx", "T_zy")}}}
    est = np.array([g["parameters"][n] for n in get_gyro_model(False, bias=False).names])
    se = np.array([g["stderr"][n] for n in get_gyro_model(False, bias=False).names])
    assert np.all(np.abs(est - x[:9]) < 4 * se)  # the 12-bit rounding adds little to the noise
    assert g["data"]["n_motions"] == 23 and g["observability"]["rank"] == 9
    # read back and applied: the rests' rates are zero to within their noise
    cal = read_gyro_block(d, out)
    w = cal.apply((x[:3] * x[9:12])[None])  # a rest's output: K·b
    assert np.all(np.abs(w) < 1e-3)
    assert "gyroscope: model gyro9" in text and f"wrote {out}" in text
    # the IMU file is a calibration file like any other: its accelerometer part reads back, its gyroscope checked
    from optcal.core.calfile import read_calibration

    assert read_calibration(out).model.name == "linear9"
    broken = tmp_path / "broken.json"
    broken.write_text(json.dumps({**d, "gyroscope": {**g, "terms": 7}}))
    with pytest.raises(InputError):
        read_calibration(broken)


def test_two_files_sharing_times_as_imu_tk(tmp_path, capsys, corpus):
    """imu_tk's Xsens pair through the command: the scale factors agree with imu_tk's within 3 standard
    errors (1/K against imu_tk's scale; the frames' difference moves them only to second order), and the
    motions' residual is that of docs/scripts/gyro_imu_tk.py."""
    acc, gyr = tmp_path / "xsens_acc.mat", tmp_path / "xsens_gyro.mat"
    for f in (acc, gyr):
        f.write_bytes(gzip.decompress((corpus / "imu_tk" / f"{f.name}.gz").read_bytes()))
    out = tmp_path / "xsens.json"
    code, text, err = run_cli(["imu", str(acc), "--gyro", str(gyr), "--gyro-units", "counts", "--units", "counts",
                                "--gravity-ms2", "9.81744", "--model", "linear9", "-o", str(out)], capsys)
    assert code == 0, err
    g = json.loads(out.read_text())["gyroscope"]
    K = np.array([g["parameters"][f"K_{a}"] for a in "xyz"])
    se = np.array([g["stderr"][f"K_{a}"] for a in "xyz"])
    imu_tk = 1 / np.array([0.000209295, 0.000209899, 0.000209483])
    assert np.all(np.abs(K - imu_tk) < 3 * se), (K - imu_tk) / se
    # the rests are found on both sensors (issue #29): the 4 settling poses that the accelerometer alone took
    # for the ends of motions (36 rests; imu_tk's variance detector finds 40) are the accelerometer's rests too,
    # none left for the gyroscope to find inside a motion, and a pose disturbed once is two rests (a "motion" of
    # under 1° between them). The motions' residual is the script's 0.35° (0.75° with the settling poses inside
    # motions: the two that bridged one carried 2.5° and 3.2°)
    n = g["data"]["n_rests"]
    assert 40 <= n <= 42 and g["data"]["n_motions"] == n - 1
    assert 0.33 < np.rad2deg(g["data"]["rms_motion_angle_rad"]) < 0.37
    assert f"accelerometer: model linear9, {n} rests" in text and "found by the gyroscope" not in text


def test_imucal_ferraris_session_end_to_end(tmp_path, capsys, corpus):
    """imucal's session (another source: deg/s, 102.4 Hz, one file): calibrated by the command, the file's
    gyroscope applied to the three 360° turns about the vertical (which tell the fit nothing about their
    own axis's scale) gives angles nearer 360° than the nominal scale, within 1.5 % on every axis; the
    motions' residual drops fourfold (docs/gyroscope.md, "imucal's Ferraris session, end to end")."""
    out = tmp_path / "imucal.json"
    code, text, err = run_cli(["imu", str(IMUCAL), *IMUCAL_ARGS, "-o", str(out)], capsys)
    assert code == 0, err
    d = json.loads(out.read_text())
    g = d["gyroscope"]
    assert g["units"]["raw"] == "deg/s" and g["data"]["n_motions"] >= 10
    cal = read_gyro_block(d, out)
    raw = np.genfromtxt(IMUCAL, delimiter=",", names=True)
    W = np.column_stack([raw["gyr_x"], raw["gyr_y"], raw["gyr_z"]])
    sections = json.loads((IMUCAL.parent / "example_ferraris_session_list.json").read_text())
    t = np.arange(len(W)) / 102.4
    for name in ("x_rot", "y_rot", "z_rot"):
        a, b = sections[name]["start"], sections[name]["end"]
        turned = np.rad2deg(np.linalg.norm(np.trapezoid(cal.apply(W[a:b + 1]), t[a:b + 1], axis=0)))
        nominal = np.linalg.norm(np.trapezoid(W[a:b + 1] - cal.offset_raw, t[a:b + 1], axis=0))
        assert abs(turned - 360) < 0.015 * 360, (name, turned)
        assert abs(turned - 360) < abs(nominal - 360) or abs(turned - 360) < 1.0, (name, turned, nominal)
    assert "0." in text and "calibrated" in text


def _one_axis(tmp_path):
    a = np.linspace(0, 2 * np.pi, 13)[:-1]
    return _recording(tmp_path, attitudes=Rotation.from_rotvec(np.outer(a, [1, 0, 0])).as_matrix())[0]


def _two_axes(tmp_path):
    """24 poses reached by turns about the body's x and y axes only, alternately (40° to 120°): gravity
    visits every direction, so the accelerometer is determined, but the gyroscope never turns about z."""
    rng = np.random.default_rng(5)
    C = [np.eye(3)]
    for k in range(23):
        axis = np.eye(3)[k % 2] * rng.choice([-1, 1])
        C.append(C[-1] @ Rotation.from_rotvec(axis * np.deg2rad(rng.uniform(40, 120))).as_matrix())
    return _recording(tmp_path, attitudes=np.array(C))[0]


def _shifted_gyro_times(tmp_path):
    path, _, sim = _recording(tmp_path)
    d = sim.data
    acc = tmp_path / "acc.csv"
    np.savetxt(acc, np.column_stack([d.t, d.F]), delimiter=",", header="t,ax,ay,az", comments="", fmt="%.9g")
    gyr = tmp_path / "gyr.csv"
    np.savetxt(gyr, np.column_stack([d.t + d.t[-1] + 1.0, np.round(d.W)]), delimiter=",", fmt="%.9g")
    return acc, ["--gyro", str(gyr)]


def _two_clocks(tmp_path, cut=None):
    """The accelerometer and the gyroscope in two files, each with its own sample times (the gyroscope's 0.4 of a
    step later, its last 50 samples missing; ``cut``: its samples in that time range removed, a gap)."""
    path, x, sim = _recording(tmp_path)
    d = sim.data
    acc = tmp_path / "acc.csv"
    np.savetxt(acc, np.column_stack([d.t, d.F]), delimiter=",", header="t,ax,ay,az", comments="", fmt="%.9g")
    step = float(np.median(np.diff(d.t)))
    tg, W = d.t[:-50] + 0.4 * step, np.array([np.interp(d.t[:-50] + 0.4 * step, d.t, d.W[:, k]) for k in range(3)]).T
    if cut is not None:
        keep = (tg < cut[0]) | (tg > cut[1])
        tg, W = tg[keep], W[keep]
    gyr = tmp_path / "gyr.csv"
    np.savetxt(gyr, np.column_stack([tg, np.round(W)]), delimiter=",", fmt="%.9g")
    return acc, gyr, x, sim


def test_a_gyroscope_file_with_its_own_times_is_interpolated_to_the_accelerometer_s(tmp_path, capsys):
    """Two files whose times differ (a phone's accelerometer and gyroscope logs, issue #29: refused before as
    "the two files must share their sample times"): the gyroscope is interpolated linearly to the accelerometer's
    times, as a ROS bag's second topic is, and said in a note; the accelerometer's samples after the gyroscope's
    last have no rate and are not used. The gyroscope's parameters are the truth within 4 standard errors."""
    acc, gyr, x, sim = _two_clocks(tmp_path)
    out = tmp_path / "imu.json"
    code, text, err = run_cli(["imu", str(acc), "--gyro", str(gyr), "--gyro-units", "counts", "--gyro-scale", "1000",
                               "--model", "linear9", "-o", str(out), "--json"], capsys)
    assert code == 0, err
    notes = json.loads(text)["notes"]
    # 51: the last 50 and the first (the gyroscope starts 0.4 of a step after it)
    assert ("the gyroscope's file has its own times: interpolated linearly to the accelerometer's times (51 "
            "accelerometer sample(s) without a gyroscope sample: outside its span or in a gap of its samples)") in notes
    g = json.loads(out.read_text())["gyroscope"]
    names = get_gyro_model(False, bias=False).names
    est = np.array([g["parameters"][n] for n in names])
    se = np.array([g["stderr"][n] for n in names])
    assert np.all(np.abs(est - x[:9]) < 4 * se), (est - x[:9]) / se
    assert g["data"]["n_motions"] == len(sim.data.start)


def test_a_gap_in_the_gyroscope_s_samples_leaves_its_motion_out(tmp_path, capsys):
    """The gyroscope's file misses 0.6 s in the middle of the fifth motion (a phone log of another lab missed 11.9 s,
    and the motion across it was integrated as if the rate had been constant: K_x 5 % off, exit 0). The motion
    is left out with a note, the others fitted; no rest holds a sample without the gyroscope."""
    path, x, sim = _recording(tmp_path)
    d = sim.data
    mid = 0.5 * (d.t[d.start[4]] + d.t[d.stop[4]])
    acc, gyr, x, sim = _two_clocks(tmp_path, cut=(mid - 0.3, mid + 0.3))
    code, text, err = run_cli(["imu", str(acc), "--gyro", str(gyr), "--gyro-units", "counts", "--gyro-scale", "1000",
                               "--model", "linear9", "--json"], capsys)
    assert code == 0, err
    out = json.loads(text)
    gap = [n for n in out["notes"] if "across a gap in the samples" in n]
    assert len(gap) == 1 and gap[0].startswith(f"1 motion(s) across a gap in the samples left out of the gyroscope's "
                                               f"fit ({len(d.start) - 1} used)"), out["notes"]
    names = get_gyro_model(False, bias=False).names
    g = out["gyroscope"]
    est = np.array([g["parameters"][n] for n in names])
    se = np.array([g["stderr"][n] for n in names])
    assert np.all(np.abs(est - x[:9]) < 4 * se), (est - x[:9]) / se


def test_a_time_gap_in_one_file_leaves_its_motion_out():
    """A logger that paused inside a motion (samples 0.5 s apart at 100 Hz): that motion is not integrated across
    the gap (GyroData.gapped_motions); the others are."""
    from optcal.core.gyro.data import GyroData

    rng = np.random.default_rng(3)
    model = get_gyro_model(False)
    x = draw_truth(model, rng, 1000.0)
    sim = simulate_imu(model, x, poses=24, rest_s=2.0, rng=rng)
    d = sim.data
    t = d.t.copy()
    k = (d.start[2] + d.stop[2]) // 2
    t[k:] += 0.5  # a pause of half a second inside the third motion
    g = GyroData(t, d.W, d.F, d.detected_rests)
    assert len(g.gapped_motions) == 1 and g.n_motions == len(d.start) - 1
    assert g.gapped_motions[0, 0] <= t[k] <= g.gapped_motions[0, 1]


def _saturated(tmp_path):
    path, _, sim = _recording(tmp_path)
    a = np.loadtxt(path, delimiter=",", skiprows=1)
    k = sim.data.start[3] + 20  # inside the fourth motion
    a[k:k + 5, 4] = 65535.0
    a[:, 4:] = np.clip(a[:, 4:], 0, 65535)
    return _write(tmp_path / "sat.csv", a[:, 0], a[:, 1:4], a[:, 4:])


def _no_rotation(tmp_path):
    path, _, sim = _recording(tmp_path)
    a = np.loadtxt(path, delimiter=",", skiprows=1)
    a[:, 4:] = np.round(32768 + sim.data.W[:, :] * 0 + np.random.default_rng(1).normal(0, 2, a[:, 4:].shape))
    return _write(tmp_path / "still.csv", a[:, 0], a[:, 1:4], a[:, 4:])


def test_saturated_motion_left_out_with_a_note(tmp_path, capsys):
    """A motion during which the gyroscope reaches its rail is left out of the fit, with a note naming it; the
    other motions are fitted (issue #29: two saturated motions of ~30 cost six whole recordings)."""
    path, _, sim = _recording(tmp_path)
    code, text, err = run_cli(["imu", str(path), *ARGS, "--json"], capsys)
    assert code == 0, err
    whole = json.loads(text)["gyroscope"]
    code, text, err = run_cli(["imu", str(_saturated(tmp_path)), *ARGS, "--json"], capsys)
    assert code == 0, err
    out = json.loads(text)
    g = out["gyroscope"]
    assert g["data"]["n_motions"] == whole["data"]["n_motions"] - 1
    assert any("1 motion(s) during which the gyroscope reached a rail left out" in n for n in out["notes"])
    for k in ("K_x", "K_y", "K_z"):  # the fit without that motion is the fit, within its standard errors
        assert abs(g["parameters"][k] - whole["parameters"][k]) < 3 * whole["stderr"][k]


def test_too_many_saturated_motions_refused(tmp_path, capsys):
    """When the motions left after the saturated ones do not determine the gyroscope, the refusal says why."""
    path, _, sim = _recording(tmp_path)
    a = np.loadtxt(path, delimiter=",", skiprows=1)
    for k in range(len(sim.data.start) - 2):
        a[sim.data.start[k] + 5: sim.data.start[k] + 8, 4] = 65535.0
    a[:, 4:] = np.clip(a[:, 4:], 0, 65535)
    path = _write(tmp_path / "sat.csv", a[:, 0], a[:, 1:4], a[:, 4:])
    out = tmp_path / "out.json"
    code, text, err = run_cli(["imu", str(path), *ARGS, "-o", str(out)], capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1 and not out.exists()
    assert f"{len(sim.data.start) - 2} of {len(sim.data.start)} motions reach the gyroscope's rail" in err


@pytest.mark.parametrize("case, extra, message", [
    ("one_axis", [], "leave model linear9 unobservable"),  # gravity in one plane: the accelerometer refuses first
    ("two_axes", [], "gyroscope parameter(s) K_z, T_xz, T_yz"),
    ("times", ["--gyro-columns", "0,1,2,3"], "do not overlap: give both files' times in one clock"),
    ("no_rotation", [], "stays within its rest noise through every motion"),
])
def test_bad_input_exit_2_one_line_nothing_written(tmp_path, capsys, case, extra, message):
    gyro_args = ARGS
    if case == "one_axis":
        path = _one_axis(tmp_path)
    elif case == "two_axes":
        path = _two_axes(tmp_path)
    elif case == "times":
        path, more = _shifted_gyro_times(tmp_path)
        gyro_args = more + ["--gyro-units", "counts", "--gyro-scale", "1000", "--model", "linear9"]
    else:
        path = _no_rotation(tmp_path)
    out = tmp_path / "out.json"
    code, text, err = run_cli(["imu", str(path), *gyro_args, *extra, "-o", str(out)], capsys)
    assert code == 2
    assert message in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


def test_two_files_without_times_of_different_lengths_are_refused(tmp_path, capsys):
    """Two files with no time column read at one `--rate` start at 0 together only by assumption: of different
    lengths (a lab's 108,000 and 72,000 rows at 1,200 Hz), nothing aligns them, and they were joined over the
    shorter one's span without a word. Refused in one line; of the same length they are the same samples."""
    acc, gyr, x, sim = _two_clocks(tmp_path)
    a = np.loadtxt(acc, delimiter=",", skiprows=1)[:, 1:]
    g = np.loadtxt(gyr, delimiter=",")[:, 1:]
    np.savetxt(acc, a, delimiter=",", fmt="%.9g")
    np.savetxt(gyr, g, delimiter=",", fmt="%.9g")
    rate = f"{1.0 / float(np.median(np.diff(sim.data.t))):.9g}"
    out = tmp_path / "imu.json"
    code, text, err = run_cli(["imu", str(acc), "--gyro", str(gyr), "--rate", rate, "--gyro-units", "counts",
                               "--gyro-scale", "1000", "--model", "linear9", "-o", str(out)], capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1 and not out.exists()
    assert f"the accelerometer's file has {len(a)} samples and the gyroscope's {len(g)}, and neither has a time " \
           "column" in err


def test_a_rail_in_converted_units_is_found_where_the_rate_piles_up():
    """A ±250 °/s gyroscope whose counts were converted to °/s (32768/131.07 = 250.004) and logged at 22 Hz: its
    fast turns sit at ±250.004 for 1-7 samples at a time, too briefly for a run of 10 (a rocket board of another
    lab: its fit was refused as "likely a wrong rate ... or saturation", naming no cause). The extremes that pile
    up are rails; a rate that peaks without clipping has none."""
    from optcal.core.recording.reading import piled_extremes, piled_saturation

    rng = np.random.default_rng(0)
    x = rng.normal(0, 0.5, 4000)  # rests, and 30 fast turns of 0.5 s peaking at ±300 °/s
    for k, sign in zip(range(60, 3900, 128), np.tile([1.0, -1.0], 15)):
        x[k:k + 11] += sign * 300.0 * np.sin(np.pi * np.arange(11) / 10.0)
    q = np.round(x * 131.07) / 131.07  # counts, converted
    clipped = np.clip(q, -32768 / 131.07, 32767 / 131.07)
    assert piled_extremes(clipped) == [-32768 / 131.07, 32767 / 131.07]
    assert piled_extremes(np.round(0.7 * x * 131.07) / 131.07) == []  # peaks at ±210 °/s, unclipped
    W = np.column_stack([clipped, np.round(0.7 * x * 131.07) / 131.07, np.zeros(4000)])
    sat, where = piled_saturation(W)
    assert list(where) == ["gx"] and np.array_equal(sat, np.abs(clipped) > 249.99)
    # a gyroscope that never turns, printed to 0.01 °/s, reading 0.02 or 0.03: its extremes pile up, no rail
    still = np.where(rng.random(4000) < 0.5, 0.02, 0.03)
    assert piled_extremes(still) == []


def test_calibrate_with_the_gyroscope_file_takes_the_rests_imu_takes(tmp_path, capsys):
    """Two files: ``calibrate --raw --gyro`` judges the rests on the gyroscope too, so it takes the rests, the model
    and the accelerometer's parameters that ``imu`` takes (two hand-held logs of another lab: calibrate alone 28
    rests and nonlinear12, imu 29 and linear9); without --raw, --gyro is refused in one line."""
    acc, gyr, x, sim = _two_clocks(tmp_path)
    code, text, err = run_cli(["calibrate", str(acc), "--raw", "--gyro", str(gyr), "--json"], capsys)
    assert code == 0, err
    cal = json.loads(text)
    code, text, err = run_cli(["imu", str(acc), "--gyro", str(gyr), "--gyro-units", "counts", "--gyro-scale", "1000",
                               "--json"], capsys)
    assert code == 0, err
    imu = json.loads(text)
    assert cal["recording"]["intervals"] == imu["recording"]["intervals"]
    assert cal["model"] == imu["accelerometer"]["model"]
    assert cal["parameters"] == pytest.approx(imu["accelerometer"]["parameters"], rel=1e-9, abs=1e-12)
    code, text, err = run_cli(["calibrate", str(acc), "--gyro", str(gyr)], capsys)
    assert code == 2 and "--gyro judges the rests of a raw recording on its gyroscope too: give --raw" in err


def test_calibrate_takes_the_gyroscope_columns_imu_takes(tmp_path, capsys):
    """One headerless file whose gyroscope columns are named by number (a lab's log of accelerometer, gyroscope and
    magnetometer counts): ``calibrate --raw --gyro-columns`` judges the rests on them as ``imu`` does, the same
    rests (it had no such option: 40 rests where imu took 35); without --raw refused in one line."""
    path, x, sim = _recording(tmp_path)
    a = np.loadtxt(path, delimiter=",", skiprows=1)
    bare = tmp_path / "bare.csv"
    np.savetxt(bare, a, delimiter=",", fmt="%.9g")  # t, ax, ay, az, gx, gy, gz without a header
    cols = ["--columns", "t=0,ax=1,ay=2,az=3", "--gyro-columns", "4,5,6"]
    code, text, err = run_cli(["calibrate", str(bare), "--raw", *cols, "--json"], capsys)
    assert code == 0, err
    cal = json.loads(text)
    code, text, err = run_cli(["imu", str(bare), *cols, "--gyro-units", "counts", "--gyro-scale", "1000", "--json"],
                              capsys)
    assert code == 0, err
    imu = json.loads(text)
    assert cal["recording"]["intervals"] == imu["recording"]["intervals"]
    code, text, err = run_cli(["calibrate", str(bare), "--raw", "--columns", "t=0,ax=1,ay=2,az=3", "--json"], capsys)
    alone = json.loads(text)  # the accelerometer alone: its own rests (what the option changes)
    assert code == 0 and alone["recording"]["intervals"] != cal["recording"]["intervals"]
    code, text, err = run_cli(["calibrate", str(bare), *cols], capsys)
    assert code == 2 and "--gyro-columns judges the rests of a raw recording on its gyroscope too: give --raw" in err


def test_a_rest_shorter_than_the_stillness_window_stays_within_itself():
    """still_rests on a rest of 8 samples at 200 Hz (the window is 10): the loop over rests it replaced averaged with
    np.convolve's "same", which returns the window's length when the rest is shorter, and moved the rest's end 2
    samples past its own; the vectorised one stays inside it."""
    from optcal.core.gyro.data import still_rests

    rng = np.random.default_rng(40)
    W = rng.normal(0, 1, (400, 3))
    t = np.arange(400) * 0.005
    rests = np.array([[102, 110], [200, 380]])
    out = still_rests(W, t, rests)
    assert np.all(out[:, 0] >= rests[:, 0]) and np.all(out[:, 1] <= rests[:, 1])
