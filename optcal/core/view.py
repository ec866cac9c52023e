"""Views of a problem over its parameters, and its shared evaluation counter (docs/design.md, "Views, the shared
counter and the budget"): the part of the problem interface the solvers use that does not depend on what is being
calibrated. The accelerometer's problem (:class:`optcal.core.problem.CalibrationProblem`) and the gyroscope's
(:class:`optcal.core.gyro.problem.GyroProblem`) both offer it through :class:`ParameterViews`.

A view holds some parameters fixed (``restrict``: the papers' four stages) and may search in normalised
coordinates x = centre + halfwidth · z, z ∈ [−1, 1] (``normalised``; 2020 paper §3.4). Views share one
:class:`~optcal.core.budget.Counter`, so a budget covers everything done on a problem and its best point is kept
(:class:`CountedProblem`, which the design problem of :mod:`optcal.core.plan` uses too).
"""

from __future__ import annotations

import copy

import numpy as np

from optcal.core.budget import Budget, Counter
from optcal.core.errors import InputError


class CountedProblem:
    """Mixin: the shared counter and budget, and the evaluation entry points of the problem interface over one
    method ``_evaluate(X, keep_residuals) -> (residuals or None, costs)`` that counts and enforces the budget;
    ``from_full`` maps the counter's best full vector into the problem's coordinates."""

    counter: Counter

    def start(self, budget=None) -> Counter:
        """Reset the shared counter with a new budget (solvers call this once per solve)."""
        self.counter.__init__(Budget.of(budget))
        return self.counter

    @property
    def nfev(self) -> int:
        return self.counter.nfev

    @property
    def best(self) -> tuple[np.ndarray | None, float]:
        """Best point ever evaluated (in this problem's coordinates) and its cost."""
        c = self.counter
        return (None if c.best_x is None else self.from_full(c.best_x)), c.best_f

    def residuals_batch(self, X) -> np.ndarray:
        """Residuals (S, m) of a population (S, n); counts S evaluations."""
        return self._evaluate(X)[0]

    def residuals(self, x) -> np.ndarray:
        return self._evaluate(np.asarray(x, float)[None])[0][0]

    def cost_batch(self, X) -> np.ndarray:
        """Costs (S,) of a population (S, n) in one call; candidates past the budget cost inf."""
        return self._evaluate(X, keep_residuals=False)[1]

    def cost(self, x) -> float:
        return float(self._evaluate(np.asarray(x, float)[None], keep_residuals=False)[1][0])


class ParameterViews(CountedProblem):
    """Mixin: views and coordinates of a problem with ``model`` (``names``, ``n_params``, ``groups()``),
    ``centre``, ``halfwidth`` (full vectors) and the view state ``free``, ``x_fixed``, ``is_normalised`` and
    ``counter``. A subclass that caches per-view data clears it in :meth:`_new_view`."""

    model: object
    centre: np.ndarray
    halfwidth: np.ndarray
    free: np.ndarray
    x_fixed: np.ndarray
    is_normalised: bool

    def _new_view(self) -> None:
        """Called on a fresh view (a copy of this problem): drop what depends on the view."""

    def restrict(self, groups_or_indices, at: np.ndarray | None = None):
        """A view over some parameters (group names or full-vector indices); the rest stay at ``at``."""
        groups = self.model.groups()
        idx: list[int] = []
        for g in np.atleast_1d(groups_or_indices):
            if isinstance(g, str | np.str_):
                if str(g) not in groups:
                    raise InputError(
                        f"model {self.model.name} has no parameter group {g!r}; it has {', '.join(groups)}")
                idx.extend(groups[str(g)])
            else:
                idx.append(int(g))
        view = copy.copy(self)
        view.free = np.array(sorted(set(idx)), int)
        view.x_fixed = np.array(self.x_fixed if at is None else at, float)
        view._new_view()
        return view

    def normalised(self):
        """A view in unit-box coordinates z: x = centre + halfwidth · z, z ∈ [−1, 1]."""
        view = copy.copy(self)
        view.is_normalised = True
        view._new_view()
        return view

    @property
    def n(self) -> int:
        return len(self.free)

    @property
    def names(self) -> list[str]:
        return [self.model.names[i] for i in self.free]

    @property
    def lb(self) -> np.ndarray:
        return -np.ones(self.n) if self.is_normalised else (self.centre - self.halfwidth)[self.free]

    @property
    def ub(self) -> np.ndarray:
        return np.ones(self.n) if self.is_normalised else (self.centre + self.halfwidth)[self.free]

    @property
    def x0(self) -> np.ndarray:
        """The starting point in this view's coordinates (the centre, or the values held)."""
        return self.from_full(self.x_fixed if self.n < self.model.n_params else self.centre)

    def to_full(self, X) -> np.ndarray:
        X = np.atleast_2d(np.asarray(X, float))
        if X.shape[1] != self.n:
            raise ValueError(f"expected {self.n} coordinates, got {X.shape[1]}")
        if self.is_normalised:
            X = self.centre[self.free] + self.halfwidth[self.free] * X
        full = np.tile(self.x_fixed, (X.shape[0], 1))
        full[:, self.free] = X
        return full

    def from_full(self, x_full) -> np.ndarray:
        x = np.asarray(x_full, float)[..., self.free]
        if self.is_normalised:
            x = (x - self.centre[self.free]) / self.halfwidth[self.free]
        return x
