"""Compiled integration of a gyroscope's rate over the motions between rests (numba, cached on disk).

The calibrated rate of sample i is affine in the raw rate w_i and the specific force f_i (g),

    ω_i = M·w_i + c + D·f_i,

with M, c, D the 21 numbers :mod:`optcal.core.gyro.model` derives from the parameters (``AFFINE`` =
M row-major, c, D row-major). Over one motion the body's attitude relative to its attitude at the first
sample obeys q̇ = ½ q ⊗ (0, ω) (Hamilton quaternions, body rates; Tedaldi, Pretto and Menegatti, ICRA
2014, §IV-B). It is integrated on the sample times with the classical fourth-order Runge-Kutta step, ω
taken linear between samples (ω_i at the start of a step, their mean at its middle, ω_{i+1} at its end),
and the quaternion renormalised after each step, as imu_tk's ``quatIntegrationStepRK4`` does. The
gravity direction u0 of the rest before the motion, expressed in the body frame at the end, is R(q)ᵀ·u0;
its two components along the tangent basis (e1, e2) of the measured direction u1 at the rest after the
motion are the motion's residuals (each an angle in rad to first order).

:func:`rotate_batch` evaluates a population of candidates (S, 21) over every motion in one call;
:func:`rotate_jacobian` propagates the tangents of the first ``n_dir`` affine numbers alongside one
candidate (forward mode: exact derivatives of the discrete integrator, not finite differences).
"""

from __future__ import annotations

import numpy as np
from numba import njit

N_AFFINE = 21  # M (9), c (3), D (9)
JIT = dict(cache=True, error_model="numpy")


@njit(**JIT, inline="always")
def _qmul_rate(q0, q1, q2, q3, wx, wy, wz):
    """½ q ⊗ (0, w): the quaternion derivative for body rate w."""
    return (0.5 * (-q1 * wx - q2 * wy - q3 * wz),
            0.5 * (q0 * wx + q2 * wz - q3 * wy),
            0.5 * (q0 * wy + q3 * wx - q1 * wz),
            0.5 * (q0 * wz + q1 * wy - q2 * wx))


@njit(**JIT, inline="always")
def _rate(P, w, f, i):
    wx = P[0] * w[i, 0] + P[1] * w[i, 1] + P[2] * w[i, 2] + P[9] + P[12] * f[i, 0] + P[13] * f[i, 1] + P[14] * f[i, 2]
    wy = P[3] * w[i, 0] + P[4] * w[i, 1] + P[5] * w[i, 2] + P[10] + P[15] * f[i, 0] + P[16] * f[i, 1] + P[17] * f[i, 2]
    wz = P[6] * w[i, 0] + P[7] * w[i, 1] + P[8] * w[i, 2] + P[11] + P[18] * f[i, 0] + P[19] * f[i, 1] + P[20] * f[i, 2]
    return wx, wy, wz


@njit(**JIT, inline="always")
def _rotate_back(q0, q1, q2, q3, u):
    """R(q)ᵀ·u: a vector fixed in the frame of the motion's start, in the body frame at its end."""
    x, y, z = u[0], u[1], u[2]
    # rotation by the conjugate quaternion: u − 2 q0 (v × u) + 2 v × (v × u), v = (q1, q2, q3)
    tx = 2.0 * (q2 * z - q3 * y)
    ty = 2.0 * (q3 * x - q1 * z)
    tz = 2.0 * (q1 * y - q2 * x)
    return (x - q0 * tx + (q2 * tz - q3 * ty),
            y - q0 * ty + (q3 * tx - q1 * tz),
            z - q0 * tz + (q1 * ty - q2 * tx))


