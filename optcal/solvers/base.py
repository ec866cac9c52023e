"""The solver contract (docs/design.md, "The solver contract").

A solver is constructed with its options (an unknown option or a bad value is an error) and has
``solve(problem, *, x0=None, budget, rng, callback=None) -> SolverResult``. The result uses SciPy's field
names (``x, fun, success, status, message, nfev, nit``) plus ``runtime_s`` and a convergence ``trace`` of
(evaluations, best cost, seconds). Budgets are enforced by the problem; the problem also keeps the best
point ever evaluated, so a solver stopped by its budget (or by an error) still returns that point.

Subclasses implement ``_solve(problem, x0, rng, callback) -> dict`` with any of ``x, nit, status,
message, success``; they evaluate populations with ``problem.cost_batch`` in one call per iteration.

Every result says why the solve ended (``stop_reason``, :data:`STOP_REASONS`): its budget, the target cost,
the solver's own termination, the stagnation rule (:class:`Stagnation`, for the solvers that take it), the
user's callback, or an error.
"""

from __future__ import annotations

import importlib.util
import math
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar, Protocol, runtime_checkable

import numpy as np

from optcal.core.errors import BudgetExhausted, InputError
from optcal.core.problem import CalibrationProblem


@runtime_checkable
class Problem(Protocol):
    """What every solver may use of the problem it minimises (as pymoo's ``Problem``): the calibration's
    :class:`optcal.core.problem.CalibrationProblem`, the gyroscope's :class:`optcal.core.gyro.problem.GyroProblem` and
    the planner's :class:`optcal.core.plan.problem.DesignProblem` all provide it (tests/test_conformance.py).

    - ``n``: the number of free coordinates; ``x0`` (n,): the start point when the caller gives none.
    - ``centre``, ``halfwidth``: (n,) the search box, ``centre ± halfwidth`` in the solver's coordinates (the
      unit box around 0 for a normalised problem); a start point is taken inside it.
    - ``cost(x)``: the cost of one point (n,); ``cost_batch(X)``: the costs (S,) of a population (S, n) in one
      call, the way a swarm evaluates its members.
    - ``start(budget)``: a new solve: the evaluation budget (an int, or an :class:`optcal.core.budget.Budget` with a
      time limit and a target cost) that the problem itself enforces, raising
      :class:`optcal.core.errors.BudgetExhausted` past it; returns the ``counter`` (evaluations, the trace of
      improvements).
    - ``best``: (x, cost) of the best point evaluated since ``start``.
    - ``to_full(X)``, ``from_full(x_full)``: between the solver's coordinates and the full parameter vector in
      the model's units (what traces and results record).
    """

    n: int
    x0: np.ndarray
    centre: np.ndarray
    halfwidth: np.ndarray
    counter: Any

    def cost(self, x) -> float: ...

    def cost_batch(self, X) -> np.ndarray: ...

    def start(self, budget=None) -> Any: ...

    @property
    def best(self) -> tuple[np.ndarray | None, float]: ...

    def to_full(self, X) -> np.ndarray: ...

    def from_full(self, x_full) -> np.ndarray: ...


@runtime_checkable
class LeastSquaresProblem(Problem, Protocol):
    """A :class:`Problem` whose cost is a sum of squared residuals, for the least-squares solvers: the
    residuals (m,) at a point, their Jacobian (m, n) and the cost's gradient (n,)."""

    def residuals(self, x) -> np.ndarray: ...

    def jacobian(self, x) -> np.ndarray: ...

    def gradient(self, x) -> np.ndarray: ...


@dataclass(frozen=True)
class Option:
    """A solver option: default, type, and an optional check (a predicate with a description)."""

    default: Any
    kind: type | tuple = float
    doc: str = ""
    choices: tuple | None = None
    check: Any = None  # callable(value) -> bool
    check_doc: str = ""

    def validate(self, name: str, value, solver: str):
        kinds = self.kind if isinstance(self.kind, tuple) else (self.kind,)
        if float in kinds and isinstance(value, int | np.integer) and not isinstance(value, bool):
            value = float(value)
        if isinstance(value, str) and str not in kinds:
            value = _parse(value, kinds, name, solver)
        if value is None and self.default is not None:  # null for an option that has a value: not its default
            raise InputError(f"solver {solver}: option {name} cannot be null; leave it out for its default "
                             f"{self.default!r}")
        if value is not None and not isinstance(value, kinds) or (isinstance(value, bool) and bool not in kinds):
            raise InputError(
                f"solver {solver}: option {name}={value!r} must be {'/'.join(k.__name__ for k in kinds)}"
            )
        if self.choices is not None and value not in self.choices:
            choices = ", ".join(map(str, self.choices))
            raise InputError(f"solver {solver}: option {name}={value!r}; choose one of {choices}")
        if self.check is not None and not self.check(value):
            raise InputError(f"solver {solver}: option {name}={value!r} is invalid; it must be {self.check_doc}")
        return value


