"""Calibration files for other tools (docs/exchange.md): optcal's linear part converted exactly to imu_tk,
imucal, Kalibr and the affine matrix and back; what a format cannot hold refused; imucal's own code applies
an exported file as ``optcal apply`` does; the commands' one-line errors and their outputs."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from corpus import corpus_root

from optcal.app.cli import main
from optcal.core.calfile import read_calibration
from optcal.core.errors import InputError
from optcal.core.exchange import FORMATS, common, export_text, import_calibration, imu_tk, imucal, kalibr, matrix
from optcal.core.gravity import G0
from optcal.core.model import get_model

DATA = corpus_root() / "imucal"  # the real corpus, beside the project (tests/corpus.py)
LINEAR = ("diag6", "linear9", "scale+bias+misalignment6")
SCALE = {"counts": 16384.0, "g": 1.0, "m/s2": G0, "mg": 1000.0, "volts": 0.3}


def random_linear(rng, model: str, units: str, *, bias: bool = True) -> np.ndarray:
    """A linear calibration with every parameter bounded away from zero: scale factors within ±2 % of the
    unit's nominal (signs as drawn), biases 1e-3..5e-2 g, angles 1e-3..1e-2 rad (non-trivial misalignment)."""
    m = get_model(model)
    x = np.empty(m.n_params)
    sign = rng.choice([-1.0, 1.0], m.n_params)
    x[:3] = SCALE[units] * (1 + rng.uniform(-0.02, 0.02, 3))
    x[3:6] = sign[3:6] * rng.uniform(1e-3, 5e-2, 3) if bias else 0.0
    x[6:] = sign[6:] * rng.uniform(1e-3, 1e-2, m.n_params - 6)
    return x


def cal_file(tmp_path, model: str, x, units: str, name="cal.json", g_local=1.0, extra=None) -> Path:
    """An optcal calibration file with the given parameters (the fields read_calibration requires)."""
    m = get_model(model)
    doc = {"format": "optcal-calibration", "format_version": 1, "model": m.name, "terms": list(m.terms),
           "parameters": m.to_dict(x), "stderr": {n: None for n in m.names}, "units": {"input": "g", "output": units},
           "g_local": g_local, "data": {"n_positions": 24, "rms_residual_g": 1e-5, "source": None},
           "solver": "scipy-lm", "created": "2026-01-01T00:00:00Z", **(extra or {})}
    path = tmp_path / name
    path.write_text(json.dumps(doc))
    return path


def test_the_cell_map_is_the_models():
    """(M, o) from the parameters reproduce the model's own forward map: N = M·A + o (design.md, "Terms and
    parameters"-3.2)."""
    rng = np.random.default_rng(1)
    A = rng.standard_normal((50, 3))
    for model in LINEAR:
        x = random_linear(rng, model, "counts")
        M, o = common.matrix_of(get_model(model), x)
        N = get_model(model).forward(x, A)[0]
        np.testing.assert_allclose(A @ M.T + o, N, rtol=1e-14, atol=1e-10)
        assert common.LinearPart(M, o, "counts").specific_force(N) == pytest.approx(A, abs=1e-13)


def test_optcal_parameters_from_the_linear_part_choose_the_smallest_exact_model():
    rng = np.random.default_rng(2)
    for model in LINEAR:
        x = random_linear(rng, model, "g")
        m2, x2 = common.parameters_of(common.LinearPart(*common.matrix_of(get_model(model), x), "g"))
        assert m2.name == model
        np.testing.assert_allclose(x2, x, rtol=1e-15)
    x = random_linear(rng, "scale+bias+misalignment6", "g")
    lin = common.LinearPart(*common.matrix_of(get_model("scale+bias+misalignment6"), x), "g")
    with pytest.raises(InputError, match="`model` linear9 cannot hold .*S_xz, S_xy, S_yx"):
        common.parameters_of(lin, "linear9")
    with pytest.raises(InputError, match="choose one of diag6, linear9"):
        common.parameters_of(lin, "nonlinear12")


