"""The CI study (studies/specs/ci.toml) against the committed tolerances (studies/ci_tolerances.toml):
accuracy, success rate and verification error fail the build when they regress; time is only reported."""

from __future__ import annotations

from studies.ci import check, load_tolerances, propose, run_ci


def test_ci_study_within_tolerances(tmp_path, capsys):
    summary, wall = run_ci(tmp_path)
    with capsys.disabled():
        print(f"\nCI study: {len(summary)} solvers in {wall:.1f} s (reported, not asserted)")
    bad = check(summary, load_tolerances())
    assert bad == [], "\n".join(bad)


def test_check_flags_a_regression_and_a_missing_solver():
    s = [{"solver": "a", "accuracy": 1.4, "success_rate": 0.5, "ver_mean_ug": 10.0},
         {"solver": "b", "accuracy": 1.0, "success_rate": 1.0, "ver_mean_ug": float("nan")}]
    tol = {"a": {"max_accuracy": 1.3, "min_success_rate": 0.75, "max_ver_mean_ug": 11.0},
           "b": {"max_accuracy": 1.3, "min_success_rate": 0.75, "max_ver_mean_ug": 11.0},
           "c": {"max_accuracy": 1.3, "min_success_rate": 0.75, "max_ver_mean_ug": 11.0}}
    bad = check(s, tol)
    assert bad == ["the tolerances name a solver the study lacks: c", "a: accuracy = 1.4, tolerance <= 1.3",
                   "a: success_rate = 0.5, tolerance >= 0.75", "b: ver_mean_ug = nan, tolerance <= 11"]
    assert 'max_accuracy = 1.75' in propose(s[:1], 8) and "min_success_rate = 0.25" in propose(s[:1], 8)