@njit(**JIT)
def _integrate(P, w, f, t, s0, s1):
    """Attitude quaternion at sample s1 relative to sample s0 for the affine numbers P."""
    q0, q1, q2, q3 = 1.0, 0.0, 0.0, 0.0
    ax, ay, az = _rate(P, w, f, s0)
    for i in range(s0, s1):
        h = t[i + 1] - t[i]
        bx, by, bz = _rate(P, w, f, i + 1)
        mx, my, mz = 0.5 * (ax + bx), 0.5 * (ay + by), 0.5 * (az + bz)
        k10, k11, k12, k13 = _qmul_rate(q0, q1, q2, q3, ax, ay, az)
        a = 0.5 * h
        k20, k21, k22, k23 = _qmul_rate(q0 + a * k10, q1 + a * k11, q2 + a * k12, q3 + a * k13, mx, my, mz)
        k30, k31, k32, k33 = _qmul_rate(q0 + a * k20, q1 + a * k21, q2 + a * k22, q3 + a * k23, mx, my, mz)
        k40, k41, k42, k43 = _qmul_rate(q0 + h * k30, q1 + h * k31, q2 + h * k32, q3 + h * k33, bx, by, bz)
        s = h / 6.0
        q0 += s * (k10 + 2.0 * k20 + 2.0 * k30 + k40)
        q1 += s * (k11 + 2.0 * k21 + 2.0 * k31 + k41)
        q2 += s * (k12 + 2.0 * k22 + 2.0 * k32 + k42)
        q3 += s * (k13 + 2.0 * k23 + 2.0 * k33 + k43)
        n = np.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
        q0, q1, q2, q3 = q0 / n, q1 / n, q2 / n, q3 / n
        ax, ay, az = bx, by, bz
    return q0, q1, q2, q3


@njit(**JIT)
def rotate_batch(P, w, f, t, start, stop, u0, E, out):
    """Residuals ``out`` (S, m, 2) of candidates P (S, 21) on motions k = start[k] … stop[k] (sample
    indices into w, f, t), gravity directions u0 (m, 3) and tangent bases E (m, 2, 3)."""
    for s in range(P.shape[0]):
        p = P[s]
        for k in range(start.shape[0]):
            q0, q1, q2, q3 = _integrate(p, w, f, t, start[k], stop[k])
            vx, vy, vz = _rotate_back(q0, q1, q2, q3, u0[k])
            for j in range(2):
                out[s, k, j] = E[k, j, 0] * vx + E[k, j, 1] * vy + E[k, j, 2] * vz


