"""Compiled residuals, costs and Jacobians of a calibration problem (numba, cached on disk).

The model's equations come from :mod:`optcal.kernels._terms`, generated from the term table; this module
adds what the problem does with them, one candidate per outer iteration:

* the inverse, A from N: A₀ = M⁻¹(N − c) with M·A + c the linearisation of F at A = 0 (exact for the
  linear terms), then fixed-point steps A ← A + M⁻¹(N − F(A)) over all positions until the step is
  below ``tol``, with the stopping rule of :meth:`optcal.model.Model.inverse` (the NumPy oracle);
* the norm residuals e_j = ‖A_j‖ − g (2020 paper, Eq. 12), then the gauge rows G·(x − centre);
* the reference residuals (N_j − F(A_ref,j)) / K0, in g;
* the analytic Jacobian: for the norm cost, ∂e_j/∂x = −wᵀ ∂F/∂x with (∂F/∂A)ᵀ w = A_j/‖A_j‖ (implicit
  function theorem); for the reference residuals, −∂F/∂x / K0.

Everything a call needs travels in a few flat buffers laid out by :func:`pack` (floats, integers, and a
scratch buffer allocated once per view): numba checks the type of every argument on each call, and
three buffers cost a fraction of a microsecond where a dozen separate arrays cost about one. The
buffers also carry the *view*: which parameters are free, the fixed values of the others, and the
affine map z → x of normalised coordinates. Per-position data are stored axis by axis (rows of an
(8, n) block), so the sweep over positions reads memory in order and vectorises.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ._terms import NQ, forward_all, forward_dA, forward_dq, forward_seed, linear_part

# The integer buffer: sizes and flags, then the slots of the model's parameters and the free indices.
H_N, H_P, H_NF, H_NG, H_MODE, H_AFFINE, H_MAXIT, H_VARIANT, HEADER = range(9)
NORM, REFERENCE = 0, 1
# Rows of the per-position block: N (3 rows), the reference specific force (3), dT, dt.
ROW_N, ROW_REF, ROW_DTEMP, ROW_DTIME, POS_ROWS = 0, 3, 6, 7, 8
N_SCALARS = 5  # K0 (3), g, tol

JIT = dict(cache=True, error_model="numpy")  # IEEE results (inf, nan) instead of ZeroDivisionError
# Helpers of the per-candidate loop are inlined by numba itself: as separate functions, every array
# argument costs a reference-count update per call, which measured 3x the arithmetic of a candidate.
INLINE = dict(JIT, inline="always")


def pack(*, N, ref, dtemp, dtime, K0, g, centre, gauge, slots, affine: bool, variant: int, free, x_fixed,
         offset, scale, tol: float = 1e-15, max_iter: int = 60) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The float, integer and scratch buffers of one problem view (see the module docstring).

    Floats: the scalars K0, g, tol; the (8, n) per-position block; the (2 + n_gauge, p) per-parameter
    block (centre, fixed values, gauge rows); the (2, n_free) view block (offset, scale of z → x)."""
    n, p, nf = len(N), len(centre), len(free)
    ng = 0 if gauge is None else len(gauge)
    pos = np.zeros((POS_ROWS, n))
    pos[ROW_N:ROW_N + 3] = np.asarray(N, float).T
    if ref is not None:
        pos[ROW_REF:ROW_REF + 3] = np.asarray(ref, float).T
    if dtemp is not None:
        pos[ROW_DTEMP] = dtemp
    if dtime is not None:
        pos[ROW_DTIME] = dtime
    par = np.vstack([centre, x_fixed] + ([] if gauge is None else [gauge])).astype(float)
    fb = np.concatenate([np.asarray(K0, float), [g, tol], pos.ravel(), par.ravel(),
                         np.asarray(offset, float), np.asarray(scale, float)])
    head = np.zeros(HEADER, np.int64)
    head[[H_N, H_P, H_NF, H_NG]] = n, p, nf, ng
    head[H_MODE] = NORM if ref is None else REFERENCE
    head[H_AFFINE], head[H_MAXIT], head[H_VARIANT] = int(affine), max_iter, variant
    ib = np.concatenate([head, np.asarray(slots, np.int64), np.asarray(free, np.int64)])
    m = (3 * n if ref is not None else n) + ng
    work = np.empty(p + NQ + m + 4 * n + 1)
    return np.ascontiguousarray(fb), np.ascontiguousarray(ib), work


@njit(**INLINE)
def _view(fb, ib):
    """(slots, free, per-position block, per-parameter block, view block) of the buffers."""
    n, p, nf, ng = ib[H_N], ib[H_P], ib[H_NF], ib[H_NG]
    o_par = N_SCALARS + POS_ROWS * n
    o_view = o_par + (2 + ng) * p
    return (ib[HEADER:HEADER + p], ib[HEADER + p:HEADER + p + nf], fb[N_SCALARS:o_par].reshape((POS_ROWS, n)),
            fb[o_par:o_view].reshape((2 + ng, p)), fb[o_view:o_view + 2 * nf].reshape((2, nf)))


