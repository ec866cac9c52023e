"""The front door (optcal/app/api.py, docs/api.md): every python block of docs/api.md runs, in order, in one
session from the repository's root, and the values it computes are checked; then the functions' one-line
errors for what a user can get wrong. The blocks that read the real corpus name it by its default path
(tests/corpus.py), run on the folder the tests use, and are left out (their tests skipped) where it is absent."""

from __future__ import annotations

import ast
import contextlib
import io
import re
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pytest
from corpus import DEFAULT, corpus, corpus_present, corpus_root

import optcal
from optcal.core.errors import InputError

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "api.md"
MPU = corpus_root() / "mpu6050" / "example_data_calibration.csv"  # the real corpus (tests/corpus.py)


def _mpu():
    """MPU for a call that reads it: the test is skipped where the corpus is absent."""
    return corpus("mpu6050", "example_data_calibration.csv")


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    """The namespace after running every python block of docs/api.md, and what they printed."""
    blocks = re.findall(r"^```python\n(.*?)^```", DOC.read_text(), re.S | re.M)
    assert len(blocks) >= 7
    ns: dict = {}
    out = io.StringIO()
    mp = pytest.MonkeyPatch()
    mp.chdir(ROOT)
    mp.setattr(tempfile, "tempdir", str(tmp_path_factory.mktemp("api_doc")))  # the doc's mkdtemp goes here
    present, left_out = corpus_present(), set()  # without the corpus: the names its blocks would bind
    try:
        with contextlib.redirect_stdout(out):
            for i, code in enumerate(blocks):
                names = [n for n in ast.walk(ast.parse(code)) if isinstance(n, ast.Name)]
                if not present and (DEFAULT in code or left_out & {n.id for n in names}):
                    left_out |= {n.id for n in names if isinstance(n.ctx, ast.Store)}
                    continue
                code = code.replace(DEFAULT, str(corpus_root()))
                exec(compile(code, f"docs/api.md block {i + 1}", "exec"), ns)
    finally:
        mp.undo()
    print(out.getvalue())
    return ns, out.getvalue()


def test_every_front_door_function_has_a_section():
    text = DOC.read_text()
    for name in ("calibrate", "apply", "read_recording", "noise", "calibrate_imu"):
        assert f"## `optcal.{name}`" in text, name
        assert getattr(optcal, name) is getattr(__import__("optcal.app.api", fromlist=[name]), name)


def test_calibrate_recovers_the_simulated_truth(session):
    ns, _ = session
    cal, truth = ns["cal"], ns["truth"]
    assert cal.model.name == "linear9"
    z = (cal.x - cal.model.from_dict(truth)) / cal.stderr
    print("errors in standard errors:", np.round(z, 2))
    assert np.all(np.abs(z) < 4)
    assert np.all(cal.stderr[:3] < 2e-5)  # 20 µg per position, 24 positions
    # the same positions from an array and from a positions CSV (written at full precision)
    np.testing.assert_allclose(ns["from_array"].x, cal.x, rtol=1e-12)
    np.testing.assert_allclose(ns["from_csv"].x, cal.x, rtol=1e-12)


def test_calibrate_a_raw_recording(corpus, session):
    ns, _ = session
    mpu = ns["mpu"]
    K = np.array([mpu.parameters[f"K_{a}"] for a in "xyz"])
    print("MPU-6050 scale factors, counts per g:", K)
    assert len(mpu.problem.data) == 10 and mpu.model.name == "diag6"
    assert np.all(np.abs(K / 16384 - 1) < 0.022)
    assert 400e-6 < mpu.fit.rms_g < 650e-6  # diag6 has no cross-axis terms (tests/test_real_data.py)
    # linear9 from the same ten positions leaves one degree of freedom: refused; forced, it is marked
    weak = ns["weak"]
    assert weak.model.name == "linear9" and weak.forced[0].startswith("10 positions leave linear9 only 1 residual")
    assert weak.notes[0].startswith("forced although the data do not determine it: 10 positions leave linear9")


