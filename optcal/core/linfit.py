"""Closed-form starting points: an algebraic ellipsoid fit (norm cost) or a linear regression
(turntable reference), turned into ``scale``, ``bias`` and gauge ``misalignment`` parameters.

With the norm cost, the position means lie on the ellipsoid (N − o)ᵀ MᵀM (N − o) = g², where
M = (diag(K)·T)⁻¹ and o = diag(K)·b. In the gauge of docs/design.md, "The gauge of `misalignment`", T is lower
triangular, so M is too, and MᵀM is factorised by a Cholesky decomposition of the index-reversed matrix.
"""

from __future__ import annotations

import numpy as np

from optcal.core.errors import InputError
from optcal.core.model import T_CELLS, Model


def _quadric(N: np.ndarray, full: bool) -> tuple[np.ndarray, np.ndarray, float]:
    """Least-squares quadric NᵀQN + 2qᵀN = 1 through the points (the constant fixed at −1)."""
    x, y, z = N.T
    if full:
        D = np.stack([x * x, y * y, z * z, 2 * x * y, 2 * x * z, 2 * y * z, 2 * x, 2 * y, 2 * z], 1)
    else:
        D = np.stack([x * x, y * y, z * z, 2 * x, 2 * y, 2 * z], 1)
    # Columns are scaled so the solution does not depend on the output units (counts vs g).
    s = np.linalg.norm(D, axis=0)
    s[s == 0] = 1.0
    v = np.linalg.lstsq(D / s, np.ones(len(N)), rcond=None)[0] / s
    if full:
        a, b, c, d, e, f, g, h, i = v
        Q = np.array([[a, d, e], [d, b, f], [e, f, c]])
    else:
        a, b, c, g, h, i = v
        Q = np.diag([a, b, c])
    return Q, np.array([g, h, i]), -1.0


def ellipsoid_to_params(Q: np.ndarray, o: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(K, b, T) in the lower-triangular gauge from MᵀM = Q (normalised to radius g) and centre o."""
    P = np.eye(3)[::-1]
    L = np.linalg.cholesky(P @ Q @ P)
    M = P @ L.T @ P  # lower triangular with MᵀM = Q
    DT = np.linalg.inv(M)
    sign = np.sign(np.diag(DT))
    DT = DT * sign[:, None]  # keep positive scale factors (the norm cannot see the sign)
    K = np.diag(DT).copy()
    T = DT / K[:, None]
    return K, o / K, T


def linear_start(model: Model, N: np.ndarray, g_local: float = 1.0, ref: np.ndarray | None = None) -> np.ndarray:
    """A starting parameter vector for ``model`` from a closed-form linear fit; nonlinear terms zero."""
    x = np.zeros(model.n_params)
    groups = model.groups()
    names = model.names
    if ref is not None:
        # Traditional (turntable) calibration: regress N on [A, 1] per axis.
        D = np.column_stack([ref, np.ones(len(ref))])
        coef, *_ = np.linalg.lstsq(D, N, rcond=None)
        DT, off = coef[:3].T, coef[3]
        K = np.diag(DT).copy()
        T = DT / K[:, None]
        b = off / K
    else:
        full = "misalignment" in groups and len(N) >= 9
        Q, q, c = _quadric(N, full)
        try:
            o = -np.linalg.solve(Q, q)
        except np.linalg.LinAlgError:
            raise InputError(
                "the positions do not determine an ellipsoid; use more, and more varied, positions") from None
        r = o @ Q @ o - c
        Qn = Q * g_local**2 / r
        if not np.all(np.linalg.eigvalsh(Qn) > 0):
            raise InputError(
                "the position means do not lie on an ellipsoid (wrong units, or the sensor moved during the "
                "positions?); check the data"
            )
        K, b, T = ellipsoid_to_params(Qn, o)
    values = {"K_x": K[0], "K_y": K[1], "K_z": K[2], "b_x": b[0], "b_y": b[1], "b_z": b[2]}
    values.update({name: T[i, j] for (i, j), name in T_CELLS.items()})
    for k, n in enumerate(names):
        if n in values:
            x[k] = values[n]
    return x