def _round_trip_pure(fmt, lin):
    if fmt == "imu_tk":
        return imu_tk.from_imu_tk(*imu_tk.loads(imu_tk.dumps(*imu_tk.to_imu_tk(lin, "m/s2")), "f"), lin.units, "m/s2")
    if fmt == "imucal":
        return imucal.from_imucal(json.loads(imucal.dumps(imucal.to_imucal(lin))), "f")[0]
    if fmt == "kalibr":
        M, _ = kalibr.to_kalibr(lin)
        return kalibr.from_kalibr(kalibr.loads(kalibr.dumps(M), "f"), lin.units)
    C, d = matrix.to_matrix(lin, "m/s2")
    return matrix.from_matrix(*matrix.loads(json.loads(matrix.dumps(C, d, lin.units, "m/s2")), "f")[:4])


@pytest.mark.parametrize("fmt", FORMATS)
def test_round_trip_is_the_identity_on_the_linear_part(fmt, tmp_path):
    """optcal → format → optcal, through the format's file text, gives every parameter back to 1e-12
    relative, in the same model, for several random calibrations per linear model and units. Kalibr holds no
    bias and no cells above the diagonal, and takes only units with a value in m/s², so its cases are those."""
    rng = np.random.default_rng(15)
    worst = 0.0
    n_cases = 0
    for model in LINEAR:
        for units in ("counts", "g", "m/s2", "mg"):
            if fmt == "kalibr" and (units == "counts" or model == "scale+bias+misalignment6"):
                continue
            for _ in range(4):
                x = random_linear(rng, model, units, bias=fmt != "kalibr")
                m = get_model(model)
                lin = common.LinearPart(*common.matrix_of(m, x), units)
                back = _round_trip_pure(fmt, lin)
                assert back.units == units
                m2, x2 = common.parameters_of(back)
                assert m2.name == m.name
                np.testing.assert_allclose(x2, x, rtol=1e-12, atol=0)
                # the same through the files and the public functions the commands use
                path = cal_file(tmp_path, model, x, units)
                text, _ = export_text(read_calibration(path), fmt)
                out = tmp_path / f"out.{fmt}"
                out.write_text(text)
                kw = {"units": units} if fmt in ("imu_tk", "kalibr") else {}
                doc, _ = import_calibration(out, fmt, **kw)
                assert doc["model"] == m.name and doc["units"]["raw"] == units
                x3 = m.from_dict(doc["parameters"])
                np.testing.assert_allclose(x3, x, rtol=1e-12, atol=0)
                nz = x != 0
                worst = max(worst, float(np.max(np.abs(x3[nz] / x[nz] - 1))))
                n_cases += 1
    print(f"{fmt}: {n_cases} calibrations, worst relative parameter change {worst:.2e}")
    assert n_cases >= 24


def test_imu_tk_text_is_what_its_loader_reads():
    """21 numbers: T row by row, K, B (CalibratedTriad::load reads them in that order); T has a unit
    diagonal and T·K·(X − B) in m/s² is g0 times optcal's specific force."""
    rng = np.random.default_rng(3)
    m = get_model("linear9")
    x = random_linear(rng, "linear9", "counts")
    lin = common.LinearPart(*common.matrix_of(m, x), "counts")
    T, K, B = imu_tk.to_imu_tk(lin)
    numbers = [float(v) for v in imu_tk.dumps(T, K, B).split()]
    assert len(numbers) == 21 and numbers[:9] == T.ravel().tolist() and numbers[18:] == B.tolist()
    np.testing.assert_array_equal(np.diag(T), 1.0)
    assert np.all(np.triu(T, 1) == 0)  # optcal's lower-triangular gauge is kept, not re-gauged
    X = m.forward(x, rng.standard_normal((20, 3)))[0]
    np.testing.assert_allclose((T @ K @ (X - B).T).T, G0 * lin.specific_force(X), rtol=1e-12)
    with pytest.raises(InputError, match="holds 21 numbers .* has 20"):
        imu_tk.loads(" ".join(["1"] * 20), "f")
    with pytest.raises(InputError, match="'x' is not a number"):
        imu_tk.loads(" ".join(["1"] * 20 + ["x"]), "f")


