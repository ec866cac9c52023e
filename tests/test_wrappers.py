"""The two wrappers: ``staged:<inner>`` (2020 paper §3.4 / 2015 paper Algorithm 1) and ``mcs:<inner>``
(2015 paper §6.2), on a 24-position nonlinear12 problem with presets, plus their command-line use.

The inner solvers here are scipy-lm (deterministic, exact), the random-search plugin's class (stochastic,
imported from examples/ by path, so these tests do not depend on other backends) and, for the CLI forms
the issue names, bsas and nafsa when they are registered.
"""

from __future__ import annotations

import functools
import json
import sys
from pathlib import Path

import numpy as np
import pytest

from optcal import solvers
from optcal.app.cli import main
from optcal.core.errors import InputError
from optcal.core.presets import draw_truth, manufacturer_presets
from optcal.core.problem import Budget, CalibrationProblem
from optcal.core.simulate import simulate
from optcal.solvers.base import Solver
from optcal.solvers.mcs import MonteCarlo
from optcal.solvers.staged import Staged

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "examples" / "random_search_plugin"))
from optcal_random_search import RandomSearch  # noqa: E402

SEED = 31
PAPER_ORDER = ["scale", "bias", "misalignment", "nonlinear"]


@functools.cache
def setting():
    rng = np.random.default_rng(SEED)
    truth = draw_truth("nonlinear12", rng)
    sim = simulate("nonlinear12", truth, rng, scheme="24", noise_g=10e-6)
    presets = manufacturer_presets(truth, rng)
    ref = solvers.get("scipy-lm").solve(problem(sim.data, presets), budget=1000, rng=0)
    return sim, presets, ref


def problem(data=None, presets=None, model="nonlinear12"):
    if data is None:
        sim, presets, _ = setting()
        data = sim.data
    return CalibrationProblem(model, data, presets=presets)


def gap(f):
    f_ref = setting()[2].fun
    return (f - f_ref) / f_ref


def cost(p, x):
    return float(np.sum(p.residuals_full(p.to_full(x)) ** 2))


# -- staged --------------------------------------------------------------------------------------------
def test_staged_runs_the_papers_stages_in_order_each_holding_the_others():
    p = problem()
    res = solvers.get("staged:scipy-lm", max_cycles=3).solve(p, rng=0)
    log = res.extra["stages"]
    assert [s["group"] for s in log] == PAPER_ORDER * 3
    groups = p.model.groups()
    before = p.to_full(p.x0)[0]
    for s in log:
        changed = np.flatnonzero(s["x_full"] != before)
        assert set(changed) <= set(groups[s["group"]]), f"stage {s['group']} moved {changed}"
        assert len(changed) > 0  # every stage did something from the presets
        before = s["x_full"]
    # Costs after each stage never rise; the result is the last stage's point.
    funs = [s["fun"] for s in log]
    assert all(b <= a for a, b in zip(funs, funs[1:]))
    np.testing.assert_array_equal(res.x_full, log[-1]["x_full"])
    assert res.fun == funs[-1] == pytest.approx(cost(p, res.x), rel=1e-12)


@pytest.mark.parametrize("model, stages", [
    ("diag6", ["scale", "bias"]),
    ("linear9", ["scale", "bias", "misalignment"]),
    ("scale+bias+misalignment+cubic", PAPER_ORDER),
    ("scale+bias+misalignment+quadratic+temperature_bias", PAPER_ORDER + ["temperature"]),
])
def test_staged_works_on_any_model_by_its_groups(model, stages):
    rng = np.random.default_rng(5)
    truth = draw_truth(model, rng)
    sim = simulate(model, truth, rng, scheme="36", noise_g=10e-6, temp=(20.0, 40.0) if "temp" in model else None)
    p = CalibrationProblem(model, sim.data, presets=manufacturer_presets(truth, rng))
    res = solvers.get("staged:scipy-lm", max_cycles=2).solve(p, rng=0)
    assert [s["group"] for s in res.extra["stages"]] == stages * 2
    assert res.success and res.fun < p.cost(p.x0)


def test_staged_groups_option_and_restricted_problems():
    p = problem()
    res = solvers.get("staged:scipy-lm", groups="bias,scale", max_cycles=2).solve(p, rng=0)
    assert [s["group"] for s in res.extra["stages"]] == ["bias", "scale"] * 2
    x0 = p.to_full(p.x0)[0]
    rest = np.setdiff1d(np.arange(12), p.model.groups()["bias"] + p.model.groups()["scale"])
    np.testing.assert_array_equal(res.x_full[rest], x0[rest])
    # A restricted view keeps its fixed parameters fixed: only the free groups are stages.
    v = p.restrict(["misalignment", "nonlinear"], at=x0)
    r2 = solvers.get("staged:scipy-lm", max_cycles=1).solve(v, rng=0)
    assert [s["group"] for s in r2.extra["stages"]] == ["misalignment", "nonlinear"]
    assert r2.x.shape == (6,)
    with pytest.raises(InputError, match="groups"):
        solvers.get("staged:scipy-lm", groups="scale,wobble")
    with pytest.raises(InputError, match="unknown option"):
        solvers.get("staged:scipy-lm", cycles=3)


