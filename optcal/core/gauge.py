"""The linear algebra of observability and the gauge rows (docs/design.md, "How the code finds them" and
"Minimum-constraint gauge rows").

The Jacobian of the position residuals, each column in natural units, has near-zero singular values along
the directions the norm cost cannot see; their null space, in a sparse basis, names those directions
(:func:`optcal.core.analysis.observability`) and, divided by the natural units, gives the minimum-constraint
gauge rows that :class:`optcal.core.problem.CalibrationProblem` appends (:func:`gauge_rows`).

The functions take any object with the problem's ``model``, ``ctx``, ``data``, ``reference`` and
``jacobian_full``: this module sits below both :mod:`optcal.core.problem` and :mod:`optcal.core.analysis`, so that
the problem can fix its gauge without importing the analysis that is built on it.
"""

from __future__ import annotations

import numpy as np

from optcal.core.presets import family

# Relative singular value below which a direction is unobservable (Fisher information below RTOL² of the
# best-determined direction; docs/design.md, "How the code finds them").
RTOL = 1e-3


def natural_units(problem, x_full: np.ndarray) -> np.ndarray:
    """One 'natural' unit per parameter: a change of one unit moves residuals by O(1) g."""
    model = problem.model
    K = np.abs(x_full[model.groups()["scale"]])
    out = np.ones(model.n_params)
    for k, n in enumerate(model.names):
        f = family(n)
        if f in ("K", "K2", "K3"):
            out[k] = K["xyz".index(n[-1])]
        elif f in ("beta", "gamma") and problem.ctx.dtemp is not None:
            out[k] = 1.0 / max(np.std(problem.ctx.dtemp), 1e-12)
        elif f == "d" and problem.ctx.dt is not None:
            out[k] = 1.0 / max(np.std(problem.ctx.dt), 1e-12)
    return out


def n_position_residuals(problem) -> int:
    """Number of data residuals (gauge rows excluded)."""
    return problem.n_position_residuals


def sparse_basis(V: np.ndarray) -> np.ndarray:
    """A sparse basis of span(V) (columns): Gauss-Jordan elimination of Vᵀ with full pivoting, so each
    direction is led by the parameter it moves most; columns of unit norm."""
    R = V.T.copy()
    free = np.ones(R.shape[1], bool)
    for r in range(R.shape[0]):
        sub = np.abs(R[r:]) * free
        i, c = np.unravel_index(int(np.argmax(sub)), sub.shape)
        R[[r, r + i]] = R[[r + i, r]]
        R[r] /= R[r, c]
        others = np.arange(R.shape[0]) != r
        R[others] -= np.outer(R[others, c], R[r])
        free[c] = False
    R[np.abs(R) < 1e-9] = 0.0
    B = R.T
    return B / np.linalg.norm(B, axis=0, keepdims=True)


def null_space(problem, x_full: np.ndarray, rtol: float = RTOL) -> tuple[int, np.ndarray, np.ndarray, np.ndarray]:
    """Rank, singular values relative to the largest, the null space (p, p − rank; sparse basis, natural
    units) and the natural units of the position residuals' Jacobian at ``x_full``."""
    u = natural_units(problem, x_full)
    J = problem.jacobian_full(x_full)[: n_position_residuals(problem)] * u
    # every right singular vector, and no more left ones than J has columns (full_matrices=True made U m × m:
    # gigabytes for a file of thousands of positions)
    _, s, vt = np.linalg.svd(J, full_matrices=J.shape[0] < J.shape[1])
    s_full = np.zeros(J.shape[1])
    s_full[: len(s)] = s
    rel = s_full / s_full[0]
    rank = int(np.sum(rel > rtol))
    null = vt[rank:].T
    return rank, rel, (sparse_basis(null) if null.size else null), u


def gauge_rows(problem, centre: np.ndarray) -> np.ndarray | None:
    """The minimum-constraint rows G (one per unobservable direction at ``centre``: the null-space
    direction divided by the natural units), or None when every direction is observable."""
    rank, _, null, u = null_space(problem, centre)
    return null.T / u if rank < problem.model.n_params else None