def _parse(text: str, kinds: tuple, name: str, solver: str):
    for k in kinds:
        try:
            if k is bool:
                if text.lower() in ("true", "1", "yes"):
                    return True
                if text.lower() in ("false", "0", "no"):
                    return False
                continue
            return k(text)
        except ValueError:
            continue
    raise InputError(f"solver {solver}: option {name}={text!r} is not a {'/'.join(k.__name__ for k in kinds)}")


def positive(v) -> bool:
    return v > 0


def probability(v) -> bool:
    return 0.0 <= v <= 1.0


# Why a solve ended (SolverResult.stop_reason): the evaluation budget, the time budget, the target cost, the
# solver's own termination (its tolerances, pycma's criteria, its iteration count), the stagnation rule, the
# user's callback, or an error (status -1).
STOP_REASONS = ("budget", "time", "target", "own", "stagnation", "callback", "error")


@dataclass(frozen=True)
class Stagnation:
    """The stagnation rule: a solve ends once its best cost has improved by no more than ``rtol`` of itself
    over the last ``window`` evaluations, ``window`` being the share ``share`` of its evaluation budget (of
    each stage's, inside ``staged:``). It is checked once per iteration (at the solver's callback), so a
    solve ends at the first iteration boundary after the rule holds. Only solvers that set
    :attr:`Solver.stops_on_stagnation` take it: those without a termination of their own that ends a run
    once it has converged (docs/algorithms.md, "Conventions shared by the search methods", "Stopping"). Without an
    evaluation limit it never fires.

    The best cost at evaluation e − W is read from the problem's trace (every improvement, with the
    evaluation count at which it happened), so the rule does not depend on how often the solver calls back.
    """

    share: float = 0.25
    rtol: float = 1e-6

    def __post_init__(self):
        if not 0.0 < self.share <= 1.0:
            raise InputError(f"stagnation share={self.share!r} must be in (0, 1]: the window's share of the budget")
        if not self.rtol >= 0.0:
            raise InputError(f"stagnation rtol={self.rtol!r} must be >= 0")

    def window(self, max_evals: int | None) -> int | None:
        """The window in evaluations for a solve of ``max_evals`` evaluations (None: no limit, no window)."""
        return None if max_evals is None else max(1, math.ceil(self.share * max_evals))

    def describe(self, window: int | None) -> str:
        return (f"stagnation: the best cost improved by no more than {self.rtol:g} of itself over the last "
                f"{window} evaluations")


class _StagnationCheck:
    """The rule on one problem's counter: the index of the last trace entry at or before evaluation
    nfev − W moves forward only, so a check costs a few operations per iteration."""

    def __init__(self, rule: Stagnation, counter):
        self.rule, self.counter = rule, counter
        self.W = rule.window(counter.budget.max_evals)
        self.j = -1

    def __call__(self) -> bool:
        if self.W is None:
            return False
        c = self.counter
        e = c.nfev - self.W
        tr = c.trace
        while self.j + 1 < len(tr) and tr[self.j + 1][0] <= e:
            self.j += 1
        if self.j < 0:  # no finite cost W evaluations ago: nothing to compare with
            return False
        return tr[self.j][1] - c.best_f <= self.rule.rtol * abs(c.best_f)


@dataclass
class SolverResult:
    """Outcome of one solve, with :class:`scipy.optimize.OptimizeResult`'s field names where it has them.

    - ``x`` (n,): the best point evaluated, in the solver's coordinates; ``fun``: its cost (NaN when no finite
      cost was evaluated).
    - ``success``: the solve ended normally (its budget, its target, its own termination, the stagnation
      rule or the user's callback) with a finite cost; False after an error or without a finite cost.
    - ``status``: the solver's own code where it has one (SciPy's ``least_squares``, NLopt's), else 0; 1 when
      the budget ended the run, 2 when the callback stopped it, -1 on a numerical error or no finite cost.
    - ``message``: why, in words; ``stop_reason``: why, as one of :data:`STOP_REASONS`.
    - ``nfev``: cost evaluations (a population of S counts S); ``njev``: Jacobian evaluations; ``nit``:
      iterations, as the solver counts them.
    - ``runtime_s``: wall time of the solve, s.
    - ``trace``: (evaluations, best cost, seconds) at every improvement; ``trace_x``: the best full parameter
      vector at each of them; ``x_full``: the best point as the full parameter vector (model units).
    - ``solver``: the registered name; ``extra``: what a solver adds (a wrapper's stages, pycma's stop dict).
    """

    x: np.ndarray
    fun: float
    success: bool
    status: int
    message: str
    nfev: int
    nit: int
    runtime_s: float
    trace: list = field(default_factory=list)
    njev: int = 0
    trace_x: list = field(default_factory=list)  # the best full parameter vector at each trace entry
    x_full: np.ndarray | None = None
    solver: str = ""
    extra: dict = field(default_factory=dict)
    stop_reason: str = ""  # one of STOP_REASONS

    def to_dict(self) -> dict:
        return {
            "x": [float(v) for v in self.x], "fun": float(self.fun), "success": bool(self.success),
            "status": int(self.status), "message": self.message, "nfev": int(self.nfev), "nit": int(self.nit),
            "runtime_s": float(self.runtime_s), "solver": self.solver, "stop_reason": self.stop_reason,
        }


