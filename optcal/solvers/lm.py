"""Levenberg-Marquardt in NumPy with the problem's exact Jacobian: the one-off fit of ``optcal calibrate`` and
``optcal imu`` (docs/design.md, "Per-position residuals, outliers, the robust loss, what the data determine and weak
fits", docs/performance.md "One calibration from a raw recording").

Why not SciPy's (``scipy-lm``, MINPACK's lmder, which stays registered and is what the studies run): importing
``scipy.optimize`` costs 0.3–0.4 s on the project's machine, most of the 0.5 s that a whole ``optcal calibrate
--raw`` process may take (issue #20), for a fit that itself takes a millisecond. The method is Marquardt's
(1963) with his scaling of the damping by the diagonal of JᵀJ and Nielsen's (1999) update of the damping
(Madsen, Nielsen & Tingleff 2004, "Methods for non-linear least squares problems", algorithm 3.16); each step
solves the damped system as the least-squares problem [J; √μ·D] p ≈ [−r; 0], not through the normal
equations, so the Jacobian's conditioning is not squared. The stopping tests are MINPACK's (Moré, Garbow &
Hillstrom 1980, the user guide's §2.3): the cosine between the residual and the Jacobian's columns (gtol), the
actual and predicted relative reductions of the cost (ftol) and the scaled step relative to the scaled point
(xtol). tests/test_lm.py checks that it reaches scipy-lm's minimum on accelerometer and gyroscope problems.
"""

from __future__ import annotations

import numpy as np

from optcal.core.errors import InputError
from optcal.solvers.base import Option, Solver, positive
from optcal.solvers.registry import register

# SciPy's status codes and messages, so that a result reads the same whichever Levenberg-Marquardt ran
MESSAGES = {0: "the maximum number of function evaluations is exceeded",
            1: "`gtol` termination condition is satisfied", 2: "`ftol` termination condition is satisfied",
            3: "`xtol` termination condition is satisfied",
            4: "both `ftol` and `xtol` termination conditions are satisfied"}


def levenberg_marquardt(fun, jac, x0, *, ftol=1e-15, xtol=1e-15, gtol=1e-15, max_nfev=None, callback=None):
    """Minimise ½‖fun(x)‖² from ``x0``; returns (x, status, nfev, njev). ``callback(nfev)`` after each accepted
    step; ``max_nfev`` None: 100·(n + 1), MINPACK's default."""
    x = np.asarray(x0, float).copy()
    n = x.size
    max_nfev = 100 * (n + 1) if max_nfev is None else int(max_nfev)
    r = fun(x)
    J = jac(x)
    nfev, njev = 1, 1
    F = 0.5 * float(r @ r)
    D = np.linalg.norm(J, axis=0)
    D[D == 0] = 1.0
    # μ relative to the scaled diagonal of JᵀJ: Madsen, Nielsen & Tingleff's τ = 1e-6 for a start believed close
    # (presets or the linear ellipsoid fit: optcal.solvers.base.Solver.start_point)
    mu, nu = 1e-6, 2.0
    zeros = np.zeros(n)
    while True:
        g = J.T @ r
        rnorm = np.sqrt(2.0 * F)
        cols = np.linalg.norm(J, axis=0)
        with np.errstate(divide="ignore", invalid="ignore"):
            cosine = np.where(cols > 0, np.abs(g) / (cols * rnorm), 0.0) if rnorm > 0 else np.zeros(n)
        if rnorm == 0.0 or np.max(cosine, initial=0.0) <= gtol:
            return x, 1, nfev, njev
        D = np.maximum(D, cols)  # MINPACK keeps the largest column norm seen
        while True:
            if nfev >= max_nfev:
                return x, 0, nfev, njev
            A = np.vstack([J, np.diag(np.sqrt(mu) * D)])
            p = np.linalg.lstsq(A, np.concatenate([-r, zeros]), rcond=None)[0]
            # the damped step is about 1/(1 + μ) of the undamped one: judged as that, so that a run slowed by
            # a large μ (after rejected trials) is not taken for converged
            small_step = (1.0 + mu) * np.linalg.norm(D * p) <= xtol * (np.linalg.norm(D * x) + xtol)
            x_new = x + p
            r_new = fun(x_new)
            nfev += 1
            F_new = 0.5 * float(r_new @ r_new) if np.all(np.isfinite(r_new)) else np.inf
            Jp = J @ p
            predicted = 0.5 * float(Jp @ Jp) + mu * float((D * p) @ (D * p))  # = F − L(p) for the damped step
            # F − F_new as ½ Σ (r − r_new)(r + r_new): the difference of the residuals keeps the digits that the
            # difference of the two sums of squares loses near the minimum (where it decides acceptance)
            actual = 0.5 * float((r - r_new) @ (r + r_new)) if np.isfinite(F_new) else -np.inf
            rho = actual / predicted if predicted > 0 else -np.inf
            if rho > 0:
                small_f = (abs(actual) <= ftol * F and predicted <= ftol * F) if F > 0 else True
                x, r, F = x_new, r_new, F_new
                mu *= max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
                nu = 2.0
                if callback is not None:
                    callback(nfev)
                if small_f or small_step:
                    return x, (4 if small_f and small_step else 2 if small_f else 3), nfev, njev
                J = jac(x)
                njev += 1
                break
            if small_step or mu > 1e30:  # no decrease even along a vanishing step: the rounding floor
                return x, 3, nfev, njev
            if predicted <= ftol * F and mu <= 1.0:
                # the lightly damped model promises less than ftol of the cost and the evaluation cannot show
                # even that (its own rounding is larger): converged in ftol's sense, as MINPACK's test, which it
                # also applies to rejected trials; raising μ would only shrink the step to xtol, evaluating
                # the residuals a dozen times more for nothing
                return x, 2, nfev, njev
            mu *= nu
            nu *= 2.0


@register
class LevenbergMarquardt(Solver):
    """Levenberg-Marquardt in NumPy with the exact Jacobian (Marquardt 1963; Nielsen's damping update)."""

    name = "lm"
    family = "local"
    few_evaluations = True  # tens of residuals and Jacobians: the NumPy evaluation, not the compiled kernel
    uses_rng = False  # deterministic: no Generator is built for it
    options = {
        "ftol": Option(1e-15, float, "relative reduction of the cost to stop", check=positive, check_doc="> 0"),
        "xtol": Option(1e-15, float, "relative change of x to stop", check=positive, check_doc="> 0"),
        "gtol": Option(1e-15, float, "cosine between residual and Jacobian columns to stop", check=positive,
                       check_doc="> 0"),
    }
    default_budget = 2000

    def __init__(self, **options):
        if "loss" in options or "f_scale" in options:
            raise InputError("solver lm (Levenberg-Marquardt) takes no robust loss; use --solver scipy-trf "
                             "--option loss=soft_l1")
        super().__init__(**options)

    def _solve(self, problem, x0, rng, callback):
        cfg = self.config
        budget = problem.counter.budget.max_evals
        x, status, nfev, _ = levenberg_marquardt(
            problem.residuals, problem.jacobian, x0, ftol=cfg["ftol"], xtol=cfg["xtol"], gtol=cfg["gtol"],
            max_nfev=None if budget is None else max(1, budget), callback=callback)
        return {"x": x, "nit": nfev, "status": status, "message": MESSAGES[status], "success": True}
