"""The calibration file (docs/design.md, "Calibration file"): exact round trip, refusal to overwrite, clear errors for
other versions and missing fields, and `apply` (Python API and `optcal apply`) inverting the model."""

import json
import math
from dataclasses import replace
from datetime import datetime

import numpy as np
import pytest

from optcal.app.cli import main
from optcal.app.fit import calibrate
from optcal.core.calfile import FORMAT, FORMAT_VERSION, calibration_to_dict, read_calibration, write_calibration
from optcal.core.errors import InputError
from optcal.core.model import Context, get_model
from optcal.core.presets import PAPER_TRUTH
from optcal.core.recording.reading import RAIL_MARGIN
from optcal.core.schemes import random_orientations
from optcal.core.simulate import simulate

COUNTS_TRUTH = {"K_x": 16301.0, "K_y": 16452.0, "K_z": 16690.0, "b_x": 0.021, "b_y": -0.013, "b_z": 0.042,
                "S_yz": 2.0e-3, "S_zy": -1.5e-3, "S_zx": 1.0e-3, "K2_x": 3.0, "K2_y": -2.0, "K2_z": 4.0}


@pytest.fixture(scope="module")
def fitted():
    sim = simulate("seed15", PAPER_TRUTH, np.random.default_rng(11), scheme="24")
    return calibrate(sim.data, "seed15")


@pytest.fixture(scope="module")
def counts_cal():
    m = get_model("nonlinear12")
    sim = simulate(m, COUNTS_TRUTH, np.random.default_rng(3), scheme="36", noise_g=20e-6)
    return calibrate(replace(sim.data, units="counts"), m)


def test_round_trip_is_exact(tmp_path, fitted):
    path = tmp_path / "cal.json"
    write_calibration(fitted, path, units_in="g", units_out="g", source="sim 24")
    d = json.loads(path.read_text())
    assert d["format"] == FORMAT and d["format_version"] == FORMAT_VERSION == 2
    assert d["model"] == "seed15" and d["terms"] == ["scale", "bias", "misalignment6", "quadratic"]
    assert d["units"] == {"raw": "g", "calibrated": "g", "parameters": fitted.model.units("g")}
    assert d["units"]["parameters"]["K_x"] == "g/g" and d["units"]["parameters"]["S_xz"] == "rad"
    assert d["solver"] == "lm"
    assert d["data"] == {"n_positions": 24, "rms_residual_g": fitted.fit.rms_g, "source": "sim 24"}
    assert datetime.fromisoformat(d["created"].replace("Z", "+00:00")).tzinfo is not None
    assert d["observability"]["rank"] == 12 and len(d["observability"]["unobservable"]) == 3
    # the three unobservable angles have no standard error: null in the file, NaN when read
    assert sum(v is None for v in d["stderr"].values()) == 6
    cf = read_calibration(path)
    assert cf.model == fitted.model and cf.g_local == fitted.problem.g_local
    np.testing.assert_array_equal(cf.x, fitted.x)  # bit for bit
    np.testing.assert_array_equal(np.isnan(cf.stderr), np.isnan(fitted.stderr))
    ok = np.isfinite(fitted.stderr)
    np.testing.assert_array_equal(cf.stderr[ok], fitted.stderr[ok])
    assert cf.parameters == fitted.parameters and cf.units_in == "g" and cf.units_out == "g"
    assert calibration_to_dict(fitted, units_out="g")["parameters"] == d["parameters"]


def test_existing_file_is_kept_unless_overwrite(tmp_path, fitted):
    path = tmp_path / "cal.json"
    path.write_text("precious")
    with pytest.raises(InputError, match="--force"):
        write_calibration(fitted, path, units_in="g", units_out="g")
    assert path.read_text() == "precious"
    write_calibration(fitted, path, units_in="g", units_out="g", overwrite=True)
    assert read_calibration(path).model.name == "seed15"


