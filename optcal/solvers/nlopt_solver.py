"""NLopt (Johnson, "The NLopt nonlinear-optimization package") on the calibration cost.

``nlopt`` takes the algorithm as an option; the registered variants fix it: ``nlopt-bobyqa`` (Powell's
BOBYQA, quadratic models), ``nlopt-sbplx`` (Rowan's Subplex), ``nlopt-neldermead``, ``nlopt-crs2``
(controlled random search with local mutation, Kaelo & Ali 2006), ``nlopt-isres`` (improved stochastic
ranking evolution strategy, Runarsson & Yao 2005), ``nlopt-lbfgs`` (Nocedal's low-storage BFGS) and
``nlopt-slsqp`` (Kraft's sequential quadratic programming). The LD_ algorithms get the exact gradient
2·Jᵀr from the problem's Jacobian.

* **Normalised coordinates.** NLopt searches z ∈ [−1, 1]ⁿ with x = centre + half-width·z
  (``problem.normalised()``). The parameters differ by five orders of magnitude (scale factors near 1,
  second-order terms near 1e-5), while NLopt's derivative-free methods start with one step size for all
  coordinates, the global ones sample the box uniformly, and xtol_rel compares each step with |x|
  (tolerances five orders apart in x). In the unit box every parameter is searched on the same footing,
  its box being its expected range around the presets (2020 paper §3.4 asks for the same).
* **Objective scale.** The cost is divided by its first finite value (the start), so that it is O(1):
  L-BFGS and SLSQP have absolute internal thresholds that a cost of 1e-9 g² would meet at the start.
* **Return codes.** NLopt's results are mapped by :data:`RESULTS` (code → message, success), never left to
  NLopt's exceptions: the Python wrapper raises ``RoundoffLimited``, ``ForcedStop`` etc. after the run,
  and re-raises any exception from the objective. The objective therefore catches the problem's
  ``BudgetExhausted`` (and a callback's stop) itself, asks NLopt to stop, and the run is reported from
  the code; the problem keeps the best point whatever happens.
* **A failure at the optimum.** NLOPT_FAILURE (L-BFGS's line search finding no decrease) is checked:
  when the Gauss-Newton step from the best point is below :data:`STATIONARY_STEP` the run converged and
  is reported so (two more evaluations, counted).
* **Non-finite costs** are passed to NLopt as +inf (NaN breaks the simplex and random-search methods:
  measured, Nelder-Mead and CRS2 stall on NaN and recover on inf), with a zero gradient.
* **Seeding.** NLopt has one global generator; it is seeded from ``rng`` before every run
  (``nlopt.srand``), so stochastic algorithms give the same result for the same seed.
* **ISRES population.** NLopt's default, 20(n+1), did not improve on the presets within 20,000
  evaluations on the 6- and 12-parameter problems (its step sizes shrink once per generation, and a box
  ~400 Cramér-Rao deviations wide needs many generations); 2(n+1) reached a relative cost gap of 1e-4
  in about 6,000 evaluations on 6 parameters, so that is the automatic population here.
* **Budget.** The problem enforces it: the evaluation after the last allowed one raises inside the
  objective and stops NLopt, so a binding budget is used exactly. A gradient evaluation counts two (the
  residuals and the Jacobian), as ``problem.gradient`` does. NLopt evaluates one point per call (it has no
  batched interface), so the population methods here are not vectorised.
"""

from __future__ import annotations

import math

import numpy as np

from optcal.core.errors import BudgetExhausted, InputError
from optcal.solvers._lazy import LazyModule
from optcal.solvers._unitbox import normalised_start
from optcal.solvers.base import Option, Solver, StopSolver
from optcal.solvers.registry import register, register_variant

# imported at the first solve (the registry lists the solver as unavailable without it)
nlopt = LazyModule("nlopt", globals(), "nlopt")

# algorithm → (family, uses the gradient)
ALGORITHMS = {
    "LN_BOBYQA": ("local", False),
    "LN_SBPLX": ("local", False),
    "LN_NELDERMEAD": ("local", False),
    "GN_CRS2_LM": ("global", False),
    "GN_ISRES": ("global", False),
    "LD_LBFGS": ("local", True),
    "LD_SLSQP": ("local", True),
}

