"""Units (issue #13, docs/design.md, "Units and frames", "Calibration file"): every parameter's unit from one table
(Model.units), in the printed table, the --json outputs and the calibration file; apply and nav refuse a calibration
whose units are not the data's or the truth's."""

import json

import numpy as np
import pytest

from optcal.app.cli import main
from optcal.app.fit import calibrate
from optcal.core.calfile import read_calibration, write_calibration
from optcal.core.data import guess_units
from optcal.core.model import TERMS, get_model
from optcal.core.presets import PAPER_TRUTH
from optcal.core.schemes import random_orientations
from optcal.core.simulate import simulate

COUNTS = {"K_x": 16301.0, "K_y": 16452.0, "K_z": 16690.0, "b_x": 0.021, "b_y": -0.013, "b_z": 0.042,
          "S_yz": 2.0e-3, "S_zy": -1.5e-3, "S_zx": 1.0e-3}


def test_each_terms_parameters_have_the_units_of_the_design_table():
    every = get_model("+".join(t for t in TERMS if t != "misalignment"))
    u = every.units("counts")
    expected = {"K_x": "counts/g", "b_y": "g", "S_xz": "rad", "K2_z": "counts/g²", "K3_x": "counts/g³",
                "kappa_y": "1", "c_xy": "1/g", "beta_z": "g/°C", "gamma_x": "1/°C", "d_y": "g/s"}
    assert {n: u[n] for n in expected} == expected
    assert list(u) == list(every.names)
    assert get_model("linear9").units("m/s2")["K_x"] == "(m/s²)/g"
    assert get_model("diag6").units("volts")["K_y"] == "V/g" and get_model("diag6").units("mg")["K_z"] == "mg/g"
    assert get_model("nonlinear12").units("g")["K2_x"] == "g/g²"


@pytest.mark.parametrize("magnitude, units", [(1.0, "g"), (9.80665, "m/s2"), (1000.0, "mg"), (16384.0, "counts"),
                                              (4096.0, "counts"), (300.0, None), (0.0, None), (float("nan"), None)])
def test_the_units_a_magnitude_looks_like(magnitude, units):
    assert guess_units(magnitude) == units


@pytest.fixture(scope="module")
def counts_files(tmp_path_factory):
    d = tmp_path_factory.mktemp("units")
    m = get_model("linear9")
    from dataclasses import replace

    sim = simulate(m, COUNTS, np.random.default_rng(2), scheme="24", noise_g=20e-6)
    data = replace(sim.data, units="counts")
    data.to_csv(d / "pc.csv")
    write_calibration(calibrate(data, m), d / "calc.json", units_out="counts")
    A = random_orientations(400, np.random.default_rng(3))
    np.savetxt(d / "raw_g.csv", np.column_stack([np.arange(400) / 100.0, A]), delimiter=",", header="t,ax,ay,az",
               comments="", fmt="%.10g")
    (d / "truth_g.json").write_text(json.dumps({k: v for k, v in PAPER_TRUTH.items() if k in m.names}))
    return d


def test_the_calibration_file_states_raw_calibrated_and_parameter_units(counts_files):
    doc = json.loads((counts_files / "calc.json").read_text())
    assert doc["format_version"] == 2
    assert doc["units"]["raw"] == "counts" and doc["units"]["calibrated"] == "g"
    assert doc["units"]["parameters"] == {**{f"K_{a}": "counts/g" for a in "xyz"}, **{f"b_{a}": "g" for a in "xyz"},
                                          "S_yz": "rad", "S_zy": "rad", "S_zx": "rad"}
    cf = read_calibration(counts_files / "calc.json")
    assert cf.raw_units == "counts" and cf.calibrated_units == "g" and cf.parameter_units["K_x"] == "counts/g"


