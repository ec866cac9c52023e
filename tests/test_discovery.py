"""Discovery (issue 7, docs/design.md, "Model discovery"): on data with a hidden effect, the workflow names the
missing term, adds it, and the residual shrinks to what the true model leaves; on data without one it adds nothing."""

import dataclasses
import json

import numpy as np
import pytest
from corpus import corpus_root
from scipy import stats

from optcal import get_model, simulate
from optcal.app.cli import main
from optcal.app.workflows.discovery import discover, fit_model
from optcal.core.discovery import EXPLAINED, NO_DOF, REMAINS
from optcal.core.errors import InputError
from optcal.core.model import TERMS
from optcal.core.presets import draw_truth

NOISE = 10e-6
PATTERN = (1.0, -1.0, 1.0, -1.0, 1.0, -1.0)


def effect(term, size):
    """A hidden effect of the given size on every parameter of ``term``, with alternating signs."""
    return {p: size * PATTERN[k] for k, p in enumerate(TERMS[term].params)}


def hidden(effects, scheme, seed, base="linear9", columns=False, setpoints=True, **kw):
    """Simulated positions with ``effects`` hidden. With ``columns`` the data carry temperature and time.

    simulate() ramps the temperature linearly over the positions, which are equally spaced in time, so
    T − T0 and t − t0 are proportional and temperature_bias and bias_drift are the same regressor. With
    ``setpoints`` the temperature set-points are visited in a random order instead (the rows are shuffled
    and keep increasing time stamps, or, for a drift effect, the temperatures are shuffled)."""
    rng = np.random.default_rng(seed)
    truth = draw_truth(base, rng)
    if columns:
        kw.update(temp=(20.0, 40.0), times=True)
    sim = simulate(base, truth, rng, scheme=scheme, noise_g=NOISE, effects=effects, **kw)
    data = sim.data
    if columns and setpoints:
        if any("t" in TERMS[t].needs for t in effects):
            data = dataclasses.replace(data, temp=rng.permutation(data.temp))
        else:
            data = dataclasses.replace(data.subset(rng.permutation(len(data))), t=data.t)
    return sim, data


def true_model_rms(sim, data, base, terms):
    """The residual RMS the true model leaves (fitted, started at the truth)."""
    model = get_model(base)
    for t in terms:
        model = model.with_term(t)
    return fit_model(model, data, 1.0, x0=sim.truth_vector(model)).rms


# term: (scheme, base, effect size, columns). Sizes lift the base model's residual RMS to at least 3 × the
# noise (asserted). quadratic and scale_asymmetry use 36 positions: on the 24-position scheme they are the
# same regressor (see test_quadratic_and_scale_asymmetry_are_confounded_on_24_positions).
SINGLE = {
    "quadratic": ("36", "linear9", 1.5e-4, False),
    "cubic": ("24", "linear9", 2e-4, False),
    "scale_asymmetry": ("36", "linear9", 5e-4, False),
    "cross_coupling": ("24", "linear9", 1.2e-4, False),
    "temperature_bias": ("random:30", "linear9", 8e-6, True),
    "temperature_scale": ("random:30", "linear9", 1.5e-5, True),
    "bias_drift": ("random:30", "linear9", 2.5e-7, True),
    "misalignment": ("24", "diag6", 1.2e-4, False),
}