def test_other_versions_and_missing_fields_are_clear_errors(tmp_path, fitted):
    good = calibration_to_dict(fitted, units_out="g")

    def check(d, match, text=None):
        p = tmp_path / "bad.json"
        p.write_text(text if text is not None else json.dumps(d))
        with pytest.raises(InputError, match=match):
            read_calibration(p)

    check(None, "not a JSON calibration file", text="{not json")
    check({**good, "format": "imucal"}, "not an optcal calibration file")
    check({**good, "format_version": 4}, "format_version 4; this optcal reads versions 1, 2 and 3")
    check({k: v for k, v in good.items() if k != "format_version"}, "format_version None")
    for key in ("model", "terms", "parameters", "stderr", "units", "g_local", "data", "solver", "created"):
        check({k: v for k, v in good.items() if k != key}, f"lacks the field '{key}'")
    check({**good, "parameters": {k: v for k, v in good["parameters"].items() if k != "K_y"}}, "K_y")
    check({**good, "parameters": {**good["parameters"], "K_x": "big"}}, "not a number")
    check({**good, "model": "linear9"}, "does not match its terms")
    check({**good, "units": {"calibrated": "g"}}, "lacks 'raw'")
    check({**good, "data": {"n_positions": 24}}, "rms_residual_g")
    check({**good, "g_local": 9.81}, "not a local gravity in g")
    with pytest.raises(InputError, match="cannot read"):
        read_calibration(tmp_path / "absent.json")


def test_the_schema_names_the_field_in_one_line(tmp_path, fitted):
    """Wrong JSON types, unknown fields and values out of range: one line naming the field as the file
    writes it (dotted), never a traceback."""
    good = calibration_to_dict(fitted, units_out="g")
    p = tmp_path / "bad.json"
    cases = [
        ({**good, "stderr": {**good["stderr"], "K_x": "x"}},
         "field 'stderr.K_x' is not a number (it is string \"x\"): the file is damaged"),
        ({**good, "parameters": {**good["parameters"], "K_x": None}}, "field 'parameters.K_x' is not a number (it is "
                                                                      "null)"),
        ({**good, "parameters": {**good["parameters"], "K_x": math.inf}},
         "field 'parameters.K_x' is inf, not a finite number"),
        ({**good, "parameters": {**good["parameters"], "K_q": 1.0}}, "parameter(s) K_q are not in model seed15"),
        ({**good, "note": "mine"}, "field 'note' is not part of format version 2"),
        ({**good, "data": {**good["data"], "n_positions": 24.5}}, "field 'data.n_positions' is not an integer"),
        ({**good, "units": "g"}, "field 'units' is not an object (it is string \"g\")"),
        ({**good, "solver": 3}, "field 'solver' is not a string (it is integer 3)"),
    ]
    for d, message in cases:
        p.write_text(json.dumps(d))
        with pytest.raises(InputError) as exc:
            read_calibration(p)
        msg = str(exc.value)
        assert msg.startswith(f"{p}: ") and message in msg and "\n" not in msg, msg


def test_apply_inverts_the_model(counts_cal, tmp_path):
    write_calibration(counts_cal, tmp_path / "c.json", units_in="g", units_out="counts")
    cf = read_calibration(tmp_path / "c.json")
    rng = np.random.default_rng(0)
    A = random_orientations(5000, rng) * rng.uniform(0.2, 1.8, (5000, 1))
    N = cf.model.forward(cf.x, A)[0]
    got = cf.apply(N, chunk=1234)  # several chunks, one partial
    np.testing.assert_allclose(got, A, rtol=0, atol=1e-12)
    with pytest.raises(InputError, match="three columns"):
        cf.apply(N[:, :2])


