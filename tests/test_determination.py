"""A calibration only when the data determine it (issue #20, items 3 and 7; optcal/core/determination.py,
docs/design.md, "Per-position residuals, outliers, the robust loss, what the data determine and weak fits"): each
class of refusal with its one line, the default model's fallback and its note,
the expert's override recorded in the calibration file and announced by optcal apply, and well-posed fits
(simulated, counts with an unsigned offset, seed15's gauge) left alone."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest

from optcal.app.cli import main
from optcal.app.fit import calibrate
from optcal.core import determination
from optcal.core.calfile import read_calibration, write_calibration
from optcal.core.data import PositionsData
from optcal.core.errors import InputError
from optcal.core.model import get_model
from optcal.core.presets import PAPER_TRUTH
from optcal.core.schemes import six_position, tilt
from optcal.core.simulate import simulate

N12 = get_model("nonlinear12")
L9 = get_model("linear9")
TRUTH12 = {k: v for k, v in PAPER_TRUTH.items() if k in N12.names}
TRUTH9 = {k: v for k, v in PAPER_TRUTH.items() if k in L9.names}


def _sim(model=N12, truth=TRUTH12, seed=1, scheme="24", noise_g=10e-6, **kw):
    return simulate(model, truth, np.random.default_rng(seed), scheme=scheme, noise_g=noise_g, **kw).data


def _refused(*args, **kw) -> str:
    with pytest.raises(InputError) as info:
        calibrate(*args, **kw)
    line = str(info.value)
    assert "\n" not in line
    return line


# -- each class of refusal -------------------------------------------------------------------------------------
def test_rank_deficient_positions_are_refused_naming_the_directions_and_a_smaller_model():
    """The six ±axis poses, twice: the norm sees no misalignment (docs/design.md, "What a fit refuses"), so linear9
    has rank 6 of 9; diag6 is determined by the same 12 positions (6 residual degrees of freedom) and the line names
    it."""
    data = _sim(L9, TRUTH9, scheme="6")
    twice = replace(data, N=np.vstack([data.N, data.N + 1e-5 * np.random.default_rng(0).standard_normal((6, 3))]),
                    position=np.arange(12), n_samples=None, std=None, sem=None, t=None, temp=None)
    line = _refused(twice, "linear9")
    assert line.startswith("these positions leave model linear9 unobservable (rank 6 of 9; directions: ")
    assert all(s in line for s in ("S_yz", "S_zy", "S_zx"))
    assert "fit a smaller model (`model` diag6)" in line and "`force_weak`" in line
    assert calibrate(twice, "diag6").fit.dof == 6


def test_too_few_positions_for_the_model():
    line = _refused(_sim().subset(range(10)), "nonlinear12")
    assert line.startswith("10 positions give 10 residuals, fewer than the 12 parameters of nonlinear12; "
                           "record at least 15 positions (more varied)")


def test_fewer_than_three_residual_degrees_of_freedom():
    idx = [0, 1, 2, 4, 6, 8, 9, 12, 17, 21]  # linear9 observable, one spare residual
    line = _refused(_sim(L9, TRUTH9, noise_g=1e-3, seed=0).subset(idx), "linear9")
    assert line.startswith("10 positions leave linear9 only 1 residual degree(s) of freedom (9 determined "
                           "parameters), fewer than 3; record at least 12 positions")


def test_an_exact_fit_of_12_positions_to_12_parameters():
    data = _sim(scheme="random:12", seed=3)
    line = _refused(data, "nonlinear12")
    assert line.startswith("12 positions give 12 residuals for the 12 determined parameters of nonlinear12: an "
                           "exact fit, with no residual left to judge it by; record at least 15 positions")
    cal = calibrate(data, "nonlinear12", force_weak=True)  # the expert's fit: residual at rounding level
    assert cal.fit.rms_g < 1e-9 and cal.forced == [line.split("; record")[0]]


def test_exact_data_are_refused_after_the_fit():
    """24 positions simulated without noise: 12 degrees of freedom, but residuals at the rounding of the
    numbers, so nothing measures the noise (the standard errors would be zero)."""
    line = _refused(_sim(noise_g=0.0), "nonlinear12")
    assert line.startswith("the residual RMS over 24 positions is ") and "at the rounding of the numbers" in line
    assert "calibrate from recorded positions" in line
    # with the noise stated, residuals a million times below it (χ²/dof < 1e-6) are refused the same way
    data = _sim(noise_g=5e-9)  # residuals of a few ng: above rounding, far below 10 µg
    line = _refused(data, "nonlinear12", noise_g=10e-6)
    assert "times below the noise of the position means (10 µg)" in line


def test_an_implausible_scale_factor_of_2_5e7():
    """Outputs 2.5e7 times what a sensor in g reads (the issue's tumble taken as static intervals gave such
    factors): the fit is refused, naming the parameter, its ratio to the nominal and the bounds."""
    truth = {**TRUTH9, "K_x": 2.5e7, "K_y": 2.5e7, "K_z": 2.5e7}
    line = _refused(_sim(L9, truth), "linear9")
    assert line.startswith("the fit of linear9 is physically implausible: K_x = 2.5e+07 g/g against the nominal 1 "
                           "± 30% (also K_y, K_z); check the units")
    assert "rows: a recording's samples?" not in line  # 24 positions
    # in counts the same sensor is plausible: the nominal is the outputs' sphere, 2.5e7 per g
    cal = calibrate(replace(_sim(L9, truth), units="counts"), "linear9")
    assert cal.forced == [] and cal.x[0] == pytest.approx(2.5e7, rel=1e-3)


def test_an_offset_beyond_half_a_g():
    line = _refused(_sim(L9, {**TRUTH9, "b_x": 0.6}), "linear9")
    assert "b_x = 0.6 g is beyond ±0.5 g" in line


def test_a_misalignment_of_10_degrees():
    line = _refused(_sim(L9, {**TRUTH9, "S_yz": math.radians(10)}), "linear9")
    assert "S_yz = 0.1745 rad (10°) is beyond ±5°" in line
    # 4° is within the bound
    assert calibrate(_sim(L9, {**TRUTH9, "S_yz": math.radians(4)}), "linear9").forced == []


def test_nonlinear_temperature_and_drift_bounds():
    """Bounds of the terms beyond linear9, judged on given parameters: a quadratic term 6 % of the scale at 1 g,
    a bias temperature coefficient moving the offset by 0.6 g over the data's ±10 °C, a drift of 0.6 g over
    the data's 100 s."""
    m = get_model("linear9+quadratic+temperature_bias+bias_drift")
    data = _sim(L9, TRUTH9, temp=(10.0, 30.0), times=True)
    dtemp = determination.span(data.temp, centred=True)
    dt = determination.span(data.t, centred=False)
    x = m.from_dict({**TRUTH9, "K2_x": 0.01, "beta_y": 1e-4, "d_z": 1e-6})
    assert determination.plausibility(m, x, data) == []
    x = m.from_dict({**TRUTH9, "K2_x": 0.06, "beta_y": 0.6 / dtemp, "d_z": 0.6 / dt})
    (r,) = determination.plausibility(m, x, data)
    assert r.kind == "implausible"
    assert r.reason.endswith("K2_x = 0.06 g/g² changes the output at 1 g by 0.06 of the scale factor, bound 0.05 "
                             "(also beta_y, d_z)")


