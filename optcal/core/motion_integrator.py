"""The gyroscope's integration over the motions in NumPy: the residuals and their exact Jacobian for one or a
few candidates, without loading numba (whose start costs most of a second per process, more than the tens of
evaluations of a least-squares fit need). The same discrete integrator as :mod:`optcal.core.kernels.gyro`, to
rounding (``tests/test_gyro_integrate.py``).

One classical Runge-Kutta step of q̇ = ½ q ⊗ (0, ω) with ω linear between samples (ω_a at the start, ω_b at
the end, their mean at the middle) is q ↦ q ⊗ μ: the ODE is linear in q, so every stage is q times a
polynomial in the pure quaternions A = (0, ω_a/2), B = (0, s/4), C = (0, ω_b/2), s = ω_a + ω_b, and with
B ⊗ B = −|s|²/16 the step collapses to (h the step length)

    μ₀ = 1 − h²|s|²/32 + h⁴|s|²(ω_a·ω_b)/1536
    μ⃗ = h s/4 + h²(ω_a × ω_b)/24 − h³|s|² s/384 − h⁴|s|²(ω_a × ω_b)/1536

(for ω_a = ω_b = ω: the Taylor series of cos(h|ω|/2) and sin(h|ω|/2)·ω̂ to fourth order). Renormalising
after each step, as imu_tk's ``quatIntegrationStepRK4`` does, divides by |μ| and turns nothing, so a
motion's attitude is the ordered product Q = μ̂₁ ⊗ μ̂₂ ⊗ … ⊗ μ̂_n of the normalised steps μ̂ = μ/|μ|; the
products of every motion are formed together, level by level (a Hillis-Steele scan over the steps,
restarted at each motion).

The Jacobian is reverse mode on that product. A residual r = e·v(Q), v(Q) = Q* ⊗ (0, u0) ⊗ Q / |Q|², has the
gradient g = −2 ((0, u0) ⊗ Q ⊗ (0, e) + r Q)/|Q|² in the four numbers of Q, and through Q = L_{i−1} ⊗ μ_i ⊗
S_{i+1} the gradient λ_i = L*_{i−1} ⊗ g ⊗ S*_{i+1} in those of μ̂_i (y·(p ⊗ x ⊗ s) = (p* ⊗ y ⊗ s*)·x); with
the inclusive prefix L_i = L_{i−1} ⊗ μ̂_i, S*_{i+1} = Q* ⊗ L_i / |L_i|², so the one scan gives every λ_i, and
since r does not change when one factor is scaled, the gradient in μ_i itself is λ_i/|μ_i|. That
times ∂μ_i/∂ω_a and ∂μ_i/∂ω_b (the closed form above, differentiated), times the rate's derivatives in the
affine numbers (ω = M·w + c + D·f), summed over the motion's steps, is the Jacobian row.

Arrays are component first (a quaternion array is (4, …, n), a vector array (3, …, n)): each component is
then one contiguous row, and a product is sixteen multiplications of whole rows. Gathers along the steps use
``np.take``, which keeps that layout (fancy indexing of the last axis would put it first).
"""

from __future__ import annotations

import numpy as np

IDENTITY = np.array([1.0, 0.0, 0.0, 0.0])
CHUNK = 1 << 18  # numbers per row of a population's arrays (2 MiB)
BLOCK = 16  # steps per block of the scan (MotionIntegrator)


def qmul(p, q) -> np.ndarray:
    """Hamilton products p ⊗ q of quaternions (4, ...), scalar first, broadcast."""
    p0, p1, p2, p3 = p
    q0, q1, q2, q3 = q
    return np.array([p0 * q0 - p1 * q1 - p2 * q2 - p3 * q3,
                     p0 * q1 + p1 * q0 + p2 * q3 - p3 * q2,
                     p0 * q2 - p1 * q3 + p2 * q0 + p3 * q1,
                     p0 * q3 + p1 * q2 - p2 * q1 + p3 * q0])


def conj(q) -> np.ndarray:
    return np.array([q[0], -q[1], -q[2], -q[3]])


