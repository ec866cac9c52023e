"""Benchmark of planning (docs/planning.md): 24 hand-held positions for nonlinear12 with the command's defaults
(the exchange over 1000 candidates with its refinement, and CMA-ES from 2 random starts of 5,000 evaluations,
refined), and a plan:D12 scheme name resolved without solvers. The issue's budget for the first is 10 s on one
core; extra_info holds the criteria against the papers' 24-position scheme."""

import numpy as np

from optcal.app.workflows.plan import solve_design
from optcal.core.plan.design import make_criterion, plan
from optcal.core.schemes import scheme


def test_bench_plan_24_nonlinear12(benchmark):
    crit = make_criterion("nonlinear12", "D")
    design, record = benchmark.pedantic(
        lambda: solve_design(crit, 24, solver="cmaes", starts=2, budget=5000, rng=np.random.default_rng(0)),
        rounds=1, iterations=1)
    paper = float(crit(scheme("24")[None])[0])
    assert design.value < 0.9 * paper
    assert record["solver_value"] <= 1.01 * record["exchange"]
    benchmark.extra_info.update(criterion=design.value, exchange=record["exchange"],
                                solver=record["solver_value"], ratio_to_paper_24=design.value / paper)


def test_bench_plan_name_d12(benchmark):
    crit = make_criterion("nonlinear12", "D")
    d = benchmark.pedantic(lambda: plan(crit, 12, rng=np.random.default_rng(0)), rounds=1, iterations=1)
    assert d.n == 12 and np.isfinite(d.value)
    benchmark.extra_info.update(criterion=d.value)
