"""optcal apply with an IMU file (issue #23): the gyroscope's samples become calibrated angular rate wx, wy, wz
in rad/s beside the specific force. On imu_tk's Xsens pair (two files sharing times, raw counts): the rests
read zero rate within the bias spread the file records, and integrating a motion's rates gives the rotation
the fit found. One file with the gyroscope's columns: named or found by their header names, the same rates
as the library's; what is missing is said in one line."""

from __future__ import annotations

import gzip
import json

import numpy as np
import pytest
from conftest import run_cli
from scipy.spatial.transform import Rotation

from optcal.app.cli import main
from optcal.core.gyro import draw_truth, get_gyro_model, simulate_imu
from optcal.core.gyro.calfile import read_gyro_block

G_SITE = 9.81744  # m/s², imu_tk's test_imu_calib.cpp (tests/test_gyro_imu_command.py)


@pytest.fixture(scope="module")
def xsens(tmp_path_factory, corpus):
    """The Xsens pair calibrated by optcal imu (linear9, gyroscope bias from the rests) and applied to itself."""
    d = tmp_path_factory.mktemp("xsens")
    acc, gyr = d / "xsens_acc.mat", d / "xsens_gyro.mat"
    for f in (acc, gyr):
        f.write_bytes(gzip.decompress((corpus / "imu_tk" / f"{f.name}.gz").read_bytes()))
    cal = d / "xsens.json"
    assert main(["imu", str(acc), "--gyro", str(gyr), "--gyro-units", "counts", "--units", "counts",
                 "--gravity-ms2", str(G_SITE), "--model", "linear9", "-o", str(cal)]) == 0
    out = d / "applied.csv"
    assert main(["apply", str(cal), str(acc), "--gyro", str(gyr), "-o", str(out)]) == 0
    return {"acc": acc, "gyro": gyr, "cal": cal, "out": out, "dir": d}


@pytest.fixture(scope="module")
def xsens_rests(xsens):
    """The rests optcal imu found (its detector on both sensors), and the fit's problem on them."""
    from optcal.app.workflows.recording import positions_from_raw
    from optcal.core.gyro.data import GyroData
    from optcal.core.gyro.problem import GyroProblem
    from optcal.core.recording import read_recording

    gyro = read_recording(xsens["gyro"], None, units="volts")  # the gyroscope's file: its N holds the rates
    pos = positions_from_raw(xsens["acc"], units="counts", model="linear9", g_local=G_SITE / 9.80665, gyro=gyro)
    rests = pos.extra["detection"].intervals
    a = np.loadtxt(xsens["out"], delimiter=",", skiprows=1)
    block = json.loads(xsens["cal"].read_text())["gyroscope"]
    W = np.loadtxt(xsens["gyro"])[:, 1:4]
    K = np.array([block["parameters"][f"K_{c}"] for c in "xyz"])
    problem = GyroProblem(GyroData(a[:, 0], W, a[:, 1:4], rests, units="counts"), bias=block["bias_mode"], scale=K)
    x = get_gyro_model(False, bias=False).vector(block["parameters"])
    return {"rests": rests, "t": a[:, 0], "F": a[:, 1:4], "w": a[:, 4:7], "block": block, "problem": problem, "x": x}


def test_header_and_the_rates_are_the_librarys(xsens, capsys):
    head = xsens["out"].read_text().splitlines()[0].split(",")
    assert head == ["t", "ax", "ay", "az", "wx", "wy", "wz"]
    a = np.loadtxt(xsens["out"], delimiter=",", skiprows=1)
    from optcal.core.calfile import read_calibration

    cal = read_gyro_block(read_calibration(xsens["cal"]).meta, xsens["cal"])
    expected = cal.apply(np.loadtxt(xsens["gyro"])[:, 1:4])
    # apply writes 10 significant digits
    np.testing.assert_allclose(a[:, 4:7], expected, rtol=1e-9, atol=1e-12)


