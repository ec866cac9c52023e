"""Our ``pso`` against pyswarms' ``GlobalBestPSO`` (an optional test dependency) on the same cost.

The cost is the normalised ``seed15`` problem of the 2020 paper's setting (24 positions, 10 µg noise,
manufacturer presets as the search centre): its ``cost_batch`` takes the swarm (n_particles, 15) and
returns (n_particles,), which is exactly pyswarms' objective signature, so it is passed directly. Both
run with the same swarm size, coefficients (w = 0.7298, c1 = c2 = 1.49618), bounds (the unit box) and
number of evaluations: ours evaluates the initial swarm and then once per iteration, pyswarms evaluates
at the start of each of its iterations, so pyswarms gets ITERATIONS + 1 of them. pyswarms starts from
a swarm drawn the way ours is (uniform in the box, the start point as particle 0); everything else is
its default (periodic boundary handling, velocities drawn uniform in [0, 1)).

Benchmarks (ITERATIONS = 100, seed 1 of five): ``benchmark.extra_info`` has the final cost of both
and their ratio, the median final costs over the five test seeds and their ratio, and the runtime ratio
(ours / pyswarms, best of three runs each with ``time.perf_counter``, so it is there under
``--benchmark-disable`` too). The plain test compares the medians over five seeds at 40 iterations
(before convergence) and 200 (after).
pyswarms configures logging with a file ``report.log`` in the working directory unless told otherwise;
``LOG_CFG`` points it at a configuration that changes nothing.
"""

from __future__ import annotations

import functools
import time

import numpy as np
import pytest

from optcal import solvers
from optcal.core.presets import PAPER_TRUTH, manufacturer_presets
from optcal.core.problem import CalibrationProblem
from optcal.core.simulate import simulate

N_PARTICLES = 30
ITERATIONS = 100
COEFFS = {"w": 0.7298, "c1": 1.49618, "c2": 1.49618}
SEEDS = np.random.SeedSequence(1995).spawn(6)  # one data seed, five solver seeds


@pytest.fixture(scope="module")
def global_best_pso(tmp_path_factory):
    cfg = tmp_path_factory.mktemp("pyswarms") / "logging.json"
    cfg.write_text('{"version": 1, "disable_existing_loggers": false}')
    mp = pytest.MonkeyPatch()
    mp.setenv("LOG_CFG", str(cfg))
    try:
        yield pytest.importorskip("pyswarms.single").GlobalBestPSO
    finally:
        mp.undo()


@functools.cache
def problem() -> CalibrationProblem:
    rng = np.random.default_rng(SEEDS[0])
    presets = manufacturer_presets(PAPER_TRUTH, rng)
    sim = simulate("seed15", PAPER_TRUTH, rng, scheme="24", noise_g=10e-6)
    return CalibrationProblem("seed15", sim.data, presets=presets)


def run_ours(seed, iterations: int = ITERATIONS) -> tuple[float, int]:
    res = solvers.get("pso", n_particles=N_PARTICLES, iterations=iterations, **COEFFS).solve(
        problem(), rng=np.random.default_rng(seed))
    return res.fun, res.nfev


def run_pyswarms(gbest_cls, seed, iterations: int = ITERATIONS) -> tuple[float, int]:
    p = problem()
    zp = p.normalised()
    rng = np.random.default_rng(seed)
    init = rng.uniform(-1.0, 1.0, (N_PARTICLES, zp.n))
    init[0] = zp.x0
    # pyswarms draws from numpy's legacy global generator: seed it from ours, and put it back after.
    state = np.random.get_state()  # noqa: NPY002
    np.random.seed(int(rng.integers(2**31)))  # noqa: NPY002
    try:
        p.start(None)
        opt = gbest_cls(N_PARTICLES, zp.n, options={k: COEFFS[k] for k in ("c1", "c2", "w")},
                        bounds=(zp.lb, zp.ub), init_pos=init)
        cost, _ = opt.optimize(zp.cost_batch, iters=iterations + 1, verbose=False)
    finally:
        np.random.set_state(state)  # noqa: NPY002
    return float(cost), p.nfev


@functools.cache
def side_by_side(gbest_cls) -> dict:
    def best_time(fn):
        times, out = [], None
        for _ in range(3):
            t0 = time.perf_counter()
            out = fn()
            times.append(time.perf_counter() - t0)
        return min(times), out

    t_ours, (f_ours, _) = best_time(lambda: run_ours(SEEDS[1]))
    t_theirs, (f_theirs, _) = best_time(lambda: run_pyswarms(gbest_cls, SEEDS[1]))
    # One seed's costs scatter by tens of percent; the median over the five test seeds compares better.
    med_ours = float(np.median([run_ours(s)[0] for s in SEEDS[1:]]))
    med_theirs = float(np.median([run_pyswarms(gbest_cls, s)[0] for s in SEEDS[1:]]))
    return {"n_particles": N_PARTICLES, "evaluations": N_PARTICLES * (ITERATIONS + 1),
            "final_cost_ours": f_ours, "final_cost_pyswarms": f_theirs, "cost_ratio": f_ours / f_theirs,
            "median_cost_ours_5_seeds": med_ours, "median_cost_pyswarms_5_seeds": med_theirs,
            "median_cost_ratio_5_seeds": med_ours / med_theirs,
            "time_ours_s": t_ours, "time_pyswarms_s": t_theirs, "time_ratio": t_ours / t_theirs}


def test_bench_pso_ours(benchmark, global_best_pso):
    fun, nfev = benchmark(run_ours, SEEDS[1])
    benchmark.extra_info.update(side_by_side(global_best_pso))
    assert nfev == N_PARTICLES * (ITERATIONS + 1) and np.isfinite(fun)


def test_bench_pso_pyswarms(benchmark, global_best_pso):
    fun, nfev = benchmark(run_pyswarms, global_best_pso, SEEDS[1])
    benchmark.extra_info.update(side_by_side(global_best_pso))
    assert nfev == N_PARTICLES * (ITERATIONS + 1) and np.isfinite(fun)


@functools.cache
def optimum() -> float:
    return solvers.get("scipy-trf").solve(problem(), budget=300, rng=0).fun


@pytest.mark.parametrize("iterations", [40, 200])
def test_pso_reaches_an_equal_or_lower_cost_than_pyswarms(global_best_pso, iterations):
    """Median final cost over five solver seeds, same evaluations, same problem.

    At 40 iterations neither has converged and ours is lower (measured: 6.9 vs 17 times the
    least-squares optimum; pyswarms' default velocities, uniform in [0, 1) per coordinate, throw its
    swarm around a unit box at first). At 200 both have converged: equal, within 2 % of the optimum
    (measured 0.9 % and 0.3 %). At 100, the benchmark's setting, they are within 1 % of each other.
    """
    ours = [run_ours(s, iterations) for s in SEEDS[1:]]
    theirs = [run_pyswarms(global_best_pso, s, iterations) for s in SEEDS[1:]]
    evaluations = N_PARTICLES * (iterations + 1)
    assert {n for _, n in ours} == {n for _, n in theirs} == {evaluations}
    f_ours, f_theirs = np.median([f for f, _ in ours]), np.median([f for f, _ in theirs])
    print(f"\npso vs pyswarms GlobalBestPSO, {N_PARTICLES} particles, {evaluations} evaluations, 5 seeds: "
          f"median final cost / optimum {f_ours / optimum():.4f} vs {f_theirs / optimum():.4f}")
    if iterations < 100:
        assert f_ours < 0.7 * f_theirs
    else:
        assert f_ours < 1.02 * optimum() and f_theirs < 1.02 * optimum()