def test_kalibr_m_is_lower_triangular_and_dimensionless():
    """For outputs in g Kalibr's M is diag(K)·T itself (a_m/g0 = diag(K)·T·a/g0): optcal's gauge is Kalibr's."""
    rng = np.random.default_rng(4)
    m = get_model("linear9")
    x = random_linear(rng, "linear9", "g", bias=False)
    M_o, o = common.matrix_of(m, x)
    M, bias = kalibr.to_kalibr(common.LinearPart(M_o, o, "g"))
    np.testing.assert_allclose(M, M_o, rtol=1e-15)
    assert np.all(np.triu(M, 1) == 0) and np.all(bias == 0)
    M_mg, _ = kalibr.to_kalibr(common.LinearPart(M_o * 1000, o, "mg"))
    np.testing.assert_allclose(M_mg, M_o, rtol=1e-15)


@pytest.mark.parametrize("fmt", FORMATS)
def test_a_nonlinear_calibration_is_refused(fmt, tmp_path):
    m = get_model("nonlinear12")
    x = np.concatenate([random_linear(np.random.default_rng(5), "linear9", "g"), [1e-4, -2e-4, 3e-4]])
    cal = read_calibration(cal_file(tmp_path, "nonlinear12", x, "g"))
    with pytest.raises(InputError, match=f"term\\(s\\) quadratic \\(K2_x, K2_y, K2_z\\) that the {fmt} format"):
        export_text(cal, fmt)
    assert m.n_params == 12


def test_a_temperature_calibration_is_refused(tmp_path):
    m = get_model("linear9+temperature_bias")
    x = np.concatenate([random_linear(np.random.default_rng(6), "linear9", "g"), [1e-5, 2e-5, 3e-5]])
    cal = read_calibration(cal_file(tmp_path, m.name, x, "g", extra={"context": {"T0": 25.0}}))
    with pytest.raises(InputError, match="temperature_bias \\(beta_x, beta_y, beta_z\\)"):
        export_text(cal, "matrix")


def test_kalibr_refuses_what_its_model_cannot_hold(tmp_path):
    rng = np.random.default_rng(7)
    cal = read_calibration(cal_file(tmp_path, "linear9", random_linear(rng, "linear9", "g"), "g"))
    with pytest.raises(InputError, match="holds no accelerometer bias .* `bias_online`"):
        export_text(cal, "kalibr")
    text, notes = export_text(cal, "kalibr", bias_online=True)  # M alone: the bias is Kalibr's to estimate
    assert "not in the file" in notes[0]
    assert np.array_equal(kalibr.loads(text, "f"), kalibr.to_kalibr(common.linear_part(cal, "kalibr"),
                                                                     bias_online=True)[0])
    six = read_calibration(cal_file(tmp_path, "scale+bias+misalignment6",
                                    random_linear(rng, "scale+bias+misalignment6", "g", bias=False), "g", "c6.json"))
    with pytest.raises(InputError, match="lower triangular, but .* S_xz, S_xy, S_yx non-zero"):
        export_text(six, "kalibr")
    counts = read_calibration(cal_file(tmp_path, "linear9", random_linear(rng, "linear9", "counts", bias=False),
                                       "counts", "cc.json"))
    with pytest.raises(InputError, match="outputs are in counts, which have no fixed value in m/s²"):
        export_text(counts, "kalibr")


def test_kalibr_import_reads_a_result_entry_and_a_bare_one(tmp_path):
    M = np.array([[1.001, 0, 0], [2e-3, 0.999, 0], [-1e-3, 3e-3, 1.002]])
    entry = kalibr.dumps(M)
    bare = "model: scale-misalignment\naccelerometers:\n  M: " + json.dumps(M.tolist()) + "\n"
    for i, text in enumerate((entry, "%YAML:1.0\n" + entry, bare)):
        (tmp_path / f"k{i}.yaml").write_text(text)
        doc, notes = import_calibration(tmp_path / f"k{i}.yaml", "kalibr")
        assert doc["model"] == "linear9" and doc["units"]["raw"] == "m/s2"
        assert doc["parameters"]["K_x"] == pytest.approx(1.001 * G0, rel=1e-15)
        assert doc["parameters"]["S_yz"] == pytest.approx(2e-3 / 0.999, rel=1e-14)
        assert doc["parameters"]["b_x"] == 0.0 and "no accelerometer bias" in notes[0]
    (tmp_path / "two.yaml").write_text(entry + entry.replace("imu0", "imu1"))
    with pytest.raises(InputError, match="holds 2 IMU entries \\(imu0, imu1\\)"):
        import_calibration(tmp_path / "two.yaml", "kalibr")
    (tmp_path / "cal.yaml").write_text("imu0:\n  model: calibrated\n")
    with pytest.raises(InputError, match="model 'calibrated'"):
        import_calibration(tmp_path / "cal.yaml", "kalibr")


