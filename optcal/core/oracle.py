"""The NumPy evaluation of a calibration problem: the test oracle that the compiled kernel is checked
against (docs/design.md, "One table, three evaluators"), with the same residuals (design.md, "Norm residuals
and cost", "Reference (turntable) residuals" and "Minimum-constraint gauge rows") and Jacobian (design.md,
"Evaluation paths and the Jacobian": the implicit function theorem at the inverse) written on arrays through
:class:`optcal.core.model.Model`. :class:`optcal.core.problem.CalibrationProblem` exposes them as
``residuals_full_numpy`` and ``jacobian_full_numpy``.
"""

from __future__ import annotations

import numpy as np


def residuals(problem, X_full) -> np.ndarray:
    """Residuals (S, m) of full parameter vectors (S, p) through the NumPy model; not counted."""
    X_full = np.atleast_2d(X_full)
    # Blocks of about 16k position-candidates keep the element-wise chain in cache (measured
    # 1.6x faster than one block at S = 10,000 on 24 positions).
    step = max(1, 16384 // len(problem.data))
    if len(X_full) > step:
        return np.concatenate([residuals(problem, X_full[i:i + step]) for i in range(0, len(X_full), step)])
    with np.errstate(all="ignore"):
        if problem.reference:
            N = problem.model.forward(X_full, problem.data.ref, problem.ctx)
            return ((problem.data.N - N) / problem._K0).reshape(len(X_full), -1)
        A = problem.model.inverse(X_full, problem.data.N, problem.ctx)
        r = np.linalg.norm(A, axis=-1) - problem.g_local
    if problem._gauge is not None:
        r = np.concatenate([r, (X_full - problem.centre) @ problem._gauge.T], axis=1)
    return r


def jacobian(problem, x_full) -> np.ndarray:
    """Jacobian (m, p) of the residuals at one full parameter vector, from the model's derivatives
    (:meth:`Model.dforward_dA`, :meth:`Model.dforward_dp`, by complex step); not counted."""
    x_full = np.asarray(x_full, float)
    if problem.reference:
        Fp = problem.model.dforward_dp(x_full, problem.data.ref, problem.ctx)  # (n, 3, p)
        return (-Fp / problem._K0[None, :, None]).reshape(-1, x_full.size)
    A = problem.model.inverse(x_full[None], problem.data.N, problem.ctx)[0]
    Fa = problem.model.dforward_dA(x_full[None], A[None], problem.ctx)[0]  # (n, 3, 3)
    Fp = problem.model.dforward_dp(x_full, A, problem.ctx)  # (n, 3, p)
    dA = -np.linalg.solve(Fa, Fp)  # (n, 3, p)
    u = A / np.linalg.norm(A, axis=1, keepdims=True)
    J = np.einsum("ni,nip->np", u, dA)
    return J if getattr(problem, "_gauge", None) is None else np.vstack([J, problem._gauge])
