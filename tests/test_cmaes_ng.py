"""CMA-ES (``cmaes``, pycma) and nevergrad's optimisers (``ng:NAME``) beyond the conformance suite: the
command line's budget and accuracy on a 24-position ``nonlinear12`` problem, IPOP and BIPOP restarts, seeds,
options, and the errors a user meets (docs/algorithms.md, CMA-ES and nevergrad sections)."""

from __future__ import annotations

import importlib.util
import json

import numpy as np
import pytest

from optcal import read_positions, solvers
from optcal.app.cli import main
from optcal.core.errors import InputError
from optcal.core.problem import CalibrationProblem


@pytest.fixture(scope="module")
def positions_csv(tmp_path_factory):
    """A 24-position nonlinear12 data set (10 µg noise), written by ``optcal simulate``."""
    path = tmp_path_factory.mktemp("cma") / "sim24.csv"
    assert main(["simulate", "--scheme", "24", "--model", "nonlinear12", "--seed", "3", "-o", str(path)]) == 0
    return path


@pytest.fixture(scope="module")
def lm_cost(positions_csv, tmp_path_factory):
    """The optimum's cost, from Levenberg-Marquardt (which reaches it: tests/test_local_solvers.py)."""
    return calibrate_json(positions_csv, "scipy-lm")["cost"]


def calibrate_json(path, solver, *args) -> dict:
    import contextlib
    import io

    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(["calibrate", str(path), "--solver", solver, "--seed", "1", "--json", *args]) == 0
    return json.loads(out.getvalue())


@pytest.fixture
def problem24(positions_csv):
    """A fresh problem (its own evaluation counter) on the 24 simulated positions, each time it is called."""
    return lambda: CalibrationProblem("nonlinear12", read_positions(positions_csv))


# -- the command line: the budget is used exactly, and the optimum is reached --------------------------------
def test_cli_cmaes_uses_the_budget_exactly_and_reaches_the_optimum(positions_csv, lm_cost):
    # Restarts keep CMA-ES searching until the budget is spent; one run alone stops by itself earlier.
    d = calibrate_json(positions_csv, "cmaes", "--budget", "20000", "--option", "restarts=3")
    assert d["nfev"] == 20000
    assert abs(d["cost"] - lm_cost) / lm_cost < 1e-6
    # A budget that binds inside the first run.
    d = calibrate_json(positions_csv, "cmaes", "--budget", "1234")
    assert d["nfev"] == 1234 and "budget" in d["message"]


def test_cli_ngopt_uses_the_budget_exactly_and_approaches_the_optimum(positions_csv, lm_cost):
    d = calibrate_json(positions_csv, "ng:NGOpt", "--budget", "3001")
    assert d["nfev"] == 3001  # 3001 is not a multiple of the batch: the last batch is cut to fit
    # From the presets' cost (far above: tests/test_conformance.py) to within 25 % of the optimum's.
    assert (d["cost"] - lm_cost) / lm_cost < 0.25
    assert d["solver"] == "ng:NGOpt"


# -- CMA-ES ------------------------------------------------------------------------------------------------
def test_cmaes_default_run_converges_and_stops_by_itself(problem24):
    p = problem24()
    r = solvers.get("cmaes").solve(p, budget=20000, rng=1)
    ref = solvers.get("scipy-lm").solve(p)
    assert r.nfev < 20000 and r.status == 0 and "tolfun" in r.message
    assert abs(r.fun - ref.fun) / ref.fun < 1e-6
    runs = r.extra["runs"]
    assert len(runs) == 1 and runs[0]["popsize"] == 4 + int(3 * np.log(12)) == 11
    assert runs[0]["nfev"] == r.nfev == 11 * runs[0]["generations"]


def test_ipop_doubles_the_population_at_each_restart(problem24):
    p = problem24()
    r = solvers.get("cmaes", restarts=3, restart_strategy="ipop").solve(p, budget=20000, rng=2)
    runs = r.extra["runs"]
    assert [run["popsize"] for run in runs] == [11, 22, 44, 88][: len(runs)]
    assert len(runs) == 4 and r.nfev == 20000 and sum(run["nfev"] for run in runs) == 20000
    assert all(run["sigma0"] == 0.1 for run in runs)


def test_bipop_interlaces_small_and_large_regimes(problem24):
    p = problem24()
    r = solvers.get("cmaes", restarts=3, restart_strategy="bipop", sigma0=0.2).solve(p, budget=60000, rng=3)
    runs = r.extra["runs"]
    regimes = [run["regime"] for run in runs]
    assert regimes[0] == "default" and "small" in regimes and "large" in regimes
    large = [run["popsize"] for run in runs if run["regime"] == "large"]
    assert large == [22, 44, 88][: len(large)]  # doubling from the default λ = 11
    assert len(large) <= 3
    for k, run in enumerate(runs):
        if run["regime"] == "small":
            # λ_s = ⌊λ_def (λ_L/λ_def)^(U1²)⌋ between λ_def and the latest large λ; σ0·10^(−2 U2) ≤ σ0
            lam_l = max([11] + [q["popsize"] for q in runs[:k] if q["regime"] == "large"])
            assert 11 <= run["popsize"] <= lam_l
            assert 0.2 * 1e-2 <= run["sigma0"] <= 0.2
    assert sum(run["nfev"] for run in runs) == r.nfev


