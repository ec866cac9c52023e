"""Compiled residuals, costs and Jacobians of a calibration problem (numba, cached on disk).

The model's equations come from :mod:`optcal.core.kernels._terms`, generated from the term table; this module
adds what the problem does with them, one candidate per outer iteration:

* the inverse, A from N: A₀ = M⁻¹(N − c) with M·A + c the linearisation of F at A = 0 (exact for the
  linear terms), then fixed-point steps A ← A + M⁻¹(N − F(A)) over all positions until the step is
  below ``tol``, with the stopping rule of :meth:`optcal.core.model.Model.inverse` (the NumPy oracle);
* the norm residuals e_j = ‖A_j‖ − g (2020 paper, Eq. 12), then the gauge rows G·(x − centre);
* the reference residuals (N_j − F(A_ref,j)) / K0, in g;
* the analytic Jacobian: for the norm cost, ∂e_j/∂x = −wᵀ ∂F/∂x with (∂F/∂A)ᵀ w = A_j/‖A_j‖ (implicit
  function theorem); for the reference residuals, −∂F/∂x / K0;
* user features: the parameters of user-defined terms (:func:`optcal.core.terms.user_term`) sit in slots after the
  canonical ones (:func:`optcal.core.kernels.codegen.slot_indices`), and each adds K_i·c·w_j·A_x^e0·A_y^e1·A_z^e2
  (·sgn of the previous pose's A_k) to output i, from a table of (slot, i, e0, e1, e2, k) rows and the data's
  weights w_j (temperature, time, sinusoid) laid out by :func:`pack`. Models without them take the same
  branch-free loops as before.

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

from optcal.core.kernels._terms import NQ, forward_all, forward_dA, forward_dq, forward_seed, linear_part
from optcal.core.terms import PREV_DEADZONE_G, SAME_POSE_DEG

# The integer buffer: sizes and flags, then the slots of the model's parameters, the free indices and the user
# features' table (H_NU rows of USER_COLS); H_NQX is the length of q, the canonical slots and the user ones.
H_N, H_P, H_NF, H_NG, H_MODE, H_AFFINE, H_MAXIT, H_VARIANT, H_NU, H_NQX, HEADER = range(11)
USER_COLS = 6  # slot of the coefficient, output axis, e0, e1, e2, previous pose's axis (−1: none)
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
    slots = np.asarray(slots, np.int64)
    table, weights = _user_features(slots, n, dtemp, dtime)
    head[H_NU], head[H_NQX] = len(table), max(NQ, int(slots.max(initial=-1)) + 1)
    ib = np.concatenate([head, slots, np.asarray(free, np.int64), table.ravel()])
    fb = np.concatenate([fb, weights.ravel()])
    m = (3 * n if ref is not None else n) + ng
    work = np.empty(p + head[H_NQX] + m + 4 * n + 1)
    return np.ascontiguousarray(fb), np.ascontiguousarray(ib), work


def _user_features(slots, n, dtemp, dtime) -> tuple[np.ndarray, np.ndarray]:
    """The user features' table (rows of USER_COLS integers) and weights (one row of n per feature)."""
    from optcal.core.kernels.codegen import user_spec

    rows, weights = [], []
    for s in slots[slots >= NQ]:
        axis, feature, kind = user_spec(int(s))
        rows.append([s, axis, *feature.exps, -1 if feature.prev is None else feature.prev])
        weights.append(np.broadcast_to(feature.weight(dtemp, dtime, kind), (n,)))
    if not rows:
        return np.zeros((0, USER_COLS), np.int64), np.zeros((0, n))
    return np.array(rows, np.int64), np.array(weights, float)


@njit(**INLINE)
def _view(fb, ib):
    """(slots, free, per-position block, per-parameter block, view block) of the buffers."""
    n, p, nf, ng = ib[H_N], ib[H_P], ib[H_NF], ib[H_NG]
    o_par = N_SCALARS + POS_ROWS * n
    o_view = o_par + (2 + ng) * p
    return (ib[HEADER:HEADER + p], ib[HEADER + p:HEADER + p + nf], fb[N_SCALARS:o_par].reshape((POS_ROWS, n)),
            fb[o_par:o_view].reshape((2 + ng, p)), fb[o_view:o_view + 2 * nf].reshape((2, nf)))


@njit(**INLINE)
def _user_view(fb, ib):
    """(table (nu, USER_COLS), weights (nu, n)) of the user features."""
    n, p, nf, ng, nu = ib[H_N], ib[H_P], ib[H_NF], ib[H_NG], ib[H_NU]
    o_ib = HEADER + p + nf
    o_fb = N_SCALARS + POS_ROWS * n + (2 + ng) * p + 2 * nf
    return ib[o_ib:o_ib + USER_COLS * nu].reshape((nu, USER_COLS)), fb[o_fb:o_fb + nu * n].reshape((nu, n))


