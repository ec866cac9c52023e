"""The Fisher information of a set of gravity directions, vectorised over a population of designs.

A design is N unit specific-force directions a_j in the sensor frame. At nominal parameters x₀ (unit scale
factors, everything else zero, or any point the caller gives) the norm residual of position j has the
Jacobian row ∂e_j/∂x (2020 paper Eq. 12, the problem's analytic Jacobian through the implicit function
theorem), and N positions with input-referred noise σ per axis give the information F = Σ_j j_jᵀ j_j / σ²
(docs/design.md, "Cramér-Rao bound"). Columns are in natural units (:func:`optcal.core.gauge.natural_units`) and, when
the model has directions that no design can see (seed15's three body-frame rotations), the information is that of the
observable subspace: F_obs = Qᵀ F Q with Q an orthonormal basis of the complement of the null space, the
same projection as :func:`optcal.core.analysis.projected_crlb`. Rows of every design in a population are
evaluated in one call of the compiled Jacobian (S·N positions at once): no loop over candidates.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from optcal.core.data import PositionsData
from optcal.core.errors import InputError
from optcal.core.gauge import RTOL, natural_units, null_space
from optcal.core.model import Model, get_model
from optcal.core.plan.sphere import fibonacci_sphere
from optcal.core.problem import CalibrationProblem


class _RowsProblem(CalibrationProblem):
    """A problem built once (its closed-form start and gauge computed once), whose positions are then replaced:
    the Jacobian of new directions costs only the kernel, not a new problem's linear fit of S·N positions.
    Nothing but the data changes (no gauge rows, the centre and K0 stay at the nominal point's), so the packed
    kernel buffers are the only state to drop. (A public way to do this belongs in CalibrationProblem.)"""

    def with_outputs(self, N: np.ndarray) -> _RowsProblem:
        self.data = PositionsData(N=N)
        self._full_buffers = None
        return self


@dataclass(frozen=True)
class InformationModel:
    """What the design criteria need of a model: Jacobian rows of directions, in natural units, projected
    onto the observable subspace. ``x`` is the parameter point (default: nominal), ``noise_g`` σ (g)."""

    model: Model
    x: np.ndarray
    noise_g: float

    @classmethod
    def of(cls, model, noise_g: float = 10e-6, x: np.ndarray | None = None) -> InformationModel:
        m = get_model(model)
        if m.needs:
            raise InputError(f"model {m.name} needs {', '.join(m.needs)} (temperature or time), which a choice of "
                             "directions alone cannot plan; plan for its static part, e.g. --model nonlinear12")
        if not (np.isfinite(noise_g) and noise_g > 0):
            raise InputError(f"`noise_g` = {noise_g!r}: the noise SD of a position mean must be a positive number "
                             "of g (e.g. 10 µg)")
        xx = m.default_vector(1.0) if x is None else np.asarray(x, float)
        return cls(m, xx, float(noise_g))

    @property
    def names(self) -> tuple[str, ...]:
        return self.model.names

    def _problem(self, directions: np.ndarray) -> CalibrationProblem:
        N = self.model.forward(self.x, directions)[0]
        return CalibrationProblem(self.model, PositionsData(N=N), fix_gauge=False, check=False)

    @cached_property
    def _rows_problem(self) -> _RowsProblem:
        d = fibonacci_sphere(64)
        return _RowsProblem(self.model, PositionsData(N=self.model.forward(self.x, d)[0]), fix_gauge=False,
                            check=False)

    def rows(self, directions: np.ndarray) -> np.ndarray:
        """Jacobian rows (..., p) in natural units of directions (..., 3), all in one compiled call."""
        d = np.asarray(directions, float)
        flat = d.reshape(-1, 3)
        flat = flat / np.linalg.norm(flat, axis=1, keepdims=True)  # directions: only their orientation counts
        N = self.model.forward(self.x, flat)[0]
        J = self._rows_problem.with_outputs(N).jacobian_full(self.x) * self.units
        return J.reshape(*d.shape[:-1], J.shape[1])

    @cached_property
    def units(self) -> np.ndarray:
        return natural_units(self._problem(fibonacci_sphere(8)), self.x)

    @cached_property
    def basis(self) -> np.ndarray:
        """Q (p, r): orthonormal basis of the observable subspace in natural units (the null space is that of
        a dense spread of directions: what no design can see)."""
        _, _, null, _ = null_space(self._problem(fibonacci_sphere(400)), self.x, RTOL)
        p = self.model.n_params
        if null.size == 0:
            return np.eye(p)
        # the orthogonal complement of the null space: the left singular vectors beyond its rank
        U, _, _ = np.linalg.svd(null, full_matrices=True)
        return U[:, null.shape[1]:]

    @property
    def n_observable(self) -> int:
        return self.basis.shape[1]

    def projected_rows(self, directions: np.ndarray) -> np.ndarray:
        """Rows (..., r) on the observable basis, scaled by 1/σ: their outer products sum to F_obs."""
        return self.rows(directions) @ self.basis / self.noise_g

    def information(self, directions: np.ndarray) -> np.ndarray:
        """F_obs (S, r, r) of designs (S, N, 3) (or (N, 3): one design, (1, r, r))."""
        R = self.projected_rows(np.asarray(directions, float).reshape(-1, *np.shape(directions)[-2:]))
        return np.einsum("snp,snq->spq", R, R)

    def sd(self, F: np.ndarray, check: bool = True) -> np.ndarray:
        """Cramér-Rao SD (S, p) of every parameter's observable part, in the parameters' own units, from F_obs
        (S, r, r); inf where F_obs is singular (the design does not determine the parameters; ``check``
        False: no such test, for an information with a prior)."""
        lam, V = np.linalg.eigh(F)
        ok = (lam[:, 0] > RTOL**2 * np.maximum(lam[:, -1], 1e-300)) | (not check)
        inv = np.where(ok[:, None], 1.0 / np.where(lam > 0, lam, 1.0), 0.0)
        W = self.basis @ V  # (S, p, r): the eigenvectors in parameter coordinates
        var = np.einsum("spr,sr->sp", W * W, inv)
        out = np.sqrt(var) * self.units
        out[~ok] = np.inf
        return out
