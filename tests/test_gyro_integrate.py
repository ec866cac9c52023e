"""optcal.core.motion_integrator, the gyroscope's integration in NumPy (the least-squares fits of ``optcal imu``),
against the compiled integrator of optcal.core.kernels.gyro: the same residuals to rounding, the same exact
Jacobian, the closed-form Runge-Kutta step against the four stages written out, and the fit itself."""

from __future__ import annotations

import numpy as np
import pytest

from optcal.core.errors import InputError
from optcal.core.gyro import GyroProblem, draw_truth, get_gyro_model, simulate_imu
from optcal.core.kernels import gyro as kernel
from optcal.core.motion_integrator import BLOCK, CHUNK, NumpyRotations, qmul, step_quaternions
from optcal.solvers.registry import get

SCALE = 1000.0


def _rk4_step(wa, wb, h):
    """One classical Runge-Kutta step of q̇ = ½ q ⊗ (0, ω) from q = 1, ω linear between wa and wb (the
    stages of imu_tk's quatIntegrationStepRK4 written out; no renormalisation)."""
    def f(q, w):
        return 0.5 * qmul(q, np.concatenate([[0.0], w]))

    q = np.array([1.0, 0.0, 0.0, 0.0])
    wm = 0.5 * (wa + wb)
    k1 = f(q, wa)
    k2 = f(q + 0.5 * h * k1, wm)
    k3 = f(q + 0.5 * h * k2, wm)
    k4 = f(q + h * k3, wb)
    return q + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)


def test_closed_form_step_is_the_runge_kutta_step():
    rng = np.random.default_rng(0)
    for _ in range(200):
        wa, wb = rng.normal(0, 3.0, 3), rng.normal(0, 3.0, 3)  # rad/s, up to ~10 rad/s
        h = rng.uniform(1e-3, 0.05)
        np.testing.assert_allclose(step_quaternions(wa[:, None], wb[:, None], np.array([h]))[:, 0],
                                   _rk4_step(wa, wb, h), rtol=0, atol=2e-16)


def _problem_data(g_sensitivity: bool, seed: int, **kw):
    rng = np.random.default_rng(seed)
    model = get_gyro_model(g_sensitivity)
    x = draw_truth(model, rng, SCALE)
    return simulate_imu(model, x, rng=rng, **kw).data


def _both(data, P, n_dir):
    d = data
    ref = np.empty((len(P), d.n_motions, 2))
    kernel.rotate_batch(np.ascontiguousarray(P), d.W, d.F, d.t, d.start, d.stop, d.u0, d.E, ref)
    Jref = np.empty((d.n_motions, 2, n_dir))
    kernel.rotate_jacobian(np.ascontiguousarray(P[0]), n_dir, d.W, d.F, d.t, d.start, d.stop, d.u0, d.E, Jref)
    rot = NumpyRotations(d.W, d.F, d.t, d.start, d.stop, d.u0, d.E)
    return ref, Jref, rot.rotate_batch(P), rot.rotate_jacobian(P[0], n_dir)


@pytest.mark.parametrize("g_sensitivity, bias", [(False, "rests"), (False, "fit"), (True, "fit")])
def test_same_residuals_and_jacobian_as_the_kernel(g_sensitivity, bias):
    """Five candidates around the start, every affine number a direction: residuals to 1e-14 rad, the
    Jacobian to 1e-11 of each column's largest entry."""
    data = _problem_data(g_sensitivity, 7, poses=24)
    p = GyroProblem(data, g_sensitivity=g_sensitivity, bias=bias, scale=SCALE)
    rng = np.random.default_rng(1)
    X = p.centre + 0.2 * p.halfwidth * rng.standard_normal((5, p.model.n_params))
    P = p.model.affine(X)
    n_dir = 21 if g_sensitivity else 12 if bias == "fit" else 9
    ref, Jref, R, J = _both(p.data, P, n_dir)
    assert np.max(np.abs(R - ref)) < 1e-14
    assert np.max(np.abs(J - Jref) / np.abs(Jref).max(axis=(0, 1))) < 1e-11