def test_apply_reuses_the_calibrations_reference_temperature(tmp_path):
    m = get_model("linear9+temperature_bias")
    truth = {**{k: v for k, v in COUNTS_TRUTH.items() if k in m.names}, "beta_x": 2e-4, "beta_y": -1e-4,
             "beta_z": 3e-4}
    sim = simulate(m, truth, np.random.default_rng(4), scheme="36", noise_g=10e-6, temp=(15.0, 35.0))
    cal = calibrate(replace(sim.data, units="counts"), m)  # the truth's scale factors are counts per g
    write_calibration(cal, tmp_path / "t.json", units_in="g", units_out="counts")
    cf = read_calibration(tmp_path / "t.json")
    T0 = float(np.mean(sim.data.temp))
    assert cf.meta["context"] == {"T0": T0}
    # new data at other temperatures: the correction is relative to the calibration's T0, not theirs
    rng = np.random.default_rng(1)
    A = random_orientations(200, rng)
    temp = rng.uniform(40.0, 45.0, 200)
    N = m.forward(cf.x, A, Context(dtemp=temp - T0))[0]
    np.testing.assert_allclose(cf.apply(N, temp=temp), A, atol=1e-12)
    with pytest.raises(InputError, match="temp"):
        cf.apply(N)
    # a file without its reference temperature cannot be applied: refused when read, naming context.T0
    (tmp_path / "t0.json").write_text(json.dumps({**cf.meta, "context": {"T0": None}}))
    with pytest.raises(InputError, match=r"needs context\.T0"):
        read_calibration(tmp_path / "t0.json")


def _raw(path, t, N):
    np.savetxt(path, np.column_stack([t, N]), delimiter=",", header="t,ax,ay,az", comments="", fmt="%.17g")
    return str(path)