# -- imucal: its own code applies the exported file as optcal apply does ---------------------------------
imucal_pkg = pytest.importorskip("imucal")


def _write_recording(path, N, rate=100.0):
    t = np.arange(len(N)) / rate
    np.savetxt(path, np.column_stack([t, N]), delimiter=",", header="t,ax,ay,az", comments="", fmt="%.17g")


def _optcal_apply(tmp_path, cal, rec, units):
    out = tmp_path / "applied.csv"
    assert main(["apply", str(cal), str(rec), "-o", str(out), "--output-units", "m/s2", "--units", units,
                 "--force"]) == 0
    return np.loadtxt(out, delimiter=",", skiprows=1)[:, 1:4]


def _imucal_apply(path, N):
    from imucal.management import load_calibration_info

    info = load_calibration_info(path)
    acc, _ = info.calibrate(acc=N, gyr=np.zeros_like(N), acc_unit=info.from_acc_unit, gyr_unit=info.from_gyr_unit)
    return acc


def _agree(a, b):
    """Largest per-sample difference relative to the sample's magnitude."""
    return float(np.max(np.linalg.norm(a - b, axis=1) / np.linalg.norm(b, axis=1)))


def test_imucal_applies_an_exported_fit_as_optcal_apply_does(tmp_path, capsys):
    """A linear9 fit (scipy-lm, 24 simulated positions in counts) exported to imucal: imucal's loader reads it
    and its calibrate gives optcal apply's specific force (m/s²) on a raw recording to 1e-9 relative
    (optcal apply writes 10 significant digits, so up to 5e-10), and the library's to 1e-13."""
    from optcal import simulate
    from optcal.app.fit import calibrate
    from optcal.core.calfile import write_calibration

    rng = np.random.default_rng(8)
    truth = get_model("linear9").to_dict(random_linear(rng, "linear9", "counts"))
    sim = simulate("linear9", truth, rng, noise_g=20e-6)
    fit = calibrate(replace(sim.data, units="counts"), "linear9")
    cal = tmp_path / "cal.json"
    write_calibration(fit, cal, units_out="counts")
    assert main(["export", str(cal), "--format", "imucal", "-o", str(tmp_path / "imucal.json")]) == 0
    A = rng.standard_normal((2000, 3))
    A /= np.linalg.norm(A, axis=1)[:, None]  # a sensor turned through random attitudes at rest
    N = get_model("linear9").forward(fit.x, A)[0] + rng.normal(0, 3, (2000, 3))  # counts, with noise
    _write_recording(tmp_path / "raw.csv", N)
    ours = _optcal_apply(tmp_path, cal, tmp_path / "raw.csv", "counts")
    theirs = _imucal_apply(tmp_path / "imucal.json", N)
    err = _agree(ours, theirs)
    exact = _agree(G0 * read_calibration(cal).apply(N), theirs)  # the library, without the CSV's 10 digits
    print(f"imucal vs optcal apply: worst relative difference {err:.2e} (CLI), {exact:.2e} (library)")
    assert err < 1e-9 and exact < 1e-13
    assert np.median(np.linalg.norm(theirs, axis=1)) == pytest.approx(G0, rel=1e-3)


