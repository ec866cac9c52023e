"""optcal export and optcal import with an IMU file's gyroscope (issue #23): imu_tk's second file, imucal's
K_g, R_g, K_ga, b_g and Kalibr's gyroscope intrinsics and noise fields. Export then import gives the same
gyroscope to 1e-12 relative; imucal's own code applies the exported gyroscope as optcal apply does; what a
format cannot hold is refused in one line, nothing written."""

from __future__ import annotations

import gzip
import json
import math
from pathlib import Path

import numpy as np
import pytest
from conftest import run_cli

from optcal.app.cli import main
from optcal.core.calfile import read_calibration
from optcal.core.exchange.common import LinearPart, calibration_dict
from optcal.core.gravity import G0
from optcal.core.gyro.calfile import read_gyro_block
from optcal.core.gyro.model import get_gyro_model

DEG = 180.0 / math.pi


def gyro_block(model, x, units, offset=None) -> dict:
    block = {"model": model.name, "terms": list(model.terms), "bias_mode": "fit" if model.bias else "rests",
             "parameters": {n: float(v) for n, v in zip(model.names, x, strict=True)},
             "units": {"raw": units, "calibrated": "rad/s"}}
    if offset is not None:
        block["offset_raw"] = [float(v) for v in offset]
    return block


def imu_file(path, block, acc_units="m/s2", bias=True, seed=0) -> Path:
    """An IMU calibration file: a linear9 accelerometer (M lower triangular, near 1 g per g in ``acc_units``)
    and the gyroscope ``block``."""
    rng = np.random.default_rng(seed)
    k = {"m/s2": G0, "g": 1.0, "counts": 16384.0}[acc_units]
    M = k * (np.eye(3) + np.tril(2e-3 * rng.standard_normal((3, 3))))
    o = k * 0.02 * rng.standard_normal(3) if bias else np.zeros(3)
    doc = calibration_dict(LinearPart(M, o, acc_units), fmt="test", source="test", g_local=1.0001)
    path.write_text(json.dumps({**doc, "gyroscope": block}))
    read_calibration(path)  # a valid IMU file
    return path


def gyro_of(path):
    cal = read_calibration(path)
    return read_gyro_block(cal.meta, path)


def assert_same_gyroscope(a, b, rtol=1e-12):
    """The same scale factors, misalignments and g-sensitivity to ``rtol`` relative, and the same output offset
    (the whole raw output at zero rate: offset_raw + K·b, however a file splits it)."""
    (Ka, Ta, _, Ga), (Kb, Tb, _, Gb) = ([m[0] for m in c.model.matrices(c.x[None])] for c in (a, b))
    for u, v in ((Ka, Kb), (Ta, Tb), (Ga, Gb), (a.output_offset(), b.output_offset())):
        np.testing.assert_allclose(v, u, rtol=rtol, atol=rtol * 1e-3 * max(1e-300, np.max(np.abs(u))))


def _counts_gyro9():
    model = get_gyro_model(False, bias=False)
    x = np.array([4780.0, -4770.0, 4775.0, 0.0093, -0.0118, -0.0050, 0.0322, -0.0151, 0.0233])
    return gyro_block(model, x, "counts", offset=[32777.2, 32459.9, 32511.9])


def _gyro21(units, seed, bias=True):
    rng = np.random.default_rng(seed)
    model = get_gyro_model(True)
    k = {"deg/s": DEG, "rad/s": 1.0, "counts": 16.4 * DEG}[units]
    x = np.concatenate([k * (1 + 0.01 * rng.standard_normal(3)), 0.01 * rng.standard_normal(6),
                        (0.002 * rng.standard_normal(3)) if bias else np.zeros(3), 1e-3 * rng.standard_normal(9)])
    return gyro_block(model, x, units)


