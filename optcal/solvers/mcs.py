"""``mcs:<inner>``: the 2015 paper's Monte-Carlo averaging around any solver.

2015 paper §5.3.2 and §6.2: "100-time MCS is conducted after the single NAFSA to bring in the random
factors", and the mean of the runs is taken as the estimate, with the standard deviation of the runs as
"an indicator for representing the stability of the estimates" (its Table 3, last column). Its
Algorithm 1 (§5.3.2) takes the mean within each of the four phases, which is ``staged:mcs:nafsa``;
``mcs:staged:nafsa`` averages whole four-stage runs instead. Both compose through the registry.
"""

from __future__ import annotations

import numpy as np

from optcal.core.errors import BudgetExhausted, InputError
from optcal.solvers.base import Option, Solver, SolverResult, StopSolver, positive
from optcal.solvers.registry import register_wrapper
from optcal.solvers.staged import StoppedWithin, detached, solve_within


class MonteCarlo(Solver):
    """k independent runs of ``inner`` (2015 paper §6.2); the estimate is the mean of their results.

    Run i gets its own generator, ``rng.spawn(runs)[i]``, so runs are independent and the whole is
    reproducible from one seed; every run starts from the same ``x0`` (the presets or the initialiser).
    Each run's result is its best point; the estimate ``x`` is the mean of the runs that found a finite
    cost, in the problem's coordinates, and ``fun`` is the cost of that mean (one evaluation, counted).
    ``extra`` holds ``sd`` (per-parameter standard deviation of the runs, ddof = 1, same coordinates as
    ``x``), ``x_runs`` and ``fun_runs``, and the best point any run found (``best_x``, ``best_fun``),
    which need not be the mean.

    Budget: the total covers all runs and the final evaluation of the mean. With an evaluation limit,
    run i gets an equal share of what is left, ``(left − 1) // (runs not yet done)``, so what a run does
    not use goes to the later runs; without one, each run gets the inner solver's default budget, and
    ``solve`` without a budget gives ``runs × inner default + 1``. Each run uses the inner solver's full
    ``solve`` on a view with its own counter, merged into the shared one (see
    :func:`optcal.solvers.staged.solve_within`). If the budget ends before every run is done, the mean is over
    the runs that finished (``extra["runs_done"]``), and the mean's cost is then computed outside the
    budget if no evaluation is left (said in the message).
    """

    name = "mcs"
    family = "wrapper"
    options = {
        "runs": Option(100, int, "number of independent runs k (the 2015 paper: 100)", check=positive,
                       check_doc="> 0"),
    }

    def __init__(self, inner: Solver, **options):
        super().__init__(**options)
        self.inner = inner
        self.name = f"mcs:{inner.name}"
        d = inner.default_budget
        self.default_budget = None if d is None else d * self.config["runs"] + 1

    def solve(self, problem, **kwargs) -> SolverResult:
        if not self.inner.is_available():
            raise InputError(self.inner.unavailable_message())
        res = super().solve(problem, **kwargs)
        mean = res.extra.get("mean")
        if mean is not None:
            res.extra["best_x"], res.extra["best_fun"] = res.x, res.fun
            res.x, res.fun = np.asarray(mean, float), float(res.extra["mean_fun"])
            res.x_full = problem.to_full(res.x)[0]
            if not np.isfinite(res.fun):
                res.success = False
                res.message = f"{res.message}; the mean of the runs has no finite cost"
        return res

    def _solve(self, problem, x0, rng, callback):
        runs, counter = self.config["runs"], problem.counter
        rngs = rng.spawn(runs)
        xs, fs, nit, done = [], [], 0, 0
        status, message = 0, f"{runs} runs done"
        try:
            for k in range(runs):
                evals = self.inner.default_budget
                if counter.budget.max_evals is not None:
                    left = counter.budget.max_evals - counter.nfev - 1  # one kept for the mean
                    if left < 1:
                        raise BudgetExhausted("evaluation budget used up")
                    evals = max(1, left // (runs - k))
                r = solve_within(self.inner, detached(problem), counter, evals=evals, x0=x0, rng=rngs[k],
                                 callback=callback, nit0=nit)
                nit, done = nit + r.nit, done + 1
                if np.isfinite(r.fun):
                    xs.append(r.x)
                    fs.append(r.fun)
        except BudgetExhausted as exc:
            status, message = 1, f"{exc} after {done} of {runs} runs"
        except StoppedWithin as stop:  # the interrupted run's best point so far is its estimate
            if np.isfinite(stop.result.fun):
                xs.append(stop.result.x)
                fs.append(stop.result.fun)
            status, message = 2, f"stopped by callback in run {done + 1} of {runs}"
        except StopSolver:
            status, message = 2, f"stopped by callback after {done} of {runs} runs"
        extra = {"runs_done": done, "runs_finite": len(xs), "fun_runs": fs}
        if not xs:
            return {"nit": nit, "status": -1, "success": False, "extra": extra,
                    "message": f"{message}; no run found a finite cost"}
        X = np.array(xs)
        mean = X.mean(axis=0)
        extra.update(mean=mean, x_runs=X, sd=X.std(axis=0, ddof=1) if len(X) > 1 else np.full(X.shape[1], np.nan))
        try:
            extra["mean_fun"] = float(problem.cost_batch(mean[None])[0])
        except BudgetExhausted:
            extra["mean_fun"] = float(np.sum(problem.residuals_full(problem.to_full(mean)) ** 2))
            message += "; the mean's cost was computed outside the budget"
        return {"nit": nit, "status": status, "message": message, "success": True, "extra": extra}


register_wrapper("mcs", MonteCarlo)