@njit(**INLINE)
def _power(a, e):
    v = 1.0
    for _ in range(e):
        v *= a
    return v


COS_SAME_POSE = float(np.cos(np.radians(SAME_POSE_DEG)))


@njit(**INLINE)
def _previous_sign(src, k, j):
    """sgn of component k of the previous pose's specific force in ``src`` (3+, n): the position before the run
    of positions within SAME_POSE_DEG of each other that holds j; 0 below the dead zone and for the first pose
    (optcal.core.terms.previous_signs)."""
    if k < 0:
        return 1.0
    i = j
    while i > 0:
        a0, a1, a2 = src[0, i], src[1, i], src[2, i]
        b0, b1, b2 = src[0, i - 1], src[1, i - 1], src[2, i - 1]
        c = (a0 * b0 + a1 * b1 + a2 * b2) / np.sqrt((a0 * a0 + a1 * a1 + a2 * a2) * (b0 * b0 + b1 * b1 + b2 * b2))
        if c < COS_SAME_POSE:
            break
        i -= 1
    if i == 0:
        return 0.0
    a = src[k, i - 1]
    if abs(a) < PREV_DEADZONE_G:
        return 0.0
    return 1.0 if a > 0 else -1.0


@njit(**JIT)
def _user_outputs(q, tab, w, j, a0, a1, a2, src):
    """The user features' contribution (u0, u1, u2) to the outputs of position j."""
    u0 = u1 = u2 = 0.0
    for f in range(tab.shape[0]):
        i = tab[f, 1]
        v = (q[i] * q[tab[f, 0]] * w[f, j] * _power(a0, tab[f, 2]) * _power(a1, tab[f, 3]) * _power(a2, tab[f, 4])
             * _previous_sign(src, tab[f, 5], j))
        if i == 0:
            u0 += v
        elif i == 1:
            u1 += v
        else:
            u2 += v
    return u0, u1, u2


@njit(**INLINE)
def _user_derivatives(q, tab, w, j, a, src, dA, dq):
    """Add the user features' ∂F/∂A to dA (9, row-major) and their ∂F/∂q to dq (3, NQX) at position j."""
    for f in range(tab.shape[0]):
        i, slot = tab[f, 1], tab[f, 0]
        ws = w[f, j] * _previous_sign(src, tab[f, 5], j)
        mono = _power(a[0], tab[f, 2]) * _power(a[1], tab[f, 3]) * _power(a[2], tab[f, 4])
        dq[i, slot] = q[i] * ws * mono
        dq[i, i] += q[slot] * ws * mono
        for m in range(3):
            e = tab[f, 2 + m]
            if e > 0:
                d = float(e)
                for k in range(3):
                    d *= _power(a[k], tab[f, 2 + k] - (1 if k == m else 0))
                dA[3 * i + m] += q[i] * q[slot] * ws * d


@njit(**JIT)
def n_residuals(ib):
    n = ib[H_N]
    return (3 * n if ib[H_MODE] == REFERENCE else n) + ib[H_NG]


@njit(**INLINE)
def _scratch(work, ib):
    """x (p), q (NQX), r (m), A and step sizes (4, n) in the scratch buffer."""
    n, p, m, nq = ib[H_N], ib[H_P], n_residuals(ib), ib[H_NQX]
    o = p + nq + m
    return work[:p], work[p:p + nq], work[p + nq:o], work[o:o + 4 * n].reshape((4, n))


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
def _affine_start(mi, c, N0, N1, N2, A0, A1, A2):
    """Every position's A from the linear part alone, A = M⁻¹(N − c): the inversion's start (the answer for an
    affine model)."""
    for j in range(N0.size):
        r0, r1, r2 = N0[j] - c[0], N1[j] - c[1], N2[j] - c[2]
        A0[j] = mi[0] * r0 + mi[1] * r1 + mi[2] * r2
        A1[j] = mi[3] * r0 + mi[4] * r1 + mi[5] * r2
        A2[j] = mi[6] * r0 + mi[7] * r1 + mi[8] * r2


@njit(**INLINE)
def _newton_step(mi, j, r0, r1, r2, A0, A1, A2, step):
    """Position j's A moved by M⁻¹ times its output residual; the step's size |δA|₁ into step[j] (≥ the
    max-norm the NumPy oracle uses, so the sweep stops no earlier than it does)."""
    d0 = mi[0] * r0 + mi[1] * r1 + mi[2] * r2
    d1 = mi[3] * r0 + mi[4] * r1 + mi[5] * r2
    d2 = mi[6] * r0 + mi[7] * r1 + mi[8] * r2
    A0[j] += d0
    A1[j] += d1
    A2[j] += d2
    step[j] = abs(d0) + abs(d1) + abs(d2)


