"""SciPy ``least_squares`` with the problem's exact Jacobian: Levenberg-Marquardt (MINPACK) and the
trust-region-reflective method (Branch, Coleman & Li 1999)."""

from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares

from .base import Option, Solver, positive
from .registry import register


class ScipyLeastSquares(Solver):
    family = "local"
    method = "lm"
    options = {
        "ftol": Option(1e-15, float, "relative change of the cost to stop", check=positive, check_doc="> 0"),
        "xtol": Option(1e-15, float, "relative change of x to stop", check=positive, check_doc="> 0"),
        "gtol": Option(1e-15, float, "gradient norm to stop", check=positive, check_doc="> 0"),
        "x_scale": Option("jac", (str, float), "variable scaling: 'jac' or a number"),
    }
    default_budget = 2000

    def _solve(self, problem, x0, rng, callback):
        cfg = self.config
        budget = problem.counter.budget.max_evals
        res = least_squares(
            problem.residuals, x0, jac=problem.jacobian, method=self.method,
            ftol=cfg["ftol"], xtol=cfg["xtol"], gtol=cfg["gtol"], x_scale=cfg["x_scale"],
            max_nfev=None if budget is None else max(1, budget),
        )
        callback(res.nfev)
        return {"x": res.x, "nit": int(res.nfev), "status": int(res.status), "message": res.message,
                "success": bool(res.status > 0 or np.isfinite(res.cost))}


@register
class ScipyLM(ScipyLeastSquares):
    """Levenberg-Marquardt (MINPACK's lmder) with the exact Jacobian."""

    name = "scipy-lm"
    method = "lm"


@register
class ScipyTRF(ScipyLeastSquares):
    """Trust-region reflective least squares with the exact Jacobian."""

    name = "scipy-trf"
    method = "trf"
