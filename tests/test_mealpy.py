"""mealpy's optimisers as the ``mealpy:NAME`` family (optcal/solvers/mealpy_solver.py, docs/algorithms.md, "mealpy's
optimisers (`mealpy:<NAME>`)"), beyond the
conformance suite (which runs GWO, WOA, HHO, SHADE and PSO through every check of the solver contract): names,
options and their one-line errors, the epochs sized from the budget, batched evaluation, seeds (mealpy's global
NumPy draws included), the stagnation rule, the listing, and the mealpy study spec's report."""

from __future__ import annotations

import importlib.util
import json
import math

import numpy as np
import pytest

from optcal import solvers
from optcal.app.cli import main
from optcal.core.errors import InputError
from optcal.core.presets import draw_truth, manufacturer_presets
from optcal.core.problem import CalibrationProblem
from optcal.core.simulate import simulate
from optcal.solvers.base import Stagnation
from optcal.solvers.mealpy_solver import evaluations_per_epoch, resolve

pytestmark = pytest.mark.skipif(importlib.util.find_spec("mealpy") is None, reason="mealpy is not installed")


class CountingProblem(CalibrationProblem):
    """Logs the number of candidates of every evaluation call (views share the log)."""

    calls: list | None = None

    def residuals_full(self, X_full):
        if self.calls is not None:
            self.calls.append(len(np.atleast_2d(X_full)))
        return super().residuals_full(X_full)


@pytest.fixture(scope="module")
def data():
    rng = np.random.default_rng(7)
    truth = draw_truth("nonlinear12", rng)
    sim = simulate("nonlinear12", truth, rng, scheme="24", noise_g=10e-6)
    return sim.data, manufacturer_presets(truth, rng)


def problem(data, cls=CalibrationProblem):
    p = cls("nonlinear12", data[0], presets=data[1])
    if cls is CountingProblem:
        p.calls = []
    return p


# -- names and options ---------------------------------------------------------------------------------
@pytest.mark.parametrize("name, cls", [("GWO", "OriginalGWO"), ("OriginalGWO", "OriginalGWO"), ("gwo", "OriginalGWO"),
                                       ("originalwoa", "OriginalWOA"), ("DevSMA", "DevSMA"), ("EPC", "DevEPC")])
def test_names_resolve_to_mealpy_classes(name, cls):
    assert resolve(name).__name__ == cls
    assert solvers.get(f"mealpy:{name}").name == f"mealpy:{name}"


@pytest.mark.parametrize("name, needle", [("mealpy:GW", "GWO"), ("mealpy:WhaleOpt", "optcal solvers"),
                                          ("mealpy:", "mealpy:GWO")])
def test_unknown_names_are_one_line_errors(name, needle):
    with pytest.raises(InputError) as e:
        solvers.get(name)
    assert needle in str(e.value) and "\n" not in str(e.value) and len(str(e.value)) <= 300


def test_settings_pass_through_and_bad_ones_are_one_line_errors(data):
    r = solvers.get("mealpy:GWO", pop_size=20).solve(problem(data), budget=1000, rng=1)
    assert r.extra["pop_size"] == 20 and r.nfev == 1000
    with pytest.raises(InputError) as e:  # unknown: the optimiser's settings are named
        solvers.get("mealpy:GWO", popsize=20)
    assert "popsize" in str(e.value) and "pop_size" in str(e.value) and "\n" not in str(e.value)
    with pytest.raises(InputError) as e:  # out of mealpy's range: its own check, on one line
        solvers.get("mealpy:GWO", pop_size=2)
    assert "pop_size" in str(e.value) and "[5, 10000]" in str(e.value) and "\n" not in str(e.value)
    with pytest.raises(InputError) as e:  # mealpy's OriginalBCO refuses its own default: say which setting
        solvers.get("mealpy:BCO")
    assert "n_chemotaxis" in str(e.value) and "--option" in str(e.value)
    assert solvers.get("mealpy:BCO", n_chemotaxis=3).passthrough == {"n_chemotaxis": 3}
    with pytest.raises(InputError):
        solvers.get("mealpy:GWO", mode="parallel")


def test_cli_calibrates_with_a_mealpy_optimiser(tmp_path):
    path = tmp_path / "sim.csv"
    assert main(["simulate", "--scheme", "24", "--model", "nonlinear12", "--seed", "3", "-o", str(path)]) == 0
    import contextlib
    import io

    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(["calibrate", str(path), "--solver", "mealpy:WOA", "--budget", "3000", "--seed", "1",
                     "--option", "pop_size=30", "--json"]) == 0
    d = json.loads(out.getvalue())
    assert d["solver"] == "mealpy:WOA" and d["nfev"] == 3000