@njit(**INLINE)
def _sweep_done(step, n, prev, tol):
    """(stop, size) after a sweep: its largest step is NaN (no inverse), or the error left after it,
    size·ρ/(1−ρ) with ρ the steps' ratio, is below tol (as Model.inverse stops)."""
    size = 0.0
    for j in range(n):
        size = max(size, step[j])
    if not size == size:
        return True, size
    rho = min(size / prev, 0.5) if prev > 0 else 0.0
    return size <= tol or (prev < np.inf and size * rho / (1.0 - rho) <= tol), size


@njit(**INLINE)
def _invert_all(forward, q, pos, affine, tol, max_iter, A):
    """Specific force A[0:3] (3, n) of every position from its outputs: Model.inverse's iteration,
    sweeping all positions per step (a loop without branches, which the compiler vectorises)."""
    lp = linear_part(q)
    mi, c = _inverse3(lp[:9]), lp[9:]
    N0, N1, N2, dT, dt = pos[ROW_N], pos[ROW_N + 1], pos[ROW_N + 2], pos[ROW_DTEMP], pos[ROW_DTIME]
    A0, A1, A2, step = A[0], A[1], A[2], A[3]
    n = N0.size
    _affine_start(mi, c, N0, N1, N2, A0, A1, A2)
    if affine:
        return
    prev = np.inf
    for _ in range(max_iter):
        for j in range(n):
            f0, f1, f2 = forward(q, A0[j], A1[j], A2[j], dT[j], dt[j])
            _newton_step(mi, j, N0[j] - f0, N1[j] - f1, N2[j] - f2, A0, A1, A2, step)
        done, prev = _sweep_done(step, n, prev, tol)
        if done:
            break


@njit(**JIT)
def _invert_all_user(q, pos, tol, max_iter, A, tab, w):
    """:func:`_invert_all` with the user features added to each position's outputs; each position sees the
    previous positions' A of this sweep (their previous pose's sign). With the whole table's forward map (a model
    with user features takes it: codegen.variant_of). Compiled once and called, not inlined: the entry points
    that hold it compile faster, and models with user features are the rarer ones."""
    lp = linear_part(q)
    mi, c = _inverse3(lp[:9]), lp[9:]
    N0, N1, N2, dT, dt = pos[ROW_N], pos[ROW_N + 1], pos[ROW_N + 2], pos[ROW_DTEMP], pos[ROW_DTIME]
    A0, A1, A2, step = A[0], A[1], A[2], A[3]
    n = N0.size
    _affine_start(mi, c, N0, N1, N2, A0, A1, A2)
    prev = np.inf
    for _ in range(max_iter):
        for j in range(n):
            f0, f1, f2 = forward_all(q, A0[j], A1[j], A2[j], dT[j], dt[j])
            u0, u1, u2 = _user_outputs(q, tab, w, j, A0[j], A1[j], A2[j], A)
            _newton_step(mi, j, N0[j] - f0 - u0, N1[j] - f1 - u1, N2[j] - f2 - u2, A0, A1, A2, step)
        done, prev = _sweep_done(step, n, prev, tol)
        if done:
            break


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
    return s + _norm_residuals(fb, ib, x, par, r, A)


@njit(**INLINE)
def _norm_residuals(fb, ib, x, par, r, A):
    """The norm residuals ‖A_j‖ − g and the gauge rows into r; returns their Σ r²."""
    n = ib[H_N]
    s = 0.0
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
def _residuals_of_user(fb, ib, x, q, pos, par, r, A, tab, w):
    """:func:`_residuals_of` of a model with user features (the whole table's forward map), a function of its own:
    numba caches machine code only when no compiled function is passed to a function that is not inlined, and this
    one is compiled once rather than inlined into every entry point."""
    n = ib[H_N]
    s = 0.0
    if ib[H_MODE] == REFERENCE:
        k0, k1, k2 = fb[0], fb[1], fb[2]
        ref = pos[ROW_REF:ROW_REF + 3]
        for j in range(n):
            f0, f1, f2 = forward_all(q, ref[0, j], ref[1, j], ref[2, j], pos[ROW_DTEMP, j], pos[ROW_DTIME, j])
            u0, u1, u2 = _user_outputs(q, tab, w, j, ref[0, j], ref[1, j], ref[2, j], ref)
            e0 = (pos[ROW_N, j] - f0 - u0) / k0
            e1 = (pos[ROW_N + 1, j] - f1 - u1) / k1
            e2 = (pos[ROW_N + 2, j] - f2 - u2) / k2
            r[3 * j], r[3 * j + 1], r[3 * j + 2] = e0, e1, e2
            s += e0 * e0 + e1 * e1 + e2 * e2
        return s
    _invert_all_user(q, pos, fb[4], ib[H_MAXIT], A, tab, w)
    return s + _norm_residuals(fb, ib, x, par, r, A)


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
    if ib[H_NU] > 0:
        return _batch_user(Z, fb, ib, work, f, R, keep_residuals)
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
        best, best_f = _keep(c, s, f, R, r, keep_residuals, best, best_f)
    return best


