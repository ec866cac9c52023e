"""Global-best particle swarm optimisation with Clerc-Kennedy constriction, synchronous and vectorised
(``docs/algorithms.md``, "Particle swarm optimisation (`pso`)")."""

from __future__ import annotations

import numpy as np

from optcal.solvers._unitbox import clip_unit, finite_costs, nan_to_inf, normalised_start
from optcal.solvers.base import Option, Solver, positive
from optcal.solvers.registry import register


@register
class PSO(Solver):
    """Global-best PSO (Kennedy & Eberhart 1995) with the constriction coefficients of Clerc & Kennedy
    (2002, "The particle swarm — explosion, stability, and convergence", IEEE TEC 6(1)):
    χ = 0.7298 and c1 = c2 = χ·2.05 = 1.49618, in the inertia form of Bratton & Kennedy (2007):

        v = w·v + c1·r1 ⊙ (p − x) + c2·r2 ⊙ (g − x);  x = clip(x + v),   r1, r2 ~ U(0, 1) fresh each step.

    Synchronous: the whole swarm moves, is evaluated in one batched call, then personal bests p update
    on strict improvement and the global best g is taken over them. A non-finite cost counts as +inf.
    ``v_clamp`` (optional) limits each velocity component to that fraction of the box width.

    The swarm lives in the problem's unit box z ∈ [-1, 1]^n (2020 paper §3.4): particles start uniform
    in the box, one of them at ``x0`` (the presets or the initialiser; ``init="uniform"`` leaves it out),
    with zero velocity (Engelbrecht 2012, "Particle swarm optimization: velocity initialization", CEC: zero initial
    velocities keep particles from leaving a bounded space early). Evaluations: n_particles per iteration plus the
    initial swarm.
    """

    name = "pso"
    family = "metaheuristic"
    options = {
        "n_particles": Option(40, int, "swarm size", check=lambda v: v >= 2, check_doc=">= 2"),
        "w": Option(0.7298, float, "inertia (constriction) weight", check=lambda v: 0.0 <= v < 1.0,
                    check_doc="in [0, 1)"),
        "c1": Option(1.49618, float, "cognitive coefficient", check=lambda v: v >= 0.0, check_doc=">= 0"),
        "c2": Option(1.49618, float, "social coefficient", check=lambda v: v >= 0.0, check_doc=">= 0"),
        "iterations": Option(500, int, "number of iterations", check=positive, check_doc="> 0"),
        "v_clamp": Option(None, float, "maximum speed per coordinate as a fraction of the box width (None: off)",
                          check=lambda v: v is None or v > 0, check_doc="> 0 or None"),
        "init": Option("start", str, "initial swarm: uniform in the box with x0 as one particle ('start') or "
                       "without it ('uniform')", choices=("start", "uniform")),
    }

    def __init__(self, **options):
        super().__init__(**options)
        # Without a budget, exactly what the iterations use: the initial swarm plus one swarm per iteration.
        self.default_budget = self.config["n_particles"] * (self.config["iterations"] + 1)

    def _solve(self, problem, x0, rng, callback):
        cfg = self.config
        w, c1, c2 = cfg["w"], cfg["c1"], cfg["c2"]
        zp, z0 = normalised_start(problem, x0)
        n_p, n = cfg["n_particles"], zp.n
        vmax = None if cfg["v_clamp"] is None else 2.0 * cfg["v_clamp"]  # the box is 2 wide
        x = rng.uniform(-1.0, 1.0, (n_p, n))
        if cfg["init"] == "start":
            x[0] = z0
        v = np.zeros_like(x)
        # p (personal bests) and g (the global best, broadcast to every particle) in one array, so that
        # p − x and g − x are one ufunc call; every array is updated in place.
        pg = np.empty((2, n_p, n))
        p, g = pg
        p[...] = x
        f_p = finite_costs(zp.cost_batch(x))
        g[...] = p[f_p.argmin()]
        coeffs = np.array([c1, c2])[:, None, None]
        diff, r = np.empty_like(pg), np.empty_like(pg)
        for t in range(1, cfg["iterations"] + 1):
            rng.random(out=r)  # r1, r2: the numbers of rng.random((2, n_p, n))
            # v = w·v + c1·r1 ⊙ (p − x) + c2·r2 ⊙ (g − x), the terms in that order
            np.multiply(r, coeffs, out=r)
            np.subtract(pg, x, out=diff)
            np.multiply(r, diff, out=r)
            np.multiply(v, w, out=v)
            np.add(v, r[0], out=v)
            np.add(v, r[1], out=v)
            if vmax is not None:
                np.clip(v, -vmax, vmax, out=v)
            clip_unit(np.add(x, v, out=x))
            f = zp.cost_batch(x)
            nan_to_inf(f)
            improved = f < f_p
            np.copyto(p, x, where=improved[:, None])
            np.copyto(f_p, f, where=improved)
            g[...] = p[f_p.argmin()]
            callback(t)
        return {"nit": cfg["iterations"], "status": 0, "message": "maximum number of iterations reached",
                "success": True}
