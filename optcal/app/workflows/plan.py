"""Planning with a registered solver (application layer: it imports the solver registry; docs/planning.md, "Method").

The design problem (:class:`optcal.core.plan.problem.DesignProblem`) is solved by any solver that needs only costs
(and, for gradient methods, ``gradient``), from ``starts`` independent random points of the unit box drawn
from the user's generator; the best design is refined on the sphere when the fixture allows it. The exchange
algorithm over the fixture's candidates runs beside it as a check, and the better design is the plan.
"""

from __future__ import annotations

import numpy as np

from optcal.core.errors import InputError
from optcal.core.plan.criteria import Criterion
from optcal.core.plan.design import Design, design_of, exchange, refine
from optcal.core.plan.fixtures import candidates
from optcal.core.plan.problem import DesignProblem

DEFAULT_SOLVER = "cmaes"


def solve_design(crit: Criterion, n: int, *, fixture: str = "free", solver: str = DEFAULT_SOLVER,
                 starts: int = 4, budget: int | None = None, rng: np.random.Generator, grid: int = 1000,
                 options: dict | None = None) -> tuple[Design, dict]:
    """The plan and a record of both methods: {solver, starts: [criterion per start], exchange}."""
    from optcal.app.fit import get_solver

    if not (isinstance(starts, int) and 1 <= starts <= 100):
        raise InputError(f"`starts` = {starts!r}: give 1 to 100 starts of the solver")
    cands, continuous = candidates(fixture, grid)
    ex_idx, ex_val = exchange(crit, cands, n, rng, starts=3)
    if not np.isfinite(ex_val):
        raise InputError(f"no {n} positions of fixture {fixture!r} determine model {crit.info.model.name}: its "
                         "candidate directions leave parameters inseparable; use a finer fixture (e.g. faces:15 or "
                         "free) or a smaller model")
    ex_dirs = cands[ex_idx]
    if continuous and np.isfinite(ex_val):
        ex_dirs, ex_val = refine(crit, ex_dirs)
    record: dict = {"solver": solver, "exchange": float(ex_val), "starts": [], "refined": continuous}
    if solver == "exchange":
        chosen, method = ex_dirs, f"exchange over {len(cands)} candidates" + (", refined" if continuous else "")
    else:
        s = get_solver(solver, **(options or {}))
        problem = DesignProblem(crit, n, None if continuous else cands)
        best_x, best_f = None, np.inf
        for _ in range(starts):
            z0 = rng.uniform(-1.0, 1.0, problem.n)
            try:
                res = s.solve(problem, x0=z0, budget=budget, rng=rng)
            except (AttributeError, NotImplementedError):
                raise InputError(f"solver {solver} needs residuals or a model, which a design problem does not "
                                 "have; use a search method (cmaes, pso, bsas, scipy-de, nlopt-sbplx, ...)") from None
            record["starts"].append(float(res.fun))
            if res.fun < best_f:
                best_x, best_f = res.x, float(res.fun)
        if best_x is None:
            raise InputError(f"solver {solver} found no design that determines model {crit.info.model.name} "
                             f"with {n} positions; use more positions or the exchange (--solver exchange)")
        sd = problem.directions(best_x[None])[0]
        if continuous:
            sd, _ = refine(crit, sd)
        sv = float(crit(sd[None])[0])
        record["solver_value"] = sv
        chosen, method = ((sd, f"{solver}, {starts} starts" + (", refined" if continuous else ""))
                          if sv <= ex_val else (ex_dirs, f"exchange over {len(cands)} candidates (better than "
                                                           f"{solver})"))
    if not np.isfinite(crit(np.asarray(chosen)[None])[0]):
        raise InputError(f"no {n} positions of fixture {fixture!r} determine model {crit.info.model.name}: use a "
                         "finer fixture (faces:15, free) or a smaller model")
    return design_of(crit, chosen, fixture, method), record