@njit(**JIT)
def _batch_user(Z, fb, ib, work, f, R, keep_residuals):
    """:func:`_batch` of a model with user features (:func:`_residuals_of_user`)."""
    slots, free, pos, par, view = _view(fb, ib)
    x, q, r, A = _scratch(work, ib)
    tab, w = _user_view(fb, ib)
    best, best_f = -1, np.inf
    for s in range(Z.shape[0]):
        _full(Z, s, free, par, view, x, q, slots)
        c = _residuals_of_user(fb, ib, x, q, pos, par, r, A, tab, w)
        best, best_f = _keep(c, s, f, R, r, keep_residuals, best, best_f)
    return best


@njit(**INLINE)
def _keep(c, s, f, R, r, keep_residuals, best, best_f):
    """Candidate s's cost c into f (NaN when not finite) and its residuals into R; the best row so far."""
    if np.isfinite(c):
        f[s] = c
        if c < best_f:
            best, best_f = s, c
    else:
        f[s] = np.nan
    if keep_residuals:
        R[s, :] = r
    return best, best_f


@njit(**JIT)
def jacobian(z, fb, ib, work, J):
    """The analytic Jacobian (m, nf) of the residuals at z, in the view's coordinates, into J."""
    slots, free, pos, par, view = _view(fb, ib)
    x, q, r, A = _scratch(work, ib)
    _full(z.reshape((1, z.size)), 0, free, par, view, x, q, slots)
    n, nf = ib[H_N], free.size
    dq = np.zeros((3, ib[H_NQX]))
    dT, dt = pos[ROW_DTEMP], pos[ROW_DTIME]
    tab, w = _user_view(fb, ib)
    nu = tab.shape[0]
    dA = np.zeros(9)
    a = np.zeros(3)
    if ib[H_MODE] == REFERENCE:
        ref = pos[ROW_REF:ROW_REF + 3]
        for j in range(n):
            forward_dq(q, pos[ROW_REF, j], pos[ROW_REF + 1, j], pos[ROW_REF + 2, j], dT[j], dt[j], dq)
            if nu > 0:
                a[0], a[1], a[2] = ref[0, j], ref[1, j], ref[2, j]
                _user_derivatives(q, tab, w, j, a, ref, dA, dq)
            for i in range(3):
                for c in range(nf):
                    J[3 * j + i, c] = -dq[i, slots[free[c]]] / fb[i] * view[1, c]
        return
    if nu == 0:
        _invert_all(forward_all, q, pos, ib[H_AFFINE] != 0, fb[4], ib[H_MAXIT], A)
    else:
        _invert_all_user(q, pos, fb[4], ib[H_MAXIT], A, tab, w)
    for j in range(n):
        a0, a1, a2 = A[0, j], A[1, j], A[2, j]
        norm = np.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
        # w solves (∂F/∂A)ᵀ w = A/‖A‖; then ∂e/∂x = −wᵀ ∂F/∂x.
        m = forward_dA(q, a0, a1, a2, dT[j], dt[j])
        forward_dq(q, a0, a1, a2, dT[j], dt[j], dq)
        if nu > 0:
            for k in range(9):
                dA[k] = m[k]
            a[0], a[1], a[2] = a0, a1, a2
            _user_derivatives(q, tab, w, j, a, A, dA, dq)
            m = (dA[0], dA[1], dA[2], dA[3], dA[4], dA[5], dA[6], dA[7], dA[8])
        fi = _inverse3(m)
        u0, u1, u2 = a0 / norm, a1 / norm, a2 / norm
        w0 = fi[0] * u0 + fi[3] * u1 + fi[6] * u2
        w1 = fi[1] * u0 + fi[4] * u1 + fi[7] * u2
        w2 = fi[2] * u0 + fi[5] * u1 + fi[8] * u2
        for c in range(nf):
            k = slots[free[c]]
            J[j, c] = -(w0 * dq[0, k] + w1 * dq[1, k] + w2 * dq[2, k]) * view[1, c]
    for k in range(ib[H_NG]):
        for c in range(nf):
            J[n + k, c] = par[2 + k, free[c]] * view[1, c]
