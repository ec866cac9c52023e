"""SciPy's differential evolution (Storn & Price 1997), vectorised over the population.

``scipy.optimize.differential_evolution`` with ``vectorized=True`` and ``updating="deferred"``: each
generation's trial vectors reach the objective as one (n, S) array, which is transposed to the problem's
(S, n) and evaluated by one ``problem.cost_batch`` call (S = popsize·n). The search runs in the problem's
normalised coordinates z ∈ [−1, 1]ⁿ (x = centre + half-width·z; 2020 paper §3.4), the start (presets or
initialiser) replaces the first member of the initial population, and SciPy's generator is seeded with an
integer drawn from ``rng``.

Budget: the problem enforces it; the number of generations is set so that the last one takes exactly the
evaluations left (the problem evaluates as many candidates of that generation as allowed, the rest cost
+inf and are never selected). Non-finite costs are passed to SciPy as +inf (its selection compares
energies; NaN would never lose a comparison against itself and can be picked by argmin).

``polish`` (off by default) finishes with L-BFGS-B from the best member, as SciPy's polish does, but with
the problem's exact gradient; every evaluation goes through the problem, so it is counted and stopped by
the budget like the rest. With an evaluation budget, a tenth of it is kept for the polish.
"""

from __future__ import annotations

import math

import numpy as np

from optcal.core.errors import BudgetExhausted, InputError
from optcal.solvers._unitbox import normalised_start
from optcal.solvers.base import Option, Solver, positive, probability
from optcal.solvers.registry import register

POLISH_SHARE = 0.1  # of an evaluation budget kept for the polish when it is on
STRATEGIES = ("best1bin", "best1exp", "rand1bin", "rand1exp", "rand2bin", "rand2exp", "randtobest1bin",
              "randtobest1exp", "currenttobest1bin", "currenttobest1exp", "best2bin", "best2exp")


def _parse_mutation(value):
    """A float F or a (low, high) dithering range, from Python or from the CLI text 'low,high'."""
    if isinstance(value, str):
        try:
            parts = tuple(float(v) for v in value.split(","))
        except ValueError:
            parts = ()
        value = parts[0] if len(parts) == 1 else parts
    if isinstance(value, int | float) and not isinstance(value, bool):
        value = float(value)
        ok = 0.0 <= value <= 2.0
    else:
        value = tuple(float(v) for v in value) if isinstance(value, tuple | list) else ()
        ok = len(value) == 2 and 0.0 <= value[0] < value[1] <= 2.0
    if not ok:
        raise InputError(f"solver scipy-de: option mutation={value!r} must be F in [0, 2] or 'low,high' "
                         "with 0 <= low < high <= 2")
    return value


@register
class ScipyDE(Solver):
    """Differential evolution (SciPy), one batched cost call per generation."""

    name = "scipy-de"
    family = "metaheuristic"
    default_budget = 20000
    options = {
        "popsize": Option(15, int, "population = popsize × number of parameters", check=positive,
                          check_doc="> 0"),
        "mutation": Option((0.5, 1.0), (float, tuple, str), "differential weight F, or a (low, high) range "
                           "drawn each generation (dithering)"),
        "recombination": Option(0.7, float, "crossover probability", check=probability, check_doc="in [0, 1]"),
        "strategy": Option("best1bin", str, "SciPy's DE strategy", choices=STRATEGIES),
        "tol": Option(0.01, float, "stop when std(energies) <= atol + tol·|mean(energies)|",
                      check=lambda v: v >= 0, check_doc=">= 0"),
        "atol": Option(0.0, float, "absolute part of the convergence test", check=lambda v: v >= 0,
                       check_doc=">= 0"),
        "polish": Option(False, bool, "finish with L-BFGS-B (exact gradient), counted against the budget"),
        "maxiter": Option(1000, int, "generations when the budget sets no evaluation limit", check=positive,
                          check_doc="> 0"),
    }

    def check_config(self) -> None:
        self.config["mutation"] = _parse_mutation(self.config["mutation"])

    def _solve(self, problem, x0, rng, callback):
        cfg = self.config
        pn, z0 = normalised_start(problem, x0)
        n = pn.n
        S = cfg["popsize"] * n
        budget = problem.counter.budget
        maxiter = cfg["maxiter"]
        if budget.max_evals is not None:
            # the initial population and `maxiter` generations, the last one cut by the budget (less the
            # part kept for the polish)
            left = budget.max_evals - problem.counter.nfev
            if cfg["polish"]:
                left -= int(POLISH_SHARE * left)
            maxiter = max(0, math.ceil(left / S) - 1)

        def energies(Z):
            Z = np.asarray(Z, float)
            f = pn.cost_batch(Z.T if Z.ndim == 2 else Z[None, :])
            f = np.where(np.isfinite(f), f, np.inf)
            return f if Z.ndim == 2 else float(f[0])

        generation = [0]

        def each_generation(intermediate_result):
            generation[0] += 1
            callback(generation[0])

        from scipy.optimize import differential_evolution  # here: importing the registry stays light

        try:
            res = differential_evolution(
                energies, [(-1.0, 1.0)] * n, strategy=cfg["strategy"], maxiter=maxiter, popsize=cfg["popsize"],
                tol=cfg["tol"], atol=cfg["atol"], mutation=cfg["mutation"], recombination=cfg["recombination"],
                rng=int(rng.integers(2**63)), callback=each_generation, polish=self._polish(pn) if cfg["polish"]
                else False, init="latinhypercube", updating="deferred", vectorized=True, x0=z0,
            )
        except BudgetExhausted as exc:  # within the polish (the generations are sized to the budget)
            return {"nit": generation[0], "status": 1, "success": True,
                    "message": f"{exc} (in the L-BFGS-B polish after {generation[0]} generations)"}
        if budget.max_evals is not None and not res.success:  # SciPy: the generations ran out
            polished = " and the L-BFGS-B polish" if cfg["polish"] else ""
            return {"nit": int(res.nit), "status": 1, "success": True,
                    "message": f"evaluation budget used up by {res.nit} generations{polished}"}
        return {"nit": int(res.nit), "status": 0 if res.success else 1, "success": True,
                "message": f"differential evolution: {res.message}"}

    @staticmethod
    def _polish(pn):
        """SciPy's polish hook: L-BFGS-B from the best member with the exact gradient 2·Jᵀr, on the cost
        divided by its value at the start of the polish (L-BFGS-B's gtol is absolute)."""
        scale = []

        def fun_and_grad(z):
            r = pn.residuals(z)
            f = float(r @ r)
            if not np.isfinite(f):
                return np.inf, np.zeros_like(z)
            if not scale:
                scale.append(1.0 / f if f > 0 else 1.0)
            return f * scale[0], 2.0 * scale[0] * pn.jacobian(z).T @ r

        def polish(func, x0, **kwargs):
            from scipy.optimize import minimize

            return minimize(fun_and_grad, x0, jac=True, method="L-BFGS-B", bounds=kwargs.get("bounds"))

        return polish
