"""The study report's statistics and records (issue #22): paired comparisons between solvers over the same runs
(Wilcoxon signed-rank, Holm correction, rank-biserial effect size; optcal/studies/paired.py), the solver settings, the
provenance and the other fields of summary.json, and the report's paired table, on the CI study."""

from __future__ import annotations

import json

import numpy as np
import pytest

from optcal.studies import paired
from optcal.studies.execute import run_study
from optcal.studies.report import SUMMARY_FORMAT, read_summary, write_report
from optcal.studies.spec import load


def test_holm_by_hand():
    # sorted 0.01, 0.03, 0.04, 0.5 times 4, 3, 2, 1 = 0.04, 0.09, 0.08, 0.5; made monotone: 0.08 -> 0.09
    assert paired.holm([0.01, 0.04, 0.03, np.nan, 0.5])[[0, 1, 2, 4]] == pytest.approx([0.04, 0.09, 0.09, 0.5])


def test_holm_matches_statsmodels():
    multitest = pytest.importorskip("statsmodels.stats.multitest")  # iohinspector's dependencies bring it
    multipletests = multitest.multipletests

    rng = np.random.default_rng(3)
    for _ in range(20):
        p = rng.uniform(0, 0.2, size=rng.integers(1, 12))
        assert paired.holm(p) == pytest.approx(multipletests(p, method="holm")[1], abs=1e-15)
    assert np.isnan(paired.holm([0.01, np.nan])[1]) and paired.holm([0.01, np.nan])[0] == 0.01


def test_signed_rank_is_scipys_wilcoxon_and_the_rank_biserial_correlation():
    from scipy import stats

    d = np.array([1.0, 2.0, 3.0, -0.5, 4.0, 5.0, 6.0, 7.0])
    p, r = paired.signed_rank(d)
    assert p == stats.wilcoxon(d).pvalue
    # ranks of |d|: 0.5 -> 1, the others 2..8; W+ = 35, W- = 1
    assert r == pytest.approx((35 - 1) / 36)
    assert paired.signed_rank(-d)[1] == pytest.approx(-r)
    assert paired.signed_rank(np.zeros(5)) == (1.0, 0.0)


class _G:
    def __init__(self, solver, values):
        self.solver = solver
        self.rows = [{"run": i, "status": "ok", "accuracy": v} for i, v in enumerate(values)]


def test_compare_to_best_flags_a_solver_worse_in_every_run_and_not_a_tie():
    rng = np.random.default_rng(5)
    best = rng.uniform(0.8, 1.2, 12)
    groups = [_G("best", best), _G("worse", best + 0.3 + 0.01 * rng.random(12)),
              _G("same", best + 0.01 * rng.standard_normal(12))]
    recs = {r["solver"]: r for r in paired.compare_to_best(groups, presets=False)}
    w = recs["worse"]
    assert w["verdict"] == "worse" and w["rank_biserial"] == 1.0 and w["n"] == 12 and w["median_diff"] > 0.3
    assert w["p_holm"] == pytest.approx(min(1.0, 2 * w["p"]))  # two tests in the family; this one the smaller
    assert recs["same"]["verdict"] == "no difference"
    # a failed run is left out of its pair
    groups[1].rows[0]["status"] = "failed"
    assert {r["solver"]: r for r in paired.compare_to_best(groups, False)}["worse"]["n"] == 11


def _ci_study(folder):
    run_study(load("ci"), folder, progress=False)
    write_report(folder)


@pytest.fixture(scope="module")
def ci_report(computed_once):
    folder = computed_once("ci_report", _ci_study)  # once for every xdist worker; the tests only read it
    return folder, (folder / "report.md").read_text(), read_summary(folder)