def test_counts_with_an_unsigned_offset_are_plausible():
    """An unsigned 16-bit ADC reads about 32768 at zero g (the Xsens MTi of the real corpus's imu_tk/: offsets
    32360 to 33276 counts, about 8 g as b): the offset is judged against the outputs' sphere centre, not ±0.5 g."""
    truth = {**TRUTH9, "K_x": 4070.0, "K_y": 4050.0, "K_z": 4070.0, "b_x": 8.14, "b_y": 8.2, "b_z": 7.95}
    data = replace(_sim(L9, truth, noise_g=30e-6), units="counts")
    nominal, centre = determination.nominal_scale(data)
    assert nominal == pytest.approx(4063, rel=0.01)
    np.testing.assert_allclose(centre, [4070 * 8.14, 4050 * 8.2, 4070 * 7.95], rtol=1e-3)
    assert calibrate(data, "linear9").forced == []
    # the same fit with its zero-g output moved 0.6 g from the centre is refused
    x = L9.from_dict({**truth, "b_x": 8.14 + 0.6})
    (r,) = determination.plausibility(L9, x, data)
    assert "b_x = 8.74 g puts the zero-g output" in r.reason and "more than 0.5 g from the outputs' centre" in r.reason


def test_seed15_gauge_and_well_posed_fits_are_not_refused():
    cal = calibrate(_sim(get_model("seed15"), PAPER_TRUTH), "seed15")
    assert cal.observability.rank == 12 and cal.forced == []
    cal = calibrate(_sim())
    assert cal.model.name == "nonlinear12" and cal.requested_model is None and cal.forced == []
    assert not any(n.startswith(("forced", "nonlinear12 (the default model)")) for n in cal.notes)