@pytest.mark.parametrize("term", list(SINGLE))
def test_each_hidden_term_alone_is_named_and_the_gap_closes(term):
    # Each step tests at family-wise level α = 0.01, so about 1 run in 100 adds a spurious second term
    # after the true one (it happens for quadratic with seed 0); 10 seeds: the term is named first in all
    # of them, and nothing else follows in at least 9.
    scheme, base, size, columns = SINGLE[term]
    exact = 0
    for seed in range(10):
        sim, data = hidden({term: effect(term, size)}, scheme, seed, base, columns)
        rep = discover(data, base=base, noise_g=NOISE)
        assert rep.initial.rms >= 3 * NOISE, "the effect must lift the base model's RMS to 3 × the noise"
        assert rep.added[:1] == [term], (seed, rep.summary())
        exact += rep.added == [term]
        assert rep.final.rms <= 1.3 * true_model_rms(sim, data, base, [term])
        step = rep.steps[0]
        assert step.after.rms < step.before.rms / 2
        assert set(step.parameters) == set(TERMS[term].params)
        # the fitted coefficients recover the hidden ones within 5 standard errors
        for name, v in step.parameters.items():
            assert abs(v - sim.truth[name]) < 5 * step.stderr[name], (name, v, sim.truth[name], step.stderr[name])
    assert exact >= 9


def test_two_hidden_effects_are_both_named_and_nothing_else():
    effects = {"cubic": effect("cubic", 2e-4), "temperature_bias": effect("temperature_bias", 5e-6)}
    for seed in range(3):
        sim, data = hidden(effects, "36", seed, columns=True)
        rep = discover(data, noise_g=NOISE)
        assert sorted(rep.added) == ["cubic", "temperature_bias"], rep.summary()
        assert rep.final.rms <= 1.3 * true_model_rms(sim, data, "linear9", effects)
        assert rep.verdict == EXPLAINED


@pytest.mark.parametrize("scheme,columns", [("24", False), ("random:30", True)])
def test_without_a_hidden_effect_nothing_is_added_in_19_of_20_seeds(scheme, columns):
    added, verdicts = [], []
    for seed in range(20):
        _, data = hidden({}, scheme, 1000 + seed, columns=columns)
        rep = discover(data, noise_g=NOISE)
        added.append(rep.added)
        verdicts.append(rep.verdict)
        first_round = rep.steps[0].scores if rep.steps else rep.last_round
        assert sum(s.tested for s in first_round) == (7 if columns else 4)  # every candidate with its columns
    assert sum(not a for a in added) >= 19, added
    assert verdicts.count(EXPLAINED) >= 18


@pytest.mark.parametrize("term,scheme,columns", [("cubic", "24", False), ("temperature_bias", "random:30", True)])
def test_once_the_true_term_is_in_nothing_else_is_added(term, scheme, columns):
    size = SINGLE[term][2]
    clean = 0
    for seed in range(20):
        _, data = hidden({term: effect(term, size)}, scheme, 2000 + seed, columns=columns)
        rep = discover(data, base=f"linear9+{term}", noise_g=NOISE)
        clean += not rep.added
    assert clean >= 19


def test_statistics_follow_their_definitions():
    sim, data = hidden({"cubic": effect("cubic", 2e-4)}, "24", 5)
    rep = discover(data, noise_g=NOISE)
    step = rep.steps[0]
    m = len(data)
    rss0, rss1 = m * step.before.rms**2, m * step.after.rms**2
    p0, p1 = 9, 12
    f = ((rss0 - rss1) / (p1 - p0)) / (rss1 / (m - p1))
    d = step.to_dict()
    assert d["df"] == [3, m - p1]
    assert d["statistic"] == pytest.approx(f, rel=1e-9)
    assert d["p_value"] == pytest.approx(stats.f.sf(f, 3, m - p1), rel=1e-9)
    assert d["delta_bic"] == pytest.approx(m * np.log(rss1 / rss0) + 3 * np.log(m), rel=1e-9)
    assert d["lr_statistic"] == pytest.approx(m * np.log(rss0 / rss1), rel=1e-9)
    assert d["p_threshold"] == pytest.approx(rep.alpha / 4)  # 4 candidates without temp and t columns
    # the chosen term has the lowest p-value of the round
    assert all(c["p_value"] >= d["p_value"] for c in d["candidates"] if c["tested"])
    # the refit started from the current fit and only improved it
    assert all(s.fit.rss <= step.before.rss * (1 + 1e-9) for s in step.scores if s.tested)
    # the residuals follow the added term before the step (added-variable correlation) and are orthogonal
    # to each of its regressors after it
    assert np.corrcoef(step.added_variable(), step.before.residuals)[0, 1] > 0.9
    corr = d["correlations"]
    assert set(corr) == {"K3_x", "K3_y", "K3_z"} and corr["K3_x"]["regressor"] == "A_x³"
    assert max(abs(c["after"]) for c in corr.values()) < 0.05