def test_rests_read_zero_rate_within_the_bias_spread(xsens_rests):
    """The file subtracts one offset, the rests' mean output; the MTi's bias drifts between rests by the
    spread the file records (offset_spread_raw: 4 to 6 counts, 0.9 to 1.4 mrad/s). Each rest's mean rate is
    within 3 spreads of zero, their RMS is the spread (within 30 %), and their mean is zero within 3 spreads
    / √rests (measured: RMS 0.91, 1.34, 1.13 mrad/s; the mean 2e-5 rad/s)."""
    r, block = xsens_rests, xsens_rests["block"]
    K = np.array([block["parameters"][f"K_{c}"] for c in "xyz"])
    spread = np.array(block["offset_spread_raw"]) / np.abs(K)  # rad/s
    means = np.array([r["w"][a:b].mean(axis=0) for a, b in r["rests"]])
    n = len(means)
    assert n >= 30
    assert np.all(np.abs(means) < 3 * spread)
    rms = np.sqrt(np.mean(means**2, axis=0))
    assert np.all((0.7 * spread < rms) & (rms < 1.3 * spread)), (rms, spread)
    assert np.all(np.abs(means.mean(axis=0)) < 3 * spread / np.sqrt(n))
    # and the rates are what a motion reads: rad/s, not counts (a 90° turn in 2 to 5 s)
    assert 0.3 < np.max(np.abs(r["w"])) < 10.0


def _integrate(t, w, a, b) -> Rotation:
    """The body-frame attitude change from sample a to b: the product of exp(ω·dt), ω the mean of each
    step's two samples."""
    wm = 0.5 * (w[a:b] + w[a + 1:b + 1])
    R = Rotation.identity()
    for step in Rotation.from_rotvec(wm * np.diff(t[a:b + 1])[:, None]):
        R = R * step
    return R


def test_integrating_a_motion_gives_the_fits_rotation(xsens_rests):
    """Every motion between two rests: the rotation integrated from apply's rates agrees with the fit's own
    integrator (optcal.core.gyro.problem.GyroProblem.rotation, RK4) within the bias the file cannot follow: the
    fit interpolates the bias between rests, the file subtracts one offset, so they differ by up to the
    spread times the motion's duration (measured: at most 0.91 of it, 0.04° to 0.5°, on turns of 30° to
    180°; a few split poses, under 1°). And the integrated rotation carries the gravity direction of
    the rest before onto the rest after within the fit's residual for that motion plus that bound (RMS
    0.67°; the fit's, with its interpolated bias, 0.76°)."""
    r, p, x = xsens_rests, xsens_rests["problem"], xsens_rests["x"]
    block = r["block"]
    spread = np.linalg.norm(np.array(block["offset_spread_raw"]) / np.abs(
        np.array([block["parameters"][f"K_{c}"] for c in "xyz"])))
    fit_angles = p.motion_angles(x)
    turns, carried = [], []
    for k in range(p.data.n_motions):
        a, b = int(p.data.start[k]), int(p.data.stop[k])
        mine = _integrate(r["t"], r["w"], a, b)
        theirs = Rotation.from_rotvec(p.rotation(x, a, b))
        bound = 2 * spread * (r["t"][b] - r["t"][a])
        assert (mine.inv() * theirs).magnitude() < bound, k
        turns.append(theirs.magnitude())
        (a0, b0), (a1, b1) = p.data.rests[k], p.data.rests[k + 1]
        u0, u1 = r["F"][a0:b0].mean(axis=0), r["F"][a1:b1].mean(axis=0)
        u0, u1 = u0 / np.linalg.norm(u0), u1 / np.linalg.norm(u1)
        angle = np.arccos(np.clip(mine.inv().apply(u0) @ u1, -1, 1))
        assert angle < fit_angles[k] + bound, k
        carried.append(angle)
    # turns of 30° to 180°, and a few under 1°: poses the detection split in two where they were disturbed
    deg = np.rad2deg(turns)
    assert deg.max() > 150 and np.all((deg > 20) | (deg < 1)) and np.sum(deg < 1) <= 4, np.sort(deg)[:5]
    assert np.rad2deg(np.sqrt(np.mean(np.square(carried)))) < 1.0  # 3.35° at the nominal scale (optcal imu)