class CallbackInfo(Mapping):
    """What a user's callback receives after each iteration: ``x`` (the best point so far, in the
    problem's coordinates), ``fun`` (its cost), ``nit`` and ``nfev``, as they were at the call. The best
    point is converted to the problem's coordinates only if ``x`` is read: callbacks that only count
    iterations (the wrappers' own) then cost almost nothing per iteration."""

    __slots__ = ("_problem", "_x_full", "_fun", "_nit", "_nfev")
    KEYS = ("x", "fun", "nit", "nfev")

    def __init__(self, problem: Problem, nit: int):
        c = problem.counter
        # best_x is replaced, never changed in place, when the best improves: holding it is a snapshot
        self._problem, self._x_full, self._fun, self._nit, self._nfev = problem, c.best_x, c.best_f, nit, c.nfev

    def __getitem__(self, key: str):
        if key == "x":
            return None if self._x_full is None else self._problem.from_full(self._x_full)
        if key == "fun":
            return self._fun
        if key == "nit":
            return self._nit
        if key == "nfev":
            return self._nfev
        raise KeyError(key)

    def __iter__(self):
        return iter(self.KEYS)

    def __len__(self) -> int:
        return len(self.KEYS)


class StopSolver(Exception):
    """Raised inside a solver when the user's callback asks to stop."""


class Stagnated(StopSolver):
    """Raised at a solver's callback when the stagnation rule holds: a stop, so that a wrapper ends its
    inner solve and then itself, as it does for the user's callback."""


def budget_reason(counter) -> str:
    """Why a solve that ended without an exception of its own ended, from its counter: the budget that stopped
    it (the evaluations, the time, the target cost), or else the solver's own termination ("own")."""
    b, stopped = counter.budget, counter.stopped
    if stopped:
        return {"evaluation budget used up": "budget", "time budget used up": "time",
                "target cost reached": "target"}.get(stopped, "budget")
    if b.target is not None and counter.best_f <= b.target:
        return "target"
    if b.max_evals is not None and counter.nfev >= b.max_evals:
        return "budget"
    return "own"