def cross(a, b) -> np.ndarray:
    """a × b of vectors (3, ...), broadcast."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def dot(a, b) -> np.ndarray:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def pure(v) -> np.ndarray:
    """The pure quaternions (0, v) of vectors v (3, ...)."""
    return np.concatenate([np.zeros((1,) + v.shape[1:]), v])


def step_quaternions(wa, wb, h) -> np.ndarray:
    """μ (4, ..., n) of Runge-Kutta steps of length h (n,) s between rates wa and wb (3, ..., n) rad/s."""
    s = wa + wb
    s2 = dot(s, s)
    h2 = h * h
    h4 = h2 * h2
    # written into one array row by row, the same numbers as stacking mu0 and the vector part (which costs a
    # third of the time on a population's steps)
    out = np.empty((4,) + s2.shape)
    np.multiply(h4 * s2, dot(wa, wb), out=out[0])
    out[0] /= 1536.0
    out[0] += 1.0 - h2 * s2 / 32.0
    a = h / 4.0 - h2 * h * s2 / 384.0
    c = h2 / 24.0 - h4 * s2 / 1536.0
    for i, (j, k) in enumerate(((1, 2), (2, 0), (0, 1))):  # (wa × wb)_i = wa_j wb_k − wa_k wb_j
        np.multiply(a, s[i], out=out[1 + i])
        out[1 + i] += c * (wa[j] * wb[k] - wa[k] * wb[j])
    return out


def log_vertex(ks: np.ndarray, costs: np.ndarray) -> float:
    """The scale searches' last step (:func:`optcal.core.gyro.problem.common_scale`,
    :func:`optcal.core.recording.attitude.gyro_scale`): the vertex of the parabola in log k through the best of the
    candidates ``ks`` (costs ``costs``) and its two neighbours, kept within them; the best candidate itself at an
    end of the grid or where the parabola opens downward."""
    j = int(np.argmin(costs))
    if 0 < j < len(ks) - 1:
        x, y = np.log(ks[j - 1:j + 2]), costs[j - 1:j + 2]
        den = (x[0] - x[1]) * (x[0] - x[2]) * (x[1] - x[2])
        A = (x[2] * (y[1] - y[0]) + x[1] * (y[0] - y[2]) + x[0] * (y[2] - y[1])) / den
        B = (x[2] ** 2 * (y[0] - y[1]) + x[1] ** 2 * (y[2] - y[0]) + x[0] ** 2 * (y[1] - y[2])) / den
        if A > 0:
            return float(np.exp(np.clip(-B / (2 * A), x[0], x[2])))
    return float(ks[j])


def rotate_back(Q, u) -> np.ndarray:
    """R(Q)ᵀ·u (3, ...) for unit quaternions Q (4, ...): u, fixed at a motion's start, in the body frame at its
    end (u − q₀ t + v × t with t = 2 v × u, v = (q₁, q₂, q₃), as the kernel's ``_rotate_back``)."""
    t = 2.0 * cross(Q[1:], u)
    return u - Q[0] * t + cross(Q[1:], t)


class MotionIntegrator:
    """The steps of every motion k (samples ``start[k]`` … ``stop[k]`` of times ``t``) on a grid of blocks.

    Each motion's steps fill blocks of ``BLOCK`` consecutive steps, the last block padded with steps of zero
    length (μ = 1 exactly, whatever the rate); the grid is (BLOCK, blocks), so that step c of every block is
    one contiguous row. The products within the blocks are formed column by column (BLOCK − 1 products of
    rows), the blocks' products by a Hillis-Steele scan restarted at each motion (a handful of levels over
    the blocks rather than a dozen over the steps), and each step's prefix is its block's exclusive prefix
    times its place in the block."""

    def __init__(self, t: np.ndarray, start: np.ndarray, stop: np.ndarray):
        start, stop = np.asarray(start, np.intp), np.asarray(stop, np.intp)
        steps = stop - start
        self.n_motions = m = len(steps)
        nblocks = -(-steps // BLOCK)
        self.first_block = np.concatenate([[0], np.cumsum(nblocks)[:-1]]).astype(np.intp)
        self.last_block = self.first_block + nblocks - 1
        self.block_motion = np.repeat(np.arange(m), nblocks)
        brank = np.arange(int(nblocks.sum())) - self.first_block[self.block_motion]  # block's place in its motion
        # every grid cell's step: its motion's sample at the step's start (the motion's last at the padding)
        place = brank[None, :] * BLOCK + np.arange(BLOCK)[:, None]  # (BLOCK, blocks): step's place in its motion
        real = place < steps[self.block_motion][None, :]
        ia = np.where(real, start[self.block_motion][None, :] + place, stop[self.block_motion][None, :])
        self.h = np.where(real, np.diff(np.asarray(t, float), append=np.inf)[ia], 0.0)
        # the samples the steps touch, and each cell's two columns among them (padding: its motion's last)
        self.samples, inverse = np.unique(np.concatenate([ia.ravel(), np.where(real, ia + 1, ia).ravel()]),
                                          return_inverse=True)
        self.col_a, self.col_b = inverse[: ia.size].reshape(ia.shape), inverse[ia.size:].reshape(ia.shape)
        # scan level d multiplies block j by the product ending d blocks earlier when that is in its motion
        self.levels = []
        d = 1
        while d <= brank.max(initial=0):
            self.levels.append((d, brank[d:] >= d))
            d *= 2

    def _blocks(self, mu: np.ndarray):
        """Products within the blocks X (4, ..., BLOCK, blocks) and the blocks' inclusive products T (4, ...,
        blocks) within each motion."""
        X = mu.copy()
        for c in range(1, BLOCK):
            X[..., c, :] = qmul(X[..., c - 1, :], X[..., c, :])
        T = X[..., BLOCK - 1, :].copy()
        for d, inside in self.levels:
            T[..., d:] = np.where(inside, qmul(T[..., :-d], T[..., d:]), T[..., d:])
        return X, T

    def prefix(self, mu: np.ndarray):
        """Inclusive products L = μ_first ⊗ … ⊗ μ_i within each motion for every cell of the grid (4, ...,
        BLOCK, blocks), the exclusive ones (the same without μ_i), and each motion's product (4, ..., m)."""
        X, T = self._blocks(mu)
        before = np.empty_like(T)  # the product of the motion's earlier blocks
        before[..., 1:] = T[..., :-1]
        before[..., self.first_block] = IDENTITY.reshape((4,) + (1,) * (T.ndim - 1))
        L = qmul(before[..., None, :], X)
        excl = np.concatenate([before[..., None, :], L[..., :-1, :]], axis=-2)
        return L, excl, T[..., self.last_block]

    def steps_of(self, omega: np.ndarray) -> np.ndarray:
        """μ (4, ..., BLOCK, blocks) for calibrated rates ``omega`` (3, ..., len(samples)) at ``samples``."""
        return step_quaternions(np.take(omega, self.col_a, axis=-1), np.take(omega, self.col_b, axis=-1), self.h)

    def attitudes(self, omega: np.ndarray) -> np.ndarray:
        """Each motion's attitude change Q (4, ..., m), unit quaternions, for rates as :meth:`steps_of`."""
        mu = self.steps_of(omega)
        _, T = self._blocks(mu / np.sqrt(np.sum(mu * mu, axis=0)))
        Q = T[..., self.last_block]
        return Q / np.sqrt(np.sum(Q * Q, axis=0))


class NumpyRotations:
    """:mod:`optcal.core.kernels.gyro`'s ``rotate_batch`` and ``rotate_jacobian`` in NumPy, for data ``W``, ``F``
    (n, 3), times ``t``, motions ``start``–``stop``, directions ``u0`` (m, 3) and tangent bases ``E`` (m, 2, 3)."""

    def __init__(self, W, F, t, start, stop, u0, E):
        self.integrator = it = MotionIntegrator(t, start, stop)
        self.w = np.ascontiguousarray(np.asarray(W, float)[it.samples].T)  # (3, samples)
        self.f = np.ascontiguousarray(np.asarray(F, float)[it.samples].T)
        self.u0 = np.ascontiguousarray(np.asarray(u0, float).T)  # (3, m)
        self.E = np.ascontiguousarray(np.asarray(E, float).transpose(1, 2, 0))  # (2, 3, m)
        # what the rate's derivatives multiply: ∂ω_p/∂M_pq = w_q, ∂ω_p/∂c_p = 1, ∂ω_p/∂D_pq = f_q
        self.features = np.concatenate([self.w, np.ones((1, self.w.shape[1])), self.f])

    def rates(self, P: np.ndarray) -> np.ndarray:
        """Calibrated rates ω = M·w + c + D·f (3, S, samples) rad/s of affine numbers P (S, 21)."""
        M, c, D = P[:, :9].reshape(-1, 3, 3), P[:, 9:12], P[:, 12:21].reshape(-1, 3, 3)
        return (np.einsum("spq,qn->psn", M, self.w) + c.T[:, :, None]
                + np.einsum("spq,qn->psn", D, self.f))

    def rotate_batch(self, P: np.ndarray) -> np.ndarray:
        """Residuals (S, m, 2) in rad of candidates' affine numbers P (S, 21)."""
        P = np.atleast_2d(np.asarray(P, float))
        # candidates a few at a time: a population of hundreds over 20,000 steps would hold gigabytes at once
        c = max(1, CHUNK // max(1, self.integrator.h.size))
        out = np.empty((len(P), self.integrator.n_motions, 2))
        for a in range(0, len(P), c):
            v = rotate_back(self.integrator.attitudes(self.rates(P[a:a + c])), self.u0[:, None])  # (3, S, m)
            out[a:a + c] = np.einsum("ism,jim->smj", v, self.E)
        return out

    def rotate_jacobian(self, P: np.ndarray, n_dir: int) -> np.ndarray:
        """Derivatives (m, 2, n_dir) of the residuals of one candidate P (21,) with respect to its first
        ``n_dir`` affine numbers (M row-major, then c, then D row-major)."""
        it = self.integrator
        omega = self.rates(np.asarray(P, float)[None])[:, 0]
        wa, wb = np.take(omega, it.col_a, axis=-1), np.take(omega, it.col_b, axis=-1)  # (3, BLOCK, blocks)
        mu = step_quaternions(wa, wb, it.h)
        size = np.sqrt(np.sum(mu * mu, axis=0))
        L, Lprev, Q = it.prefix(mu / size)  # Q (4, m): unit to rounding
        n2 = np.sum(Q * Q, axis=0)
        v = rotate_back(Q / np.sqrt(n2), self.u0)
        r = np.einsum("im,jim->jm", v, self.E)  # (2, m)
        # each residual's gradient in Q's four numbers, then in each step's (module docstring)
        g = -2.0 * (qmul(qmul(pure(self.u0), Q)[:, None], pure(self.E.transpose(1, 0, 2))) + r * Q[:, None]) / n2
        G = np.take(qmul(g, conj(Q)[:, None]), it.block_motion, axis=-1)[:, :, None]  # (4, 2, 1, blocks): g ⊗ Q*
        lam = qmul(qmul(conj(Lprev)[:, None], G), L[:, None]) / (np.sum(L * L, axis=0) * size)  # (4, 2, BLOCK, blocks)
        da, db = self._step_gradients(lam, wa[:, None], wb[:, None], it.h)  # (3, 2, BLOCK, blocks) each
        k = 3 if n_dir <= 9 else 4 if n_dir <= 12 else 7
        fa, fb = np.take(self.features[:k], it.col_a, axis=-1), np.take(self.features[:k], it.col_b, axis=-1)
        per_block = np.einsum("pjcb,qcb->pjqb", da, fa) + np.einsum("pjcb,qcb->pjqb", db, fb)  # (3, 2, k, blocks)
        block = np.add.reduceat(per_block, it.first_block, axis=-1).transpose(3, 1, 0, 2)  # (m, 2, 3, k)
        m = it.n_motions
        parts = [block[..., :3].reshape(m, 2, 9)]
        if k > 3:
            parts.append(block[..., 3])
        if k > 4:
            parts.append(block[..., 4:].reshape(m, 2, 9))
        return np.concatenate(parts, axis=2)[..., :n_dir]

    @staticmethod
    def _step_gradients(lam, wa, wb, h):
        """λ·∂μ/∂ω_a and λ·∂μ/∂ω_b (3, j, ...) for gradients λ (4, j, ...) in the steps' quaternions, rates wa and
        wb (3, 1, ...) broadcasting against them: the closed
        form of the module docstring differentiated. With μ⃗ = α s + β (ω_a × ω_b), α = h/4 − h³|s|²/384 and
        β = h²/24 − h⁴|s|²/1536: (∂μ⃗/∂ω_a)ᵀλ = α λ − ((h³/192)(s·λ) + (h⁴/768)((ω_a × ω_b)·λ)) s + β ω_b × λ
        (λ × ω_a for ω_b); ∂μ₀/∂ω_a = −h²s/16 + h⁴(2 (ω_a·ω_b) s + |s|² ω_b)/1536 (ω_a for ω_b)."""
        s = wa + wb
        s2 = dot(s, s)
        x = cross(wa, wb)
        h2 = h * h
        h3 = h2 * h
        h4 = h2 * h2
        l0, lv = lam[0], lam[1:]  # (j, ...), (3, j, ...)
        c0 = (-h2 / 16.0 + h4 * dot(wa, wb) / 768.0) * s
        e = h4 * s2 / 1536.0
        alpha = h / 4.0 - h3 * s2 / 384.0
        beta = h2 / 24.0 - h4 * s2 / 1536.0
        common = alpha * lv - ((h3 / 192.0) * dot(s, lv) + (h4 / 768.0) * dot(x, lv)) * s + l0 * c0
        da = common + beta * cross(wb, lv) + l0 * (e * wb)
        db = common + beta * cross(lv, wa) + l0 * (e * wa)
        return da, db
