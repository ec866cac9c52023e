"""The ``ellipsoid`` solver: the convex (SDP) ellipsoid fit of the position means, turned into ``linear9``
parameters (docs/design.md, "The installation matrix T"; the fit itself, its equations and its checks are in
:mod:`optcal.solvers._ellipsoid_fit`, which the solver contract also uses for the local methods' default start).

Terms beyond ``linear9`` (nonlinear, temperature, drift) are set to zero: for those models the fit is a
one-shot initialiser, not an optimiser.
"""

from __future__ import annotations

from optcal.core.errors import InputError
from optcal.core.model import Model
from optcal.solvers._ellipsoid_fit import (
    LINEAR,
    check_ellipsoid,
    ellipsoid_start,
    fit_ellipsoid,
    fit_problem,
    fit_to_vector,
)
from optcal.solvers.base import Option, Solver
from optcal.solvers.registry import register

__all__ = ["Ellipsoid", "check_ellipsoid", "ellipsoid_start", "fit_ellipsoid", "fit_to_vector"]


@register
class Ellipsoid(Solver):
    """Convex (SDP) ellipsoid fit of the position means → scale, bias and gauge misalignment."""

    name = "ellipsoid"
    family = "convex"
    requires = ("cvxpy",)
    default_budget = 1
    options = {
        "solver": Option("auto", str, "cvxpy solver", choices=("auto", "CLARABEL", "SCS")),
        "polish": Option(True, bool, "solve the KKT system when the semidefinite constraint is inactive"),
    }

    def start_point(self, problem, x0):
        """The method needs no starting point (``x0`` is ignored). Data that cannot be an ellipsoid are
        refused here, before the run, with an InputError (one line from the CLI) rather than reported as
        a failed run; the check is exact and cheap (:func:`check_ellipsoid`), the fit itself is timed."""
        if not isinstance(problem.model, Model):  # the gyroscope's problem (optcal.core.gyro) has no ‖A‖ to fit
            raise InputError("the ellipsoid fit is the accelerometer's convex fit of ‖A‖; use a least-squares or "
                             "search solver for this problem")
        if problem.reference:
            fit_problem(problem)  # raises: the fit needs the norm cost
        check_ellipsoid(problem.data.N, problem.g_local, misalignment="misalignment" in problem.model.groups())
        return problem.x0

    def _solve(self, problem, x0, rng, callback):
        fit = fit_problem(problem, self.config["solver"], self.config["polish"])
        problem.cost(problem.from_full(fit_to_vector(problem.model, fit)))
        callback(1)
        others = [n for t in problem.model.terms if t not in LINEAR for n in _term_params(t)]
        how = f"convex ellipsoid fit ({fit['solver']}{', polished' if fit['polished'] else ''})"
        if others:
            how += (f"; the terms beyond linear9 ({', '.join(others)}) are set to 0: a one-shot initialiser, "
                    "not an optimiser of this model")
        return {"nit": 1, "status": 0, "success": True, "message": how, "extra": {"fit": fit}}


def _term_params(term: str) -> tuple[str, ...]:
    from optcal.core.model import TERMS

    return TERMS[term].params
