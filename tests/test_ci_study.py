"""The CI study (optcal/studies/specs/ci.toml) against its committed baseline (optcal/studies/ci_tolerances.toml),
checked with the study's own intervals (optcal/app/study_ci.py): accuracy, noise-floor share and verification error
fail when the baseline lies outside the new run's 95 % bootstrap interval on the bad side; the run time is reported."""

from __future__ import annotations

import math

from optcal.app.study_ci import TOLERANCES, check, junit_xml, load_baseline, propose, regressions, run_ci


def test_ci_study_within_its_baseline(tmp_path, capsys):
    measured, wall, _ = run_ci(tmp_path)
    results = check(measured, load_baseline())
    with capsys.disabled():
        print(f"\nCI study: {len(measured)} solvers in {wall:.1f} s (reported, not asserted)")
    assert regressions(results) == []
    assert {r.status for r in results if r.metric == "runtime_median_s"} == {"reported"}
    # the study's seeds are fixed: the committed code reproduces its baseline to the digits the file keeps
    base = load_baseline()["solvers"]
    for name, m in measured.items():
        for k in ("accuracy", "success_rate", "ver_mean_ug"):
            assert math.isclose(m[k][0], base[name][k], rel_tol=1e-5), (name, k)


M = {"a": {"accuracy": (1.4, 1.2, 1.6), "success_rate": (0.5, 0.25, 0.75), "ver_mean_ug": (10.0, 9.0, 11.0),
           "runtime_median_s": (0.02, 0.01, 0.03)},
     "b": {"accuracy": (1.0, 0.9, 1.1), "success_rate": (1.0, 1.0, 1.0), "ver_mean_ug": (math.nan, math.nan, math.nan),
           "runtime_median_s": (0.5, 0.4, 0.6)}}
B = {"machine": "here", "solvers": {
    "a": {"accuracy": 1.1, "success_rate": 0.7, "ver_mean_ug": 10.5, "runtime_median_s": 0.02},
    "b": {"accuracy": 1.05, "success_rate": 1.0, "ver_mean_ug": 11.0, "runtime_median_s": 0.1},
    "c": {"accuracy": 1.0, "success_rate": 1.0, "ver_mean_ug": 11.0}}}


def test_a_baseline_outside_the_interval_on_the_bad_side_is_a_regression():
    bad = regressions(check(M, B, here="here"))
    # a: accuracy 1.1 lies below [1.2, 1.6] (worse now); success 0.7 lies within [0.25, 0.75]; b's verification
    # error is not a number; the run time is not checked unless asked; c is missing from the study
    assert bad == ["the baseline names a solver the study lacks: c",
                   "a: accuracy = 1.4 [1.2, 1.6] RMSE/CRLB, baseline 1.1 (worse than the baseline; lower is better)",
                   "b: ver_mean_ug = nan [nan, nan] µg, baseline 11 (worse than the baseline; lower is better)"]
    with_rt = regressions(check(M, B, here="here", runtime=True))
    assert with_rt[-1] == ("b: runtime_median_s = 0.5 [0.4, 0.6] s, baseline 0.1 (worse than the baseline; "
                           "lower is better)")
    # on another machine the run time is reported even when asked
    assert regressions(check(M, B, here="elsewhere", runtime=True)) == bad


def test_a_better_value_is_never_a_regression_and_proposals_round_trip(tmp_path):
    better = {"a": {**M["a"], "accuracy": (0.5, 0.4, 0.6), "success_rate": (1.0, 1.0, 1.0)}}
    assert regressions(check(better, {"machine": "x", "solvers": {"a": B["solvers"]["a"]}})) == []
    p = tmp_path / "b.toml"
    p.write_text(propose({"a": M["a"]}, "t"))
    doc = load_baseline(p)
    assert doc["solvers"]["a"] == {"accuracy": 1.4, "success_rate": 0.5, "ver_mean_ug": 10.0, "runtime_median_s": 0.02}
    xml = junit_xml(check({"a": M["a"]}, doc), "t")
    assert 'tests="4" failures="0" errors="0" skipped="1"' in xml
    assert TOLERANCES.name == "ci_tolerances.toml"
