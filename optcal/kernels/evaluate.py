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

Everything a call needs travels in two flat buffers (floats and integers, laid out by :func:`pack`):
numba checks the type of every argument on each call, and two buffers cost a fraction of a microsecond
where a dozen separate arrays cost about one. The buffers also carry the *view*: which parameters are
free, the fixed values of the others, and the affine map z → x of normalised coordinates.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ._terms import NQ, forward_all, forward_dA, forward_dq, forward_seed, linear_part

# Header of the integer buffer: sizes and flags, then where each array starts.
(H_N, H_P, H_NF, H_NG, H_MODE, H_AFFINE, H_MAXIT, H_VARIANT, O_SLOTS, O_FREE, O_N, O_REF, O_DTEMP, O_DTIME, O_K0, O_G,
 O_CENTRE, O_GAUGE, O_XFIXED, O_OFFSET, O_SCALE, O_TOL, HEADER) = range(23)
NORM, REFERENCE = 0, 1

JIT = dict(cache=True, error_model="numpy")  # IEEE results (inf, nan) instead of ZeroDivisionError
# Helpers of the per-candidate loop are inlined by numba itself: as separate functions, every array
# argument costs a reference-count update per call, which measured 3x the arithmetic of a candidate.
INLINE = dict(JIT, inline="always")


def pack(*, N, ref, dtemp, dtime, K0, g, centre, gauge, slots, affine: bool, variant: int, free, x_fixed,
         offset, scale,
         tol: float = 1e-15, max_iter: int = 60) -> tuple[np.ndarray, np.ndarray]:
    """The float and integer buffers of one problem view (see the module docstring)."""
    n, p = len(N), len(centre)
    zeros = np.zeros(n)
    floats = [np.ravel(N), np.ravel(ref) if ref is not None else np.zeros(3 * n),
              zeros if dtemp is None else np.asarray(dtemp, float),
              zeros if dtime is None else np.asarray(dtime, float),
              np.asarray(K0, float), np.array([g], float), np.asarray(centre, float),
              np.zeros(0) if gauge is None else np.ravel(gauge), np.asarray(x_fixed, float),
              np.asarray(offset, float), np.asarray(scale, float), np.array([tol])]
    starts = np.cumsum([0] + [len(f) for f in floats])[:-1]
    fb = np.ascontiguousarray(np.concatenate(floats), dtype=np.float64)
    ints = [np.asarray(slots, np.int64), np.asarray(free, np.int64)]
    head = np.zeros(HEADER, np.int64)
    head[[H_N, H_P, H_NF, H_NG]] = n, p, len(free), 0 if gauge is None else len(gauge)
    head[H_MODE] = NORM if ref is None else REFERENCE
    head[H_AFFINE], head[H_MAXIT], head[H_VARIANT] = int(affine), max_iter, variant
    head[O_SLOTS], head[O_FREE] = HEADER, HEADER + p
    head[O_N:O_TOL + 1] = starts
    ib = np.ascontiguousarray(np.concatenate([head] + ints), dtype=np.int64)
    return fb, ib


@njit(**INLINE)
def _view(fb, ib):
    n, p, nf, ng = ib[H_N], ib[H_P], ib[H_NF], ib[H_NG]
    slots = ib[ib[O_SLOTS]:ib[O_SLOTS] + p]
    free = ib[ib[O_FREE]:ib[O_FREE] + nf]
    N = fb[ib[O_N]:ib[O_N] + 3 * n].reshape((n, 3))
    ref = fb[ib[O_REF]:ib[O_REF] + 3 * n].reshape((n, 3))
    dtemp = fb[ib[O_DTEMP]:ib[O_DTEMP] + n]
    dtime = fb[ib[O_DTIME]:ib[O_DTIME] + n]
    K0 = fb[ib[O_K0]:ib[O_K0] + 3]
    centre = fb[ib[O_CENTRE]:ib[O_CENTRE] + p]
    gauge = fb[ib[O_GAUGE]:ib[O_GAUGE] + ng * p].reshape((ng, p))
    x_fixed = fb[ib[O_XFIXED]:ib[O_XFIXED] + p]
    offset = fb[ib[O_OFFSET]:ib[O_OFFSET] + nf]
    scale = fb[ib[O_SCALE]:ib[O_SCALE] + nf]
    return slots, free, N, ref, dtemp, dtime, K0, fb[ib[O_G]], centre, gauge, x_fixed, offset, scale, fb[ib[O_TOL]]


