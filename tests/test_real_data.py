"""Real recordings made by others (the real corpus, beside the project: tests/corpus.py; each folder with its
licence and a README):

- ``imucal/``: from the imucal project (MIT licence; github.com/mad-lab-fau/imucal): a labelled
  six-position session in raw counts (``annotated_session.csv``) with imucal's own Ferraris calibration of
  it (``example_cal.json``), and a continuous six-position session in m/s² with its section list.
- ``mpu6050/``: from the ImuCalibration project for an MPU-6050 (MIT licence): a hand-turned int16 recording
  (``example_data_calibration.csv``, ±2 g range, nominally 16384 counts per g) with that project's static
  intervals (``static_intervals.csv``) and accelerometer parameters (``params_acc.csv``).
"""

import json

import numpy as np
import pytest
from corpus import corpus_root

from optcal.app.cli import main
from optcal.app.fit import calibrate
from optcal.app.workflows.recording import choose_threshold
from optcal.core.analysis import observability
from optcal.core.errors import InputError
from optcal.core.problem import CalibrationProblem
from optcal.core.recording import (
    given_intervals,
    label_intervals,
    positions_from_recording,
    read_intervals,
    read_recording,
)

REAL = corpus_root()  # the real corpus, beside the project (tests/corpus.py)
IMUCAL, MPU = REAL / "imucal", REAL / "mpu6050"
POSES = ["x_p", "x_a", "y_p", "y_a", "z_p", "z_a"]
G_IMUCAL = 9.81  # imucal's Ferraris calibration assumes |g| = 9.81 m/s² (reproduced exactly below)
G0 = 9.80665

pytestmark = pytest.mark.usefixtures("corpus")  # skipped, with the one reason, where the corpus is absent


def _mask(iv, n):
    m = np.zeros(n, bool)
    for s, e in iv:
        m[s:e] = True
    return m


def _overlaps(a, b):
    """(len(a), len(b)) matrix of overlapping samples between [start, end) intervals."""
    return np.clip(np.minimum(a[:, None, 1], b[None, :, 1]) - np.maximum(a[:, None, 0], b[None, :, 0]), 0, None)


# -- imucal: labelled six-position session, raw counts, 204.8 Hz ------------------------------------------
@pytest.fixture(scope="module")
def annotated():
    rec = read_recording(IMUCAL / "annotated_session.csv", columns="acc_x,acc_y,acc_z", rate=204.8,
                         units="counts", labels="part")
    det = label_intervals(rec, POSES)
    return rec, det, positions_from_recording(rec, det), json.loads((IMUCAL / "example_cal.json").read_text())


def test_imucal_sections_reproduce_imucals_own_ferraris_result(annotated):
    """Our reading and averaging of the labelled sections, put through imucal's Ferraris accelerometer
    equations (which its JSON fields show: the columns of K_a·R_a are (v⁺ − v⁻)/(2g) of each axis's two
    poses, K_a the row norms, R_a the normalised rows, b_a the on-axis midpoints), give imucal's numbers."""
    _, det, data, ref = annotated
    assert det.names == ["x_a", "x_p", "y_a", "y_p", "z_a", "z_p"]  # the file lists the sections in this order
    v = dict(zip(det.names, data.N))
    M = np.column_stack([v[f"{a}_p"] - v[f"{a}_a"] for a in "xyz"]) / (2 * G_IMUCAL)
    K = np.linalg.norm(M, axis=1)
    np.testing.assert_allclose(K, np.diag(ref["K_a"]), rtol=1e-12)
    np.testing.assert_allclose(M / K[:, None], ref["R_a"], atol=1e-12)
    b = [(v[f"{a}_p"][i] + v[f"{a}_a"][i]) / 2 for i, a in enumerate("xyz")]
    np.testing.assert_allclose(b, ref["b_a"], rtol=1e-12)