# -- round trips through the commands ------------------------------------------------------------------------
def test_imu_tk_round_trip_two_files(tmp_path, capsys):
    """imu_tk keeps the gyroscope in a second file (its T, K in rad/s per raw unit, B the raw offset): a gyro9
    (bias from the rests) comes back as gyro12 with the same K and T and the same output offset."""
    cal = imu_file(tmp_path / "imu.json", _counts_gyro9(), "counts")
    acc, gyr, back = tmp_path / "acc.calib", tmp_path / "gyro.calib", tmp_path / "back.json"
    code, out, err = run_cli(["export", cal, "--format", "imu_tk", "-o", acc, "--gyro-output", gyr], capsys)
    assert code == 0, err
    assert f"wrote {gyr}" in out and "raw W in counts, calibrated ω = T·K·(W − B) in rad/s" in out
    T, K, B = (np.array(b.split(), float) for b in gyr.read_text().split("\n\n") if b.strip())
    assert T.reshape(3, 3).diagonal().tolist() == [1.0, 1.0, 1.0]
    np.testing.assert_array_equal(B, [32777.2, 32459.9, 32511.9])  # the rests' offset, as imu_tk's bias
    code, out, err = run_cli(["import", acc, "--format", "imu_tk", "--units", "counts", "--gyro", gyr, "--gyro-units",
                               "counts", "-o", back], capsys)
    assert code == 0, err
    assert "gyroscope gyro12, raw outputs in counts" in out
    g = json.loads(back.read_text())["gyroscope"]
    assert g["solver"] == "import:imu_tk" and g["source"] == str(gyr) and g["stderr"]["K_x"] is None
    assert_same_gyroscope(gyro_of(cal), gyro_of(back))
    W = 32768 + 3000 * np.random.default_rng(1).standard_normal((50, 3))
    np.testing.assert_allclose(gyro_of(back).apply(W), gyro_of(cal).apply(W), rtol=1e-12, atol=1e-15)


def test_imucal_round_trip_with_g_sensitivity(tmp_path, capsys):
    """imucal holds the gyroscope in the same file, g-sensitivity as K_ga: gyro21 comes back with every
    parameter to 1e-12; the raw unit travels as from_gyr_unit ("a.u." for counts)."""
    block = _gyro21("counts", 3)
    cal = imu_file(tmp_path / "imu.json", block, "counts")
    out_file, back = tmp_path / "imucal.json", tmp_path / "back.json"
    code, out, err = run_cli(["export", cal, "--format", "imucal", "-o", out_file], capsys)
    assert code == 0, err
    assert "with its gyroscope" in out
    info = json.loads(out_file.read_text())
    assert info["from_gyr_unit"] == "a.u." and info["gyr_unit"] == "deg/s" and np.any(np.array(info["K_ga"]) != 0)
    code, out, err = run_cli(["import", out_file, "--format", "imucal", "-o", back], capsys)
    assert code == 0, err
    g = json.loads(back.read_text())["gyroscope"]
    assert g["model"] == "gyro21"
    np.testing.assert_allclose([g["parameters"][n] for n in block["parameters"]], list(block["parameters"].values()),
                               rtol=1e-12, atol=1e-15)
    assert_same_gyroscope(gyro_of(cal), gyro_of(back))


def test_kalibr_round_trip_and_noise_fields(tmp_path, capsys):
    """Kalibr's gyroscope M·C_gyro_i and A, in rad/s from deg/s raw outputs: gyro21 without bias comes back to
    1e-12 (Kalibr has no constant bias; biases 0). The noise fields of optcal noise's yaml go into the entry,
    units in comments."""
    block = _gyro21("deg/s", 4, bias=False)
    cal = imu_file(tmp_path / "imu.json", block, "m/s2", bias=False)
    noise = tmp_path / "noise.yaml"
    noise.write_text("accelerometer_noise_density: 8.5e-04  # [m/s^2/sqrt(Hz)]\naccelerometer_random_walk: 4.8e-04\n"
                     "gyroscope_noise_density: 5.85e-04\ngyroscope_random_walk: 2.6e-05\nupdate_rate: 100  # [Hz]\n")
    out_file, back = tmp_path / "imu.yaml", tmp_path / "back.json"
    code, out, err = run_cli(["export", cal, "--format", "kalibr", "-o", out_file, "--noise", noise], capsys)
    assert code == 0, err
    yaml = pytest.importorskip("yaml")
    entry = yaml.safe_load(out_file.read_text())["imu0"]
    assert entry["gyroscope_noise_density"] == 5.85e-4 and entry["gyroscope_random_walk"] == 2.6e-5
    assert entry["accelerometer_noise_density"] == 8.5e-4 and entry["update_rate"] == 100.0
    text = out_file.read_text()
    assert "gyroscope_random_walk: 2.6e-05  # [rad/s^2/sqrt(Hz)]" in text
    assert "accelerometer_random_walk: 0.00048  # [m/s^3/sqrt(Hz)]" in text
    Mg, A = np.array(entry["gyroscopes"]["M"]), np.array(entry["gyroscopes"]["A"])
    assert np.all(np.triu(Mg, 1) == 0) and np.any(A != 0)
    code, out, err = run_cli(["import", out_file, "--format", "kalibr", "--gyro-units", "deg/s", "-o", back], capsys)
    assert code == 0, err
    assert "noise fields" in out and "not kept" in out
    g = json.loads(back.read_text())["gyroscope"]
    assert g["model"] == "gyro21" and g["units"]["raw"] == "deg/s"
    assert_same_gyroscope(gyro_of(cal), gyro_of(back))