@njit(**JIT, inline="always")
def _drate(d, w, f, i, out):
    """∂ω_i/∂P_d (3 values) for affine number d: M's cells scale w, c's are 1, D's scale f."""
    out[0] = 0.0
    out[1] = 0.0
    out[2] = 0.0
    if d < 9:
        out[d // 3] = w[i, d % 3]
    elif d < 12:
        out[d - 9] = 1.0
    else:
        out[(d - 12) // 3] = f[i, (d - 12) % 3]


@njit(**JIT)
def rotate_jacobian(P, n_dir, w, f, t, start, stop, u0, E, out):
    """Residuals' derivatives ``out`` (m, 2, n_dir) with respect to the first ``n_dir`` affine numbers of
    one candidate P (21,): the discrete integrator of :func:`rotate_batch` differentiated in forward mode
    (each tangent propagated through every Runge-Kutta stage and the renormalisation)."""
    dq = np.empty((n_dir, 4))
    da = np.empty(3)
    db = np.empty(3)
    for k in range(start.shape[0]):
        s0, s1 = start[k], stop[k]
        q = np.array([1.0, 0.0, 0.0, 0.0])
        dq[:] = 0.0
        ax, ay, az = _rate(P, w, f, s0)
        for i in range(s0, s1):
            h = t[i + 1] - t[i]
            a = 0.5 * h
            bx, by, bz = _rate(P, w, f, i + 1)
            mx, my, mz = 0.5 * (ax + bx), 0.5 * (ay + by), 0.5 * (az + bz)
            k1 = _qmul_rate(q[0], q[1], q[2], q[3], ax, ay, az)
            y2 = (q[0] + a * k1[0], q[1] + a * k1[1], q[2] + a * k1[2], q[3] + a * k1[3])
            k2 = _qmul_rate(y2[0], y2[1], y2[2], y2[3], mx, my, mz)
            y3 = (q[0] + a * k2[0], q[1] + a * k2[1], q[2] + a * k2[2], q[3] + a * k2[3])
            k3 = _qmul_rate(y3[0], y3[1], y3[2], y3[3], mx, my, mz)
            y4 = (q[0] + h * k3[0], q[1] + h * k3[1], q[2] + h * k3[2], q[3] + h * k3[3])
            k4 = _qmul_rate(y4[0], y4[1], y4[2], y4[3], bx, by, bz)
            s = h / 6.0
            qn0 = q[0] + s * (k1[0] + 2.0 * k2[0] + 2.0 * k3[0] + k4[0])
            qn1 = q[1] + s * (k1[1] + 2.0 * k2[1] + 2.0 * k3[1] + k4[1])
            qn2 = q[2] + s * (k1[2] + 2.0 * k2[2] + 2.0 * k3[2] + k4[2])
            qn3 = q[3] + s * (k1[3] + 2.0 * k2[3] + 2.0 * k3[3] + k4[3])
            nrm = np.sqrt(qn0 * qn0 + qn1 * qn1 + qn2 * qn2 + qn3 * qn3)
            for d in range(n_dir):
                _drate(d, w, f, i, da)
                _drate(d, w, f, i + 1, db)
                dmx, dmy, dmz = 0.5 * (da[0] + db[0]), 0.5 * (da[1] + db[1]), 0.5 * (da[2] + db[2])
                e = dq[d]
                # d(½ y ⊗ ω) = ½ dy ⊗ ω + ½ y ⊗ dω (the product is bilinear)
                u = _qmul_rate(e[0], e[1], e[2], e[3], ax, ay, az)
                v = _qmul_rate(q[0], q[1], q[2], q[3], da[0], da[1], da[2])
                d1 = (u[0] + v[0], u[1] + v[1], u[2] + v[2], u[3] + v[3])
                z2 = (e[0] + a * d1[0], e[1] + a * d1[1], e[2] + a * d1[2], e[3] + a * d1[3])
                u = _qmul_rate(z2[0], z2[1], z2[2], z2[3], mx, my, mz)
                v = _qmul_rate(y2[0], y2[1], y2[2], y2[3], dmx, dmy, dmz)
                d2 = (u[0] + v[0], u[1] + v[1], u[2] + v[2], u[3] + v[3])
                z3 = (e[0] + a * d2[0], e[1] + a * d2[1], e[2] + a * d2[2], e[3] + a * d2[3])
                u = _qmul_rate(z3[0], z3[1], z3[2], z3[3], mx, my, mz)
                v = _qmul_rate(y3[0], y3[1], y3[2], y3[3], dmx, dmy, dmz)
                d3 = (u[0] + v[0], u[1] + v[1], u[2] + v[2], u[3] + v[3])
                z4 = (e[0] + h * d3[0], e[1] + h * d3[1], e[2] + h * d3[2], e[3] + h * d3[3])
                u = _qmul_rate(z4[0], z4[1], z4[2], z4[3], bx, by, bz)
                v = _qmul_rate(y4[0], y4[1], y4[2], y4[3], db[0], db[1], db[2])
                d4 = (u[0] + v[0], u[1] + v[1], u[2] + v[2], u[3] + v[3])
                g0 = e[0] + s * (d1[0] + 2.0 * d2[0] + 2.0 * d3[0] + d4[0])
                g1 = e[1] + s * (d1[1] + 2.0 * d2[1] + 2.0 * d3[1] + d4[1])
                g2 = e[2] + s * (d1[2] + 2.0 * d2[2] + 2.0 * d3[2] + d4[2])
                g3 = e[3] + s * (d1[3] + 2.0 * d2[3] + 2.0 * d3[3] + d4[3])
                # renormalisation: d(q/|q|) = (dq − q̂ (q̂·dq)) / |q|
                dot = (qn0 * g0 + qn1 * g1 + qn2 * g2 + qn3 * g3) / (nrm * nrm)
                e[0] = (g0 - qn0 * dot) / nrm
                e[1] = (g1 - qn1 * dot) / nrm
                e[2] = (g2 - qn2 * dot) / nrm
                e[3] = (g3 - qn3 * dot) / nrm
            q[0], q[1], q[2], q[3] = qn0 / nrm, qn1 / nrm, qn2 / nrm, qn3 / nrm
            ax, ay, az = bx, by, bz
        # derivative of R(q)ᵀ·u0 along each tangent: the map is u0 plus a quadratic form in q, so the
        # central difference Q(q + e) − Q(q − e) is exactly twice the derivative (polarisation)
        for d in range(n_dir):
            e = dq[d]
            px, py, pz = _rotate_back(q[0] + e[0], q[1] + e[1], q[2] + e[2], q[3] + e[3], u0[k])
            mxx, myy, mzz = _rotate_back(q[0] - e[0], q[1] - e[1], q[2] - e[2], q[3] - e[3], u0[k])
            gx, gy, gz = 0.5 * (px - mxx), 0.5 * (py - myy), 0.5 * (pz - mzz)
            for j in range(2):
                out[k, j, d] = E[k, j, 0] * gx + E[k, j, 1] * gy + E[k, j, 2] * gz