def test_imucal_norm_fit_agrees_with_imucal_within_method_differences(annotated):
    """A norm-only diag6 fit (no knowledge of the poses) against imucal's Ferraris result (which uses the
    known ±g direction of each labelled pose and estimates a full sensitivity matrix). With imucal's
    g = 9.81 m/s², scale factors agree to 3e-4 (measured ≤ 2.3e-4) and offsets to 1 count (≈ 0.5 mg;
    measured ≤ 0.54 counts): the diag6 ellipsoid has no cross-axis terms, so imucal's misalignments
    (up to 0.024 rad) move the result at second order, (0.024)² ≈ 6e-4."""
    _, _, data, ref = annotated
    # six positions, six parameters: an exact fit, no residual to judge it by, so optcal refuses it unless
    # told to write a weak fit (optcal.core.determination); forced, it is imucal's result to 3e-4
    with pytest.raises(InputError, match="exact fit"):
        calibrate(data, "diag6", g_local=G_IMUCAL / G0)
    cal = calibrate(data, "diag6", g_local=G_IMUCAL / G0, force_weak=True)
    assert len(cal.forced) == 1 and "exact fit" in cal.forced[0]
    K = cal.x[:3] / G0  # counts per g0 → counts per m/s², imucal's K_a unit
    np.testing.assert_allclose(K, np.diag(ref["K_a"]), rtol=3e-4)
    np.testing.assert_allclose(cal.x[:3] * cal.x[3:6], ref["b_a"], atol=1.0)
    assert cal.fit.rms_g < 1e-9
    # Six ±axis poses observe no misalignment with the norm cost: linear9 is refused, and its Jacobian at
    # these positions has rank 6 with the three angles as the unobservable directions.
    with pytest.raises(InputError, match="fewer than the 9 parameters"):
        calibrate(data, "linear9")
    problem = CalibrationProblem("linear9", data, check=False)
    x = np.concatenate([cal.x, np.zeros(3)])
    obs = observability(problem, x)
    assert obs.rank == 6
    assert sorted(d[0]["name"] for d in obs.unobservable) == ["S_yz", "S_zx", "S_zy"]