def test_xsens_calibration_round_trips_through_imu_tk_and_imucal(tmp_path, capsys, corpus):
    """optcal imu's own file of imu_tk's Xsens pair (gyro9, counts): through imu_tk's two files and through
    imucal, the same gyroscope to 1e-12."""
    acc, gyr = tmp_path / "xsens_acc.mat", tmp_path / "xsens_gyro.mat"
    for f in (acc, gyr):
        f.write_bytes(gzip.decompress((corpus / "imu_tk" / f"{f.name}.gz").read_bytes()))
    cal = tmp_path / "xsens.json"
    assert main(["imu", str(acc), "--gyro", str(gyr), "--gyro-units", "counts", "--units", "counts",
                 "--gravity-ms2", "9.81744", "--model", "linear9", "-o", str(cal)]) == 0
    capsys.readouterr()
    for fmt, extra_out, extra_in in (("imu_tk", ["--gyro-output", tmp_path / "g.calib"],
                                      ["--units", "counts", "--gyro", tmp_path / "g.calib", "--gyro-units", "counts"]),
                                     ("imucal", [], [])):
        out_file, back = tmp_path / f"e.{fmt}", tmp_path / f"b_{fmt}.json"
        assert run_cli(["export", cal, "--format", fmt, "-o", out_file, *extra_out], capsys)[0] == 0
        code, _, err = run_cli(["import", out_file, "--format", fmt, "-o", back, *extra_in], capsys)
        assert code == 0, err
        assert_same_gyroscope(gyro_of(cal), gyro_of(back))
        np.testing.assert_allclose(read_calibration(back).x, read_calibration(cal).x, rtol=1e-12)


# -- imucal's own code -----------------------------------------------------------------------------------------
imucal_pkg = pytest.importorskip("imucal")


def _imucal_calibrate(path, acc, gyr):
    from imucal.management import load_calibration_info

    info = load_calibration_info(path)
    return info.calibrate(acc=acc, gyr=gyr, acc_unit=info.from_acc_unit, gyr_unit=info.from_gyr_unit)


def _recording(path, N, W, rate=100.0):
    t = np.arange(len(N)) / rate
    np.savetxt(path, np.column_stack([t, N, W]), delimiter=",", header="t,ax,ay,az,gx,gy,gz", comments="",
               fmt="%.17g")
    return path


def test_imucal_applies_the_exported_gyroscope_as_optcal_apply_does(tmp_path, capsys):
    """A gyro21 calibration exported to imucal: imucal's calibrate (its K_ga takes the calibrated acceleration
    in m/s²) gives optcal apply's rates (deg/s against rad/s) to 1e-9 relative (apply writes 10 digits)."""
    cal = imu_file(tmp_path / "imu.json", _gyro21("counts", 5), "counts")
    assert run_cli(["export", cal, "--format", "imucal", "-o", tmp_path / "imucal.json"], capsys)[0] == 0
    rng = np.random.default_rng(6)
    acc_cal = read_calibration(cal)
    A = rng.standard_normal((500, 3))
    A /= np.linalg.norm(A, axis=1, keepdims=True)
    N = acc_cal.model.forward(acc_cal.x, A)[0]
    W = 300 * rng.standard_normal((500, 3)) + 20
    rec = _recording(tmp_path / "rec.csv", N, W)
    out = tmp_path / "applied.csv"
    code, _, err = run_cli(["apply", cal, rec, "-o", out, "--output-units", "m/s2"], capsys)
    assert code == 0, err
    ours = np.loadtxt(out, delimiter=",", skiprows=1)
    acc_theirs, gyr_theirs = _imucal_calibrate(tmp_path / "imucal.json", N, W)
    rel = np.max(np.linalg.norm(DEG * ours[:, 4:7] - gyr_theirs, axis=1) / np.linalg.norm(gyr_theirs, axis=1))
    print(f"imucal's calibrate on optcal's exported gyroscope: worst relative difference {rel:.2e}")
    assert rel < 1e-9, rel
    np.testing.assert_allclose(ours[:, 1:4], acc_theirs, rtol=1e-9)