def test_terms_without_their_columns_are_skipped_with_a_note():
    _, data = hidden({}, "24", 0)
    rep = discover(data, noise_g=NOISE)
    notes = {s.term: s.note for s in rep.last_round if not s.tested}
    assert set(notes) == {"temperature_bias", "temperature_scale", "bias_drift"}
    assert "temp" in notes["temperature_bias"] and "column" in notes["temperature_bias"]
    assert "t" in notes["bias_drift"].split("column(s) ")[1]


def test_six_positions_leave_nothing_to_test():
    _, data = hidden({"cubic": effect("cubic", 2e-4)}, "6", 0)
    rep = discover(data, base="diag6", noise_g=NOISE)
    assert rep.added == [] and rep.verdict == NO_DOF and rep.chi2 is None
    notes = {s.term: s.note for s in rep.last_round}
    assert all("no degrees of freedom" in notes[t] for t in ("quadratic", "cubic", "misalignment"))
    assert "needs column(s) t" in notes["bias_drift"]


def test_quadratic_and_scale_asymmetry_are_confounded_on_24_positions():
    # With |A_i| in {0, √½, 1} only, A_i³ lies in the span of A_i and A_i·|A_i|: the norm residual sees
    # quadratic and scale_asymmetry (plus scale) as the same regressor. One is named, the other is listed
    # as an equal alternative and is then skipped as unobservable.
    _, data = hidden({"quadratic": effect("quadratic", 1.5e-4)}, "24", 1)
    rep = discover(data, noise_g=NOISE)
    assert len(rep.steps) == 1 and rep.added[0] in ("quadratic", "scale_asymmetry")
    other = ({"quadratic", "scale_asymmetry"} - {rep.added[0]}).pop()
    assert other in rep.steps[0].alternatives
    c = {s.term: s for s in rep.steps[0].scores}
    assert c["quadratic"].delta_bic == pytest.approx(c["scale_asymmetry"].delta_bic, abs=0.05)
    note = {s.term: s.note for s in rep.last_round}[other]
    assert note.startswith("unobservable on these positions")


def test_linear_temperature_ramp_confounds_temperature_bias_with_drift():
    # simulate()'s default: temperature rises linearly while positions are equally spaced in time
    _, data = hidden({"temperature_bias": effect("temperature_bias", 8e-6)}, "random:30", 0, columns=True,
                     setpoints=False)
    rep = discover(data, noise_g=NOISE)
    assert len(rep.steps) == 1 and rep.added[0] in ("temperature_bias", "bias_drift")
    other = ({"temperature_bias", "bias_drift"} - {rep.added[0]}).pop()
    assert rep.steps[0].alternatives == [other]
    assert {s.term: s.note for s in rep.last_round}[other].startswith("unobservable")


