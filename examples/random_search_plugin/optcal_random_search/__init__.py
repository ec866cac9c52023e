"""An optcal solver plugin in one file: adaptive step-size random search.

Schumer & Steiglitz, "Adaptive step size random search", IEEE Trans. Automatic Control 13(3), 270-276
(1968), in its population form: each iteration draws ``m`` candidates x + σ·u, u ~ N(0, I), around the
current point, evaluates them in ONE batched call, moves to the best of them if it improves on the
current point and then widens the step (σ ← expand·σ), otherwise narrows it (σ ← contract·σ).

It is a toy (it exists to show the plugin mechanism), but it follows the contract every optcal solver
follows: options declared with defaults and checks, every random draw from the ``rng`` it is given, the
search in the problem's normalised coordinates (2020 paper §3.4), one ``cost_batch`` per iteration, the
budget left to the problem, and ``callback(nit)`` once per iteration.

The entry point in ``pyproject.toml`` (group ``optcal.solvers``) is all it takes for
``optcal solvers`` to list it and ``optcal calibrate --solver random-search`` to use it.
"""

from __future__ import annotations

import numpy as np

from optcal.solvers.base import Option, Solver, positive

__all__ = ["RandomSearch"]


class RandomSearch(Solver):
    """Adaptive step-size random search (Schumer & Steiglitz 1968), population form, unit-box coordinates."""

    name = "random-search"
    family = "metaheuristic"
    options = {
        "m": Option(20, int, "candidates per iteration (one batched evaluation)", check=positive, check_doc="> 0"),
        "iterations": Option(500, int, "maximum iterations", check=positive, check_doc="> 0"),
        "sigma_init": Option(0.1, float, "initial step σ in unit-box units", check=positive, check_doc="> 0"),
        "expand": Option(1.5, float, "σ factor after an improving iteration", check=lambda v: v >= 1.0,
                         check_doc=">= 1"),
        "contract": Option(0.7, float, "σ factor after a failed iteration", check=lambda v: 0.0 < v < 1.0,
                           check_doc="in (0, 1)"),
        "sigma_min": Option(1e-12, float, "stop when σ falls below this", check=positive, check_doc="> 0"),
    }
    default_budget = 10001

    def _solve(self, problem, x0, rng, callback):
        cfg = self.config
        # Search in z ∈ [-1, 1]^n (x = centre + halfwidth·z): the view shares the problem's counter, so
        # the budget and the best point are the problem's whichever coordinates we work in.
        zp = problem if problem.is_normalised else problem.normalised()
        z = np.clip(zp.from_full(problem.to_full(x0)[0]), -1.0, 1.0)
        fz = _finite(zp.cost_batch(z[None]))[0]
        sigma = cfg["sigma_init"]
        for it in range(1, cfg["iterations"] + 1):
            Z = np.clip(z + sigma * rng.standard_normal((cfg["m"], zp.n)), -1.0, 1.0)
            f = _finite(zp.cost_batch(Z))
            i = int(np.argmin(f))
            if f[i] < fz:
                z, fz, sigma = Z[i], f[i], sigma * cfg["expand"]
            else:
                sigma *= cfg["contract"]
            callback(it)
            if sigma < cfg["sigma_min"]:
                return {"nit": it, "message": f"step below sigma_min={cfg['sigma_min']:g}"}
        return {"nit": cfg["iterations"], "message": "maximum number of iterations reached"}


def _finite(f) -> np.ndarray:
    """A failed (NaN or infinite) cost never looks good: read it as +inf."""
    f = np.asarray(f, float)
    return np.where(np.isfinite(f), f, np.inf)