@njit(**JIT)
def n_residuals(ib):
    n = ib[H_N]
    return (3 * n if ib[H_MODE] == REFERENCE else n) + ib[H_NG]


@njit(**INLINE)
def _full(Z, s, free, x_fixed, offset, scale, x):
    """Row s of the candidates Z in the view's coordinates, as a full parameter vector into x."""
    x[:] = x_fixed
    for c in range(free.size):
        x[free[c]] = offset[c] + scale[c] * Z[s, c]


@njit(**INLINE)
def _canonical(x, slots, q):
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
def _invert_all(forward, q, N, dT, dt, affine, tol, max_iter, A, step):
    """Specific force A (3, n) of every position from its outputs N (n, 3): Model.inverse's iteration,
    sweeping all positions per step (a loop without branches, which the compiler vectorises)."""
    mi, c = _linear_inverse(q)
    n = N.shape[0]
    for j in range(n):
        r0, r1, r2 = N[j, 0] - c[0], N[j, 1] - c[1], N[j, 2] - c[2]
        A[0, j] = mi[0] * r0 + mi[1] * r1 + mi[2] * r2
        A[1, j] = mi[3] * r0 + mi[4] * r1 + mi[5] * r2
        A[2, j] = mi[6] * r0 + mi[7] * r1 + mi[8] * r2
    if affine:
        return
    prev = np.inf
    for _ in range(max_iter):
        for j in range(n):
            f0, f1, f2 = forward(q, A[0, j], A[1, j], A[2, j], dT[j], dt[j])
            r0, r1, r2 = N[j, 0] - f0, N[j, 1] - f1, N[j, 2] - f2
            d0 = mi[0] * r0 + mi[1] * r1 + mi[2] * r2
            d1 = mi[3] * r0 + mi[4] * r1 + mi[5] * r2
            d2 = mi[6] * r0 + mi[7] * r1 + mi[8] * r2
            A[0, j] += d0
            A[1, j] += d1
            A[2, j] += d2
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
def _linear_inverse(q):
    lp = linear_part(q)
    return _inverse3(lp[:9]), lp[9:]


@njit(**INLINE)
def _residuals_of(forward, x, q, slots, N, ref, dtemp, dtime, K0, g, centre, gauge, tol, mode, affine, max_iter, r,
                  A, step):
    n = N.shape[0]
    _canonical(x, slots, q)
    s = 0.0
    if mode == REFERENCE:
        for j in range(n):
            f0, f1, f2 = forward(q, ref[j, 0], ref[j, 1], ref[j, 2], dtemp[j], dtime[j])
            e0, e1, e2 = (N[j, 0] - f0) / K0[0], (N[j, 1] - f1) / K0[1], (N[j, 2] - f2) / K0[2]
            r[3 * j], r[3 * j + 1], r[3 * j + 2] = e0, e1, e2
            s += e0 * e0 + e1 * e1 + e2 * e2
        return s
    _invert_all(forward, q, N, dtemp, dtime, affine, tol, max_iter, A, step)
    for j in range(n):
        e = np.sqrt(A[0, j] * A[0, j] + A[1, j] * A[1, j] + A[2, j] * A[2, j]) - g
        r[j] = e
        s += e * e
    for k in range(gauge.shape[0]):
        e = 0.0
        for i in range(x.size):
            e += (x[i] - centre[i]) * gauge[k, i]
        r[n + k] = e
        s += e * e
    return s