def test_noise_floor_from_the_data_gives_the_verdict():
    rng = np.random.default_rng(3)
    truth = draw_truth("linear9", rng)
    # n and sx, sy, sz come with a noise density; the SD of each mean is 100 µg/√Hz / √10 s ≈ 31.6 µg
    sim = simulate("linear9", truth, rng, scheme="36", noise_density=100e-6, dwell_s=10.0,
                   effects={"cubic": effect("cubic", 6e-4)})
    rep = discover(sim.data)
    assert rep.noise_g == pytest.approx(100e-6 / np.sqrt(10.0), rel=1e-3)
    assert rep.added == ["cubic"] and rep.verdict == EXPLAINED
    d = rep.to_dict()
    assert d["noise_floor_g"] == pytest.approx(rep.noise_g)
    assert d["rms_final_g"] < 1.2 * d["expected_rms_g"]
    # stop the search early: the verdict says what the χ² test sees
    early = discover(sim.data, candidates=["quadratic"])
    assert early.added == [] and early.verdict == REMAINS and early.chi2[2] < 1e-6
    # without a noise level the 36-position scheme's six poses visited twice give the floor: their scatter, and the
    # verdict is the lack-of-fit test against it (docs/discovery.md, "Floors")
    replicated = discover(dataclasses.replace(sim.data, n_samples=None, std=None))
    d = replicated.to_dict()
    assert d["noise_floor_g"] is None and d["floor"]["kind"] == "replicates" and d["floor"]["pure_error_dof"] == 6
    assert replicated.verdict == EXPLAINED and d["lack_of_fit"]["p_value"] > 0.01
    # without either the floor is unknown, the JSON says null and the report says what to record
    sim = simulate("linear9", truth, rng, scheme="random:36", noise_density=100e-6, dwell_s=10.0,
                   effects={"cubic": effect("cubic", 6e-4)})
    unknown = discover(dataclasses.replace(sim.data, n_samples=None, std=None))
    assert unknown.to_dict()["noise_floor_g"] is None and unknown.verdict == "noise floor unknown"
    assert unknown.floor.kind is None and "hold some poses twice" in unknown.summary()


def test_report_dict_and_figure(tmp_path):
    effects = {"cubic": effect("cubic", 2e-4), "temperature_bias": effect("temperature_bias", 5e-6)}
    _, data = hidden(effects, "36", 0, columns=True)
    rep = discover(data, noise_g=NOISE)
    d = json.loads(json.dumps(rep.to_dict(), allow_nan=False))
    assert d["base"] == "linear9" and d["final_terms"] == list(rep.final_model.terms)
    assert d["final_terms"][-2:] == ["cubic", "temperature_bias"]
    assert [s["added"] for s in d["steps"]] == rep.added
    assert d["rms_initial_g"] > d["steps"][0]["rms_after_g"] > d["steps"][1]["rms_after_g"] == d["rms_final_g"]
    assert len(d["residuals_final_g"]) == 36 and d["verdict"] == EXPLAINED
    assert "K3_x" in d["final_stderr"] and d["final_stderr"]["K3_x"] > 0
    fig = rep.plot(tmp_path / "d.png")
    assert (tmp_path / "d.png").stat().st_size > 10_000
    titles = [a.get_title() for a in fig.axes if a.get_visible()]
    assert len(titles) == 1 + len(rep.steps) and titles[1].startswith("step 1: add cubic")
    # the added-variable abscissa explains the residual before the step (slope one) and not after
    s = rep.steps[1]
    x = s.added_variable()
    slope = np.polyfit(x, s.before.residuals, 1)[0]
    assert 0.7 < slope < 1.3 and abs(np.polyfit(x, s.after.residuals, 1)[0]) < 0.3


def test_bad_arguments_raise_input_errors():
    _, data = hidden({}, "24", 0)
    with pytest.raises(InputError, match="misalignment6 adds three unobservable"):
        discover(data, candidates=["misalignment6"])
    with pytest.raises(InputError, match="unknown candidate"):
        discover(data, candidates=["cubicc"])
    with pytest.raises(InputError, match="alpha"):
        discover(data, alpha=1.5)
    with pytest.raises(InputError, match="fewer than the 9 parameters"):
        discover(data.subset(np.arange(6)))


