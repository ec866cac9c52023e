"""The evaluation budget of a calibration problem and the counter that every view of it shares
(docs/design.md, "Views, the shared counter and the budget" and "Budget"): the problem counts each evaluation here,
refuses candidates past the budget, and keeps the best point ever evaluated, so that no solver can lose it.
:mod:`optcal.core.problem` re-exports both names.
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass, field

import numpy as np

from optcal.core.errors import BudgetExhausted, InputError


@dataclass(frozen=True)
class Budget:
    """Evaluation budget: at most ``max_evals`` candidate evaluations, ``max_time`` seconds, or stop
    once the best cost reaches ``target``. A Jacobian counts as one evaluation."""

    max_evals: int | None = None
    max_time: float | None = None
    target: float | None = None

    def __post_init__(self):
        if self.max_evals is not None and self.max_evals < 1:
            raise InputError(f"budget max_evals must be at least 1, got {self.max_evals}")
        if self.max_time is not None and self.max_time <= 0:
            raise InputError(f"budget max_time must be positive, got {self.max_time}")

    @classmethod
    def of(cls, budget) -> Budget:
        if budget is None:
            return cls()
        if isinstance(budget, Budget):
            return budget
        if isinstance(budget, int | np.integer):
            return cls(max_evals=int(budget))
        if isinstance(budget, dict):
            return cls(**budget)
        raise InputError(f"budget must be a Budget, an int (evaluations) or a dict, not {type(budget).__name__}")


@dataclass
class Counter:
    """Evaluations, elapsed time and the best point so far, shared by every view of a problem."""

    budget: Budget = field(default_factory=Budget)
    nfev: int = 0
    njev: int = 0
    t0: float = field(default_factory=time.perf_counter)
    best_f: float = np.inf
    best_x: np.ndarray | None = None
    trace: list = field(default_factory=list)  # (evaluations, best cost, seconds) at each improvement
    trace_x: list = field(default_factory=list)  # the best full parameter vector at each improvement
    stopped: str = ""

    def __post_init__(self):
        b = self.budget
        # The single-candidate path only compares nfev with `limit`; time and target budgets send every
        # call through `allow` (limit 0).
        self.limit = 0 if (b.max_time is not None or b.target is not None) else (
            sys.maxsize if b.max_evals is None else b.max_evals)

    def elapsed(self) -> float:
        return time.perf_counter() - self.t0

    def allow(self, S: int) -> int:
        """How many of S candidates may be evaluated now; raises when nothing may be."""
        b = self.budget
        if not self.stopped:
            if b.max_evals is not None and self.nfev >= b.max_evals:
                self.stopped = "evaluation budget used up"
            elif b.max_time is not None and self.elapsed() >= b.max_time:
                self.stopped = "time budget used up"
            elif b.target is not None and self.best_f <= b.target:
                self.stopped = "target cost reached"
        if self.stopped:
            raise BudgetExhausted(self.stopped)
        return S if b.max_evals is None else min(S, b.max_evals - self.nfev)

    def record(self, f: np.ndarray, X_full: np.ndarray) -> None:
        self.nfev += len(f)
        finite = np.isfinite(f)
        if finite.any():
            i = int(np.argmin(np.where(finite, f, np.inf)))
            if f[i] < self.best_f:
                self.improve(f[i], X_full[i].copy())

    def improve(self, f: float, x_full: np.ndarray) -> None:
        """Make (``f``, ``x_full``) the best point, after the caller found ``f < best_f``, and add it to the
        trace at the current evaluation count."""
        self.best_f, self.best_x = float(f), x_full
        self.trace.append((self.nfev, self.best_f, self.elapsed()))
        self.trace_x.append(x_full)