# -- epochs, batches ----------------------------------------------------------------------------------------
def test_epochs_are_sized_from_the_budget(data):
    # one evaluation per wolf and epoch: (20,000 − the 100 of the initial pack) / 100 = 199 epochs
    r = solvers.get("mealpy:GWO").solve(problem(data), budget=20000, rng=1)
    assert r.extra["epochs"] == 199 and r.nit == 199 and r.nfev == 20000
    # teaching-learning takes two per learner and epoch (the teacher's phase and the learners'): 100 epochs
    assert evaluations_per_epoch(resolve("TLO"), (), 12, "swarm") == 200.0
    r = solvers.get("mealpy:TLO").solve(problem(data), budget=20000, rng=1)
    assert r.extra["epochs"] == 100 and r.nfev == 20000
    # an explicit epoch count is mealpy's own: the run ends there, with budget left
    r = solvers.get("mealpy:GWO", epoch=10).solve(problem(data), budget=20000, rng=1)
    assert r.nit == 10 and r.nfev == 100 * 11 and r.stop_reason == "own"


def test_swarm_mode_evaluates_each_population_in_one_call(data):
    p = problem(data, CountingProblem)
    r = solvers.get("mealpy:GWO", pop_size=30).solve(p, budget=30 * 21, rng=2)
    assert r.nfev == 630 and p.calls == [30] * 21  # the initial pack, then one batch per epoch
    q = problem(data, CountingProblem)
    solvers.get("mealpy:GWO", pop_size=30, mode="single").solve(q, budget=630, rng=2)
    assert q.calls == [1] * 630  # mealpy's default: each wolf as it moves


def test_the_start_is_in_the_first_population(data):
    p = problem(data)
    first = {}

    def record(info):
        first.setdefault("best", info["fun"])

    solvers.get("mealpy:WOA", pop_size=20).solve(p, budget=200, rng=3, callback=record)
    # init='start': the presets are a member, so the best after the first epoch is at most their cost
    assert first["best"] <= problem(data).cost(problem(data).x0)
    r = solvers.get("mealpy:WOA", pop_size=20, init="uniform").solve(problem(data), budget=20, rng=3)
    assert r.fun > problem(data).cost(problem(data).x0)  # 20 uniform draws in the box: all far worse


# -- seeds ------------------------------------------------------------------------------------------------------
def test_seeded_runs_repeat_and_leave_numpys_global_state_alone(data):
    # SHADE draws its mutation factors from scipy.stats (NumPy's global state): seeded from rng, restored after
    np.random.seed(12345)  # noqa: NPY002 - the caller's global state, which the solve must leave as it was
    before = np.random.get_state()[1].copy()  # noqa: NPY002
    a = solvers.get("mealpy:SHADE").solve(problem(data), budget=3000, rng=5)
    assert np.array_equal(np.random.get_state()[1], before)  # noqa: NPY002
    b = solvers.get("mealpy:SHADE").solve(problem(data), budget=3000, rng=5)
    c = solvers.get("mealpy:SHADE").solve(problem(data), budget=3000, rng=6)
    assert a.fun == b.fun and np.array_equal(a.x, b.x) and [t[:2] for t in a.trace] == [t[:2] for t in b.trace]
    assert a.fun != c.fun


# -- stopping -----------------------------------------------------------------------------------------------
def test_the_stagnation_rule_ends_a_run_that_has_stopped_improving(data):
    rule = Stagnation(share=0.1, rtol=1e-5)
    full = solvers.get("mealpy:GWO").solve(problem(data), budget=20000, rng=1, stagnation=rule)  # off by default
    stop = solvers.get("mealpy:GWO", stop_on_stagnation=True).solve(problem(data), budget=20000, rng=1,
                                                                    stagnation=rule)
    print(f"GWO: {full.nfev} evaluations, cost {full.fun:.6e}; with the rule {stop.nfev}, {stop.fun:.6e}")
    assert stop.stop_reason == "stagnation" and "stagnation" in stop.message and full.stop_reason == "budget"
    assert stop.nfev < full.nfev
    # the same run up to the stop: the trace (evaluations, best cost) is the full run's, cut there
    assert [t[:2] for t in stop.trace] == [t[:2] for t in full.trace][: len(stop.trace)]
    # the rule held at the stop: the best cost one window (2,000 evaluations) back is within rtol of the last
    W = 2000
    back = [f for n, f, _ in stop.trace if n <= stop.nfev - W][-1]
    assert back - stop.fun <= 1e-5 * stop.fun
    # and a solver that does not take the rule runs as without it
    pso = [solvers.get("pso").solve(problem(data), budget=5000, rng=1, stagnation=s) for s in (None, rule)]
    assert pso[0].nfev == pso[1].nfev == 5000 and pso[0].fun == pso[1].fun and pso[1].stop_reason == "budget"


