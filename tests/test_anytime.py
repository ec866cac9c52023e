"""Anytime performance: what each trial records (best cost and accuracy on the evaluation grid, the optimum
of its data set), and the analyses of studies.anytime on hand-made inputs with known answers."""

from __future__ import annotations

import numpy as np
import pytest
from test_studies import BASE, spec_of

from studies.execute import run_study
from studies.store import Store
from studies.trial import accuracy_of, anytime_on_grid, trace_on_grid, trials, world

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
