"""Anytime performance: what each trial records (best cost and accuracy on the evaluation grid, the optimum
of its data set), and the analyses of optcal.studies.anytime on hand-made inputs with known answers."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from test_studies import BASE, spec_of

from optcal.studies.execute import run_study
from optcal.studies.store import Store
from optcal.studies.trial import accuracy_of, anytime_on_grid, trace_on_grid, trials, world

# -- what a trial records ---------------------------------------------------------------------


def test_anytime_on_grid_scores_the_best_point_of_each_grid_point():
    n = 3
    x_true = np.zeros(n)
    sd, u = np.array([1.0, 2.0, 4.0]), np.ones(n)
    bound = (sd, np.eye(n), u)
    trace = [(1, 5.0, 0.0), (3, 4.0, 0.0), (12, 1.0, 0.0)]
    xs = [np.array([3.0, 0.0, 0.0]), np.array([0.0, 2.0, 0.0]), np.array([1.0, 2.0, 4.0])]
    a = anytime_on_grid(trace, xs, x_true, bound)
    assert [r[:2] for r in a] == trace_on_grid(trace)
    by = {r[0]: r for r in a}
    # accuracy = RMS over parameters of |error| / CRLB
    assert by[1][2] == pytest.approx(np.sqrt(9 / 3)) and by[2][2] == pytest.approx(np.sqrt(9 / 3))
    assert by[3][2] == pytest.approx(np.sqrt(1 / 3)) and by[10][2] == pytest.approx(np.sqrt(1 / 3))
    assert by[13][2] == pytest.approx(1.0)
    # only the observable part counts: project the first parameter out
    P = np.diag([0.0, 1.0, 1.0])
    assert accuracy_of(xs[0], x_true, (sd, P, u))[0] == 0.0
    # a trace without points keeps its costs and has no accuracy
    assert [r[2] for r in anytime_on_grid(trace, [], x_true, bound)] == [None] * len(a)
    assert anytime_on_grid([], [], x_true, bound) == []


def test_each_trial_stores_its_anytime_curve_and_the_optimum_of_its_data(tmp_path):
    sp = spec_of(solvers_toml='[[solvers]]\nname = "scipy-lm"\n[[solvers]]\nname = "pso"\n'
                              'options = {n_particles = 10, iterations = 20}\n')
    run_study(sp, tmp_path, progress=False)
    with Store.open_existing(tmp_path) as st:
        rows = st.rows()
    assert len(rows) == 6
    by = {(r["solver"], r["run"]): r for r in rows}
    for r in rows:
        a = np.array(r["anytime"], float)
        assert [x[:2] for x in r["anytime"]] == r["trace"]
        # the curve ends at the trial's result: its final cost and its accuracy
        assert a[-1, 1] == r["fun"] and a[-1, 2] == pytest.approx(r["accuracy"], rel=1e-9)
        assert np.all(np.diff(a[:, 1]) <= 0) and np.all(np.diff(a[:, 0]) > 0)
        # every solver of a run shares the optimum of its data, which scipy-lm from the presets reaches
        assert r["f_opt"] == by["scipy-lm", r["run"]]["f_opt"]
        assert r["fun"] >= r["f_opt"] * (1 - 1e-9)
    assert all(by["scipy-lm", i]["fun"] == pytest.approx(by["scipy-lm", i]["f_opt"], rel=1e-9) for i in range(3))
    assert len({by["scipy-lm", i]["f_opt"] for i in range(3)}) == 3
    # the World's own problem is not touched by the reference fit
    w = world(trials(sp)[0])
    assert w.yard.counter.nfev == 0 and w.f_opt == by["scipy-lm", 0]["f_opt"]


def test_a_turntable_trial_has_no_in_field_optimum(tmp_path):
    sp = spec_of(base=BASE.replace("runs = 3", "runs = 1"),
                 solvers_toml='[[solvers]]\nname = "scipy-lm"\nlabel = "turntable"\nreference = true\n'
                              'reference_error_arcsec = 10\n')
    run_study(sp, tmp_path, progress=False)
    with Store.open_existing(tmp_path) as st:
        (r,) = st.rows()
    assert r["f_opt"] is None and r["anytime"][-1][2] == pytest.approx(r["accuracy"], rel=1e-9)


# -- ECDFs, profiles and bootstrap intervals on hand-made inputs ----------------------------------

from optcal.studies import anytime as A  # noqa: E402
from optcal.studies.metrics import groups  # noqa: E402
from optcal.studies.report import write_report  # noqa: E402

INF = np.inf


def test_first_hits_is_the_first_grid_point_at_or_below_each_target():
    evals, values = [1, 2, 5, 10], [5.0, 3.0, 1.0, 0.5]
    assert A.first_hits(evals, values, [10, 2, 0.7, 0.1]).tolist() == [1, 5, 10, INF]
    # a point without a value (no accuracy) reaches nothing
    assert A.first_hits(evals, [np.nan, 3.0, np.nan, 0.5], [4, 1]).tolist() == [2, 10]
    assert A.first_hits([], [], [1.0]).tolist() == [INF]


def test_ecdf_and_its_area():
    t = [1, 10, INF, 100]
    assert A.ecdf(t, [1, 5, 10, 100, 1000, INF]).tolist() == [0.25, 0.25, 0.5, 0.75, 0.75, 0.75]
    assert A.ecdf([1, np.nan], [1]).tolist() == [1.0]  # NaN: no record, left out
    assert np.isnan(A.ecdf([np.nan], [1])[0])
    # area over log10(evaluations) from 1 to top, normalised: a target at evaluation 1 scores 1, at top 0
    assert A.ecdf_area([1, INF], 100) == 0.5
    assert A.ecdf_area([10], 100) == pytest.approx(0.5)
    assert A.ecdf_area([1000], 100) == 0.0


def test_data_profile_counts_problems_solved_within_kappa_budget_units():
    # κ = evaluations / (n + 1): 4 / 4 = 1, 30 / 3 = 10, never
    d = A.data_profile([4, 30, INF], [3, 2, 3], [0.5, 1, 9.9, 10, 100])
    assert d.tolist() == pytest.approx([0, 1 / 3, 1 / 3, 2 / 3, 2 / 3])


def test_performance_profile_against_the_fastest_solver_per_problem():
    T = np.array([[10, 20], [40, 20], [INF, 5], [INF, INF]], float)
    R = A.performance_ratios(T)
    assert R.tolist() == [[1, 2], [2, 1], [INF, 1], [INF, INF]]  # nobody solves the last problem
    P = A.performance_profile(T, [1, 1.5, 2, 100])
    assert P[0].tolist() == [0.25, 0.25, 0.5, 0.5]
    assert P[1].tolist() == [0.5, 0.5, 0.75, 0.75]


def test_bootstrap_interval_contains_the_estimate_shrinks_with_more_runs_and_is_reproducible():
    rng = np.random.default_rng(1)
    widths = []
    for n in (10, 40, 160):
        z = rng.normal(size=n)
        v = 1.0 + 0.3 * (z - z.mean()) / z.std()  # the same spread at every n
        lo, hi = A.mean_ci(v, seed=7)
        assert lo < v.mean() < hi
        assert (lo, hi) == A.mean_ci(v, seed=7)  # the spec's seed fixes the resamples
        widths.append(hi - lo)
    assert widths[0] > 1.5 * widths[1] > 2.25 * widths[2]  # about 1/√n
    # whole runs are resampled: two values per run with the same mean give the same interval as one
    v = rng.normal(size=20)
    assert A.run_mean_ci(np.repeat(v, 2), np.repeat(np.arange(20), 2), 3) == pytest.approx(A.mean_ci(v, 3))
    assert np.isnan(A.mean_ci([1.0], 3)[0])


def _group_rows(n, rng, solver="s"):
    rows = []
    for i in range(n):
        e = rng.normal(0, [1e-6, 2e-6])
        rows.append({"model": "m", "scheme": "24", "solver": solver, "solver_name": solver, "run": i,
                     "reference": 0, "reference_error_arcsec": 0.0, "status": "ok", "message": "", "success": 1,
                     "converged": int(rng.random() < 0.8), "names": ["a", "b"], "err": list(e),
                     "err_proj": list(e), "crlb": [1e-6, 2e-6], "crlb_presets": [0.5e-6, 1e-6],
                     "observable": [1, 1], "fun": 1.0, "runtime_s": float(rng.uniform(0.1, 0.2)), "nfev": 10,
                     "null_dirs": [], "null_err": []})
    return rows


def test_group_intervals_bracket_the_group_summary_and_shrink_with_more_runs():
    rng = np.random.default_rng(5)
    width = {}
    for n in (12, 200):
        g = groups(_group_rows(n, rng))[0]
        ci = A.group_ci(g, seed=2020)
        s = g.summary()
        for k in ("success_rate", "accuracy", "accuracy_presets", "runtime_median_s"):
            lo, hi = ci[k]
            assert lo <= s[k] <= hi, (n, k, lo, s[k], hi)
        width[n] = {k: hi - lo for k, (lo, hi) in ci.items()}
    assert all(width[200][k] < 0.5 * width[12][k] for k in width[12])
    # the resampled statistic is the group's own: identical runs give a zero-width interval at the value
    rows = _group_rows(1, rng) * 8
    rows = [{**r, "run": i} for i, r in enumerate(rows)]
    g = groups(rows)[0]
    lo, hi = A.group_ci(g, 1)["accuracy"]
    assert lo == pytest.approx(g.accuracy) and hi == pytest.approx(g.accuracy)
    # a failed run counts as not converged and is left out of RMSE/CRLB, as in the group
    rows[0] = {**rows[0], "status": "failed", "converged": 0, "err_proj": None, "crlb": None}
    g = groups(rows)[0]
    assert A.group_ci(g, 1)["accuracy"][0] == pytest.approx(g.accuracy)


def _at_row(solver, run, anytime, f_opt=1.0, status="ok", model="m"):
    return {"model": model, "scheme": "24", "solver": solver, "run": run, "reference": 0, "status": status,
            "names": ["a", "b", "c"], "anytime": anytime, "f_opt": f_opt, "nfev": anytime[-1][0] if anytime else 0}


def test_collect_turns_anytime_records_into_hitting_times():
    rows = [
        # cost 101 → gap 100 at 1; gap 1 at 10; gap 1e-3 at 100. Accuracy 5, 1.4, 1.1.
        _at_row("fast", 0, [[1, 101.0, 5.0], [10, 2.0, 1.4], [100, 1.001, 1.1]]),
        _at_row("fast", 1, [[1, 11.0, 20.0], [3, 1.0, 1.0]]),
        _at_row("slow", 0, [[1, 101.0, 5.0], [1000, 1.5, 2.5]]),
        _at_row("slow", 1, None, status="failed"),
        {**_at_row("turntable", 0, [[1, 1.0, 1.0]]), "reference": 1},  # another cost: left out
    ]
    at = A.collect(rows, ["slow", "fast"])
    assert at.solvers == ["slow", "fast"] and at.problems == [("m", "24", 0), ("m", "24", 1)]
    assert at.n.tolist() == [3, 3] and at.top == 1000
    # COST_TARGETS 1e2, 1e1, 1, 1e-1, 1e-2, 1e-3; ACCURACY_TARGETS 10, 3, 2, 1.5, 1.2
    assert at.times("cost", 1)[0].tolist() == [1, 10, 10, 100, 100, 100]
    assert at.times("cost", 1)[1].tolist() == [1, 1, 3, 3, 3, 3]  # a gap of 0 meets every target
    assert at.times("accuracy", 1)[0].tolist() == [1, 10, 10, 10, 100]
    assert at.times("cost", 0)[0].tolist() == [1, 1000, 1000, INF, INF, INF]
    assert np.all(at.times("cost", 0)[1] == INF) and np.all(at.times("accuracy", 0)[1] == INF)  # failed
    assert at.reached("cost", 1) == 1.0 and at.reached("cost", 0) == pytest.approx(3 / 12)
    assert at.ecdf("accuracy", 0, [1, 999, 1000]).tolist() == pytest.approx([1 / 10, 1 / 10, 2 / 10])
    rec = {r["solver"]: r for r in at.table(seed=1)}
    assert rec["fast"]["solved_cost_0.01"] == 1.0 and rec["slow"]["solved_cost_0.01"] == 0.0
    assert rec["fast"]["fastest_accuracy_1.5"] == 1.0 and rec["slow"]["solved_accuracy_1.5"] == 0.0
    assert rec["slow"]["cost_reached"] == pytest.approx(3 / 12)
    # no optimum: no cost targets, accuracy targets still scored; no record at all: nothing known
    at = A.collect([_at_row("x", 0, [[1, 2.0, 1.0]], f_opt=None), _at_row("x", 1, None)])
    assert np.isnan(at.times("cost", 0)).all() and at.times("accuracy", 0)[0].tolist() == [1] * 5
    assert (at.missing, at.no_optimum) == (1, 1) and np.isnan(at.times("accuracy", 0)[1]).all()


# -- the report --------------------------------------------------------------------------------

FIGS = ("anytime_ecdf", "data_profiles", "performance_profiles")


def test_the_report_has_the_anytime_section_with_its_figures_targets_and_intervals(tmp_path):
    sp = spec_of(solvers_toml='[[solvers]]\nname = "scipy-lm"\n[[solvers]]\nname = "pso"\n'
                              'options = {n_particles = 10, iterations = 20}\n'
                              '[[solvers]]\nname = "scipy-lm"\nlabel = "turntable"\nreference = true\n')
    run_study(sp, tmp_path, progress=False)
    text = write_report(tmp_path).read_text()
    section = text.split("## Anytime performance")[1].split("## Solver settings")[0]
    assert "(f − f_opt) / f_opt ≤ 100, 10, 1, 0.1, 0.01, 0.001" in section
    assert "≤ 10, 3, 2, 1.5, 1.2" in section and "Moré & Wild" in section and "Dolan & Moré" in section
    for f in FIGS:
        p = tmp_path / "figures" / f"{f}.png"
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and p.stat().st_size > 20_000
        assert f"figures/{f}.png" in section
    # the search methods (metaheuristic and global families) get their own ECDF figure, beside scipy-lm
    p = tmp_path / "figures" / "anytime_ecdf_search.png"
    assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and "figures/anytime_ecdf_search.png" in section
    assert "run jointly: `pso`), beside scipy-lm" in section
    table = [r for r in section.splitlines() if r.startswith("| `")]
    assert [r.split("`")[1] for r in table] == ["scipy-lm", "pso"]  # every in-field solver, turntable left out
    # scipy-lm from the presets is the reference optimum: it meets every cost target on every problem
    assert table[0].split("|")[2].strip() == "100 % [100, 100]"
    # the per-cell summary carries bootstrap intervals for success, RMSE/CRLB and the median runtime
    row = next(r for r in text.splitlines() if r.startswith("| `scipy-lm` |"))
    assert row.count("[") >= 5 and "runtime s median [95 % CI]" in text
    import json

    s = json.loads((tmp_path / "summary.json").read_text())["records"][0]
    lo, hi = s["accuracy_ci"]
    assert lo < s["accuracy"] < hi and len(s["runtime_median_s_ci"]) == 2


def test_search_methods_are_the_in_field_metaheuristic_and_global_configurations():
    from optcal.studies.report_sections import search_methods

    spec = {"solvers": [{"name": n, "label": lab, "options": {}, "reference": ref} for n, lab, ref in [
        ("scipy-lm", "scipy-lm", False), ("bsas", "bsas", False), ("staged:bsas", "staged:bsas", False),
        ("nlopt-crs2", "nlopt-crs2", False), ("nlopt-bobyqa", "nlopt-bobyqa", False), ("cmaes", "cmaes", False),
        ("ng:OnePlusOne", "ng:OnePlusOne", False), ("pso", "turntable-pso", True), ("no-such", "gone", False)]]}
    present = [c["label"] for c in spec["solvers"]]
    assert search_methods(spec, present) == ["bsas", "nlopt-crs2", "cmaes", "ng:OnePlusOne"]
    assert search_methods(spec, ["scipy-lm", "cmaes"]) == ["cmaes"]


def test_an_old_store_without_anytime_columns_still_reports(tmp_path):
    import sqlite3

    from optcal.studies.store import COLUMNS

    sp = spec_of()
    run_study(sp, tmp_path, progress=False)
    con = sqlite3.connect(tmp_path / "study.sqlite")
    keep = ", ".join(c for c in COLUMNS if c not in ("f_opt", "anytime", "crlb_presets"))
    con.executescript(f"CREATE TABLE old AS SELECT {keep} FROM trials; DROP TABLE trials; "
                      "ALTER TABLE old RENAME TO trials;")
    con.close()
    text = write_report(tmp_path).read_text()
    assert "RMSE/CRLB" in text and "No anytime records" in text
    with Store.open_existing(tmp_path) as st:
        rows = st.rows()
    assert all(r["anytime"] is None and r["f_opt"] is None for r in rows)
    assert not any((tmp_path / "figures" / f"{f}.png").exists() for f in FIGS)


def test_a_new_solver_in_one_file_appears_in_every_report_without_further_code(tmp_path, monkeypatch, capsys):
    """The example plugin (one file, examples/random_search_plugin) registered as a new solver: the study
    runs it, and the per-cell table, the anytime table, the search-methods ECDF and the IOHprofiler export all
    carry it, with no code that names it."""
    import json

    from optcal.app.cli import main
    from optcal.solvers import registry

    monkeypatch.syspath_prepend(str(Path(__file__).resolve().parents[1] / "examples" / "random_search_plugin"))
    from optcal_random_search import RandomSearch

    monkeypatch.setitem(registry._SOLVERS, RandomSearch.name, (RandomSearch, {}))
    sp = spec_of(solvers_toml='[[solvers]]\nname = "scipy-lm"\n[[solvers]]\nname = "random-search"\n'
                              'options = {m = 10, iterations = 25}\n')
    run_study(sp, tmp_path / "study", progress=False)
    text = write_report(tmp_path / "study").read_text()
    cell = text.split("## nonlinear12, 24 positions")[1].split("\n## ")[0]
    assert "| `random-search` |" in cell
    section = text.split("## Anytime performance")[1].split("## Solver settings")[0]
    assert [r.split("`")[1] for r in section.splitlines() if r.startswith("| `")] == ["scipy-lm", "random-search"]
    assert "run jointly: `random-search`), beside scipy-lm" in section
    assert main(["study", "export", str(tmp_path / "study"), "--format", "ioh", "-o", str(tmp_path / "ioh")]) == 0
    assert sorted(p.name for p in (tmp_path / "ioh").iterdir()) == ["random-search", "scipy-lm"]
    (meta,) = (tmp_path / "ioh" / "random-search").glob("*.json")
    assert json.loads(meta.read_text())["algorithm"]["name"] == "random-search"
    capsys.readouterr()