def test_imucals_own_file_imported_gives_imucals_specific_force(tmp_path, corpus):
    """imucal's Ferraris calibration of its example session (the real corpus's imucal/), imported: optcal apply on the
    session's raw counts gives what imucal's calibrate gives with the original file, to 1e-9 relative. (The
    gyroscope terms come in as a gyro21 block: tests/test_gyro_export_import.py.)"""
    cal = tmp_path / "imported.json"
    assert main(["import", str(DATA / "example_cal.json"), "--format", "imucal", "-o", str(cal),
                 "--gravity-ms2", "9.81"]) == 0
    doc = json.loads(cal.read_text())
    assert doc["model"] == "scale+bias+misalignment6" and doc["units"]["raw"] == "counts"
    assert doc["g_local"] == pytest.approx(9.81 / G0, rel=1e-15)
    raw = np.genfromtxt(DATA / "annotated_session.csv", delimiter=",", names=True, dtype=None, encoding="utf-8")
    N = np.column_stack([raw["acc_x"], raw["acc_y"], raw["acc_z"]]).astype(float)
    _write_recording(tmp_path / "raw.csv", N, 204.8)
    ours = _optcal_apply(tmp_path, cal, tmp_path / "raw.csv", "counts")
    theirs = _imucal_apply(DATA / "example_cal.json", N)
    err = _agree(ours, theirs)
    exact = _agree(G0 * read_calibration(cal).apply(N), theirs)
    print(f"imucal's example calibration, {len(N)} samples: worst relative difference {err:.2e} (CLI: apply writes "
          f"10 significant digits), {exact:.2e} (library)")
    assert err < 1e-9 and exact < 1e-13
    # and back: optcal's export of the import is imucal's file, to rounding
    assert main(["export", str(cal), "--format", "imucal", "-o", str(tmp_path / "back.json")]) == 0
    back, orig = json.loads((tmp_path / "back.json").read_text()), json.loads((DATA / "example_cal.json").read_text())
    for key in ("K_a", "R_a", "b_a"):
        np.testing.assert_allclose(back[key], orig[key], rtol=1e-12, atol=1e-15)


# -- the commands ------------------------------------------------------------------------------------------
def _exit(argv) -> int:
    """The exit status of ``optcal ARGV`` (argparse's own errors exit through SystemExit)."""
    try:
        return main(argv)
    except SystemExit as exc:
        return exc.code


def _err_line(capsys) -> str:
    err = capsys.readouterr().err
    assert "Traceback" not in err and err.count("\n") == 1, err
    return err


def test_export_writes_and_import_reads_back(tmp_path, capsys):
    x = random_linear(np.random.default_rng(9), "linear9", "counts")
    cal = cal_file(tmp_path, "linear9", x, "counts", g_local=1.0002)
    for fmt in ("imu_tk", "imucal", "matrix"):
        out, back = tmp_path / f"e.{fmt}", tmp_path / f"b_{fmt}.json"
        assert main(["export", str(cal), "--format", fmt, "-o", str(out)]) == 0
        extra = ["--units", "counts"] if fmt == "imu_tk" else []
        assert main(["import", str(out), "--format", fmt, "-o", str(back), *extra]) == 0
        cf = read_calibration(back)
        assert cf.model.name == "linear9" and cf.units_out == "counts"
        np.testing.assert_allclose(cf.x, x, rtol=1e-12)
        assert cf.meta["solver"] == f"import:{fmt}" and all(v is None for v in cf.meta["stderr"].values())
    assert read_calibration(tmp_path / "b_matrix.json").g_local == 1.0002  # the matrix file carries g_local
    assert read_calibration(tmp_path / "b_imucal.json").g_local == 1.0
    out = capsys.readouterr().out
    assert "wrote" in out and "in m/s2" in out  # imu_tk's calibrated unit is stated


