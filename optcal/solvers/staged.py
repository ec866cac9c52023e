"""``staged:<inner>``: the papers' four-stage calibration procedure as a wrapper around any solver.

2020 paper §3.4 (Steps 1-4 and Figure 2) and 2015 paper §5.3.2 (Algorithm 1): the scale factors are
optimised first with every other parameter held at its preset, then the biases (scale factors loaded
from stage 1), then the installation angles, then the second-order terms; "the above steps can be
repeated until the requirements are met". Here the stages are the model's parameter groups
(``model.groups()``: scale, bias, misalignment, nonlinear, temperature, drift, in docs/design.md, "Terms and
parameters" order), so the procedure works on any model, and the cycles repeat until a cycle lowers the cost by less
than the fraction ``rtol`` or ``max_cycles`` cycles have run.

This module also holds :func:`solve_within`, the way a wrapper runs an inner solver on a view of the
problem it was given (used by ``mcs:`` too).
"""

from __future__ import annotations

import copy

import numpy as np

from optcal.core.errors import BudgetExhausted, InputError
from optcal.core.problem import Budget, CalibrationProblem, Counter
from optcal.solvers.base import Option, Solver, SolverResult, StopSolver, positive
from optcal.solvers.registry import register_wrapper

STAGE_GROUPS = ("scale", "bias", "misalignment", "nonlinear", "temperature", "drift")


class StoppedWithin(StopSolver):
    """The user's callback stopped a sub-run; ``result`` is that sub-run's (partial) result."""

    def __init__(self, result: SolverResult):
        super().__init__("stopped by callback")
        self.result = result


class _Merge:
    """Folds a sub-run's own counter into the enclosing (shared) counter; callable repeatedly."""

    def __init__(self, parent: Counter, child: Counter):
        self.parent, self.child = parent, child
        self.nfev0, self.njev0 = parent.nfev, parent.njev
        self.seen = 0

    def __call__(self) -> None:
        p, c = self.parent, self.child
        p.nfev, p.njev = self.nfev0 + c.nfev, self.njev0 + c.njev
        # The child's trace lists its own improvements; those below the enclosing best are exactly the
        # enclosing run's improvements, at shifted evaluation counts and times.
        shift, best = c.t0 - p.t0, p.best_f
        for (nfev, f, t), x in zip(c.trace[self.seen:], c.trace_x[self.seen:]):
            if f < best:
                p.trace.append((self.nfev0 + nfev, f, shift + t))
                p.trace_x.append(x)
                best = f
        self.seen = len(c.trace)
        if c.best_x is not None and c.best_f < p.best_f:
            p.best_f, p.best_x = c.best_f, c.best_x.copy()


def detached(problem: CalibrationProblem) -> CalibrationProblem:
    """A view of ``problem`` (same coordinates, same fixed values) with a counter of its own."""
    view = copy.copy(problem)
    view.counter = Counter()
    return view


def sub_budget(parent: Counter, evals: int | None) -> Budget:
    """The budget of a sub-run: ``evals`` evaluations, what is left of the enclosing time, its target.

    Raises :class:`BudgetExhausted` when the enclosing budget has nothing left."""
    parent.allow(1)
    b = parent.budget
    if b.max_evals is not None:
        left = b.max_evals - parent.nfev
        evals = left if evals is None else min(evals, left)
    max_time = None if b.max_time is None else max(b.max_time - parent.elapsed(), 1e-9)
    return Budget(max_evals=None if evals is None else max(1, int(evals)), max_time=max_time, target=b.target)