def test_summary_json_carries_study_provenance_settings_and_paired_records(ci_report):
    folder, _, doc = ci_report
    assert doc["format"] == SUMMARY_FORMAT == 2
    st = doc["study"]
    assert st["name"] == "ci" and st["runs"] == 8 and st["trials"] == 40 and st["ranked_on"] == "accuracy_presets"
    assert st["final_gap"] == 1e-8 and st["report_s"] > 0
    prov = doc["provenance"]
    assert prov["machine"]["cpus"] >= 1 and prov["python"].count(".") == 2
    assert {"numpy", "scipy", "numba", "optcal"} <= set(prov["libraries"])
    import numpy
    assert prov["libraries"]["numpy"] == numpy.__version__
    # the commit is the sessions' (git is there in a checkout; '+dirty' with local changes)
    assert prov["commit"] is None or len(prov["commit"].split("+")[0]) >= 7
    sett = {x["solver"]: x for x in doc["settings"]}
    assert list(sett) == ["scipy-lm", "staged:bsas", "pso", "nafsa", "staged:nafsa"]
    pso = sett["pso"]
    # every option as run (defaults filled in), and the iterations the 8,000-evaluation budget allowed:
    # 40 particles, the first swarm and 199 iterations of 40
    assert pso["options"]["n_particles"] == 40 and pso["options"]["iterations"] == 500
    assert pso["budget"] == {"max_evals": 8000} and pso["iterations_median"] == 199
    assert pso["evaluations_median"] == 8000 and pso["stopped_at_target"] == 0.0
    assert sett["scipy-lm"]["stopped_at_target"] == 1.0 and sett["scipy-lm"]["evaluations_median"] < 20
    recs = doc["records"]
    assert len(recs) == 5 and all("accuracy_ci" in r for r in recs)
    pr = {r["solver"]: r for r in doc["paired"]}
    assert set(pr) == {"scipy-lm", "pso", "nafsa", "staged:nafsa"}
    assert all(r["best"] == "staged:bsas" and r["n"] == 8 for r in pr.values())
    # 8 runs, every one worse than staged:bsas: exact p = 2/256, Holm over four comparisons
    assert pr["pso"]["p"] == pytest.approx(2 / 256) and pr["pso"]["p_holm"] == pytest.approx(4 * 2 / 256)
    assert pr["pso"]["verdict"] == "worse" and pr["pso"]["rank_biserial"] == 1.0
    assert json.loads((folder / "summary.json").read_text()) == doc


def test_the_report_has_the_paired_table_settings_units_and_its_own_time(ci_report):
    _, text, doc = ci_report
    sec = text.split("## Paired comparisons")[1].split("\n## ")[0]
    assert "| solver | nonlinear12, 24 (best: `staged:bsas`) |" in sec
    assert "| `pso` | worse: Δ +" in sec and "p 3.1e-02 |" in sec
    assert "## Solver settings" in text and "| `pso` | n_particles=40," in text
    assert "final cost (g²)" in text and "nautical miles" in text and "a Jacobian counts as one" in text
    assert "Solvers are ranked on RMSE/CRLB with presets" in text
    head = next(line for line in text.splitlines() if line.startswith("- Wall time"))
    assert "and this report" in head and f"{doc['study']['report_s']:.1f} s." in head
    assert "![runtime ECDFs against time](figures/anytime_ecdf_time.png)" in text
    assert "Computed by commit" in text


def test_accuracy_runtime_numbers_do_not_overlap_in_a_crowded_row():
    """The staged solvers crowd one row of accuracy_runtime.png (same accuracy, runtimes a few % apart): the
    numbers written beside them must not overlap one another."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from optcal.studies.figures import _place_numbers

    fig, ax = plt.subplots(figsize=(10.5, 6.5))
    x = 0.01 * 1.12 ** np.arange(14)  # fourteen points, 12 % apart in runtime, on two nearby rows
    y = np.where(np.arange(14) % 2, 0.86, 0.87)
    ax.scatter(x, y)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlim(3e-4, 3)
    ax.set_ylim(0.5, 12)
    _place_numbers(ax, [(a, b, str(k)) for k, (a, b) in enumerate(zip(x, y), 1)])
    fig.canvas.draw()
    r = fig.canvas.get_renderer()
    boxes = [t.get_window_extent(r) for t in ax.texts]
    assert len(boxes) == 14
    overlaps = [(i, j) for i in range(14) for j in range(i + 1, 14) if boxes[i].overlaps(boxes[j])]
    plt.close(fig)
    assert overlaps == []