# -- the default model's fallback -------------------------------------------------------------------------
def test_the_default_model_falls_back_to_the_richest_determined_one_in_one_note():
    data = _sim().subset(range(10))  # 10 positions: nonlinear12 too many parameters, linear9 one spare
    cal = calibrate(data)
    assert cal.model.name == "diag6" and cal.requested_model == "nonlinear12"
    assert cal.to_dict()["requested_model"] == "nonlinear12" and cal.to_dict()["forced"] == []
    assert cal.notes[0] == ("nonlinear12 (the default model) is not determined by these positions: 10 positions "
                            "give 10 residuals, fewer than the 12 parameters of nonlinear12; fitted diag6 instead, "
                            "the richest of nonlinear12 → linear9 → diag6 that they determine")
    cal = calibrate(_sim(L9, TRUTH9, scheme="random:14"))  # nonlinear12 would have 2 spare, linear9 has 5
    assert cal.model.name == "linear9" and cal.notes[0].startswith("nonlinear12 (the default model) is not")
    # named, the same model is refused, and the line names the model that would work
    line = _refused(data, "nonlinear12")
    assert "fit a smaller model (`model` diag6)" in line
    # when no model of the chain is determined, the default's reason and that none smaller is either
    line = _refused(_sim().subset(range(8)))
    assert line.startswith("8 positions give 8 residuals, fewer than the 12 parameters of nonlinear12 (nor any "
                           "smaller model of nonlinear12/linear9/diag6: diag6 needs 9 varied positions); record "
                           "at least 15 positions")
    assert len(line) <= 300 - len("optcal calibrate: error: ")  # whole, not cut by the CLI


def test_the_cli_falls_back_and_says_so(tmp_path, capsys):
    _sim().subset(range(10)).to_csv(tmp_path / "p.csv")
    assert main(["calibrate", str(tmp_path / "p.csv")]) == 0
    out = capsys.readouterr().out
    assert out.startswith("model diag6, 10 positions")
    assert "note: nonlinear12 (the default model) is not determined by these positions" in out
    assert main(["calibrate", str(tmp_path / "p.csv"), "--model", "nonlinear12"]) == 2
    err = capsys.readouterr().err
    assert "fit a smaller model (--model diag6), or pass --force-weak" in err


# -- the expert's override ---------------------------------------------------------------------------------
def test_a_forced_fit_is_recorded_in_its_file_and_announced_by_apply(tmp_path, capsys):
    idx = [0, 1, 2, 4, 6, 8, 9, 12, 17, 21]
    _sim(L9, TRUTH9, noise_g=1e-3, seed=0).subset(idx).to_csv(tmp_path / "p.csv")
    cal, raw = tmp_path / "cal.json", tmp_path / "raw.csv"
    argv = ["calibrate", str(tmp_path / "p.csv"), "--model", "linear9", "-o", str(cal)]
    assert main(argv) == 2 and not cal.exists()
    assert "only 1 residual degree(s) of freedom" in capsys.readouterr().err
    assert main(argv + ["--force-weak"]) == 0
    out = capsys.readouterr().out
    assert ("note: forced although the data do not determine it: 10 positions leave linear9 only 1 residual "
            "degree(s)") in out
    d = json.loads(cal.read_text())
    assert d["forced"] is True and d["format_version"] == 2
    assert d["forced_reasons"][0] == ("10 positions leave linear9 only 1 residual degree(s) of freedom (9 "
                                      "determined parameters), fewer than 3")
    assert read_calibration(cal).forced == d["forced_reasons"]
    A = six_position()
    np.savetxt(raw, np.column_stack([np.arange(6) / 100, A]), delimiter=",", header="t,ax,ay,az", comments="")
    assert main(["apply", str(cal), str(raw), "-o", str(tmp_path / "out.csv")]) == 0
    out = capsys.readouterr().out
    assert "note: applying a forced calibration (written with --force-weak although the data did not determine " \
           "it): 10 positions leave linear9 only 1 residual" in out
    # a determined fit's file has neither field, and a file with one of them alone is refused
    good = calibrate(_sim(L9, TRUTH9), "linear9")
    write_calibration(good, tmp_path / "good.json")
    g = json.loads((tmp_path / "good.json").read_text())
    assert "forced" not in g and "forced_reasons" not in g and read_calibration(tmp_path / "good.json").forced == []
    (tmp_path / "half.json").write_text(json.dumps({**g, "forced": True}))
    with pytest.raises(InputError, match="forced: true and its forced_reasons"):
        read_calibration(tmp_path / "half.json")