def test_staged_converges_linearly_to_the_optimum_and_stops_on_rtol():
    """Block-coordinate descent: each cycle shrinks the gap by a steady factor (measured ≈ 0.8 here),
    so 40 cycles reach what LM reaches at once; rtol stops it once a cycle gains too little."""
    p = problem()
    res = solvers.get("staged:scipy-lm", max_cycles=40, rtol=0.0).solve(p, budget=20000, rng=0)
    per_cycle = np.array([gap(s["fun"]) for s in res.extra["stages"] if s["group"] == "nonlinear"])
    rates = per_cycle[1:] / per_cycle[:-1]
    print(f"staged:scipy-lm gap after cycles 1, 5, 10, 20, 40: {per_cycle[[0, 4, 9, 19, 39]]}; "
          f"rate per cycle {np.median(rates):.3f}")
    assert np.all(rates < 1.0) and np.all(rates > 0.5)
    assert per_cycle[-1] < 1e-2 and per_cycle[-1] < 1e-3 * per_cycle[0]
    assert res.extra["cycles"] == 40 and "max_cycles" in res.message
    stop = solvers.get("staged:scipy-lm", max_cycles=40, rtol=0.05).solve(problem(), budget=20000, rng=0)
    k = stop.extra["cycles"]
    ends = [s["fun"] for s in stop.extra["stages"] if s["group"] == "nonlinear"]
    assert 1 < k < 40 and stop.message.startswith(f"converged after {k} cycles")
    assert (ends[-2] - ends[-1]) / ends[-2] < 0.05 <= (ends[-3] - ends[-2]) / ends[-3]