def test_cli_apply_writes_specific_force_and_refuses_to_overwrite(counts_cal, tmp_path, capsys):
    cal = tmp_path / "cal.json"
    write_calibration(counts_cal, cal, units_in="g", units_out="counts")
    rng = np.random.default_rng(2)
    A = random_orientations(3000, rng)
    N = counts_cal.model.forward(counts_cal.x, A)[0]
    raw = _raw(tmp_path / "raw.csv", np.arange(3000) / 100.0, N)
    out = tmp_path / "out.csv"
    assert main(["apply", str(cal), raw, "-o", str(out), "--output-units", "m/s2"]) == 0
    assert "3000 samples" in capsys.readouterr().out
    got = np.loadtxt(out, delimiter=",", skiprows=1)
    assert open(out).readline().strip() == "t,ax,ay,az"
    np.testing.assert_allclose(got[:, 1:], A * 9.80665, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(got[:, 0], np.arange(3000) / 100.0)
    # an existing output is never overwritten silently
    before = out.read_bytes()
    assert main(["apply", str(cal), raw, "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--force" in err[0] and out.read_bytes() == before
    assert main(["apply", str(cal), raw, "-o", str(out), "--force"]) == 0
    np.testing.assert_allclose(np.loadtxt(out, delimiter=",", skiprows=1)[:, 1:], A, rtol=1e-9, atol=1e-9)


def test_cli_apply_bad_input(counts_cal, tmp_path, capsys):
    cal = tmp_path / "cal.json"
    write_calibration(counts_cal, cal, units_in="g", units_out="counts")
    N = counts_cal.model.forward(counts_cal.x, random_orientations(500, np.random.default_rng(5)))[0]
    raw = _raw(tmp_path / "raw.csv", np.arange(500) / 100.0, N)
    v3 = tmp_path / "v3.json"
    v3.write_text(json.dumps({**json.loads(cal.read_text()), "format_version": 3}))
    cases = [
        (["apply", str(v3), raw, "-o", str(tmp_path / "a.csv")], "format_version 3"),
        (["apply", str(cal), raw, "-o", str(tmp_path / "b.csv"), "--units", "g"], "fitted to outputs in 'counts'"),
        (["apply", str(cal), str(tmp_path / "none.csv"), "-o", str(tmp_path / "c.csv")], "cannot read"),
    ]
    ms2 = _raw(tmp_path / "ms2.csv", np.arange(500) / 100.0, N / 16384 * 9.80665)
    cases.append((["apply", str(cal), ms2, "-o", str(tmp_path / "d.csv")], "--units m/s2"))
    (tmp_path / "empty.csv").write_text("\n")
    cases.append((["apply", str(cal), str(tmp_path / "empty.csv"), "-o", str(tmp_path / "e.csv")], "is empty"))
    for argv, msg in cases:
        assert main(argv) == 2, argv
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and msg in err[0], err


def test_cli_apply_without_time_and_with_saturation(counts_cal, tmp_path, capsys):
    cal = tmp_path / "cal.json"
    write_calibration(counts_cal, cal, units_in="g", units_out="counts")
    N = counts_cal.model.forward(counts_cal.x, random_orientations(400, np.random.default_rng(6)) * 2.1)[0]
    N = np.clip(np.round(N), -32768, 32767)
    path = tmp_path / "raw.txt"
    np.savetxt(path, N, fmt="%d")  # whitespace-separated, no header, no time
    out = tmp_path / "o.csv"
    assert main(["apply", str(cal), str(path), "-o", str(out)]) == 0
    text = capsys.readouterr().out
    got = np.loadtxt(out, delimiter=",", skiprows=1)
    header = open(out).readline().strip().split(",")
    assert header[:3] == ["ax", "ay", "az"]
    m = RAIL_MARGIN * 65535  # within 33 codes of a rail is at it
    sat = np.any((N <= -32768 + m) | (N >= 32767 - m), axis=1)  # 2.1 g exceeds the ±2 g int16 range on some axes
    assert 0 < sat.sum() < 400
    assert header[-1] == "saturated" and np.array_equal(got[:, -1].astype(bool), sat)
    assert f"{int(sat.sum())} saturated sample(s)" in text
    np.testing.assert_allclose(np.linalg.norm(got[~sat, :3], axis=1), 2.1, rtol=1e-3)


def test_calibrate_cli_writes_a_readable_file(tmp_path, capsys):
    sim = simulate("nonlinear12", {k: v for k, v in PAPER_TRUTH.items() if k in get_model("nonlinear12").names},
                   np.random.default_rng(8))
    pos = tmp_path / "pos.csv"
    sim.data.to_csv(pos)
    cal = tmp_path / "cal.json"
    assert main(["calibrate", str(pos), "--model", "nonlinear12", "-o", str(cal), "--json"]) == 0
    printed = json.loads(capsys.readouterr().out)
    cf = read_calibration(cal)
    assert cf.parameters == printed["parameters"] and cf.meta["data"]["source"] == str(pos)


def test_a_version_1_file_is_read_with_its_units_mapped(counts_cal, tmp_path):
    """Version 1 named the units input ("g") and output (the raw units); they are read as units.calibrated and
    units.raw, and the parameters are the same to the bit (docs/design.md, "Calibration file")."""
    d = calibration_to_dict(counts_cal, units_out="counts")
    assert d["units"]["raw"] == "counts" and d["units"]["calibrated"] == "g"
    assert d["units"]["parameters"]["K_x"] == "counts/g" and d["units"]["parameters"]["K2_x"] == "counts/g²"
    v1 = {**d, "format_version": 1, "units": {"input": "g", "output": "counts"}}
    (tmp_path / "v1.json").write_text(json.dumps(v1))
    cf = read_calibration(tmp_path / "v1.json")
    assert cf.raw_units == cf.units_out == "counts" and cf.calibrated_units == cf.units_in == "g"
    assert cf.meta["format_version"] == 2 and cf.meta["units"] == d["units"]
    np.testing.assert_array_equal(cf.x, counts_cal.x)
    # a version-2 file with version 1's names, or with units that contradict each other, is refused
    cases = [({**d, "units": {"input": "g", "output": "counts"}}, "field 'units' lacks 'raw'"),
             ({**v1, "units": {"raw": "counts", "calibrated": "g"}}, "format_version 1 names its units input"),
             ({**d, "units": {**d["units"], "raw": "furlongs"}}, "units.raw 'furlongs' is not an output unit"),
             ({**d, "units": {**d["units"], "raw": "g"}}, "units.parameters disagree with units.raw 'g' for K2_x"),
             ({**d, "units": {**d["units"], "calibrated": "m/s2"}}, "field 'units.calibrated'")]
    for doc, message in cases:
        (tmp_path / "bad.json").write_text(json.dumps(doc))
        with pytest.raises(InputError) as exc:
            read_calibration(tmp_path / "bad.json")
        assert message in str(exc.value) and "\n" not in str(exc.value), str(exc.value)
