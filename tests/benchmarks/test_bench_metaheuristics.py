"""The metaheuristics' own Python per iteration, next to the compiled cost kernel they call.

One solve per solver of the 2020 paper's setting as the studies build it (``seed15``, 24 positions,
the paper's truth, manufacturer presets as the search centre, 10 µg noise, 1° tilt) under a budget of
20,000 evaluations, seed 1. ``bas`` and ``bsas`` get enough iterations for the budget to end the run
(their defaults stop at 1,201 and 18,001 evaluations); ``staged:bas`` is the four-stage procedure
around ``bas``, whose 6,660 short iterations (three free parameters a stage) made it the slowest
solver of the ``compare`` study.

extra_info: evaluations per second and seconds per iteration of the solve (the benchmark's best
round; under ``--benchmark-disable`` one ``time.perf_counter`` run), and the fraction of a solve
spent in the compiled kernel, from one more run with the kernel's entry points
(``optcal.core.kernels.evaluate.cost_one`` and ``evaluate_batch``) wrapped in a timer as
docs/scripts/profile_study.py does (that run is a little slower than the others: about 0.3 µs of timer
per call). Run with `make bench`; under `make test` each runs once untimed, and checks what every run
must satisfy: the budget used exactly, a final cost below the start's, and the same result again
from the same seed.

The last test checks the draw-ahead of ``bas`` and ``bsas`` (random numbers for many iterations
drawn at once): the numbers and the generator's state after a run cut short are those of one draw per
iteration.
"""

from __future__ import annotations

import copy
import functools
import time

import numpy as np
import pytest

from optcal import solvers
from optcal.core.kernels import evaluate
from optcal.core.presets import PAPER_TRUTH, manufacturer_presets
from optcal.core.problem import CalibrationProblem, Counter
from optcal.core.simulate import simulate
from optcal.solvers._unitbox import unit_rows
from optcal.solvers.bas import DrawAhead
from optcal.solvers.bsas import _Draws

BUDGET = 20_000
SEED = 1
CASES = {
    "bas": {"iterations": 7000},
    "bsas": {"iterations": 700},
    "pso": {},
    "nafsa": {},
    "afsa": {},
    "oafsa": {},
    "staged:bas": {},
}


@functools.cache
def problem() -> CalibrationProblem:
    rng = np.random.default_rng(2020)
    presets = manufacturer_presets(PAPER_TRUTH, rng)
    sim = simulate("seed15", PAPER_TRUTH, rng, scheme="24", noise_g=10e-6, tilt_deg=1.0)
    return CalibrationProblem("seed15", sim.data, presets=presets, noise_g=10e-6)


def solve(name: str):
    view = copy.copy(problem())
    view.counter = Counter()  # a counter of this run's own, as optcal.studies.trial gives every trial
    return solvers.get(name, **CASES[name]).solve(view, budget=BUDGET, rng=np.random.default_rng(SEED))


def kernel_time(monkeypatch, name: str) -> tuple[float, float, object]:
    """(seconds in the kernel, seconds of the whole solve, result) of one solve with the kernel timed."""
    spent = [0.0]

    def timed(fn):
        def wrapper(*args):
            t = time.perf_counter()
            try:
                return fn(*args)
            finally:
                spent[0] += time.perf_counter() - t

        return wrapper

    with monkeypatch.context() as m:
        for entry in ("cost_one", "evaluate_batch"):
            m.setattr(evaluate, entry, timed(getattr(evaluate, entry)))
        t = time.perf_counter()
        res = solve(name)
        wall = time.perf_counter() - t
    return spent[0], wall, res


@pytest.mark.parametrize("name", list(CASES))
def test_bench_metaheuristic(benchmark, monkeypatch, name):
    solve(name)  # compiled code loaded, the problem's buffers built
    t = time.perf_counter()
    res = benchmark(solve, name)
    wall = time.perf_counter() - t
    if benchmark.stats is not None:
        wall = benchmark.stats.stats.min
    kernel, wall_timed, again = kernel_time(monkeypatch, name)
    benchmark.extra_info.update({
        "evaluations": res.nfev, "iterations": res.nit, "final_cost": res.fun,
        "evaluations_per_s": res.nfev / wall, "s_per_iteration": wall / max(res.nit, 1),
        "kernel_fraction": kernel / wall_timed, "kernel_s": kernel,
        "solver_python_s": max(wall - kernel, 0.0),
    })
    p = problem()
    start = float(np.sum(p.residuals_full(p.centre) ** 2))
    assert res.nfev == BUDGET  # the budget ended the run, used exactly
    assert res.fun < 0.5 * start
    assert again.fun == res.fun and np.array_equal(again.x, res.x) and again.nit == res.nit


def directions(rng, k, n):
    """k unit directions the way BAS and BSAS drew them one iteration at a time (BAS Eq. 1)."""
    r = rng.uniform(-1.0, 1.0, (k, n))
    return r / (np.finfo(float).eps + np.linalg.norm(r, axis=1, keepdims=True))


def test_draw_ahead_gives_the_per_iteration_stream():
    """BAS's directions and BSAS's numbers, drawn ahead in blocks, equal one draw per iteration, and a
    run that stops early leaves the generator where per-iteration draws would have (the stages of
    ``staged:`` share one generator)."""
    n, m, used = 4, 3, 37
    ahead, one = np.random.default_rng(5), np.random.default_rng(5)
    draws = DrawAhead(ahead, (n,), 400, transform=unit_rows)
    for _, b in zip(range(used), draws):
        assert np.array_equal(b, directions(one, 1, n)[0])
    draws.settle()
    assert ahead.bit_generator.state == one.bit_generator.state

    ahead, one = np.random.default_rng(6), np.random.default_rng(6)
    draws = _Draws(ahead, m, n, 100)
    for t in range(1, used + 1):
        assert np.array_equal(draws.directions(), directions(one, m, n))
        if t == used:  # stopped between the directions and the decision (a budget ends it there)
            break
        assert draws.uniform() == one.random()
        if t % 7 == 0:  # a random better beetle picked: integers drawn from the synced generator
            draws.sync()
            assert ahead.choice(np.arange(5)) == one.choice(np.arange(5))
    draws.sync()
    assert ahead.bit_generator.state == one.bit_generator.state