def test_means_of_a_slow_tumble_taken_as_static_positions_are_refused():
    """The issue's case: 13 'static' intervals cut from a slow continuous rotation. Gravity sweeps a cone in
    the sensor frame, so the 13 means lie on one circle, which leaves even diag6's ellipsoid undetermined:
    refused for every model of the chain, naming the directions (at most 3, each by its 3 largest weights)."""
    from optcal.core.data import PositionsData
    from optcal.core.synthetic_recording import tumble_recording

    N = tumble_recording(np.random.default_rng(1), duration_s=120, turn_rate_dps=3.0).recording.N
    starts = np.linspace(0, len(N) - 300, 13).astype(int)
    data = PositionsData(N=np.array([N[i:i + 300].mean(axis=0) for i in starts]), units="g")
    line = _refused(data)
    assert line.startswith("these positions leave model nonlinear12 unobservable (rank 7 of 12; directions: ")
    assert "; and 2 more)" in line and "(nor any smaller model" in line
    assert _refused(data, "diag6").startswith("these positions leave model diag6 unobservable (rank 5 of 6")


def test_real_recordings_that_determine_their_fits_are_not_refused(corpus):
    """Hassan & Bao's 24 and 49 positions (g) with the default model and linear9, and the MPU-6050's ten poses
    at the recording's own intervals (int16 counts, diag6: 4 spare degrees of freedom) pass every check;
    the same ten poses do not determine linear9 (1 spare), which is refused."""
    from scipy.io import loadmat

    from optcal.core.data import PositionsData
    from optcal.core.recording import given_intervals, positions_from_recording, read_recording

    data = corpus  # the real corpus, beside the project (tests/corpus.py)
    for name in ("CalibrationOfLowCostTriaxialInertialSensors.mat",
                 "CalibrationOfLowCostTriaxialInertialSensors50.mat"):
        (a,) = [v for k, v in loadmat(data / "hassan_bao" / name).items() if not k.startswith("__")]
        positions = PositionsData(N=a.T if a.shape[0] == 3 else a, units="g")
        for model in (None, "linear9"):
            cal = calibrate(positions, model)
            assert cal.forced == [] and cal.requested_model is None and cal.model.name == (model or "nonlinear12")
    rec = read_recording(data / "mpu6050" / "example_data_calibration.csv", units="counts")
    ref = np.loadtxt(data / "mpu6050" / "static_intervals.csv", delimiter=",").T.astype(int)
    ref[:, 1] += 1
    poses = positions_from_recording(rec, given_intervals(rec, ref))
    cal = calibrate(poses, "diag6")
    assert cal.forced == [] and np.all(np.abs(cal.x[:3] / determination.nominal_scale(poses)[0] - 1) < 0.03)
    assert "only 1 residual degree(s) of freedom" in _refused(poses, "linear9")