def test_imucal_session_through_the_cli(tmp_path, capsys):
    """The six labelled poses give an exact diag6 fit: refused in one line, nothing written; with
    --force-weak it is written, marked as forced, and equals imucal's scale factors to 3e-4."""
    cal = tmp_path / "cal.json"
    argv = ["calibrate", str(IMUCAL / "annotated_session.csv"), "--raw", "--columns", "acc_x,acc_y,acc_z",
            "--rate", "204.8", "--units", "counts", "--labels", "part=" + ",".join(POSES), "--model", "diag6",
            "--gravity-ms2", "9.81", "-o", str(cal)]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "exact fit" in err[0] and "--force-weak" in err[0]
    assert not cal.exists()
    assert main([*argv, "--force-weak", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert json.loads(cal.read_text())["forced"]
    ref = json.loads((IMUCAL / "example_cal.json").read_text())
    K = np.array([out["parameters"][f"K_{a}"] for a in "xyz"]) / G0
    np.testing.assert_allclose(K, np.diag(ref["K_a"]), rtol=3e-4)
    assert out["n_positions"] == 6 and out["g_local"] == pytest.approx(9.81 / G0)


# -- MPU-6050: hand-turned int16 recording, 100 Hz (Fs line in the header) ---------------------------------
@pytest.fixture(scope="module")
def mpu():
    rec = read_recording(MPU / "example_data_calibration.csv", units="counts")
    ref = np.loadtxt(MPU / "static_intervals.csv", delimiter=",").T.astype(int)
    ref[:, 1] += 1  # their ends are inclusive sample indices; ours are exclusive
    return rec, ref


def test_mpu6050_detection_finds_the_reference_poses(mpu):
    rec, ref = mpu
    assert rec.rate == 100.0 and len(rec) == 10245 and not rec.saturated.any()  # the gyro saturates, not acc
    det = choose_threshold(rec, "diag6")
    assert det.n_intervals == 10 == len(ref)
    # the search with diag6: k = 3 to 10 all find the 10 poses; k = 3, the shortest intervals, gives the most
    # precise calibration (standard errors 0.05 % on K, 0.07 % at k = 8; both within 0.06 % of the source's K)
    assert det.k == 3
    ov = _overlaps(det.intervals, ref)
    # one to one: each reference interval lies inside exactly one detected interval, and vice versa
    assert np.all((ov > 0).sum(axis=0) == 1) and np.all((ov > 0).sum(axis=1) == 1)
    np.testing.assert_array_equal(ov.max(axis=0), ref[:, 1] - ref[:, 0])
    # ours are longer (the reference keeps some poses to 2 to 28 samples): IoU of the static sample
    # sets measured 0.69
    a, b = _mask(det.intervals, len(rec)), _mask(ref, len(rec))
    assert (a & b).sum() / (a | b).sum() > 0.65


def test_mpu6050_scale_factors_near_nominal_and_residual(mpu):
    rec, ref = mpu
    theirs = np.loadtxt(MPU / "params_acc.csv")  # 3 misalignments, 3 scales (m/s² per count), 3 biases (counts)
    K_theirs = G0 / theirs[3:6]
    det = choose_threshold(rec, "diag6")
    data = positions_from_recording(rec, det)
    results = {"diag6": calibrate(data, "diag6"), "default": calibrate(data)}
    # ten poses do not determine linear9 (one residual degree of freedom, and S_yz = 0.093 rad fitted, beyond
    # ±5°): refused, and the default nonlinear12 falls back to diag6, the richest model they determine
    with pytest.raises(InputError, match="only 1 residual degree"):
        calibrate(data, "linear9")
    assert results["default"].model.name == "diag6"
    np.testing.assert_array_equal(results["default"].x, results["diag6"].x)
    weak = calibrate(data, "linear9", force_weak=True)
    assert any("implausible" in r for r in weak.forced) and weak.fit.rms_g < 100e-6  # 89 µg, 1 dof
    cal = results["diag6"]
    K = cal.x[:3]
    # MPU-6050 datasheet: 16384 LSB/g ±3 % at ±2 g
    assert np.all(np.abs(K / 16384 - 1) < 0.03), K
    np.testing.assert_allclose(K, K_theirs, rtol=0.005)
    # their biases are the negated output offsets (they calibrate raw + b)
    np.testing.assert_allclose(cal.x[:3] * cal.x[3:6], -theirs[6:], atol=25.0)
    # residual RMS: diag6 measured 518 µg (no cross-axis terms)
    assert 400e-6 < cal.fit.rms_g < 650e-6
    assert det.n_intervals == 10
    # with their intervals the same diag6 fit gives their scale factors to 0.05 %
    cal = calibrate(positions_from_recording(rec, given_intervals(rec, ref)), "diag6")
    np.testing.assert_allclose(cal.x[:3], K_theirs, rtol=5e-4)


# -- imucal: continuous six-position session in m/s², 102.4 Hz -----------------------------------------
def test_imucal_continuous_session_detection_finds_the_six_poses():
    rec = read_recording(IMUCAL / "example_ferraris_session.csv", rate=102.4, units="m/s2")
    sections = json.loads((IMUCAL / "example_ferraris_session_list.json").read_text())
    det = choose_threshold(rec, "diag6")  # without the section list
    static = np.array([[sections[p]["start"], sections[p]["end"]] for p in POSES])
    rot = np.array([[v["start"], v["end"]] for k, v in sections.items() if k.endswith("_rot")])
    ov = _overlaps(det.intervals, static)
    # every labelled pose lies wholly inside one detected interval; no detected interval touches a rotation
    np.testing.assert_array_equal(ov.max(axis=0), static[:, 1] - static[:, 0])
    assert np.all((ov > 0).sum(axis=0) == 1)
    assert _overlaps(det.intervals, rot).max() == 0
    # the other detected intervals are the same six poses held again (before and after the rotations):
    # every interval's mean direction is within 0.5° of one pose, and every pose is found
    data = positions_from_recording(rec, det)
    given = given_intervals(rec, *read_intervals(IMUCAL / "example_ferraris_session_list.json"))
    assert given.names == POSES
    poses = positions_from_recording(rec, given)
    u = data.N / np.linalg.norm(data.N, axis=1, keepdims=True)
    v = poses.N / np.linalg.norm(poses.N, axis=1, keepdims=True)
    ang = np.degrees(np.arccos(np.clip(u @ v.T, -1, 1)))
    assert det.n_intervals == 13 and np.all(ang.min(axis=1) < 0.5)
    assert set(ang.argmin(axis=1)) == set(range(6))
    # and the calibration from the detected intervals agrees with the one from the section list
    a, b = calibrate(data, "diag6"), calibrate(poses, "diag6", force_weak=True)  # six sections: exact fit
    np.testing.assert_allclose(a.x[:3], b.x[:3], rtol=5e-4)
    np.testing.assert_allclose(a.x[3:6], b.x[3:6], atol=5e-4)
