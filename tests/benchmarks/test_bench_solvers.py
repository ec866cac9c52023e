"""One run of every registered solver (and staged:/mcs: around scipy-lm) on the same 24-position problem.

The problem is the conformance suite's setting: ``nonlinear12``, truth drawn with a fixed seed, 10 µg
noise per axis, manufacturer presets as start and search centre; each solver gets its default budget
(at most 20 000 evaluations; at most 2 000 when timing is disabled, as under `make test`) and seed 1.
A solver with a ``warm_up(problem)`` step (casadi-ipopt builds its NLP there) is warmed up outside the
timed call.

extra_info per solver: final cost and its relative gap to scipy-lm's optimum, evaluations, iterations,
success, and the verification error of the 2020 paper (§5.1, its Table 5): on an independent 36-position
set simulated from the same truth (10 µg noise, its own seed), the mean over positions of |‖A‖ − g| in µg
with A calibrated by the solver's parameters; ``calibration_error_ug`` is the same on noise-free data,
which isolates the parameter error. Run with `make bench`; under `make test` each runs once untimed.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest

from optcal import solvers
from optcal.core.presets import draw_truth, manufacturer_presets
from optcal.core.problem import CalibrationProblem
from optcal.core.simulate import simulate

SEED = 20240611
CAP = 20_000
QUICK = 2_000
WRAPPED = {"staged:scipy-lm": {}, "mcs:scipy-lm": {"runs": 10}}
NAMES = sorted(set(solvers.names()) | set(WRAPPED))


@functools.cache
def setting():
    rng = np.random.default_rng(SEED)
    truth = draw_truth("nonlinear12", rng)
    sim = simulate("nonlinear12", truth, rng, scheme="24", noise_g=10e-6)
    presets = manufacturer_presets(truth, rng)
    verify = simulate("nonlinear12", truth, np.random.default_rng(SEED + 1), scheme="36", noise_g=10e-6)
    exact = simulate("nonlinear12", truth, np.random.default_rng(SEED + 1), scheme="36", noise_g=0.0)
    ref = solvers.get("scipy-lm").solve(CalibrationProblem("nonlinear12", sim.data, presets=presets), rng=0)
    return sim, presets, verify, exact, ref


def verification_error_ug(sim, x_full) -> float:
    """Mean |‖A‖ − g| in µg over the positions of ``sim``, A from its outputs through ``x_full``."""
    A = sim.model.inverse(np.atleast_2d(x_full), sim.data.N)[0]
    return float(np.mean(np.abs(np.linalg.norm(A, axis=1) - 1.0)) * 1e6)


@pytest.mark.parametrize("name", NAMES)
def test_bench_solver(benchmark, name):
    solver = solvers.get(name, **WRAPPED.get(name, {}))
    inner = solver
    while getattr(inner, "inner", None) is not None:
        inner = inner.inner
    if not inner.is_available():
        pytest.skip(inner.unavailable_message())
    sim, presets, verify, exact, ref = setting()
    problem = CalibrationProblem("nonlinear12", sim.data, presets=presets)
    if hasattr(inner, "warm_up"):
        inner.warm_up(problem)
    # Timed (`make bench`): the solver's default budget. Untimed (`make test`): at most QUICK evaluations,
    # enough to check the run end to end without a second full accuracy run next to the conformance suite.
    cap = QUICK if benchmark.disabled else CAP
    budget = cap if solver.default_budget is None else min(solver.default_budget, cap)
    res = benchmark.pedantic(solver.solve, args=(problem,), kwargs={"budget": budget, "rng": 1},
                             rounds=1, iterations=1)
    start = problem.to_full(problem.x0)[0]
    info = {
        "solver": name, "family": inner.family, "cost": res.fun, "gap": (res.fun - ref.fun) / ref.fun,
        "budget": budget, "nfev": res.nfev, "nit": res.nit, "success": res.success, "runtime_s": res.runtime_s,
        "verification_error_ug": verification_error_ug(verify, res.x_full),
        "calibration_error_ug": verification_error_ug(exact, res.x_full),
        "presets_verification_error_ug": verification_error_ug(verify, start),
    }
    benchmark.extra_info.update(info)
    print(" ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}" for k, v in info.items()))
    # success is recorded, not asserted: the conformance suite judges it; the benchmark measures.
    assert np.isfinite(res.fun) and res.nfev <= budget
    # No solver may hand back something worse than where it started.
    assert res.fun <= CalibrationProblem("nonlinear12", sim.data, presets=presets).cost(problem.x0)
    assert np.isfinite(info["verification_error_ug"])