def test_the_api_refuses_what_the_data_do_not_determine_with_the_clis_line(corpus, session, tmp_path, capsys):
    """The same line from optcal.calibrate and optcal calibrate (the CLI puts its option names in for the
    backquoted parameters); a forced fit is applied with a warning naming its reasons."""
    from optcal.app.cli import main

    ns, _ = session
    data = ns["mpu"].problem.data
    with pytest.raises(InputError) as info:
        optcal.calibrate(data, model="linear9")
    line = str(info.value)
    assert "\n" not in line and "only 1 residual degree(s) of freedom" in line and "`force_weak`" in line
    data.to_csv(tmp_path / "mpu.csv")
    assert main(["calibrate", str(tmp_path / "mpu.csv"), "--units", "counts", "--model", "linear9"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.endswith(line.replace("`force_weak`", "--force-weak").replace("`model`", "--model"))
    import logging

    records = []
    handler = logging.Handler()
    handler.emit = records.append
    logging.getLogger("optcal").addHandler(handler)
    try:
        optcal.apply(ns["weak"], data.N[:2])
        optcal.apply(ns["mpu"], data.N[:2])
    finally:
        logging.getLogger("optcal").removeHandler(handler)
    assert len(records) == 1 and "applying a forced calibration" in records[0].getMessage()


def test_apply_returns_the_known_specific_force(session):
    ns, _ = session
    A_known = ns["A_known"]
    np.testing.assert_allclose(optcal.apply(ns["cal"], ns["N_known"]), A_known, atol=1e-12)
    np.testing.assert_allclose(optcal.apply(str(ns["folder"] / "cal.json"), ns["N_known"]), A_known, atol=1e-12)
    np.testing.assert_allclose(optcal.apply(ns["cal"], ns["N_known"][0]), A_known[0], atol=1e-12)  # one sample
    assert np.all(np.abs(np.linalg.norm(ns["A"], axis=1) - 1) < 1e-4)


def test_read_recording_and_noise(corpus, session):
    ns, _ = session
    rec = ns["rec"]
    assert len(rec) == 10245 and rec.rate == pytest.approx(100.0) and rec.N.shape == (10245, 3)
    density = np.array([a.white.value for a in ns["white"].axes])
    print("white-noise density of the simulated noise, µg/√Hz:", density * 1e6)
    assert np.all(np.abs(density / 10e-6 - 1) < 0.03)
    rest = np.array([a.white.value for a in ns["rest"].axes]) * 1e6
    np.testing.assert_allclose(rest, [333.9, 305.7, 470.5], atol=0.06)  # docs/noise.md's MPU-6050 table
    # a Recording gives the same analysis as its file
    again = optcal.noise(optcal.read_recording(MPU, units="counts"), scale=16384)
    whole = optcal.noise(MPU, units="counts", scale=16384)
    assert [a.white.value for a in again.axes] == [a.white.value for a in whole.axes]


def test_calibrate_reads_a_path_given_as_text(session, tmp_path):
    ns, _ = session
    path = tmp_path / "p.csv"
    ns["sim"].data.to_csv(path)
    np.testing.assert_allclose(optcal.calibrate(str(path), model="linear9", noise_g=20e-6).x, ns["cal"].x,
                               rtol=1e-12)


@pytest.mark.parametrize("call, message", [
    (lambda: optcal.calibrate("no/such/file.csv"), "does not exist or is not a file"),
    (lambda: optcal.calibrate(_mpu(), units="counts"), "pass `raw`"),  # these two read the file
    (lambda: optcal.calibrate(_mpu(), units="counts", rate=100), "pass raw=True with them"),
    (lambda: optcal.calibrate(MPU, raw=True, units="counts", colums="ax,ay,az"), "unknown keyword(s) colums"),
    (lambda: optcal.calibrate(np.ones((24, 2))), "three output columns"),
    (lambda: optcal.calibrate({"a": 1}), "data must be a PositionsData"),
    (lambda: optcal.calibrate(np.ones((24, 3)), raw=True), "apply to a file path"),
    (lambda: optcal.apply(42, np.ones((2, 3))), "calibration must be an optcal calibration"),
    (lambda: optcal.apply("no/such/cal.json", np.ones((2, 3))), "cannot read"),
    (lambda: optcal.noise(np.ones((100, 3))), "noise(samples, rate=HZ)"),
    (lambda: optcal.noise(np.ones((100, 3)), rate=10, interval=(0, 1)), "slice the samples"),
])
def test_one_line_errors(call, message):
    with pytest.raises(InputError) as info:
        call()
    assert message in str(info.value) and "\n" not in str(info.value)


def test_calibrate_refuses_units_that_contradict_the_data():
    from optcal.core.data import PositionsData

    with pytest.raises(InputError, match="the positions are in 'g' but units='counts'"):
        optcal.calibrate(PositionsData(N=np.eye(3)), units="counts")


def test_the_front_door_names_import_nothing_heavy():
    """Looking the four names up loads optcal.app.api, which imports NumPy and the rest only when called."""
    code = ("import importlib, sys, optcal\n"
            "fns = optcal.calibrate, optcal.apply, optcal.read_recording, optcal.noise\n"
            "print(sorted(m for m in sys.modules if m in ('numpy', 'scipy', 'optcal.solvers')))\n"
            "importlib.import_module('optcal.core.noise')\n"  # the noise package, loaded ...
            "assert optcal.noise is fns[3], optcal.noise\n")  # ... leaves the front door's function in place
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "[]"


def test_calibrate_imu_on_imu_tk_recording(corpus, session):
    """docs/api.md's IMU block: imu_tk's Xsens pair gives the command's calibration (41 rests, found on both
    sensors), scale factors within 3 standard errors of imu_tk's own, and the written file applies
    as the object does."""
    ns, out = session
    imu, fit = ns["imu"], ns["imu"].gyroscope
    assert imu.data.n_rests == 41 and imu.data.n_motions == 40
    imu_tk = 1 / np.array([0.000209295, 0.000209899, 0.000209483])
    assert np.all(np.abs(fit.x[:3] - imu_tk) < 3 * fit.stderr[:3])
    assert not any("found by the gyroscope" in n for n in imu.notes)  # the accelerometer has them all (#29)
    assert "41 rests, 40 motions; chi2/dof 12.4" in out
    rest = optcal.apply_gyro(imu, ns["W"][:500])
    assert np.all(np.abs(rest.mean(axis=0)) < 2e-3)  # the bias's wander between rests, rad/s


@pytest.mark.parametrize("call, message", [
    (lambda: optcal.calibrate_imu(np.zeros((10, 3)), gyro_units="counts"), "needs the path of a raw recording"),
    (lambda: optcal.calibrate_imu(str(MPU), gyro_units="furlongs"), "gyro_units 'furlongs': use one of"),
    (lambda: optcal.calibrate_imu(str(MPU), gyro_units="deg/s", speed=3), "unknown keyword(s) speed"),
    (lambda: optcal.calibrate_imu(str(MPU), gyro_units="deg/s", g_sensitivity=True), "needs `gyro_bias` fit"),
    (lambda: optcal.calibrate_imu(str(MPU), gyro_units="counts", gyro_scale=-1.0), "`gyro_scale` -1.0 must be"),
    (lambda: optcal.apply_gyro(42, np.zeros(3)), "calibration must be what optcal.calibrate_imu returns"),
    (lambda: optcal.apply_gyro(str(_mpu()), np.zeros(3)), "is not a JSON calibration file"),
    (lambda: optcal.apply_gyro(str(ROOT / "tests" / "no_such.json"), np.zeros(3)), "cannot read"),
])
def test_imu_functions_refuse_in_one_line(call, message):
    with pytest.raises(InputError) as exc:
        call()
    assert message in str(exc.value) and "\n" not in str(exc.value)