class Solver:
    """Base class: option validation, budget handling, timing and the result object."""

    name: ClassVar[str] = ""
    family: ClassVar[str] = "local"  # local | metaheuristic | global | convex | wrapper
    options: ClassVar[dict[str, Option]] = {}
    requires: ClassVar[tuple[str, ...]] = ()  # optional Python packages
    default_budget: ClassVar[int] = 20000
    # A solver that needs only tens of evaluations (least squares with the Jacobian) is best served by the
    # problem's NumPy evaluation in a one-off calibration: loading the compiled kernel costs more than its fit
    # (optcal.app.fit.calibrate chooses the problem's backend by this; studies always use the kernel).
    few_evaluations: ClassVar[bool] = False
    # False for a deterministic method that draws nothing: its solve then builds no Generator (numpy.random's
    # import is a tenth of a raw calibration's start-up); the seed still makes every other solver reproducible
    uses_rng: ClassVar[bool] = True
    # Whether a solve given a Stagnation rule ends by it: for methods without a termination of their own that
    # ends a converged run (CMA-ES, also in staged:'s stages; ng: and mealpy: set it from their option
    # stop_on_stagnation, off by default). False for the local methods (their tolerances end them) and for the searches
    # whose best cost stays flat for a long stretch and then improves again (the swarms, NLopt's global methods,
    # differential evolution:
    # docs/performance.md, "Stopping at convergence"), where the rule would end runs that had not converged.
    stops_on_stagnation: ClassVar[bool] = False
    stagnation: Stagnation | None = None  # the rule of the solve in progress, for a wrapper's inner solves

    def __init__(self, **options):
        unknown = sorted(set(options) - set(self.options))
        if unknown:
            known = ", ".join(self.options) or "none"
            raise InputError(f"solver {self.name}: unknown option(s) {', '.join(unknown)}; its options are {known}")
        self.config = {k: o.default for k, o in self.options.items()}
        for k, v in options.items():
            self.config[k] = self.options[k].validate(k, v, self.name)
        self.check_config()

    def check_config(self) -> None:
        """Cross-option checks (override)."""

    @classmethod
    def is_available(cls) -> bool:
        return all(importlib.util.find_spec(p) is not None for p in cls.requires)

    @classmethod
    def unavailable_message(cls) -> str:
        missing = [p for p in cls.requires if importlib.util.find_spec(p) is None]
        return f"solver {cls.name} needs the package(s) {', '.join(missing)}; install them with pip"

    @classmethod
    def describe(cls) -> dict:
        return {
            "name": cls.name, "family": cls.family, "available": cls.is_available(),
            "options": {k: {"default": o.default, "doc": o.doc} for k, o in cls.options.items()},
        }

    # -- the contract ------------------------------------------------------------------------
    def solve(self, problem: Problem, *, x0=None, budget=None, rng=None, callback=None,
              stagnation: Stagnation | None = None) -> SolverResult:
        """Minimise ``problem``'s cost from ``x0`` within ``budget``; ``stagnation`` ends the solve by that rule
        if this solver takes it (:attr:`stops_on_stagnation`; a wrapper passes it to its inner solves)."""
        if not self.is_available():
            raise InputError(self.unavailable_message())
        if self.uses_rng:
            rng = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
        counter = problem.start(budget if budget is not None else self.default_budget)
        x_start = self.start_point(problem, x0)
        rule = stagnation if self.stops_on_stagnation else None
        check = _StagnationCheck(rule, counter) if rule is not None else None
        self.stagnation = rule  # what a wrapper passes on to its inner solves
        t0 = time.perf_counter()
        out: dict = {}
        status, message, success, reason = 0, "", True, ""
        # The iterations completed so far, as the solver reports them through its callback: what `nit`
        # is when a budget or the user's callback ends the run before `_solve` can return its own count.
        done = [0]
        fired: list[bool] = []
        try:
            out = self._solve(problem, x_start, rng, self._wrap_callback(problem, callback, done, check, fired)) or {}
            status = out.get("status", 0)
            message = out.get("message", "converged")
            success = out.get("success", True)
        except BudgetExhausted as exc:
            status, message, success = 1, str(exc), True
        except StopSolver:
            status, message, success, reason = 2, "stopped by callback", True, "callback"
        except (np.linalg.LinAlgError, FloatingPointError, ValueError, ArithmeticError) as exc:
            status, message, success, reason = -1, f"{type(exc).__name__}: {exc}", False, "error"
        finally:
            self.stagnation = None
        runtime = time.perf_counter() - t0
        if fired:  # the rule ended the solve (inside a wrapper, through its inner solve's stop)
            status, message, success, reason = 0, rule.describe(check.W), True, "stagnation"
        x_best, f_best = problem.best
        if x_best is None:
            x_best, f_best = np.asarray(x_start, float), np.nan
            success, status = False, -1
            message = message or "no finite cost was evaluated"
        if not np.isfinite(f_best):
            success = False
            message = f"{message}; no finite cost was found" if message else "no finite cost was found"
        return SolverResult(
            x=np.asarray(x_best, float), fun=float(f_best), success=bool(success), status=int(status),
            message=message, nfev=counter.nfev, nit=int(out.get("nit", done[0])), runtime_s=runtime,
            trace=list(counter.trace), njev=counter.njev, trace_x=list(counter.trace_x),
            x_full=problem.to_full(x_best)[0], solver=self.name,
            extra=out.get("extra", {}), stop_reason=reason or budget_reason(counter),
        )

    def start_point(self, problem: Problem, x0) -> np.ndarray:
        """``x0`` if given (in the problem's coordinates), else the problem's presets or linear fit."""
        if x0 is None:
            # The convex ellipsoid fit initialises every local method on a calibration problem given neither x0
            # nor presets (other problems have their own x0)
            if isinstance(problem, CalibrationProblem) and problem.presets is None and self.family == "local":
                from optcal.solvers._ellipsoid_fit import ellipsoid_start

                return ellipsoid_start(problem)
            return problem.x0
        x0 = np.asarray(x0, float)
        if x0.shape != (problem.n,):
            raise InputError(f"x0 has {x0.size} values; the problem has {problem.n} parameters")
        return x0

    def _wrap_callback(self, problem, callback, done: list | None = None, check=None, fired: list | None = None):
        done = [0] if done is None else done

        def cb(nit: int):
            done[0] = int(nit)
            if check is not None and check():
                fired.append(True)
                raise Stagnated
            if callback is None:
                return
            if callback(CallbackInfo(problem, nit)) is True:
                raise StopSolver

        return cb

    def _solve(self, problem: Problem, x0: np.ndarray, rng: np.random.Generator, callback) -> dict:
        raise NotImplementedError