def test_cmaes_seeds_reproduce_and_leave_numpy_global_state_alone(problem24):
    p = problem24()
    state = np.random.get_state()[1].copy()  # noqa: NPY002 - checking that the legacy global state is untouched
    a = solvers.get("cmaes").solve(p, budget=2000, rng=7)
    b = solvers.get("cmaes").solve(p, budget=2000, rng=7)
    c = solvers.get("cmaes").solve(p, budget=2000, rng=8)
    assert np.array_equal(a.x, b.x) and a.fun == b.fun
    assert not np.array_equal(a.x, c.x)
    assert np.array_equal(np.random.get_state()[1], state)  # noqa: NPY002


@pytest.mark.parametrize("opts, needle", [
    ({"sigma0": 0.0}, "sigma0"), ({"popsize": 1}, "popsize"), ({"restarts": -1}, "restarts"),
    ({"restart_strategy": "lipop"}, "restart_strategy"), ({"sigmaa": 0.3}, "sigmaa"),
])
def test_cmaes_bad_options_are_one_line_errors(opts, needle):
    with pytest.raises(InputError) as e:
        solvers.get("cmaes", **opts)
    assert needle in str(e.value) and "\n" not in str(e.value)


# -- nevergrad ---------------------------------------------------------------------------------------------
def test_ng_asks_batches_and_cuts_the_last_one_to_the_budget(problem24):
    p = problem24()
    sizes = []
    cost_batch = p.cost_batch

    def spy(X):
        sizes.append(len(X))
        return cost_batch(X)

    p.cost_batch = spy  # the unit-box view evaluates through the problem's own cost_batch
    r = solvers.get("ng:TwoPointsDE", batch=5).solve(p, budget=23, rng=1)
    assert r.nfev == 23 and r.nit == 5 and r.extra["batch"] == 5
    assert sizes == [5, 5, 5, 5, 3]


def test_ng_default_batch_and_sequential_optimisers(problem24):
    p = problem24()
    r = solvers.get("ng:OnePlusOne").solve(p, budget=200, rng=1)
    assert r.extra["batch"] == 4 + int(3 * np.log(12)) and r.nfev == 200


def test_ng_seeds_reproduce(problem24):
    p = problem24()
    a = solvers.get("ng:TwoPointsDE").solve(p, budget=500, rng=4)
    b = solvers.get("ng:TwoPointsDE").solve(p, budget=500, rng=4)
    c = solvers.get("ng:TwoPointsDE").solve(p, budget=500, rng=5)
    assert np.array_equal(a.x, b.x) and not np.array_equal(a.x, c.x)


def test_ng_options_pass_through_and_unknown_ones_are_refused(problem24):
    p = problem24()
    r = solvers.get("ng:TwoPointsDE", popsize=30).solve(p, budget=300, rng=1)
    assert r.nfev == 300
    with pytest.raises(InputError) as e:
        solvers.get("ng:TwoPointsDE", popsze=30)
    msg = str(e.value)
    assert "popsze" in msg and "popsize" in msg and "\n" not in msg
    with pytest.raises(InputError) as e:
        solvers.get("ng:NGOpt", popsize=30)
    assert "popsize" in str(e.value) and "NGOpt" in str(e.value)


@pytest.mark.parametrize("name, needle", [("ng:NGOp", "NGOpt"), ("ng:twopointsde", "TwoPointsDE"), ("ng:", "ng:NGOpt")])
def test_ng_unknown_names_are_one_line_errors_with_close_names(name, needle):
    with pytest.raises(InputError) as e:
        solvers.get(name)
    assert needle in str(e.value) and "\n" not in str(e.value)


def test_ng_without_nevergrad_says_how_to_install_it(positions_csv, monkeypatch, capsys):
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda n, *a: None if n == "nevergrad" else real(n, *a))
    solver = solvers.get("ng:NGOpt")
    assert not solver.is_available()
    code = main(["calibrate", str(positions_csv), "--solver", "ng:NGOpt"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1
    assert 'pip install "optcal[nevergrad]"' in err



def test_solvers_listing_names_the_ng_family(capsys):
    assert main(["solvers"]) == 0
    out = capsys.readouterr().out
    assert "cmaes" in out and "ng:<NAME>" in out
    assert "ng:<NAME>  [metaheuristic]  available" in out and 'ng.optimizers.registry' in out


def test_solvers_json_lists_the_family_with_its_options(capsys):
    assert main(["solvers", "--json"]) == 0
    fam = {f["prefix"]: f for f in json.loads(capsys.readouterr().out)["families"]}
    assert sorted(fam) == ["mealpy", "ng"]  # mealpy's family: tests/test_mealpy.py
    assert fam["ng"]["options"]["batch"]["default"] == 0 and fam["ng"]["available"] is True