def test_export_and_import_refuse_with_one_line_and_write_nothing(tmp_path, capsys):
    rng = np.random.default_rng(10)
    cal = cal_file(tmp_path, "linear9", random_linear(rng, "linear9", "g"), "g")
    x12 = np.concatenate([random_linear(rng, "linear9", "g"), [1e-4, 1e-4, 1e-4]])
    cal12 = cal_file(tmp_path, "nonlinear12", x12, "g", "c12.json")
    out = tmp_path / "out.txt"
    mat = tmp_path / "m.json"
    mat.write_text(export_text(read_calibration(cal), "matrix")[0])
    cases = [
        (["export", str(cal), "--format", "csv", "-o", str(out)], "invalid choice: 'csv'"),
        (["export", str(tmp_path / "absent.json"), "--format", "matrix", "-o", str(out)], "absent.json does not exist"),
        (["export", str(cal12), "--format", "imu_tk", "-o", str(out)], "quadratic (K2_x, K2_y, K2_z)"),
        (["export", str(cal), "--format", "kalibr", "-o", str(out)], "--bias-online"),
        (["export", str(cal), "--format", "matrix", "-o", str(out), "--bias-online"], "kalibr only"),
        (["export", str(cal), "--format", "imucal", "-o", str(out), "--calibrated-units", "g"], "in m/s2, not g"),
        (["export", str(cal), "--format", "matrix", "-o", str(tmp_path / "no" / "x.json")], "does not exist"),
        (["import", str(tmp_path / "absent.txt"), "--format", "imu_tk", "--units", "g", "-o", str(out)],
         "absent.txt does not exist"),
        (["import", str(cal), "--format", "imu_tk", "-o", str(out)], "give them with --units"),
        (["import", str(cal), "--format", "imu_tk", "--units", "g", "-o", str(out)], "is not a number"),
        (["import", str(cal), "--format", "imucal", "-o", str(out)], "cal_type None"),
        (["import", str(cal), "--format", "matrix", "-o", str(out)], "not an affine-matrix file"),
        (["import", str(cal), "--format", "kalibr", "-o", str(out)], "IMU model 'linear9'"),
        (["import", str(mat), "--format", "matrix", "-o", str(out), "--model", "nonlinear12"],
         "gives the linear part only"),
        (["import", str(mat), "--format", "matrix", "-o", str(out), "--model", "diag6"],
         "cannot hold this calibration's misalignment S_yz, S_zy, S_zx"),
        (["import", str(mat), "--format", "matrix", "-o", str(out), "--units", "counts"], "states raw units 'g'"),
    ]
    for argv, expected in cases:
        assert _exit(argv) == 2, argv
        err = _err_line(capsys)
        assert expected in err, (argv, err)
        assert not out.exists(), argv
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c12.json", "cal.json", "m.json"]  # no temporary file left


def test_an_existing_output_is_kept_unless_force(tmp_path, capsys):
    x = random_linear(np.random.default_rng(11), "diag6", "g")
    cal = cal_file(tmp_path, "diag6", x, "g")
    out = tmp_path / "m.json"
    out.write_text("mine")
    assert main(["export", str(cal), "--format", "matrix", "-o", str(out)]) == 2
    assert "exists" in _err_line(capsys) and out.read_text() == "mine"
    target = tmp_path / "imported.json"
    target.write_text("mine too")
    assert main(["export", str(cal), "--format", "matrix", "-o", str(out), "--force"]) == 0
    assert json.loads(out.read_text())["format"] == "optcal-affine-matrix"
    assert main(["import", str(out), "--format", "matrix", "-o", str(target)]) == 2
    assert "exists" in _err_line(capsys) and target.read_text() == "mine too"
    assert main(["import", str(out), "--format", "matrix", "-o", str(target), "--force"]) == 0
    assert read_calibration(target).model.name == "diag6"
    # an import that fails leaves the existing file as it was, even with --force
    (tmp_path / "bad.json").write_text(json.dumps({"format": "optcal-affine-matrix", "format_version": 1,
                                                   "C": np.zeros((3, 3)).tolist(), "d": [0, 0, 0],
                                                   "units": {"raw": "g", "calibrated": "g"}}))
    before = target.read_text()
    assert main(["import", str(tmp_path / "bad.json"), "--format", "matrix", "-o", str(target), "--force"]) == 2
    assert "singular" in _err_line(capsys) and target.read_text() == before


def test_the_commands_lists_match_the_library():
    """optcal/app/commands/export.py and import_.py keep copies of the formats and units (importing the library
    would slow every --help); they must be the library's."""
    from optcal.app.commands import export, import_
    from optcal.core.data import UNITS

    assert export.FORMATS == FORMATS and import_.FORMATS == FORMATS
    assert import_.UNITS == UNITS