def test_staged_shares_one_budget_and_merges_the_trace():
    p = problem()
    budget = 401
    res = solvers.get("staged:scipy-lm", max_cycles=30, rtol=0.0).solve(p, budget=budget, rng=0)
    log = res.extra["stages"]
    assert res.nfev == budget == sum(s["nfev"] for s in log)
    assert res.nit == sum(s["nit"] for s in log) > 0
    assert "budget used up" in log[-1]["message"] and res.success
    # Equal split: stage i may use at most (what was left) // (stages not yet run).
    used, n_total = 0, 30 * 4
    for i, s in enumerate(log):
        assert s["nfev"] <= max(1, (budget - used) // (n_total - i))
        used += s["nfev"]
    tr = np.array(res.trace)
    assert np.all(np.diff(tr[:, 0]) > 0) and np.all(np.diff(tr[:, 1]) < 0) and np.all(np.diff(tr[:, 2]) >= 0)
    assert tr[-1, 1] == res.fun and tr[-1, 0] <= res.nfev
    # The counter was not reset by the inner solves: the problem still holds the whole run.
    assert p.nfev == budget and p.best[1] == res.fun


def test_staged_split_inner_gives_each_stage_the_inner_default():
    class Capped(Solver):  # a deterministic inner whose default budget binds at once
        name, family, default_budget = "capped", "local", 3

        def _solve(self, problem, x0, rng, callback):
            problem.cost_batch(np.repeat(x0[None], 10, axis=0))
            return {}

    s = Staged(Capped(), split="inner", max_cycles=2)
    assert s.default_budget is None
    res = s.solve(problem(), rng=0)
    assert [st["nfev"] for st in res.extra["stages"]] == [3] * 8 and res.nfev == 24


def test_staged_callback_and_time_budget():
    p = problem()
    calls = []
    res = solvers.get("staged:scipy-lm").solve(p, rng=0, callback=lambda info: calls.append(info) or len(calls) == 2)
    assert res.status == 2 and len(calls) == 2 and res.nfev == calls[-1]["nfev"]
    assert calls[1]["nit"] > calls[0]["nit"] and calls[1]["fun"] < calls[0]["fun"]
    res = solvers.get("staged:scipy-lm", max_cycles=10_000, rtol=0.0).solve(p, budget=Budget(max_time=0.2), rng=0)
    assert res.status == 1 and "time budget" in res.message and res.runtime_s < 1.0


def test_wrappers_refuse_an_unavailable_inner_solver():
    class Missing(Solver):
        name, requires = "missing", ("no_such_package_optcal",)

    for w in (Staged(Missing()), MonteCarlo(Missing(), runs=2)):
        with pytest.raises(InputError, match="no_such_package_optcal"):
            w.solve(problem(), rng=0)


# -- mcs -----------------------------------------------------------------------------------------------
def test_mcs_mean_spread_and_independent_reproducible_runs():
    p = problem()
    runs, budget = 8, 8 * 600 + 1
    res = MonteCarlo(RandomSearch(), runs=runs).solve(p, budget=budget, rng=123)
    X = res.extra["x_runs"]
    assert X.shape == (runs, 12) and res.extra["runs_done"] == runs
    np.testing.assert_allclose(res.x, X.mean(axis=0), rtol=0, atol=1e-15)
    np.testing.assert_allclose(res.extra["sd"], X.std(axis=0, ddof=1))
    assert np.all(res.extra["sd"] > 0)
    assert res.fun == pytest.approx(cost(p, res.x), rel=1e-12)
    assert res.nfev == budget and res.success
    assert res.extra["best_fun"] == min(res.extra["fun_runs"] + [res.fun])  # the mean was evaluated too
    # Run i is exactly a standalone run with the i-th child generator and its share of the budget.
    children = np.random.default_rng(123).spawn(runs)
    for i in (0, runs - 1):
        alone = RandomSearch().solve(problem(), budget=600, rng=children[i])
        np.testing.assert_array_equal(alone.x, X[i])
    # Averaging: the cost is nearly quadratic here, so the mean costs less than the runs do on average
    # (Jensen), which is the point of the 2015 paper's averaging.
    print(f"mcs:random-search gap of the mean {gap(res.fun):.3f}, runs' mean gap "
          f"{np.mean([gap(f) for f in res.extra['fun_runs']]):.3f}")
    assert res.fun < np.mean(res.extra["fun_runs"])
    again = MonteCarlo(RandomSearch(), runs=runs).solve(problem(), budget=budget, rng=123)
    np.testing.assert_array_equal(again.x, res.x)


def test_mcs_of_a_deterministic_solver_and_its_options():
    p = problem()
    s = solvers.get("mcs:scipy-lm", runs="4", **{"inner.xtol": 1e-12})
    assert s.config["runs"] == 4 and s.inner.config["xtol"] == 1e-12 and s.name == "mcs:scipy-lm"
    res = s.solve(p, rng=0)
    assert np.all(res.extra["sd"] == 0) and res.extra["runs_done"] == 4
    assert gap(res.fun) <= 1e-9
    assert res.nit == 4 * solvers.get("scipy-lm", xtol=1e-12).solve(problem(), rng=0).nit
    assert s.default_budget == 4 * solvers.get("scipy-lm").default_budget + 1
    with pytest.raises(InputError, match="runs"):
        solvers.get("mcs:scipy-lm", runs=0)
    # The 2015 paper's Algorithm 1 (the mean within each phase) composes as staged:mcs:<inner>.
    nested = solvers.get("staged:mcs:scipy-lm", max_cycles=1, **{"inner.runs": 2})
    assert nested.name == "staged:mcs:scipy-lm" and nested.inner.config["runs"] == 2
    r = nested.solve(problem(), rng=0)
    assert [st["message"] for st in r.extra["stages"]] == ["2 runs done"] * 4 and r.fun < p.cost(p.x0)


def test_mcs_budget_runs_out_before_the_runs():
    p = problem()
    res = MonteCarlo(RandomSearch(), runs=10).solve(p, budget=6, rng=0)
    # Five runs of one evaluation each, then the mean's evaluation: nothing lost, nothing extra.
    assert res.nfev == 6 and res.extra["runs_done"] == 5
    assert res.status == 1 and "after 5 of 10 runs" in res.message
    assert np.isfinite(res.fun)


# -- command line ----------------------------------------------------------------------------------------
def test_cli_calibrate_composes_wrapper_names(tmp_path, capsys):
    sim, presets, ref = setting()
    csv, pre = tmp_path / "pos.csv", tmp_path / "presets.json"
    sim.data.to_csv(csv)
    pre.write_text(presets.to_json())
    names = solvers.names()
    cases = [("staged:scipy-lm", ["--option", "max_cycles=2"]), ("mcs:scipy-lm", ["--option", "runs=3"])]
    if "bsas" in names:
        cases.append(("staged:bsas", ["--budget", "2000"]))
    if "nafsa" in names:
        cases.append(("mcs:nafsa", ["--option", "runs=3", "--option", "inner.iterations=5", "--budget", "3000"]))
    for solver, extra in cases:
        rc = main(["calibrate", str(csv), "--model", "nonlinear12", "--solver", solver, "--presets", str(pre),
                   "--seed", "4", "--json", *extra])
        out = json.loads(capsys.readouterr().out)
        assert rc == 0 and out["solver"] == solver and out["success"] is True
        assert {"nfev", "nit", "runtime_s", "message"} <= set(out)
        assert out["cost"] < problem().cost(problem().x0)
    rc = main(["calibrate", str(csv), "--solver", "staged:scipy-lm", "--option", "wobble=1"])
    err = capsys.readouterr().err
    assert rc == 2 and "unknown option" in err and len(err.strip().splitlines()) == 1