def test_a_raw_recording_with_too_few_poses_for_the_default_falls_back(tmp_path, capsys, corpus):
    """The MPU-6050's ten poses found by the variance detector (its threshold searched over 2…9): no threshold
    finds intervals nonlinear12 or linear9 can be fitted to, so the default's intervals are found for diag6,
    which is fitted and said (CLI and API alike)."""
    import optcal

    path = corpus / "mpu6050" / "example_data_calibration.csv"
    cal = optcal.calibrate(path, raw=True, units="counts", threshold_k="2:9")
    assert cal.model.name == "diag6" and len(cal.problem.data) == 10 and cal.requested_model == "nonlinear12"
    assert cal.notes[0].startswith("nonlinear12 (the default model) is not determined by these positions: 10 "
                                   "positions give 10 residuals")
    assert main(["calibrate", str(path), "--raw", "--units", "counts", "--threshold-k", "2:9", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["model"] == "diag6" and out["requested_model"] == "nonlinear12" and out["n_positions"] == 10
    np.testing.assert_allclose([out["parameters"][f"K_{a}"] for a in "xyz"], cal.x[:3], rtol=1e-12)
    # a named model is not replaced: its recording error stands
    with pytest.raises(InputError, match="linear9"):
        optcal.calibrate(path, "linear9", raw=True, units="counts", threshold_k="2:9")


def _x_axis_hardly_turned(lim: float, noise: float):
    """24 positions turned about x with the x axis within ±sin(lim) of level (a tag that never points x up),
    linear9 truth, ``noise`` g per axis on each mean (n = 100 samples of SD 10·noise)."""
    m = get_model("linear9")
    x = m.from_dict({k: v for k, v in PAPER_TRUTH.items() if k in m.names})
    rng = np.random.default_rng(4)
    th = np.linspace(0, 2 * np.pi, 24, endpoint=False)
    ph = rng.uniform(-lim, lim, 24)
    A = np.column_stack([np.sin(ph), np.cos(ph) * np.sin(th), np.cos(ph) * np.cos(th)])
    N = m.forward(x[None], A)[0] + rng.normal(0, noise, A.shape)
    return PositionsData(N=N, n_samples=np.full(24, 100.0), std=np.full(A.shape, 10 * noise))


def test_the_default_model_falls_back_past_terms_known_no_better_than_a_datasheet():
    """Faces tilted by a few degrees, 2 mg noise: nonlinear12 is structurally determined, but its second-order
    terms come out with standard errors above half their datasheet spread, so linear9 is fitted, and said;
    named, nonlinear12 is fitted as named."""
    m = get_model("linear9")
    truth = {k: v for k, v in PAPER_TRUTH.items() if k in m.names}
    rng = np.random.default_rng(3)
    A = np.vstack([tilt(six_position(), 6.0, rng) for _ in range(3)])
    N = m.forward(m.from_dict(truth)[None], A)[0] + rng.normal(0, 2e-3 / np.sqrt(3), A.shape)
    data = PositionsData(N=N, n_samples=np.full(len(A), 300.0), std=np.full(A.shape, 2e-2))
    cal = calibrate(data)
    assert cal.model.name == "linear9" and cal.requested_model == "nonlinear12" and cal.forced == []
    assert cal.notes[0].startswith("nonlinear12 (the default model) is not determined by these positions: "
                                   "nonlinear12: K2_x, K2_y, K2_z known no better than a datasheet says")
    assert calibrate(data, "nonlinear12").model.name == "nonlinear12"


def test_the_default_model_is_refused_when_even_diag6_is_known_no_better_than_a_datasheet():
    """The x axis never more than 0.2 rad from level: K_x of diag6 stays as uncertain as a datasheet's spread,
    so nothing of the chain is written (one line), unless forced."""
    data = _x_axis_hardly_turned(0.2, 2e-3)
    with pytest.raises(InputError, match=r"^K_x of diag6 known no better than a datasheet says \(standard error "
                                         r"above half its spread\); record more varied positions, or pass "
                                         r"`force_weak`"):
        calibrate(data)
    cal = calibrate(data, force_weak=True)
    assert cal.model.name == "diag6" and any("known no better than a datasheet" in r for r in cal.forced)


def test_an_implausible_fit_of_many_rows_says_they_may_be_samples_within_one_line(tmp_path, capsys):
    """A wandering log of 1,200 samples read as a positions file (its rows differ by a few % of g, between what
    samples and positions show): the refusal names the first parameter out of bounds in full, counts the
    others, says that so many rows may be samples with the option that reads them, and fits the CLI's 300
    characters without cutting the parameter's line (a new user's read "K_y = 1.136e+06 (m/s²)/g is … nominal
    9.8066 (bounds ±30%); … is 487 …")."""
    from optcal.app.cli import main

    rng = np.random.default_rng(4)
    tilt = np.cumsum(rng.normal(0, 0.02, (1200, 2)), axis=0)  # a wander of 60-70° in x and y, z unchanged
    N = np.column_stack([9.81 * np.sin(tilt), np.full(1200, -11.2)]) + rng.normal(0, [0.2, 0.16, 0.44], (1200, 3))
    path = tmp_path / "drive.csv"
    np.savetxt(path, N, delimiter=",", fmt="%.5f")
    assert main(["calibrate", str(path), "--units", "m/s2"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err) <= 300 and "…" not in err, err
    assert "physically implausible: K_" in err and "(m/s²)/g against the nominal 9.8066 ± 30% (also " in err
    assert "1200 rows: a recording's samples? pass --raw" in err