# -- one file with the gyroscope's columns ------------------------------------------------------------------
@pytest.fixture(scope="module")
def one_file(tmp_path_factory):
    """A simulated IMU in counts (t, ax, ay, az, gx, gy, gz: optcal's reader knows the gyroscope by these
    names), calibrated by optcal imu."""
    d = tmp_path_factory.mktemp("one")
    rng = np.random.default_rng(0)
    model = get_gyro_model(False)
    x = draw_truth(model, rng, 1000.0)
    x[9:12] += 32768 / 1000.0
    sim = simulate_imu(model, x, poses=24, rest_s=3.0, rng=rng)
    path = d / "imu.csv"
    np.savetxt(path, np.column_stack([sim.data.t, sim.data.F, np.round(sim.data.W)]), delimiter=",",
               header="t,ax,ay,az,gx,gy,gz", comments="", fmt="%.9g")
    plain = d / "acc.csv"
    np.savetxt(plain, np.column_stack([sim.data.t, sim.data.F]), delimiter=",", header="t,ax,ay,az", comments="",
               fmt="%.9g")
    cal = d / "imu.json"
    assert main(["imu", str(path), "--gyro-columns", "gx,gy,gz", "--gyro-units", "counts", "--gyro-scale", "1000",
                 "--model", "linear9", "-o", str(cal)]) == 0
    acc_only = d / "acc.json"
    assert main(["calibrate", str(plain), "--raw", "--model", "linear9", "-o", str(acc_only)]) == 0
    return {"dir": d, "imu": path, "plain": plain, "cal": cal, "acc_only": acc_only, "W": np.round(sim.data.W)}


def test_one_file_named_or_found_by_header_gives_the_same_rates(one_file, capsys):
    d = one_file["dir"]
    by_name, by_header = d / "named.csv", d / "header.csv"
    code, out, err = run_cli(["apply", one_file["cal"], one_file["imu"], "--gyro-columns", "gx,gy,gz", "-o", by_name],
                              capsys)
    assert code == 0, err
    assert "wx, wy, wz in rad/s by gyroscope model gyro9, outputs in counts" in out
    code, out, err = run_cli(["apply", one_file["cal"], one_file["imu"], "-o", by_header], capsys)
    assert code == 0, err
    assert by_name.read_text() == by_header.read_text()
    a = np.loadtxt(by_name, delimiter=",", skiprows=1)
    from optcal.core.calfile import read_calibration

    cal = read_gyro_block(read_calibration(one_file["cal"]).meta, one_file["cal"])
    np.testing.assert_allclose(a[:, 4:7], cal.apply(one_file["W"]), rtol=1e-9, atol=1e-12)


def test_what_is_missing_is_said_in_one_line(one_file, capsys):
    d = one_file["dir"]
    # an IMU file on a recording without the gyroscope's columns: the accelerometer, and a note
    out = d / "acc_applied.csv"
    code, text, err = run_cli(["apply", one_file["cal"], one_file["plain"], "-o", out], capsys)
    assert code == 0, err
    assert out.read_text().splitlines()[0] == "t,ax,ay,az"
    notes = [line for line in text.splitlines() if "no gyroscope columns" in line]
    assert len(notes) == 1 and notes[0].startswith("note: ") and "--gyro-columns" in notes[0]
    # the gyroscope's columns asked for, but the file has no gyroscope: exit 2, one line, nothing written
    out2 = d / "none.csv"
    code, text, err = run_cli(["apply", one_file["acc_only"], one_file["imu"], "--gyro-columns", "gx,gy,gz", "-o",
                                out2], capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1 and "has no gyroscope block" in err
    assert not out2.exists()
    # the same recording with the accelerometer-only file: its gyroscope's columns are left, with a note
    code, text, err = run_cli(["apply", one_file["acc_only"], one_file["imu"], "-o", out2], capsys)
    assert code == 0 and "are not calibrated" in text
    assert out2.read_text().splitlines()[0] == "t,ax,ay,az"