def solve_within(inner: Solver, view: CalibrationProblem, parent: Counter, *, evals: int | None, x0, rng,
                 callback, nit0: int = 0, stagnation=None) -> SolverResult:
    """Run ``inner.solve`` on ``view`` (a :func:`detached` view) as one part of an enclosing solve.

    Why not call ``inner.solve`` on a plain view: :meth:`Solver.solve` begins with ``problem.start``,
    which resets the counter, and views share their parent's counter, so it would wipe the enclosing
    run's evaluations, best point and budget. Why not call ``inner._solve`` directly: the inner solver
    would then size its work from the enclosing budget and skip its own start-point and error handling.
    Instead the inner solver runs its full public ``solve`` on a view with its own counter and a budget
    of ``evals`` evaluations (capped by what the enclosing budget has left; the enclosing time limit and
    target carry over), exactly as it would run alone. That counter is merged into ``parent`` after
    every inner iteration (through the inner callback, so the user's callback sees live totals) and at
    the end: evaluations and Jacobians add up, the best point is kept if it is better, and the trace
    stays in evaluation order. The enclosing budget therefore stays exact.

    ``callback`` is the enclosing solve's ``callback(nit)``; ``nit0`` is the iterations done before this
    sub-run; ``stagnation`` (:class:`optcal.solvers.base.Stagnation`) is the enclosing solve's rule, which the sub-run
    applies to its own budget (its window a share of the sub-run's evaluations). A stop asked for by the
    callback (or by the enclosing solve's stagnation rule) is re-raised after the merge as
    :class:`StoppedWithin` (a :class:`StopSolver` carrying the sub-run's partial result). The returned
    result's ``nit`` is at least the last iteration count the inner solver reported.
    """
    merge = _Merge(parent, view.counter)
    stop, last = [], [0]

    def cb(info):
        merge()
        last[0] = int(info.get("nit", 0))
        try:
            callback(nit0 + last[0])
        except StopSolver:
            stop.append(True)
            return True
        return None

    try:
        res = inner.solve(view, x0=x0, budget=sub_budget(parent, evals), rng=rng, callback=cb, stagnation=stagnation)
    finally:
        merge()
    if stop:
        raise StoppedWithin(res)
    # A solve ended by its budget returns nit = 0 (the base class loses the count with the exception);
    # the iterations it reported through its callback did happen.
    res.nit = max(res.nit, last[0])
    return res