def test_calibrate_prints_and_writes_the_units(counts_files, capsys):
    assert main(["calibrate", str(counts_files / "pc.csv"), "--model", "linear9", "--units", "counts"]) == 0
    out = capsys.readouterr().out
    rows = {ln.split()[0]: ln.split() for ln in out.splitlines() if ln.split() and ln.split()[0] in COUNTS}
    assert rows["K_x"][-1] == "counts/g" and rows["b_x"][-1] == "g" and rows["S_yz"][-1] == "rad"
    assert float(rows["K_x"][1]) == pytest.approx(16301.0, rel=1e-3)
    assert "outputs in counts" in out
    assert main(["calibrate", str(counts_files / "pc.csv"), "--model", "linear9", "--units", "counts", "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["output_units"] == "counts" and list(res["units"]) == list(res["parameters"])
    assert res["units"]["K_y"] == "counts/g" and res["units"]["b_z"] == "g"


def test_info_and_discover_json_carry_units(counts_files, capsys):
    assert main(["info", "--model", "nonlinear12", "--noise-ug", "10", "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["units"]["K2_x"] == "g/g²" and res["output_units"] == "g" and set(res["units"]) == set(res["crlb"])
    assert main(["discover", str(counts_files / "pc.csv"), "--units", "counts", "--base", "diag6",
                 "--candidates", "misalignment", "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["output_units"] == "counts" and set(res["units"]) == set(res["final_parameters"])
    assert res["units"]["K_x"] == "counts/g"


def _one_line(capsys) -> str:
    err = capsys.readouterr().err
    assert "Traceback" not in err and err.count("\n") == 1, err
    return err


def test_apply_refuses_a_counts_calibration_on_data_in_g(counts_files, capsys):
    """(a): the calibration was fitted to counts (|K| about 16,400), the recording is in g (magnitude 1)."""
    out = counts_files / "a.csv"
    assert main(["apply", str(counts_files / "calc.json"), str(counts_files / "raw_g.csv"), "-o", str(out)]) == 2
    err = _one_line(capsys)
    assert "'counts'" in err and "look" in err and not out.exists()
    # the same data in counts are applied
    N = get_model("linear9").forward(read_calibration(counts_files / "calc.json").x,
                                     random_orientations(300, np.random.default_rng(5)))[0]
    np.savetxt(counts_files / "raw_c.csv", np.column_stack([np.arange(300) / 100.0, N]), delimiter=",",
               header="t,ax,ay,az", comments="", fmt="%.12g")
    assert main(["apply", str(counts_files / "calc.json"), str(counts_files / "raw_c.csv"), "-o", str(out)]) == 0
    got = np.loadtxt(out, delimiter=",", skiprows=1)[:, 1:]
    np.testing.assert_allclose(np.linalg.norm(got, axis=1), 1.0, atol=1e-8)


def test_nav_refuses_a_counts_calibration_against_a_plain_truth_in_g(counts_files, capsys):
    """(b): a {name: value} truth states no units; its scale factors (about 1) say g."""
    code = main(["nav", str(counts_files / "calc.json"), "--truth", str(counts_files / "truth_g.json")])
    assert code == 2
    err = _one_line(capsys)
    assert "looks like outputs in g" in err and "outputs in counts" in err
    (counts_files / "empty.json").write_text("{}")
    assert main(["nav", str(counts_files / "calc.json"), "--truth", str(counts_files / "empty.json")]) == 2
    assert "is empty" in _one_line(capsys)
    # the counts truth is accepted
    (counts_files / "truth_c.json").write_text(json.dumps(COUNTS))
    assert main(["nav", str(counts_files / "calc.json"), "--truth", str(counts_files / "truth_c.json"),
                 "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["max_error_nmi"] > 0


def test_height_without_latitude_is_refused(counts_files, capsys):
    args = ["calibrate", str(counts_files / "pc.csv"), "--model", "linear9", "--units", "counts", "--height", "250"]
    assert main(args) == 2
    assert "without a latitude" in _one_line(capsys)
    assert main(args + ["--latitude", "45"]) == 0


def test_a_gravity_that_looks_like_g_is_named(capsys):
    from optcal.core.errors import InputError
    from optcal.core.gravity import check_gravity_g, local_gravity_g

    with pytest.raises(InputError, match="looks like g, not m/s²"):
        local_gravity_g(1.0)
    with pytest.raises(InputError, match="looks like m/s², not g"):
        check_gravity_g(9.81)
    assert local_gravity_g(9.80665) == 1.0 and check_gravity_g(1.0) == 1.0


def test_an_implausible_noise_is_a_warning_not_an_error(tmp_path, capsys):
    assert main(["simulate", "--noise-ug", "10000", "-o", str(tmp_path / "p.csv")]) == 0
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "warning" in err and "10 mg per position mean is implausible" in err