# NLopt's return codes (nlopt.h, nlopt_result) → (message, success). A run stopped by the problem's
# budget or by the callback is reported by why it was stopped (see ``_solve``), not by code -5.
RESULTS = {
    1: ("NLopt: converged (NLOPT_SUCCESS)", True),
    2: ("NLopt: stopval reached", True),
    3: ("NLopt: converged (ftol_rel reached)", True),
    4: ("NLopt: converged (xtol_rel reached)", True),
    5: ("NLopt: maxeval reached", True),
    6: ("NLopt: maxtime reached", True),
    -1: ("NLopt: generic failure", False),
    -2: ("NLopt: invalid arguments (bounds, options or starting point)", False),
    -3: ("NLopt: out of memory", False),
    -4: ("NLopt: stopped by roundoff (no further progress is possible at this precision)", True),
    -5: ("NLopt: forced stop", False),
}


# NLopt's L-BFGS ends with NLOPT_FAILURE when its line search finds no decrease, which at the optimum is
# what rounding does to the cost (residuals of ~1e-5 g carry ~1e-16 g of rounding: relative changes of the
# cost below ~1e-11 are noise, and so are steps below ~1e-6 half-widths). A failure at a point whose
# Gauss-Newton step is below this is a converged run.
STATIONARY_STEP = 1e-6


def _nonnegative(v) -> bool:
    return v >= 0


@register
class NLopt(Solver):
    """NLopt with the algorithm as an option, in the problem's normalised coordinates."""

    name = "nlopt"
    family = "local"
    requires = ("nlopt",)
    default_budget = 20000
    options = {
        "algorithm": Option("LN_BOBYQA", str, "NLopt algorithm name", choices=tuple(ALGORITHMS)),
        "xtol_rel": Option(1e-12, float, "relative tolerance on z (0 = off)", check=_nonnegative,
                           check_doc=">= 0"),
        "ftol_rel": Option(1e-15, float, "relative tolerance on the cost (0 = off)", check=_nonnegative,
                           check_doc=">= 0"),
        "initial_step": Option(0.0, float, "initial step of the derivative-free methods in units of the "
                               "half-widths (0 = NLopt's default from the bounds)", check=_nonnegative,
                               check_doc=">= 0"),
        "population": Option(0, int, "population of CRS2 and ISRES (0 = automatic: NLopt's 10(n+1) for "
                             "CRS2, 2(n+1) for ISRES)", check=_nonnegative, check_doc=">= 0"),
    }

    def check_config(self) -> None:
        fam, self.uses_gradient = ALGORITHMS[self.config["algorithm"]]
        self.family = fam  # the instance's family follows its algorithm (global for GN_)
        if self.config["population"] and fam != "global":
            raise InputError(f"solver {self.name}: option population is for the global algorithms (GN_), "
                             f"not {self.config['algorithm']}")

    def _solve(self, problem, x0, rng, callback):
        cfg = self.config
        pn, z0 = normalised_start(problem, x0)
        n = pn.n
        opt = nlopt.opt(getattr(nlopt, cfg["algorithm"]), n)
        opt.set_lower_bounds(-np.ones(n))
        opt.set_upper_bounds(np.ones(n))
        if cfg["xtol_rel"]:
            opt.set_xtol_rel(cfg["xtol_rel"])
        if cfg["ftol_rel"]:
            opt.set_ftol_rel(cfg["ftol_rel"])
        if cfg["initial_step"] and not self.uses_gradient:
            opt.set_initial_step(cfg["initial_step"])
        population = cfg["population"] or (2 * (n + 1) if cfg["algorithm"] == "GN_ISRES" else 0)
        if population:
            opt.set_population(population)
        budget = problem.counter.budget
        if budget.max_time is not None:
            opt.set_maxtime(max(budget.max_time - problem.counter.elapsed(), 1e-3))
        state = {"scale": None, "stop": "", "calls": 0}
        # Derivative-free methods make 20,000 calls of a few microseconds each: their objective is the
        # lean path (problem.cost, Python floats), the gradient one keeps the full form.
        cost, isfinite = pn.cost, math.isfinite

        def objective_free(z, grad):
            if state["stop"]:  # NLopt may call again before it sees the stop (CRS2 does): evaluate nothing
                return math.inf
            try:
                f = cost(z)
                state["calls"] += 1
                callback(state["calls"])
            except BudgetExhausted as exc:
                return _stop(opt, state, str(exc), grad)
            except StopSolver:
                return _stop(opt, state, "stopped by callback", grad)
            except (np.linalg.LinAlgError, FloatingPointError, ArithmeticError):
                return math.inf  # a failed evaluation is a point NLopt should avoid, not the end of the run
            if not isfinite(f):
                return math.inf
            scale = state["scale"]
            if scale is None:
                scale = state["scale"] = 1.0 / f if f > 0 else 1.0
            return f * scale

        def objective(z, grad):
            if not grad.size:
                return objective_free(z, grad)
            if state["stop"]:
                grad[:] = 0.0
                return np.inf
            try:
                r = pn.residuals(z)
                f = float(r @ r)
                g = 2.0 * pn.jacobian(z).T @ r if np.isfinite(f) else None
                state["calls"] += 1
                callback(state["calls"])
            except BudgetExhausted as exc:
                return _stop(opt, state, str(exc), grad)
            except StopSolver:
                return _stop(opt, state, "stopped by callback", grad)
            except (np.linalg.LinAlgError, FloatingPointError, ArithmeticError):
                f = np.inf
            if not np.isfinite(f):
                grad[:] = 0.0
                return np.inf
            if state["scale"] is None:
                state["scale"] = 1.0 / f if f > 0 else 1.0
            grad[:] = np.where(np.isfinite(g), g, 0.0) * state["scale"]
            return f * state["scale"]

        opt.set_min_objective(objective if self.uses_gradient else objective_free)
        nlopt.srand(int(rng.integers(2**31)))  # NLopt's own generator, seeded from the user's seed
        try:
            opt.optimize(z0)
        except Exception as exc:
            # nlopt raises RoundoffLimited, ForcedStop, RuntimeError (-1), ValueError (-2) or MemoryError
            # (-3) for negative codes, and re-raises a foreign exception from the objective after a
            # forced stop: only the latter is not NLopt's to report.
            code = int(opt.last_optimize_result())
            if code >= 0 or (code == -5 and not state["stop"] and not isinstance(exc, nlopt.ForcedStop)):
                raise
        code = int(opt.last_optimize_result())
        if state["stop"] == "stopped by callback":
            raise StopSolver
        if state["stop"]:
            return {"nit": state["calls"], "status": 1, "success": True, "message": state["stop"]}
        message, success = RESULTS.get(code, (f"NLopt: unknown result code {code}", False))
        if code == nlopt.FAILURE:
            step = _gauss_newton_step(problem, pn)
            if step is not None and step < STATIONARY_STEP:
                success = True
                message += f" at a stationary point (Gauss-Newton step {step:.1e} half-widths: converged)"
        return {"nit": state["calls"], "status": code, "success": success, "message": message}


