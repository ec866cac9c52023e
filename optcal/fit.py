"""Fitting a positions data set end to end: problem, solver (from the registry, by name), standard errors,
observability and goodness of fit.

Application layer (CONTRIBUTING.md, "Layers"): this module runs a solver, so it imports ``solvers``; the
core modules it builds on (problem, analysis, data, model, presets) do not. The import is inside
:func:`get_solver` only because importing the solver modules loads their back-ends (cvxpy, CasADi, NLopt).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .analysis import GoodnessOfFit, Observability, crlb, goodness_of_fit, observability
from .data import PositionsData
from .errors import InputError
from .model import Model, get_model
from .presets import Presets
from .problem import CalibrationProblem

# A fit whose χ² has a p-value below this does not match the stated noise (see `calibrate`).
MISFIT_P = 1e-3


def get_solver(name: str, **options):
    """A configured solver from the registry (``solvers.registry.get``: a name, a ``wrapper:inner`` or a
    ``family:NAME``; docs/design.md §10)."""
    import solvers

    return solvers.get(name, **options)


@dataclass
class Calibration:
    """A fitted calibration: parameters, standard errors and diagnostics."""

    model: Model
    x: np.ndarray
    stderr: np.ndarray
    observability: Observability
    fit: GoodnessOfFit
    problem: CalibrationProblem
    solver: str
    result: object  # the SolverResult
    notes: list = field(default_factory=list)  # what the user should know about these numbers

    @property
    def parameters(self) -> dict[str, float]:
        return self.model.to_dict(self.x)

    def to_dict(self) -> dict:
        r = self.result
        return {
            "model": self.model.name,
            "terms": list(self.model.terms),
            "parameters": self.parameters,
            "stderr": {n: (None if not np.isfinite(s) else float(s)) for n, s in zip(self.model.names, self.stderr)},
            "rms_residual_g": self.fit.rms_g,
            "cost": self.fit.cost,
            "n_positions": len(self.problem.data),
            "g_local": self.problem.g_local,
            "solver": self.solver,
            "observability": self.observability.to_dict(),
            "notes": list(self.notes),
            "nfev": r.nfev, "nit": r.nit, "runtime_s": r.runtime_s, "success": r.success, "message": r.message,
        }


def calibrate(data: PositionsData, model: str | Model = "nonlinear12", *, solver: str = "scipy-lm",
              options: dict | None = None, g_local: float = 1.0, reference: bool = False,
              presets: Presets | None = None, seed: int | None = 0, budget=None, x0=None,
              noise_g: float | None = None) -> Calibration:
    """Fit ``model`` to ``data`` with the named solver and report parameters with standard errors."""
    model = get_model(model)
    problem = CalibrationProblem(model, data, g_local=g_local, reference=reference, presets=presets,
                                 noise_g=noise_g)
    obs = observability(problem)
    if obs.rank < model.n_params and presets is None and not model.name == "seed15":
        dirs = "; ".join(" ".join(f"{w['weight']:+.2f}·{w['name']}" for w in d) for d in obs.unobservable)
        raise InputError(
            f"these positions leave model {model.name} unobservable (rank {obs.rank} of {model.n_params}; "
            f"directions: {dirs}); use more varied positions or a smaller model"
        )
    slv = get_solver(solver, **(options or {}))
    rng = np.random.default_rng(seed)
    result = slv.solve(problem, x0=x0, budget=budget, rng=rng)
    x = problem.to_full(result.x)[0]
    obs = observability(problem, x)
    gof = goodness_of_fit(problem, x)
    sigma, notes = gof.sigma_g, []
    if gof.p_value is not None and gof.p_value < MISFIT_P:
        # The residuals are larger than the noise of the position means (the within-interval scatter of a
        # recording, or the given noise): the model misses an effect, or the positions were not static.
        # Bounds from that noise would be too small; scale them by the Birge ratio sqrt(χ²/dof), which
        # is the residual-based noise estimate (Birge 1932; the usual practice in metrology).
        birge = float(np.sqrt(gof.chi2 / gof.dof))
        sigma = gof.sigma_g * birge
        notes.append(f"chi2/dof = {gof.chi2 / gof.dof:.3g} (p = {gof.p_value:.2g}): the residuals exceed the noise "
                     f"of the position means, so the standard errors are scaled by the Birge ratio {birge:.3g}; "
                     "the model may miss an effect (try optcal discover)")
    sd, _ = crlb(problem, x, sigma)
    return Calibration(model, x, sd, obs, gof, problem, solver, result, notes)