@njit(**JIT)
def cost_one(z, fb, ib):
    """Σ r² of one candidate z in the view's coordinates (NaN when it is not finite)."""
    f = np.empty(1)
    evaluate_batch(z.reshape((1, z.size)), fb, ib, f, np.empty((0, 0)), False)
    return f[0]


@njit(**JIT)
def evaluate_batch(Z, fb, ib, f, R, keep_residuals):
    """Costs of the candidates Z (S, nf) into f (S,), and their residuals into R (S, m) when asked."""
    if ib[H_VARIANT] == 0:
        _batch(forward_seed, Z, fb, ib, f, R, keep_residuals)
    else:
        _batch(forward_all, Z, fb, ib, f, R, keep_residuals)


@njit(**INLINE)
def _batch(forward, Z, fb, ib, f, R, keep_residuals):
    slots, free, N, ref, dtemp, dtime, K0, g, centre, gauge, x_fixed, offset, scale, tol = _view(fb, ib)
    mode, affine, max_iter = ib[H_MODE], ib[H_AFFINE] != 0, ib[H_MAXIT]
    x, q = np.empty(ib[H_P]), np.empty(NQ)
    r = np.empty(n_residuals(ib))
    A, step = np.empty((3, N.shape[0])), np.empty(N.shape[0])
    for s in range(Z.shape[0]):
        _full(Z, s, free, x_fixed, offset, scale, x)
        c = _residuals_of(forward, x, q, slots, N, ref, dtemp, dtime, K0, g, centre, gauge, tol, mode, affine,
                          max_iter, r, A, step)
        f[s] = c if np.isfinite(c) else np.nan
        if keep_residuals:
            R[s, :] = r


@njit(**JIT)
def jacobian(z, fb, ib, J):
    """The analytic Jacobian (m, nf) of the residuals at z, in the view's coordinates, into J."""
    slots, free, N, ref, dtemp, dtime, K0, g, centre, gauge, x_fixed, offset, scale, tol = _view(fb, ib)
    n, p = N.shape[0], ib[H_P]
    x, q = np.empty(p), np.empty(NQ)
    _full(z.reshape((1, z.size)), 0, free, x_fixed, offset, scale, x)
    _canonical(x, slots, q)
    dq = np.zeros((3, NQ))
    nf = free.size
    if ib[H_MODE] == REFERENCE:
        for j in range(n):
            forward_dq(q, ref[j, 0], ref[j, 1], ref[j, 2], dtemp[j], dtime[j], dq)
            for i in range(3):
                for c in range(nf):
                    J[3 * j + i, c] = -dq[i, slots[free[c]]] / K0[i] * scale[c]
        return
    A, step = np.empty((3, n)), np.empty(n)
    _invert_all(forward_all, q, N, dtemp, dtime, ib[H_AFFINE] != 0, tol, ib[H_MAXIT], A, step)
    for j in range(n):
        a0, a1, a2 = A[0, j], A[1, j], A[2, j]
        norm = np.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
        # w solves (∂F/∂A)ᵀ w = A/‖A‖; then ∂e/∂x = −wᵀ ∂F/∂x.
        fa = forward_dA(q, a0, a1, a2, dtemp[j], dtime[j])
        fi = _inverse3(fa)
        u0, u1, u2 = a0 / norm, a1 / norm, a2 / norm
        w0 = fi[0] * u0 + fi[3] * u1 + fi[6] * u2
        w1 = fi[1] * u0 + fi[4] * u1 + fi[7] * u2
        w2 = fi[2] * u0 + fi[5] * u1 + fi[8] * u2
        forward_dq(q, a0, a1, a2, dtemp[j], dtime[j], dq)
        for c in range(nf):
            k = slots[free[c]]
            J[j, c] = -(w0 * dq[0, k] + w1 * dq[1, k] + w2 * dq[2, k]) * scale[c]
    for k in range(gauge.shape[0]):
        for c in range(nf):
            J[n + k, c] = gauge[k, free[c]] * scale[c]