class Staged(Solver):
    """The four-stage procedure (2020 paper §3.4, Fig. 2; 2015 paper §5.3.2, Algorithm 1) around ``inner``.

    Each stage solves ``problem.restrict(group, at=current)`` with the inner solver, the other groups
    held at the current values; its start is the current values of its group, and its result (the best
    point the stage found, never worse than its start once that was evaluated) becomes the current
    point. A cycle runs every group in ``groups`` order (default: all the model's groups, docs/design.md, "Terms and
    parameters" order, which is the papers' order: scale factors, biases, installation angles, nonlinear terms).
    Cycles repeat until one lowers the best cost by less than ``rtol`` relative, or ``max_cycles``. A
    stochastic inner solver with a small stage budget can fail to improve in a cycle by chance (a
    metaheuristic restarts its step sizes in every stage), which that rule reads as convergence; give it
    ``rtol=0`` to run all ``max_cycles``.

    Budget (the total is shared: evaluations, time and target are the problem's). ``split="equal"``:
    each stage gets an equal share of what is left, ``left // (stages not yet run, up to max_cycles)``,
    so evaluations a stage does not use (a local method that converges early) go to the later stages;
    without an evaluation limit each stage gets the inner solver's default budget, and ``solve`` without a
    budget gives the wrapper the inner solver's default in total. ``split="inner"``: each stage gets the
    inner solver's default budget (capped by what is left); ``solve`` without a budget then sets no total
    limit, only the per-stage one. How a stage runs on the shared counter: see :func:`solve_within`.

    Result: ``x`` is the best point of the whole run, ``nit`` the inner iterations summed over stages,
    the trace is merged in evaluation order, and ``extra["stages"]`` lists every stage (cycle, group,
    evaluations, iterations, best cost and full parameter vector after it, the inner message).
    """

    name = "staged"
    family = "wrapper"
    options = {
        "max_cycles": Option(5, int, "most cycles through the stages", check=positive, check_doc="> 0"),
        "rtol": Option(1e-9, float, "stop when a cycle lowers the best cost by less than this fraction (0: never)",
                       check=lambda v: v >= 0, check_doc=">= 0"),
        "split": Option("equal", str, "stage budgets: 'equal' share of what is left, or the 'inner' "
                        "solver's default per stage", choices=("equal", "inner")),
        "groups": Option("", str, "comma-separated stage order, e.g. 'scale,bias'; empty: every group of the "
                         "model in docs/design.md, 'Terms and parameters' order"),
    }

    def __init__(self, inner: Solver, **options):
        super().__init__(**options)
        self.inner = inner
        self.name = f"staged:{inner.name}"
        # The stagnation rule ends each stage of an inner solver that takes it, and the whole run
        self.stops_on_stagnation = inner.stops_on_stagnation
        # 'equal' shares the inner solver's default total; 'inner' bounds each stage instead of the total.
        self.default_budget = inner.default_budget if self.config["split"] == "equal" else None

    def check_config(self) -> None:
        wanted = [g.strip() for g in self.config["groups"].split(",") if g.strip()]
        bad = [g for g in wanted if g not in STAGE_GROUPS]
        if bad or len(set(wanted)) != len(wanted):
            raise InputError(f"solver staged: option groups={self.config['groups']!r} must name distinct groups "
                             f"from {', '.join(STAGE_GROUPS)}")

    def solve(self, problem, **kwargs) -> SolverResult:
        if not self.inner.is_available():
            raise InputError(self.inner.unavailable_message())
        return super().solve(problem, **kwargs)

    def stages(self, problem: CalibrationProblem) -> list[tuple[str, list[int]]]:
        """(group, full-vector indices) of each stage: the wanted groups present among the free parameters."""
        groups = problem.model.groups()
        wanted = [g.strip() for g in self.config["groups"].split(",") if g.strip()] or list(groups)
        free = set(problem.free.tolist())
        out = [(g, [i for i in groups.get(g, []) if i in free]) for g in wanted]
        return [(g, idx) for g, idx in out if idx]

    def _solve(self, problem, x0, rng, callback):
        cfg = self.config
        stages = self.stages(problem)
        if not stages:
            raise InputError(f"solver {self.name}: no parameter group of the problem is left to optimise")
        current = problem.to_full(x0)[0]
        state = {"nit": 0, "log": [], "cycles": 0}
        n_total = cfg["max_cycles"] * len(stages)
        try:
            status, message = self._cycles(problem, stages, current, rng, callback, state, n_total)
        except BudgetExhausted as exc:
            status, message = 1, f"{exc} in cycle {state['cycles']}"
        except StopSolver:
            status, message = 2, "stopped by callback"
        return {"nit": state["nit"], "status": status, "message": message, "success": status >= 0,
                "extra": {"stages": state["log"], "cycles": state["cycles"]}}

    def _cycles(self, problem, stages, current, rng, callback, state, n_total) -> tuple[int, str]:
        cfg, counter, f_prev = self.config, problem.counter, np.inf
        for cycle in range(1, cfg["max_cycles"] + 1):
            state["cycles"] = cycle
            for k, (group, idx) in enumerate(stages):
                view = detached(problem.restrict(idx, at=current))
                evals = self._stage_evals(counter, n_total - (cycle - 1) * len(stages) - k)
                res = solve_within(self.inner, view, counter, evals=evals, x0=view.from_full(current), rng=rng,
                                   callback=callback, nit0=state["nit"], stagnation=self.stagnation)
                state["nit"] += res.nit
                if counter.best_x is not None:
                    current = counter.best_x.copy()
                state["log"].append({"cycle": cycle, "group": group, "nfev": res.nfev, "nit": res.nit,
                                     "fun": float(counter.best_f), "x_full": current.copy(),
                                     "message": res.message})
            f = counter.best_f
            if not np.isfinite(f):
                return -1, f"no finite cost in cycle {cycle}; last stage: {state['log'][-1]['message']}"
            if np.isfinite(f_prev) and f_prev - f < cfg["rtol"] * abs(f_prev):
                return 0, (f"converged after {cycle} cycles: the last lowered the cost by "
                           f"{(f_prev - f) / abs(f_prev):.2e} relative (rtol {cfg['rtol']:g})")
            f_prev = f
        return 0, f"max_cycles={cfg['max_cycles']} cycles run"

    def _stage_evals(self, counter: Counter, stages_left: int) -> int | None:
        if self.config["split"] == "inner" or counter.budget.max_evals is None:
            return self.inner.default_budget
        return (counter.budget.max_evals - counter.nfev) // max(1, stages_left)


register_wrapper("staged", Staged)
