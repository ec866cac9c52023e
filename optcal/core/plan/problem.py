"""The design problem in the problem interface that solvers use (docs/planning.md, "Method"; CONTRIBUTING.md
"Adding a solver"): candidates are points z of the unit box [-1, 1]^n, evaluated as populations with
``cost_batch``, counted against the shared budget, the best point kept by the counter.

Hand-held (``free``): n = 2N, each direction from two coordinates by the equal-area map
a = (√(1−u²) cos φ, √(1−u²) sin φ, u) with u = z₁ and φ = π z₂ (a uniform z gives a uniform direction).
A fixture with K candidate directions: n = N, position j takes candidate ⌊(z_j + 1)/2 · K⌋. The cost is the
criterion (:class:`optcal.core.plan.criteria.Criterion`, smooth form), a positive variance; a design that does
not determine the model costs +inf. There are no residuals: least-squares solvers do not apply;
``gradient`` is the central difference of the cost, one batched call of 2n + 1 designs.
"""

from __future__ import annotations

import numpy as np

from optcal.core.budget import Counter
from optcal.core.plan.criteria import Criterion
from optcal.core.view import CountedProblem


def directions_of(Z: np.ndarray, n_positions: int) -> np.ndarray:
    """Equal-area map of unit-box points (S, 2N) to directions (S, N, 3)."""
    Z = np.clip(np.asarray(Z, float), -1.0, 1.0).reshape(len(Z), n_positions, 2)
    u, phi = Z[..., 0], np.pi * Z[..., 1]
    r = np.sqrt(np.clip(1.0 - u * u, 0.0, None))
    return np.stack([r * np.cos(phi), r * np.sin(phi), u], axis=-1)


def coordinates_of(directions: np.ndarray) -> np.ndarray:
    """The inverse map: directions (N, 3) to a unit-box point (2N,)."""
    d = np.asarray(directions, float)
    d = d / np.linalg.norm(d, axis=1, keepdims=True)
    return np.stack([d[:, 2], np.arctan2(d[:, 1], d[:, 0]) / np.pi], axis=1).ravel()


class DesignProblem(CountedProblem):
    """N positions for ``criterion``; ``cands`` (K, 3) for a fixture, None for hand-held directions."""

    is_normalised = True
    presets = None
    reference = False

    def __init__(self, criterion: Criterion, n_positions: int, cands: np.ndarray | None = None,
                 x0: np.ndarray | None = None):
        self.criterion = criterion
        self.n_positions = int(n_positions)
        self.cands = None if cands is None else np.asarray(cands, float)
        self.n = self.n_positions * (2 if self.cands is None else 1)
        self.free = np.arange(self.n)
        self.centre = np.zeros(self.n)
        self.halfwidth = np.ones(self.n)
        self.lb, self.ub = -np.ones(self.n), np.ones(self.n)
        self.x_fixed = np.zeros(self.n)
        self.x0 = np.zeros(self.n) if x0 is None else np.asarray(x0, float)
        self.counter = Counter()
        self.names = [f"z{i}" for i in range(self.n)]

    # -- coordinates: the unit box is this problem's own --------------------------------------
    def normalised(self) -> DesignProblem:
        return self

    def to_full(self, X) -> np.ndarray:
        return np.atleast_2d(np.asarray(X, float)).copy()

    def from_full(self, x_full) -> np.ndarray:
        return np.array(x_full, float)  # a copy: the counter's best point stays the counter's

    def directions(self, Z) -> np.ndarray:
        """Directions (S, N, 3) of candidates Z (S, n)."""
        Z = np.atleast_2d(np.asarray(Z, float))
        if self.cands is None:
            return directions_of(Z, self.n_positions)
        K = len(self.cands)
        idx = np.clip(np.floor((np.clip(Z, -1.0, 1.0) + 1.0) / 2.0 * K).astype(int), 0, K - 1)
        return self.cands[idx]

    def cost_batch(self, X) -> np.ndarray:
        X = np.atleast_2d(np.asarray(X, float))
        if X.shape[1] != self.n:
            raise ValueError(f"expected {self.n} coordinates, got {X.shape[1]}")
        S = len(X)
        counter = self.counter
        k = counter.allow(S)
        f = np.full(S, np.inf)
        if k:
            fk = self.criterion(self.directions(X[:k]), smooth=True)
            f[:k] = np.where(np.isnan(fk), np.nan, fk)
            counter.record(f[:k], X[:k])
        return f

    def cost(self, x) -> float:
        return float(self.cost_batch(np.asarray(x, float)[None])[0])

    def gradient(self, x, step: float = 1e-6) -> np.ndarray:
        """Central differences of the cost, one population of 2n + 1 points (counted)."""
        x = np.asarray(x, float)
        E = np.eye(self.n) * step
        f = self.cost_batch(np.vstack([x, x + E, x - E]))
        g = (f[1:self.n + 1] - f[self.n + 1:]) / (2 * step)
        return np.where(np.isfinite(g), g, 0.0)