def test_cli_json_contract(tmp_path, capsys):
    effects = {"cubic": effect("cubic", 2e-4)}
    _, data = hidden(effects, "24", 2)
    csv = tmp_path / "pos.csv"
    data.to_csv(csv)
    png = tmp_path / "steps.png"
    assert main(["discover", str(csv), "--json", "--plot", str(png)]) == 0
    out = json.loads(capsys.readouterr().out)
    for key in ("base", "steps", "final_terms", "rms_initial_g", "rms_final_g", "noise_floor_g"):
        assert key in out
    assert out["base"] == "linear9" and out["noise_floor_g"] is None
    assert [s["added"] for s in out["steps"]] == ["cubic"] and "cubic" in out["final_terms"]
    for key in ("added", "parameters", "rms_before_g", "rms_after_g", "statistic", "p_value", "delta_bic"):
        assert key in out["steps"][0]
    assert set(out["steps"][0]["parameters"]) == {"K3_x", "K3_y", "K3_z"}
    assert png.stat().st_size > 10_000
    assert main(["discover", str(csv), "--base", "nonlinear12", "--gravity-ms2", "9.80665"]) == 0
    text = capsys.readouterr().out
    assert "base nonlinear12" in text and "verdict" in text


@pytest.mark.parametrize("argv,match", [
    (["--base", "linear10"], "unknown model or term"),
    (["--candidates", "cubic,foo"], "unknown candidate"),
    (["--plot", "/nonexistent-dir/x.png"], "does not exist"),
])
def test_cli_bad_input_is_one_line(tmp_path, capsys, argv, match):
    _, data = hidden({}, "24", 0)
    csv = tmp_path / "pos.csv"
    data.to_csv(csv)
    assert main(["discover", str(csv), *argv]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and match in err and "Traceback" not in err


REAL = str(corpus_root() / "mpu6050" / "example_data_calibration.csv")  # the real corpus (tests/corpus.py)


def test_cli_runs_end_to_end_on_a_real_recording(capsys, corpus):
    # ImuCalibration's MPU-6050 recording (MIT licence): about ten poses in int16 counts at 100 Hz
    assert main(["discover", REAL, "--raw", "--units", "counts", "--columns", "ax,ay,az", "--base", "diag6",
                 "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["base"] == "diag6" and out["n_residuals"] >= 7
    assert out["noise_floor_g"] > 0  # the positions carry n and sx, sy, sz
    # against the recording's own floor, correlated noise included (docs/noise.md), scale and bias explain the
    # poses: the residual is below the floor and nothing is added (σ/√n alone made it look twice the noise)
    assert out["verdict"] == EXPLAINED and out["rms_initial_g"] < out["noise_floor_g"]
    assert out["steps"] == [] and out["chi2"]["p_value"] > 0.05


def test_verdict_on_a_recording_uses_its_noise_floor(tmp_path, corpus):
    """On a raw recording's positions (imu_tk's Xsens log) the final χ² is judged as ``optcal calibrate`` judges
    it: the F test against the recording's correlated-noise floor (analysis.goodness_of_fit), not χ²_dof with the
    floor taken as exact (issue #20, docs/noise.md), which would call the model wrong."""
    import gzip

    from optcal.app.workflows.recording import positions_from_raw
    from optcal.core.analysis import goodness_of_fit
    from optcal.core.distributions import chi2_sf

    raw = corpus / "imu_tk" / "xsens_acc.mat.gz"
    path = tmp_path / "xsens_acc.mat"
    path.write_bytes(gzip.decompress(raw.read_bytes()))
    data = positions_from_raw(path, units="counts")
    report = discover(data, base="linear9", candidates=["quadratic"])
    gof = goodness_of_fit(report.final.problem, report.final.x)
    chi2, dof, p = report.chi2
    assert gof.expected_chi2 is not None and (chi2, p) == (gof.chi2, gof.p_value)
    plain = float(chi2_sf(float(np.sum((report.final.residuals / report.sigma_j) ** 2)), dof))
    # measured: plain 0.0013, the floor's F test 0.020; at discovery's α = 0.01 the verdicts differ
    assert plain < report.alpha < p and report.verdict == EXPLAINED