@pytest.mark.parametrize("steps", [[1, 2, 3], [BLOCK - 1, BLOCK, BLOCK + 1], [5 * BLOCK + 3, 1, 40 * BLOCK]])
def test_motions_of_every_length_and_uneven_steps(steps):
    """Motions shorter than a block, of one block and a step either side, and long ones beside one-step ones,
    on jittered sample times (the padding of the blocks must change nothing)."""
    rng = np.random.default_rng(len(steps) + sum(steps))
    rest = 30
    n = sum(steps) + rest * (len(steps) + 1)
    t = np.cumsum(rng.uniform(0.005, 0.015, n))
    W = rng.normal(0, 2.0, (n, 3))  # rad/s
    F = rng.normal(0, 1.0, (n, 3))
    start, a = [], rest
    for s in steps:
        start.append(a - 1)
        a += s + rest
    start = np.array(start)
    stop = start + np.array(steps)
    u0 = rng.normal(size=(len(steps), 3))
    u0 /= np.linalg.norm(u0, axis=1, keepdims=True)
    E = rng.normal(size=(len(steps), 2, 3))

    class Data:
        pass

    d = Data()
    d.W, d.F, d.t, d.start, d.stop, d.u0, d.E, d.n_motions = W, F, t, start, stop, u0, E, len(steps)
    P = np.concatenate([np.eye(3).ravel(), [0.01, -0.02, 0.03], 1e-3 * rng.normal(size=9)])[None] \
        + 1e-2 * rng.normal(size=(3, 21))
    ref, Jref, R, J = _both(d, P, 21)
    assert np.max(np.abs(R - ref)) < 1e-13
    assert np.max(np.abs(J - Jref) / np.abs(Jref).max(axis=(0, 1))) < 1e-11


def test_a_population_larger_than_a_chunk_and_absurd_rates():
    """A population is integrated a few candidates at a time, each as alone; rates of 1e10 rad/s (the
    common-scale search's smallest scale on raw counts) stay finite, as the kernel's, which renormalises
    at every step."""
    data = _problem_data(False, 3, poses=24)
    p = GyroProblem(data, bias="rests", scale=SCALE, backend="numpy")
    X = p.centre + 0.1 * p.halfwidth * np.random.default_rng(2).standard_normal((120, p.model.n_params))
    rot = p._rotations
    many = rot.rotate_batch(p.model.affine(X))
    assert len(X) > CHUNK // rot.integrator.h.size  # more than one chunk
    np.testing.assert_allclose(many[97], rot.rotate_batch(p.model.affine(X[97:98]))[0], rtol=0, atol=1e-15)
    huge = p.centre.copy()
    huge[:3] = 1e-6  # 1e-6 output units per rad/s: every rate a million times too large
    assert np.all(np.isfinite(rot.rotate_batch(p.model.affine(huge[None]))))


def test_problem_backends_agree_and_fit_the_same():
    """GyroProblem with ``backend="numpy"``: the residuals and Jacobian of the compiled backend, and the
    Levenberg-Marquardt fit ends at the same parameters to 1e-8 of their standard errors."""
    from optcal.core import analysis

    data = _problem_data(False, 11, poses=36)
    fits = {}
    for backend in ("kernel", "numpy"):
        p = GyroProblem(data, bias="fit", scale=SCALE, backend=backend)
        res = get("lm").solve(p, rng=0)
        fits[backend] = (p, res)
    (pk, rk), (pn, rn) = fits["kernel"], fits["numpy"]
    x = pk.centre * 1.001
    np.testing.assert_allclose(pn.residuals_full(x), pk.residuals_full(x), rtol=0, atol=1e-10)
    np.testing.assert_allclose(pn.jacobian_full(x), pk.jacobian_full(x), rtol=1e-10, atol=1e-12)
    sd, _ = analysis.crlb(pk, rk.x_full)
    assert np.max(np.abs(rn.x_full - rk.x_full) / sd) < 1e-8
    assert rn.fun == pytest.approx(rk.fun, rel=1e-12)


def test_unknown_backend_is_refused():
    data = _problem_data(False, 5, poses=24)
    with pytest.raises(InputError, match="`backend` 'gpu': use one of kernel, numpy"):
        GyroProblem(data, scale=SCALE, backend="gpu")