# -- the listing ---------------------------------------------------------------------------------------------------
def test_solvers_lists_the_family_and_its_names(capsys):
    assert main(["solvers"]) == 0
    out = capsys.readouterr().out
    assert "mealpy:<NAME>  [metaheuristic]  available" in out
    assert "names (234):" in out and " OriginalGWO " in out and " OriginalHHO " in out
    assert main(["solvers", "--json"]) == 0
    fam = {f["prefix"]: f for f in json.loads(capsys.readouterr().out)["families"]}
    assert len(fam["mealpy"]["members"]) == 234 and "OriginalWOA" in fam["mealpy"]["members"]
    assert set(fam["mealpy"]["options"]) == {"mode", "init", "epoch", "stop_on_stagnation"}


def test_solvers_describes_one_member(capsys):
    assert main(["solvers", "mealpy:HHO"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("mealpy:HHO  [metaheuristic]  available  OriginalHHO (mealpy.swarm_based.HHO)")
    assert "pop_size = 100" in out and "Harris Hawks" in out
    assert main(["solvers", "mealpy:NoSuch"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "unknown mealpy optimiser" in err


def test_without_mealpy_the_family_says_how_to_install_it(monkeypatch, capsys, tmp_path):
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda n, *a: None if n == "mealpy" else real(n, *a))
    solver = solvers.get("mealpy:GWO")
    assert not solver.is_available()
    path = tmp_path / "sim.csv"
    assert main(["simulate", "--scheme", "24", "--model", "nonlinear12", "--seed", "3", "-o", str(path)]) == 0
    capsys.readouterr()
    assert main(["calibrate", str(path), "--solver", "mealpy:GWO"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "pip install --no-deps mealpy" in err


def test_mealpy_import_needs_neither_requests_nor_opfunu():
    import subprocess
    import sys

    code = "import sys, mealpy; print('requests' in sys.modules, 'opfunu' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.split() == ["False", "False"]


# -- the study spec ---------------------------------------------------------------------------------------------
@pytest.mark.slow
def test_the_mealpy_spec_reports_its_optimisers_like_every_solver(tmp_path):
    """The shipped spec (three mealpy optimisers and three yardsticks on the compare settings), cut to three
    runs of one model and scheme: each optimiser has its row in the cell's table, its place in the paired
    comparisons, its anytime curves and its settings with the reasons its trials ended."""
    from dataclasses import replace

    from optcal.studies.execute import run_study
    from optcal.studies.report import write_report
    from optcal.studies.spec import load

    spec = replace(load("mealpy").with_runs(3), models=("nonlinear12",), schemes=("24",))
    assert [c.label for c in spec.solvers][:3] == ["mealpy:GWO", "mealpy:WOA", "mealpy:HHO"]
    assert all(c.budget == {"max_evals": 20000} for c in spec.solvers)
    s = run_study(spec, tmp_path, executor="serial", progress=False)
    assert s.ran == 18 and s.failed == 0
    write_report(tmp_path, workers=0)
    text = (tmp_path / "report.md").read_text()
    doc = json.loads((tmp_path / "summary.json").read_text())
    cell = text.split("## nonlinear12, 24 positions")[1].split("![ranking]")[0]
    paired = text.split("## Paired comparisons")[1].split("\n## ")[0]
    anytime = text.split("## Anytime performance")[1].split("## Solver settings")[0]
    settings = text.split("## Solver settings")[1]
    for name in ("mealpy:GWO", "mealpy:WOA", "mealpy:HHO"):
        assert f"| `{name}` |" in cell and f"`{name}`" in paired and f"`{name}`" in anytime, name
        rec = next(r for r in doc["records"] if r["solver"] == name)
        assert rec["runs"] == 3 and math.isfinite(rec["accuracy"]) and rec["nfev_median"] <= 20000
        st = next(x for x in doc["settings"] if x["solver"] == name)
        assert abs(sum(st["stop_reasons"].values()) - 1) < 1e-12
        assert set(st["stop_reasons"]) <= {"budget", "own"}  # the rule is off for them
        assert f"| `{name}` | mode=swarm, init=start, epoch=0, stop_on_stagnation=False |" in settings
    assert any(r["solver"].startswith("mealpy:") for r in doc["paired"])
    print(settings[:1500])