@njit(**JIT)
def n_residuals(ib):
    n = ib[H_N]
    return (3 * n if ib[H_MODE] == REFERENCE else n) + ib[H_NG]


@njit(**INLINE)
def _scratch(work, ib):
    """x (p), q (NQ), r (m), A and step sizes (4, n) in the scratch buffer."""
    n, p, m = ib[H_N], ib[H_P], n_residuals(ib)
    o = p + NQ + m
    return work[:p], work[p:p + NQ], work[p + NQ:o], work[o:o + 4 * n].reshape((4, n))


@njit(**INLINE)
def _full(Z, s, free, par, view, x, q, slots):
    """Row s of the candidates Z (view coordinates) as a full parameter vector x and its canonical q."""
    x[:] = par[1]
    for c in range(free.size):
        x[free[c]] = view[0, c] + view[1, c] * Z[s, c]
    q[:] = 0.0
    for k in range(slots.size):
        q[slots[k]] = x[k]


@njit(**INLINE)
def _inverse3(m):
    """Inverse of a row-major 3×3 matrix by the adjugate (a singular one gives inf/nan, not an error)."""
    m00, m01, m02, m10, m11, m12, m20, m21, m22 = m
    c00 = m11 * m22 - m12 * m21
    c01 = m12 * m20 - m10 * m22
    c02 = m10 * m21 - m11 * m20
    det = m00 * c00 + m01 * c01 + m02 * c02
    return (c00 / det, (m02 * m21 - m01 * m22) / det, (m01 * m12 - m02 * m11) / det,
            c01 / det, (m00 * m22 - m02 * m20) / det, (m02 * m10 - m00 * m12) / det,
            c02 / det, (m01 * m20 - m00 * m21) / det, (m00 * m11 - m01 * m10) / det)


@njit(**INLINE)
def _invert_all(forward, q, pos, affine, tol, max_iter, A):
    """Specific force A[0:3] (3, n) of every position from its outputs: Model.inverse's iteration,
    sweeping all positions per step (a loop without branches, which the compiler vectorises)."""
    lp = linear_part(q)
    mi, c = _inverse3(lp[:9]), lp[9:]
    N0, N1, N2, dT, dt = pos[ROW_N], pos[ROW_N + 1], pos[ROW_N + 2], pos[ROW_DTEMP], pos[ROW_DTIME]
    A0, A1, A2, step = A[0], A[1], A[2], A[3]
    n = N0.size
    for j in range(n):
        r0, r1, r2 = N0[j] - c[0], N1[j] - c[1], N2[j] - c[2]
        A0[j] = mi[0] * r0 + mi[1] * r1 + mi[2] * r2
        A1[j] = mi[3] * r0 + mi[4] * r1 + mi[5] * r2
        A2[j] = mi[6] * r0 + mi[7] * r1 + mi[8] * r2
    if affine:
        return
    prev = np.inf
    for _ in range(max_iter):
        for j in range(n):
            f0, f1, f2 = forward(q, A0[j], A1[j], A2[j], dT[j], dt[j])
            r0, r1, r2 = N0[j] - f0, N1[j] - f1, N2[j] - f2
            d0 = mi[0] * r0 + mi[1] * r1 + mi[2] * r2
            d1 = mi[3] * r0 + mi[4] * r1 + mi[5] * r2
            d2 = mi[6] * r0 + mi[7] * r1 + mi[8] * r2
            A0[j] += d0
            A1[j] += d1
            A2[j] += d2
            # |δA|₁ ≥ the max-norm the NumPy oracle uses, so this stops no earlier than it does.
            step[j] = abs(d0) + abs(d1) + abs(d2)
        size = 0.0
        for j in range(n):
            size = max(size, step[j])
        if not size == size:  # NaN: this candidate has no inverse
            break
        # Stop when the error left after this step, size·ρ/(1−ρ), is below tol (as Model.inverse does).
        rho = min(size / prev, 0.5) if prev > 0 else 0.0
        if size <= tol or (prev < np.inf and size * rho / (1.0 - rho) <= tol):
            break
        prev = size


