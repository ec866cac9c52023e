"""Model discovery's search (docs/design.md §12): fit the base model, then forward selection over the
candidate terms, each extension refitted by a solver and scored by the F-test and ΔBIC of
:mod:`optcal.discovery.statistics` (whose docstring gives the equations and the stopping rule).

Application layer (CONTRIBUTING.md, "Layers"): this is the part of discovery that runs a solver, so it
imports ``solvers``; the statistics, the report and its text and figure are core and do not.
"""

from __future__ import annotations

import numpy as np

import solvers

from ..analysis import crlb, goodness_of_fit, observability
from ..data import PositionsData
from ..errors import InputError
from ..model import TERMS, Model, get_model
from ..problem import CalibrationProblem
from .results import DiscoveryReport, Step
from .statistics import (
    DEFAULT_ALPHA,
    DEFAULT_BIC_THRESHOLD,
    Extension,
    Fit,
    Score,
    best_of,
    candidate_pool,
    extend,
    nested_test,
    noise_per_position,
    residual_sigma,
)


def _solve(problem: CalibrationProblem, x0, solver: str, budget: int) -> tuple[np.ndarray, int]:
    res = solvers.get(solver).solve(problem, x0=x0, budget=budget, rng=np.random.default_rng(0))
    return problem.to_full(res.x)[0], res.nfev


def fit_model(model: Model, data: PositionsData, g_local: float, x0=None, *, solver: str = "lm",
              budget: int = 2000, rank: int | None = None) -> Fit:
    """Least-squares fit of ``model`` to ``data`` with the named solver; ``rank`` by default from the
    observability at the fitted point."""
    problem = CalibrationProblem(model, data, g_local=g_local)
    x, nfev = _solve(problem, x0, solver, budget)
    if rank is None:
        rank = observability(problem, x).rank
    return Fit(model, problem, x, problem.residuals_full(x)[0], rank, nfev)


def score(current: Fit, term: str, *, solver: str = "lm", budget: int = 2000) -> Score:
    """Refit with ``term`` added (warm start: current fit, new parameters zero) and test the gain."""
    ext = extend(current, term)
    if not isinstance(ext, Extension):
        return ext  # skipped, with the reason
    x, nfev = _solve(ext.problem, ext.x0, solver, budget)
    return nested_test(current, ext, x, nfev)


def discover(data: PositionsData, base: str | Model = "linear9", candidates=None, g_local: float = 1.0,
             alpha: float = DEFAULT_ALPHA, bic_threshold: float = DEFAULT_BIC_THRESHOLD, *,
             noise_g: float | None = None, max_steps: int | None = None, solver: str = "lm",
             budget: int = 2000) -> DiscoveryReport:
    """Forward selection of the missing terms (see :mod:`optcal.discovery.statistics` for the tests).

    ``noise_g``: input-referred noise of each position's mean per axis, in g; by default from the data's
    ``n`` and ``sx, sy, sz`` (else unknown, and the verdict says so).
    """
    if not 0.0 < alpha < 1.0:
        raise InputError(f"alpha must be between 0 and 1, got {alpha}")
    if noise_g is not None and not noise_g > 0:
        raise InputError(f"noise_g must be positive, got {noise_g}")
    model = get_model(base)
    pool = candidate_pool(model, candidates)
    current = fit_model(model, data, g_local, solver=solver, budget=budget)
    notes = []
    if current.rank < model.n_params:
        notes.append(f"base {model.name} has {model.n_params - current.rank} unobservable direction(s) on these "
                     "positions; degrees of freedom use its rank")
    initial, steps, last_round = current, [], []
    while pool and (max_steps is None or len(steps) < max_steps):
        scores = [score(current, t, solver=solver, budget=budget) for t in pool]
        best = best_of(scores)
        k = sum(s.tested for s in scores)
        threshold = alpha / max(k, 1)
        if best is None or not (best.p_value < threshold and best.delta_bic < bic_threshold):
            last_round = scores
            break
        sigma = residual_sigma(best.fit, noise_g if noise_g is not None else current.problem.noise_g)
        sd, _ = crlb(best.fit.problem, best.fit.x, sigma)
        stderr = {n: float(sd[best.fit.model.index(n)]) for n in TERMS[best.term].params}
        alternatives = [s.term for s in scores if s.tested and s is not best and s.delta_bic < best.delta_bic + 2.0]
        steps.append(Step(best.term, current, best.fit, best, scores, threshold, stderr, alternatives))
        current = best.fit
        pool = [t for t in pool if t != best.term]
    sigma_j = noise_per_position(current, noise_g, notes)
    floor = None if sigma_j is None else float(np.sqrt(np.mean(sigma_j**2)))
    gof = None
    if noise_g is None and sigma_j is not None:
        fit = goodness_of_fit(current.problem, current.x)
        gof = fit if fit.expected_chi2 is not None else None  # a recording's floor: judged as calibrate does
    return DiscoveryReport(model.name, initial, current, steps, last_round, alpha, bic_threshold, floor, sigma_j,
                           notes, gof)
