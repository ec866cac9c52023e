"""SciPy ``least_squares`` with the problem's exact Jacobian: Levenberg-Marquardt (MINPACK) and the
trust-region-reflective method (Branch, Coleman & Li 1999), the latter optionally with a robust loss
(docs/design.md, "Per-position residuals, outliers, the robust loss, what the data determine and weak fits")."""

from __future__ import annotations

import numpy as np

from optcal.core.analysis import ROBUST_LOSSES, noise_scale
from optcal.core.errors import InputError
from optcal.solvers.base import Option, Solver, positive
from optcal.solvers.registry import register

# f_scale over the noise SD at which each loss is 95 % as efficient as least squares for normal noise,
# (E ψ')² / E ψ² = 0.95 by numerical integration (tests/test_honest_fits.py checks it); Huber's 1.345 and
# the Cauchy loss's 2.385 are the textbook constants (Holland & Welsch 1977).
TUNING = {"soft_l1": 1.287, "huber": 1.345, "cauchy": 2.385, "arctan": 2.571}


class ScipyLeastSquares(Solver):
    family = "local"
    few_evaluations = True  # a Levenberg-Marquardt or trust-region fit takes tens of residuals and Jacobians
    method = "lm"
    options = {
        "ftol": Option(1e-15, float, "relative change of the cost to stop", check=positive, check_doc="> 0"),
        "xtol": Option(1e-15, float, "relative change of x to stop", check=positive, check_doc="> 0"),
        "gtol": Option(1e-15, float, "gradient norm to stop", check=positive, check_doc="> 0"),
        "x_scale": Option("jac", (str, float), "variable scaling: 'jac' or a number"),
    }
    default_budget = 2000

    def _solve(self, problem, x0, rng, callback):
        from scipy.optimize import least_squares  # here: scipy.optimize costs 0.3-0.4 s to import (optcal.solvers.lm)

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

    def __init__(self, **options):
        if "loss" in options or "f_scale" in options:
            raise InputError("solver scipy-lm (Levenberg-Marquardt) takes no robust loss; use --solver scipy-trf "
                             "--option loss=soft_l1")
        super().__init__(**options)


def _loss_ok(v) -> bool:
    return v in ROBUST_LOSSES


@register
class ScipyTRF(ScipyLeastSquares):
    """Trust-region reflective least squares with the exact Jacobian, and optionally a robust loss ρ.

    With ``loss`` other than ``linear`` it minimises Σ ρ((r_i/f_scale)²) (SciPy's ``least_squares``), so a
    displaced position weighs as a residual of about f_scale instead of its full square. ``f_scale`` (g)
    defaults to ``TUNING[loss]`` times the noise: the problem's (``noise_g``: stated or from the data), else
    the noise estimated from a plain fit first, with its outlying positions set aside
    (:func:`optcal.core.analysis.noise_scale`); the factor makes the loss 95 % efficient on clean normal noise. (A scale
    re-estimated from the robust fit's own residuals collapses: with f_scale below the noise, soft_l1 acts as
    an L1 fit, which interpolates some positions exactly.) The result's ``x`` is the robust optimum (the
    point of least robust cost evaluated), ``fun`` its plain cost Σr², and
    ``extra`` holds ``loss`` and ``f_scale``; the trace follows the plain cost of the points evaluated.
    """

    name = "scipy-trf"
    method = "trf"
    options = {
        **ScipyLeastSquares.options,
        "loss": Option("linear", str, "robust loss: linear (least squares), soft_l1, huber, cauchy or arctan",
                       check=_loss_ok, check_doc="one of " + ", ".join(ROBUST_LOSSES)),
        "f_scale": Option(None, float, "residual scale of the robust loss, g (default: the noise, else a robust "
                          "scale of the residuals)", check=positive, check_doc="> 0"),
    }

    def solve(self, problem, **kw):
        if self.config["loss"] == "linear":
            return super().solve(problem, **kw)
        self._robust = {"best": None, "f_scale": None}
        res = super().solve(problem, **kw)
        best, f_scale = self._robust["best"], self._robust["f_scale"]
        del self._robust
        if best is not None:
            x_full = problem.to_full(best[1])[0]
            res.x, res.x_full = np.asarray(best[1], float), x_full
            res.fun = float(np.sum(problem.residuals_full(x_full)[0] ** 2))
        res.extra = {**res.extra, "loss": self.config["loss"], "f_scale": f_scale}
        return res

    def _solve(self, problem, x0, rng, callback):
        if self.config["loss"] == "linear":
            return super()._solve(problem, x0, rng, callback)
        from scipy.optimize import least_squares

        cfg, state = self.config, self._robust
        budget = problem.counter.budget.max_evals
        x, nit = np.asarray(x0, float), 0
        scale = cfg["f_scale"] or (None if problem.noise_g is None else TUNING[cfg["loss"]] * problem.noise_g)
        if scale is None:
            # no noise known: the plain fit first, and the noise of its positions with the outliers set aside
            res = least_squares(problem.residuals, x, jac=problem.jacobian, method="trf", ftol=cfg["ftol"],
                                xtol=cfg["xtol"], gtol=cfg["gtol"], x_scale=cfg["x_scale"],
                                max_nfev=None if budget is None else max(1, budget))
            nit = int(res.nfev)
            callback(nit)
            x = res.x
            scale = TUNING[cfg["loss"]] * max(noise_scale(problem, problem.to_full(x)[0]), 1e-12)
        state["f_scale"] = float(scale)

        def fun(z):
            r = problem.residuals(z)
            # robust cost of this point (SciPy's ρ, summed), so that solve returns the robust optimum
            f = float(np.sum(_rho(cfg["loss"], (r / scale) ** 2)))
            if np.isfinite(f) and (state["best"] is None or f < state["best"][0]):
                state["best"] = (f, np.array(z, float))
            return r

        left = None if budget is None else max(1, budget - problem.counter.nfev)
        res = least_squares(fun, x, jac=problem.jacobian, method="trf", loss=cfg["loss"], f_scale=scale,
                            ftol=cfg["ftol"], xtol=cfg["xtol"], gtol=cfg["gtol"], x_scale=cfg["x_scale"],
                            max_nfev=left)
        nit += int(res.nfev)
        callback(nit)
        return {"nit": nit, "status": int(res.status), "message": res.message,
                "success": bool(res.status > 0 or np.isfinite(res.cost))}


def _rho(loss: str, z: np.ndarray) -> np.ndarray:
    """SciPy least_squares' ρ(z) for its named losses (scipy.optimize.least_squares, 'loss')."""
    if loss == "soft_l1":
        return 2.0 * (np.sqrt(1.0 + z) - 1.0)
    if loss == "huber":
        return np.where(z <= 1.0, z, 2.0 * np.sqrt(z) - 1.0)
    if loss == "cauchy":
        return np.log1p(z)
    if loss == "arctan":
        return np.arctan(z)
    return z