@njit(**INLINE)
def _residuals_of(forward, fb, ib, x, q, pos, par, r, A):
    """Residuals of the candidate x (canonical q) into r; returns Σ r²."""
    n = ib[H_N]
    s = 0.0
    if ib[H_MODE] == REFERENCE:
        k0, k1, k2 = fb[0], fb[1], fb[2]
        for j in range(n):
            f0, f1, f2 = forward(q, pos[ROW_REF, j], pos[ROW_REF + 1, j], pos[ROW_REF + 2, j], pos[ROW_DTEMP, j],
                                 pos[ROW_DTIME, j])
            e0, e1, e2 = (pos[ROW_N, j] - f0) / k0, (pos[ROW_N + 1, j] - f1) / k1, (pos[ROW_N + 2, j] - f2) / k2
            r[3 * j], r[3 * j + 1], r[3 * j + 2] = e0, e1, e2
            s += e0 * e0 + e1 * e1 + e2 * e2
        return s
    _invert_all(forward, q, pos, ib[H_AFFINE] != 0, fb[4], ib[H_MAXIT], A)
    g = fb[3]
    for j in range(n):
        e = np.sqrt(A[0, j] * A[0, j] + A[1, j] * A[1, j] + A[2, j] * A[2, j]) - g
        r[j] = e
        s += e * e
    for k in range(ib[H_NG]):
        e = 0.0
        for i in range(x.size):
            e += (x[i] - par[0, i]) * par[2 + k, i]
        r[n + k] = e
        s += e * e
    return s


@njit(**JIT)
def cost_one(z, fb, ib, work):
    """Σ r² of one candidate z in the view's coordinates (NaN when it is not finite)."""
    f = work[work.size - 1:]
    evaluate_batch(z.reshape((1, z.size)), fb, ib, work, f, work[:0].reshape((0, 0)), False)
    return f[0]


@njit(**JIT)
def evaluate_batch(Z, fb, ib, work, f, R, keep_residuals):
    """Costs of the candidates Z (S, nf) into f (S,), and their residuals into R (S, m) when asked.

    Returns the row of the lowest finite cost (−1 when none is finite)."""
    if ib[H_VARIANT] == 0:
        return _batch(forward_seed, Z, fb, ib, work, f, R, keep_residuals)
    return _batch(forward_all, Z, fb, ib, work, f, R, keep_residuals)


@njit(**INLINE)
def _batch(forward, Z, fb, ib, work, f, R, keep_residuals):
    slots, free, pos, par, view = _view(fb, ib)
    x, q, r, A = _scratch(work, ib)
    best, best_f = -1, np.inf
    for s in range(Z.shape[0]):
        _full(Z, s, free, par, view, x, q, slots)
        c = _residuals_of(forward, fb, ib, x, q, pos, par, r, A)
        if np.isfinite(c):
            f[s] = c
            if c < best_f:
                best, best_f = s, c
        else:
            f[s] = np.nan
        if keep_residuals:
            R[s, :] = r
    return best


@njit(**JIT)
def jacobian(z, fb, ib, work, J):
    """The analytic Jacobian (m, nf) of the residuals at z, in the view's coordinates, into J."""
    slots, free, pos, par, view = _view(fb, ib)
    x, q, r, A = _scratch(work, ib)
    _full(z.reshape((1, z.size)), 0, free, par, view, x, q, slots)
    n, nf = ib[H_N], free.size
    dq = np.zeros((3, NQ))
    dT, dt = pos[ROW_DTEMP], pos[ROW_DTIME]
    if ib[H_MODE] == REFERENCE:
        for j in range(n):
            forward_dq(q, pos[ROW_REF, j], pos[ROW_REF + 1, j], pos[ROW_REF + 2, j], dT[j], dt[j], dq)
            for i in range(3):
                for c in range(nf):
                    J[3 * j + i, c] = -dq[i, slots[free[c]]] / fb[i] * view[1, c]
        return
    _invert_all(forward_all, q, pos, ib[H_AFFINE] != 0, fb[4], ib[H_MAXIT], A)
    for j in range(n):
        a0, a1, a2 = A[0, j], A[1, j], A[2, j]
        norm = np.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
        # w solves (∂F/∂A)ᵀ w = A/‖A‖; then ∂e/∂x = −wᵀ ∂F/∂x.
        fi = _inverse3(forward_dA(q, a0, a1, a2, dT[j], dt[j]))
        u0, u1, u2 = a0 / norm, a1 / norm, a2 / norm
        w0 = fi[0] * u0 + fi[3] * u1 + fi[6] * u2
        w1 = fi[1] * u0 + fi[4] * u1 + fi[7] * u2
        w2 = fi[2] * u0 + fi[5] * u1 + fi[8] * u2
        forward_dq(q, a0, a1, a2, dT[j], dt[j], dq)
        for c in range(nf):
            k = slots[free[c]]
            J[j, c] = -(w0 * dq[0, k] + w1 * dq[1, k] + w2 * dq[2, k]) * view[1, c]
    for k in range(ib[H_NG]):
        for c in range(nf):
            J[n + k, c] = par[2 + k, free[c]] * view[1, c]