def test_imucals_own_calibration_imported_gives_imucals_rates(tmp_path, capsys, corpus):
    """imucal's calibration of its example session (the real corpus's imucal/example_cal.json: raw counts, K_ga
    not zero), imported with its gyroscope, applied by optcal apply to the session's raw samples: imucal's own
    calibrated rates to 1e-9 relative."""
    data = corpus / "imucal"
    cal = tmp_path / "imported.json"
    code, out, err = run_cli(["import", data / "example_cal.json", "--format", "imucal", "-o", cal], capsys)
    assert code == 0, err
    assert "gyroscope gyro21, raw outputs in counts" in out
    raw = np.genfromtxt(data / "annotated_session.csv", delimiter=",", names=True, dtype=None, encoding="utf-8")
    N = np.column_stack([raw["acc_x"], raw["acc_y"], raw["acc_z"]]).astype(float)
    W = np.column_stack([raw["gyr_x"], raw["gyr_y"], raw["gyr_z"]]).astype(float)
    rec = _recording(tmp_path / "session.csv", N, W, 204.8)
    out_csv = tmp_path / "applied.csv"
    code, _, err = run_cli(["apply", cal, rec, "-o", out_csv], capsys)
    assert code == 0, err
    ours = DEG * np.loadtxt(out_csv, delimiter=",", skiprows=1)[:, 4:7]
    _, theirs = _imucal_calibrate(data / "example_cal.json", N, W)
    scale = np.linalg.norm(theirs, axis=1)
    moving = scale > 1.0  # deg/s: relative differences of near-zero rates say nothing
    assert moving.sum() > 1000
    rel = np.max(np.linalg.norm(ours - theirs, axis=1)[moving] / scale[moving])
    print(f"imucal's example gyroscope, {moving.sum()} samples above 1 deg/s: worst relative difference {rel:.2e}")
    assert rel < 1e-9, rel


# -- what a format cannot hold ----------------------------------------------------------------------------------
def test_refusals_are_one_line_and_write_nothing(tmp_path, capsys):
    g21 = imu_file(tmp_path / "g21.json", _gyro21("deg/s", 7), "m/s2")
    counts = imu_file(tmp_path / "counts.json", _counts_gyro9(), "m/s2", bias=False)
    nobias = imu_file(tmp_path / "nobias.json", _gyro21("deg/s", 8, bias=False), "m/s2", bias=False)
    partial = tmp_path / "partial.yaml"
    partial.write_text("accelerometer_noise_density: 1e-3\naccelerometer_random_walk: 1e-4\nupdate_rate: 100\n")
    out, gout = tmp_path / "out.txt", tmp_path / "gout.txt"
    cases = [
        (["export", g21, "--format", "imu_tk", "-o", out, "--gyro-output", gout], "no g-sensitivity"),
        (["export", g21, "--format", "imu_tk", "-o", out], "--gyro-output FILE"),
        (["export", g21, "--format", "matrix", "-o", out], "one affine map"),
        (["export", counts, "--format", "kalibr", "-o", out], "no fixed value in rad/s"),
        (["export", g21, "--format", "kalibr", "-o", out], "--bias-online"),
        (["export", nobias, "--format", "kalibr", "-o", out, "--noise", partial],
         "lacks gyroscope_noise_density, gyroscope_random_walk"),
        (["export", nobias, "--format", "imucal", "-o", out, "--noise", partial], "kalibr only"),
        (["export", nobias, "--format", "imu_tk", "-o", out, "--gyro-output", out], "name the same file"),
    ]
    for argv, fragment in cases:
        code, text, err = run_cli(argv, capsys)
        assert code == 2, (argv, err)
        lines = err.strip().splitlines()
        assert len(lines) == 1 and fragment in lines[0], (fragment, err)
        assert not out.exists() and not gout.exists()
    # the accelerometer alone, when asked for: the matrix format, and imucal with the identity gyroscope
    code, text, err = run_cli(["export", g21, "--format", "matrix", "-o", out, "--accelerometer-only"], capsys)
    assert code == 0, err
    code, text, err = run_cli(["export", g21, "--format", "imucal", "-o", tmp_path / "i.json", "--accelerometer-only"],
                               capsys)
    assert code == 0 and "identity" in text
    assert json.loads((tmp_path / "i.json").read_text())["K_g"] == np.eye(3).tolist()
    # an imucal file with the identity gyroscope imports without one
    code, text, err = run_cli(["import", tmp_path / "i.json", "--format", "imucal", "-o", tmp_path / "i_back.json"],
                               capsys)
    assert code == 0, err
    assert "gyroscope" not in json.loads((tmp_path / "i_back.json").read_text())
