"""Benchmarks of the core: the seed15 cost on 24 positions (one candidate per call and in batches), the
nonlinear12 Jacobian and one SciPy LM calibration.

Run with `make bench`; under `make test` they run once each with timing disabled. Times per call or per
candidate, and ratios against the NumPy path and a Python loop measured in the same run, go to
extra_info (docs/performance.md).
"""

import time

import numpy as np
import pytest

from optcal import CalibrationProblem, get_model, simulate, solvers
from optcal.core.presets import PAPER_TRUTH


@pytest.fixture(scope="module")
def seed15_problem():
    m = get_model("seed15")
    sim = simulate(m, PAPER_TRUTH, np.random.default_rng(0), scheme="24", noise_g=10e-6)
    return CalibrationProblem(m, sim.data), sim.truth_vector(m)


def _population(x, S):
    return x + 1e-5 * np.random.default_rng(1).standard_normal((S, x.size))


def _per_call(fn, args, repeats=3):
    """Best-of-``repeats`` time per call of ``fn`` over the argument list."""
    best = np.inf
    for _ in range(repeats):
        t = time.perf_counter()
        for a in args:
            fn(a)
        best = min(best, (time.perf_counter() - t) / len(args))
    return best


def _loop_time_per_candidate(problem, X, repeats=3):
    return _per_call(problem.cost, list(X), repeats)


def _numpy_cost(problem):
    return lambda x: float(np.sum(problem.residuals_full_numpy(problem.to_full(x)) ** 2))


def test_bench_seed15_cost_one_candidate(benchmark, seed15_problem):
    """The public ``CalibrationProblem.cost(x)``: what NLopt, BAS and the staged local methods call."""
    problem, xt = seed15_problem
    X = _population(xt, 200)
    problem.start()
    f = benchmark(problem.cost, X[0])
    assert f == pytest.approx(_numpy_cost(problem)(X[0]), rel=1e-12)
    compiled = _per_call(problem.cost, list(X))
    if benchmark.stats is not None:
        compiled = benchmark.stats.stats.min
    numpy_path = _per_call(_numpy_cost(problem), list(X[:50]))
    benchmark.extra_info.update({"per_call_s": compiled, "numpy_per_call_s": numpy_path,
                                 "speedup_vs_numpy": numpy_path / compiled})


def test_bench_nonlinear12_jacobian(benchmark):
    m = get_model("nonlinear12")
    truth = {k: v for k, v in PAPER_TRUTH.items() if k in m.names}
    sim = simulate(m, truth, np.random.default_rng(3), scheme="24", noise_g=10e-6)
    problem = CalibrationProblem(m, sim.data)
    x = sim.truth_vector(m)
    J = benchmark(problem.jacobian_full, x)
    np.testing.assert_allclose(J, problem.jacobian_full_numpy(x), rtol=0, atol=1e-12)
    numpy_path = _per_call(problem.jacobian_full_numpy, [x] * 20)
    compiled = _per_call(problem.jacobian_full, [x] * 200)
    benchmark.extra_info.update({"per_call_s": compiled, "numpy_per_call_s": numpy_path,
                                 "speedup_vs_numpy": numpy_path / compiled})


@pytest.mark.parametrize("S", [1, 100, 10_000])
def test_bench_seed15_cost_batch(benchmark, seed15_problem, S):
    problem, xt = seed15_problem
    X = _population(xt, S)
    problem.start()
    f = benchmark(problem.cost_batch, X)
    assert f.shape == (S,) and np.all(np.isfinite(f))
    loop = _loop_time_per_candidate(problem, X[:200])
    # the batched time per candidate, measured here too so the ratio is available with --benchmark-disable
    t = time.perf_counter()
    problem.cost_batch(X)
    batched = (time.perf_counter() - t) / S
    if benchmark.stats is not None:
        batched = benchmark.stats.stats.min / S
    t = time.perf_counter()
    problem.residuals_full_numpy(X)
    numpy_batched = (time.perf_counter() - t) / S
    benchmark.extra_info.update({"S": S, "per_candidate_s": batched, "loop_per_candidate_s": loop,
                                 "speedup_vs_loop": loop / batched, "numpy_per_candidate_s": numpy_batched,
                                 "speedup_vs_numpy": numpy_batched / batched})


def test_bench_scipy_lm_calibration(benchmark):
    m = get_model("nonlinear12")
    truth = {k: v for k, v in PAPER_TRUTH.items() if k in m.names}
    sim = simulate(m, truth, np.random.default_rng(3), scheme="24", noise_g=10e-6)
    problem = CalibrationProblem(m, sim.data)
    lm = solvers.get("scipy-lm")
    res = benchmark(lambda: lm.solve(problem, rng=0))
    assert res.success and res.fun < 24 * (30e-6) ** 2
    benchmark.extra_info.update({"final_cost": res.fun, "nfev": res.nfev, "njev": res.njev,
                                 "max_abs_error": float(np.abs(res.x_full - sim.truth_vector(m)).max())})


def test_bench_calibrate_5000_positions(benchmark):
    """A positions file of 5,000 reference rows (a new user's table of samples against a reference IMU): the
    whole calibration with its outlier scan, which carries the hat matrix as its factor (a dense m × m hat
    matrix and an SVD with full_matrices made it minutes and gigabytes). extra_info: the solver's own time."""
    from optcal.app.fit import calibrate

    m = get_model("linear9")
    truth = {k: v for k, v in PAPER_TRUTH.items() if k in m.names}
    sim = simulate(m, truth, np.random.default_rng(2), scheme="random:5000", noise_g=500e-6, reference=True)
    res = benchmark.pedantic(calibrate, args=(sim.data, m), kwargs={"reference": True}, rounds=3, iterations=1)
    assert res.x.shape == (m.n_params,) and np.all(np.isfinite(res.x))
    benchmark.extra_info["positions"] = 5000
    benchmark.extra_info["solver_s"] = float(res.result.runtime_s)
