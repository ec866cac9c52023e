"""Benchmarks of the core: batched seed15 cost on 24 positions and one SciPy LM calibration.

Run with `make bench`; under `make test` they run once each with timing disabled. The per-candidate
times and the batched-vs-loop speed-up go to extra_info (the issue asks for ≥ 50x at S = 10,000).
"""

import time

import numpy as np
import pytest

import solvers
from optcal import CalibrationProblem, get_model, simulate
from optcal.presets import PAPER_TRUTH


@pytest.fixture(scope="module")
def seed15_problem():
    m = get_model("seed15")
    sim = simulate(m, PAPER_TRUTH, np.random.default_rng(0), scheme="24", noise_g=10e-6)
    return CalibrationProblem(m, sim.data), sim.truth_vector(m)


def _population(x, S):
    return x + 1e-5 * np.random.default_rng(1).standard_normal((S, x.size))


def _loop_time_per_candidate(problem, X, repeats=3):
    best = np.inf
    for _ in range(repeats):
        t = time.perf_counter()
        for x in X:
            problem.cost(x)
        best = min(best, (time.perf_counter() - t) / len(X))
    return best


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
    benchmark.extra_info.update({"S": S, "per_candidate_s": batched, "loop_per_candidate_s": loop,
                                 "speedup_vs_loop": loop / batched})


def test_bench_scipy_lm_calibration(benchmark):
    m = get_model("nonlinear12")
    truth = {k: v for k, v in PAPER_TRUTH.items() if k in m.names}
    sim = simulate(m, truth, np.random.default_rng(3), scheme="24", noise_g=10e-6)
    problem = CalibrationProblem(m, sim.data)
    lm = solvers.get("scipy-lm")
    res = benchmark(lambda: lm.solve(problem, rng=0))
    assert res.success and res.fun < 24 * (30e-6) ** 2
    benchmark.extra_info.update({"final_cost": res.fun, "nfev": res.nfev,
                                 "max_abs_error": float(np.abs(res.x_full - sim.truth_vector(m)).max())})
