"""optcal.solvers.lm, optcal's Levenberg-Marquardt in NumPy (the commands' default fit), against SciPy's MINPACK
(scipy-lm) on the accelerometer's and the gyroscope's problems, on a classic test function, and at its edges."""

import subprocess
import sys

import numpy as np
import pytest

import optcal
from optcal.app.fit import calibrate
from optcal.core.gyro import GyroProblem, draw_truth, get_gyro_model, simulate_imu
from optcal.solvers.lm import levenberg_marquardt
from optcal.solvers.registry import get


@pytest.mark.parametrize("model", ["nonlinear12", "linear9", "diag6", "seed15"])
def test_same_minimum_as_minpack_on_the_accelerometer(model):
    """Over 20 simulated recordings per model and scheme, the parameters agree with scipy-lm's to within
    1e-6 of their standard errors and the cost to 1e-9 relative; never higher than scipy-lm's beyond that.
    (seed15 has three unobservable directions: a gauge fixes them the same way for both.)"""
    worst = 0.0
    for seed in range(20):
        for scheme in ("24", "36"):
            data = optcal.simulate(model, None, seed, scheme=scheme, tilt_deg=1.0).data
            a = calibrate(data, model, solver="lm", force_weak=model == "seed15")
            b = calibrate(data, model, solver="scipy-lm", force_weak=model == "seed15")
            assert a.result.status > 0 and a.result.success
            assert a.fit.cost <= b.fit.cost * (1 + 1e-9)
            se = np.where(np.isfinite(b.stderr) & (b.stderr > 0), b.stderr, np.nan)
            worst = max(worst, float(np.nanmax(np.abs(a.x - b.x) / se)))
    assert worst < 1e-6


def test_same_minimum_as_minpack_on_the_gyroscope():
    rng = np.random.default_rng(3)
    model = get_gyro_model(False)
    x = draw_truth(model, rng, 1000.0)
    problem = GyroProblem(simulate_imu(model, x, poses=24, rng=rng).data, scale=1000.0)
    a = get("lm").solve(problem, rng=0, budget=2000)
    b = get("scipy-lm").solve(problem, rng=0, budget=2000)
    assert a.fun == pytest.approx(b.fun, rel=1e-9)
    np.testing.assert_allclose(a.x, b.x, rtol=1e-7, atol=1e-9)


def test_rosenbrock_from_the_classic_start():
    """Moré, Garbow & Hillstrom (1981) problem 1: r = (10(x2 − x1²), 1 − x1) from (−1.2, 1) to (1, 1)."""
    def fun(x):
        return np.array([10 * (x[1] - x[0] ** 2), 1 - x[0]])

    def jac(x):
        return np.array([[-20 * x[0], 10.0], [-1.0, 0.0]])

    x, status, nfev, _ = levenberg_marquardt(fun, jac, [-1.2, 1.0])
    np.testing.assert_allclose(x, [1.0, 1.0], atol=1e-12)
    assert status > 0 and nfev < 40


def test_budget_and_non_finite_trial_points():
    """Past ``max_nfev`` the status is 0 (SciPy's); a trial point with a non-finite residual is a rejected
    step, not an error."""
    def fun(x):
        return np.array([np.exp(x[0]) - 2.0, x[0] - 0.5]) if x[0] < 5 else np.array([np.nan, np.nan])

    def jac(x):
        return np.array([[np.exp(x[0])], [1.0]])

    _, status, nfev, _ = levenberg_marquardt(fun, jac, [4.9], max_nfev=3)
    assert status == 0 and nfev == 3
    x, status, _, _ = levenberg_marquardt(fun, jac, [4.9])
    # the least-squares point of e^x − 2 and x − 0.5: (e^x − 2)e^x + x − 0.5 = 0, by Newton's method
    best = 0.7
    for _ in range(50):
        best -= ((np.exp(best) - 2) * np.exp(best) + best - 0.5) / ((2 * np.exp(best) - 2) * np.exp(best) + 1)
    cost = lambda z: float(np.sum(fun(np.atleast_1d(z)) ** 2))  # noqa: E731
    # converged in ftol's sense (1e-15 of the cost): within rounding of the minimum, and x to ~1e-9
    assert status > 0 and cost(x[0]) <= cost(best) * (1 + 1e-15) and x[0] == pytest.approx(best, abs=1e-8)


def test_registry_import_loads_no_optimisation_library():
    """Why lm exists: building the registry and running lm import neither scipy nor any solver back end."""
    code = ("import sys, optcal; from optcal.app.fit import calibrate; "
            "calibrate(optcal.simulate('nonlinear12', None, 1).data); "
            "print(sorted({m.split('.')[0] for m in sys.modules} & "
            "{'scipy', 'casadi', 'nlopt', 'cvxpy', 'cma', 'nevergrad', 'numba'}))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip().splitlines()[-1] == "[]"
