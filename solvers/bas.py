"""Beetle antennae search, BAS (Jiang & Li, "BAS: beetle antennae search algorithm for optimization
problems", arXiv:1710.10724, 2017), for minimisation, as in ``docs/ALGORITHMS.md`` §BAS.

Also holds the two helpers the swarm searches of this package share: the unit-box view of a problem
(2020 paper §3.4: parameters of very different magnitudes must be searched at a similar scale) and the
rule that a non-finite cost counts as +inf.
"""

from __future__ import annotations

import numpy as np

from .base import Option, Solver, positive
from .registry import register

EPS = np.finfo(float).eps


def normalised_start(problem, x0) -> tuple[object, np.ndarray]:
    """The problem's unit-box view z ∈ [-1, 1]^n (x = centre + halfwidth·z) and ``x0`` mapped into it.

    The view shares the problem's evaluation counter, so the budget and the best point are kept by the
    problem whichever coordinates the search works in. A start outside the box is clipped into it.
    """
    zp = problem if problem.is_normalised else problem.normalised()
    z0 = zp.from_full(problem.to_full(x0)[0])
    return zp, np.clip(z0, -1.0, 1.0)


def finite_costs(f) -> np.ndarray:
    """Costs with NaN and ±inf replaced by +inf, so that a failed evaluation never looks good."""
    f = np.asarray(f, float)
    return np.where(np.isfinite(f), f, np.inf)


def unit_directions(rng: np.random.Generator, k: int, n: int) -> np.ndarray:
    """k random directions b = r / (ε + ‖r‖), r ~ U(-1, 1)^n (BAS Eq. 1; BSAS Eq. 1)."""
    r = rng.uniform(-1.0, 1.0, (k, n))
    return r / (EPS + np.linalg.norm(r, axis=1, keepdims=True))


def sign_of_difference(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """sign(a − b) with a tie of two infinite costs read as 0 (no information) instead of NaN."""
    with np.errstate(invalid="ignore"):
        return np.nan_to_num(np.sign(a - b), nan=0.0)


@register
class BAS(Solver):
    """Beetle antennae search (Jiang & Li 2017, arXiv:1710.10724), for minimisation.

    Each iteration t draws one random unit direction b (paper Eq. 1), probes the right and left antennae
    x_r = x + d·b and x_l = x − d·b (Eq. 2), and always steps away from the worse one,
    x = x − δ·b·sign(f(x_r) − f(x_l)) (Eq. 3, written for minimisation); the best point is kept apart
    (the problem keeps it). Antenna length and step decay as in the paper (Eqs. 4–5):
    d = η_d·d + d0 and δ = η_δ·δ, with η_d = η_δ = 0.95 and d0 = 0.01 by default. Points are clipped to
    the box.

    The search runs in the problem's unit-box coordinates z ∈ [-1, 1]^n and starts from ``x0`` (the
    presets or the initialiser, 2020 paper §3.4), not from a random point. The two antennae are one
    batched evaluation and the move another: three evaluations per iteration, plus one for the start.
    A tie of the antennae (sign 0, also when both are non-finite) leaves x where it is, as ``sign`` does
    in the paper.

    ``d_init`` and ``step_init`` are optcal's choices for the unit box (the paper's values are for its
    test functions): presets err by about 1/40 of the default box half-widths, so the optimum lies a few
    hundredths from the start, and of δ0 = 0.01, 0.02, 0.03, 0.05 and 0.1, 0.03 gave BAS its lowest median
    final cost on the 2020 paper's setting (tests/test_beetles_pso.py). δ shrinks by 0.95 per iteration,
    so after the default 400 iterations (1201 evaluations, the default budget) it is 1.2e-9 of its start
    and x no longer moves.
    """

    name = "bas"
    family = "metaheuristic"
    options = {
        "d_init": Option(0.03, float, "initial antenna length d (unit-box units)", check=positive, check_doc="> 0"),
        "step_init": Option(0.03, float, "initial step δ (unit-box units)", check=positive, check_doc="> 0"),
        "eta_d": Option(0.95, float, "antenna decay η_d in d = η_d·d + d_floor",
                        check=lambda v: 0.0 < v <= 1.0, check_doc="in (0, 1]"),
        "eta_step": Option(0.95, float, "step decay η_δ in δ = η_δ·δ",
                           check=lambda v: 0.0 < v <= 1.0, check_doc="in (0, 1]"),
        "d_floor": Option(0.01, float, "constant d0 added to the antenna length each iteration",
                          check=lambda v: v >= 0.0, check_doc=">= 0"),
        "iterations": Option(400, int, "number of iterations T", check=positive, check_doc="> 0"),
    }

    def __init__(self, **options):
        super().__init__(**options)
        # Without a budget, exactly what T iterations use: 1 start + 3 per iteration.
        self.default_budget = 1 + 3 * self.config["iterations"]

    def _solve(self, problem, x0, rng, callback):
        cfg = self.config
        zp, z = normalised_start(problem, x0)
        n = zp.n
        d, step = cfg["d_init"], cfg["step_init"]
        zp.cost_batch(z[None])
        for t in range(1, cfg["iterations"] + 1):
            b = unit_directions(rng, 1, n)[0]
            antennae = np.clip(np.stack([z + d * b, z - d * b]), -1.0, 1.0)
            f_right, f_left = finite_costs(zp.cost_batch(antennae))
            z = np.clip(z - step * b * sign_of_difference(f_right, f_left), -1.0, 1.0)
            zp.cost_batch(z[None])  # x always moves; the problem keeps the best point
            d = cfg["eta_d"] * d + cfg["d_floor"]
            step = cfg["eta_step"] * step
            callback(t)
        return {"nit": cfg["iterations"], "status": 0, "message": "maximum number of iterations reached",
                "success": True, "extra": {"step": step, "d": d}}
