"""CMA-ES through pycma, one generation per batched evaluation, with IPOP and BIPOP restarts."""

from __future__ import annotations

import math

import numpy as np

from optcal.core.errors import BudgetExhausted
from optcal.solvers._unitbox import normalised_start
from optcal.solvers.base import Option, Solver, positive
from optcal.solvers.registry import register

RESTART_STRATEGIES = ("none", "ipop", "bipop")


def default_popsize(n: int) -> int:
    """pycma's default population size, 4 + ⌊3 ln n⌋ (Hansen & Ostermeier 2001)."""
    return 4 + int(3 * math.log(n))


@register
class CMAES(Solver):
    """CMA-ES (Hansen & Ostermeier 2001, "Completely derandomized self-adaptation in evolution strategies",
    Evolutionary Computation 9(2)) as implemented by pycma (N. Hansen et al., ``cma`` on PyPI,
    https://github.com/CMA-ES/pycma, doi:10.5281/zenodo.2559634), driven through its ask/tell interface
    (``cma.CMAEvolutionStrategy``): each generation's λ candidates are one ``problem.cost_batch`` call
    (docs/algorithms.md, "CMA-ES (`cmaes`)").

    The search runs in the problem's unit box z ∈ [-1, 1]^n (2020 paper §3.4) with pycma's own boundary
    handling (``bounds=[-1, 1]``, its default ``BoundTransform``), and every run starts its mean at ``x0``
    (the presets or the initialiser). Options:

    - ``sigma0``: the initial step size σ0 in unit-box units (the box is 2 wide per parameter; presets
      err by about 1/40 of a half-width, so the default 0.1 covers them a few times over).
    - ``popsize``: λ, candidates per generation; 0 is pycma's default 4 + ⌊3 ln n⌋.
    - ``restarts`` and ``restart_strategy``: after a run stops by pycma's own termination criteria, up to
      ``restarts`` more runs from ``x0`` with fresh random numbers. ``none``: the same λ and σ0 each time.
      ``ipop`` (Auger & Hansen 2005, "A restart CMA evolution strategy with increasing population size",
      CEC): restart k has λ = 2^k·λ_def, σ0 unchanged. ``bipop`` (Hansen 2009, "Benchmarking a
      BI-population CMA-ES on the BBOB-2009 function testbed", GECCO workshop): two interlaced regimes,
      chosen before each restart by the evaluations each has spent so far (the first, default run is
      booked to the small regime, as pycma's ``fmin`` does): while the small regime has spent less than
      the large one, a small-regime run with λ_s = ⌊λ_def·(λ_L/λ_def)^(U1²)⌋ and σ0·10^(−2·U2) (U1, U2 ~
      U(0, 1) from ``rng``; λ_L the population of the latest large run, λ_def before any) and at most half
      the evaluations the large regime has spent; otherwise a large-regime run, λ doubled from the last
      large one and σ0 unchanged. ``restarts`` counts the large-regime restarts only (small runs do not
      count), and the restarts end after the last of them, as in pycma's ``fmin``. This is our own loop over
      ``CMAEvolutionStrategy``, written from the paper and pycma's ``fmin`` (whose regime choice it
      follows), not ``cma.fmin2`` itself: ``fmin2`` draws the small regime's λ and σ from NumPy's global
      random state and evaluates through its own loop, which cannot be seeded from ``rng`` nor share our
      batched, budgeted evaluation.

    Budget: the problem enforces it; the last generation the budget allows is evaluated as far as it
    goes (the rest cost +inf) and the next call ends the run, so a binding budget is used exactly.
    Without restarts left, a run that stops by itself ends the solve before the budget.

    Termination uses pycma's criteria with its defaults, with one change of scale: pycma's ``tolfun`` and
    ``tolfunhist`` are absolute (1e-11, 1e-12) and calibration costs are about 1e-9, so pycma is given
    the cost divided by the lowest finite cost of the run's first generation (a positive constant: the
    ranking, which is all CMA-ES selects on, is unchanged), which makes those tolerances relative. A
    non-finite cost (NaN, or +inf past the budget) is ranked behind every finite one of its generation.

    Random numbers: pycma samples through its ``randn`` option, here a NumPy Generator seeded from
    ``rng`` (``seed=int(rng.integers(2**31))`` per run); pycma's ``seed`` option is left unset (NaN), so
    NumPy's global random state is neither read nor reseeded.
    """

    name = "cmaes"
    family = "metaheuristic"
    default_budget = 20000
    options = {
        "sigma0": Option(0.1, float, "initial step size σ0 in unit-box units (the box is [-1, 1] per parameter)",
                         check=positive, check_doc="> 0"),
        "popsize": Option(0, int, "population λ per generation; 0: pycma's default 4 + floor(3 ln n)",
                          check=lambda v: v == 0 or v >= 2, check_doc="0 (default) or >= 2"),
        "restarts": Option(0, int, "restarts after a run stops by itself (bipop: large-population restarts)",
                           check=lambda v: v >= 0, check_doc=">= 0"),
        "restart_strategy": Option("ipop", str, "none: same λ and σ0; ipop: λ doubles each restart (Auger & "
                                   "Hansen 2005); bipop: interlaced large/small populations (Hansen 2009)",
                                   choices=RESTART_STRATEGIES),
    }
    requires = ("cma",)
    stops_on_stagnation = True

    def _solve(self, problem, x0, rng, callback):
        import cma

        cfg = self.config
        zp, z0 = normalised_start(problem, x0)
        n = zp.n
        lam_def = cfg["popsize"] or default_popsize(n)
        runs: list[dict] = []
        state = {"nit": 0, "small": 0, "large": 0, "n_large": 0}
        extra = {"runs": runs, "popsize_default": lam_def}
        while True:
            regime, lam, sigma, maxfevals = self._next_run(len(runs), lam_def, rng, state)
            run = {"regime": regime, "popsize": lam, "sigma0": sigma, "nfev": 0, "generations": 0, "stop": ""}
            runs.append(run)
            try:
                self._run(cma, zp, z0, lam, sigma, maxfevals, rng, callback, state, run)
            except BudgetExhausted as exc:  # caught here so that the runs' record reaches the result
                run["stop"] = str(exc)
                return {"nit": state["nit"], "status": 1, "success": True, "extra": extra,
                        "message": f"{exc} in run {len(runs)} ({regime} regime, λ={lam})"}
            finally:
                state["small" if regime in ("default", "small") else "large"] += run["nfev"]
            if self._done(len(runs), state):
                break
        stops = "; ".join(f"run {i + 1} (λ={r['popsize']}): {r['stop']}" for i, r in enumerate(runs))
        return {"nit": state["nit"], "status": 0, "success": True, "message": f"pycma stopped: {stops}",
                "extra": extra}

    def _next_run(self, k: int, lam_def: int, rng, state) -> tuple[str, int, float, float]:
        """(regime, λ, σ0, evaluation limit) of run k (0: the first)."""
        sigma0, strategy = self.config["sigma0"], self.config["restart_strategy"]
        if k == 0:
            return "default", lam_def, sigma0, math.inf
        if strategy == "none":
            return "same", lam_def, sigma0, math.inf
        if strategy == "ipop":
            return "large", lam_def * 2**k, sigma0, math.inf
        if state["small"] < max(1, state["large"]):
            u1, u2 = rng.random(2)
            lam = int(lam_def * (2 ** state["n_large"]) ** (u1**2))
            return "small", lam, sigma0 * 10 ** (-2 * u2), 0.5 * state["large"]
        state["n_large"] += 1
        return "large", lam_def * 2 ** state["n_large"], sigma0, math.inf

    def _done(self, runs: int, state) -> bool:
        if self.config["restart_strategy"] == "bipop":
            return state["n_large"] >= self.config["restarts"]
        return runs > self.config["restarts"]

    def _run(self, cma, zp, z0, lam, sigma, maxfevals, rng, callback, state, run) -> None:
        gen = np.random.default_rng(int(rng.integers(2**31)))
        opts = {"popsize": lam, "bounds": [-1.0, 1.0], "seed": np.nan,
                "randn": lambda *shape: gen.standard_normal(shape), "maxfevals": maxfevals,
                "verbose": -9, "verb_log": 0, "verb_disp": 0}
        es = cma.CMAEvolutionStrategy(z0, sigma, opts)
        scale = None
        cost_batch = zp.cost_batch
        while not es.stop():
            X = es.ask()
            nfev0 = zp.counter.nfev
            f = cost_batch(np.asarray(X))
            run["nfev"] += zp.counter.nfev - nfev0
            finite = np.isfinite(f)
            if scale is None and finite.any():
                low = float(f[finite].min())
                scale = low if low > 0 else 1.0
            g = f / (scale or 1.0)
            if not finite.all():
                worst = float(g[finite].max()) if finite.any() else 0.0
                g[~finite] = worst + 1.0 + abs(worst)  # behind every finite cost of the generation
            es.tell(X, g.tolist())
            run["generations"] += 1
            state["nit"] += 1
            callback(state["nit"])
        run["stop"] = ", ".join(f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}" for k, v in es.stop().items())