def _gauss_newton_step(problem, pn) -> float | None:
    """Largest Gauss-Newton step from the best point, in half-widths (two counted evaluations: the
    residuals and the Jacobian), or None when the budget has no room for them."""
    x, _ = problem.best
    if x is None:
        return None
    z = pn.from_full(problem.to_full(x)[0])
    try:
        r = pn.residuals(z)
        J = pn.jacobian(z)
    except BudgetExhausted:
        return None
    if not (np.all(np.isfinite(r)) and np.all(np.isfinite(J))):
        return None
    return float(np.max(np.abs(np.linalg.lstsq(J, -r, rcond=None)[0])))


def _stop(opt, state: dict, why: str, grad) -> float:
    state["stop"] = state["stop"] or why
    opt.force_stop()
    if grad.size:
        grad[:] = 0.0
    return np.inf


class NLoptGlobal(NLopt):
    """The global (GN_) algorithms registered as variants report family ``global``."""

    family = "global"


for _name, _cls, _alg in (
    ("nlopt-bobyqa", NLopt, "LN_BOBYQA"),
    ("nlopt-sbplx", NLopt, "LN_SBPLX"),
    ("nlopt-neldermead", NLopt, "LN_NELDERMEAD"),
    ("nlopt-crs2", NLoptGlobal, "GN_CRS2_LM"),
    ("nlopt-isres", NLoptGlobal, "GN_ISRES"),
    ("nlopt-lbfgs", NLopt, "LD_LBFGS"),
    ("nlopt-slsqp", NLopt, "LD_SLSQP"),
):
    register_variant(_name, _cls, algorithm=_alg)
