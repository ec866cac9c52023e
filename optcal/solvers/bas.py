"""Beetle antennae search, BAS (Jiang & Li, "BAS: beetle antennae search algorithm for optimization
problems", arXiv:1710.10724, 2017), for minimisation, as in ``docs/algorithms.md``, "Beetle antennae search (`bas`)".

The helpers every search method shares (the unit-box view and start, non-finite costs) are in
``optcal.solvers._unitbox``.
"""

from __future__ import annotations

import numpy as np

from optcal.solvers._unitbox import clip_unit, normalised_start, uniform_pm1, unit_rows
from optcal.solvers.base import Option, Solver, positive
from optcal.solvers.registry import register


def unit_directions(rng: np.random.Generator, k: int, n: int) -> np.ndarray:
    """k random directions b = r / (ε + ‖r‖), r ~ U(-1, 1)^n (BAS Eq. 1; BSAS Eq. 1)."""
    return unit_rows(uniform_pm1(rng, (k, n)))


def sign_of_difference(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """sign(a − b) with a tie of two infinite costs read as 0 (no information) instead of NaN."""
    with np.errstate(invalid="ignore"):
        return np.nan_to_num(np.sign(a - b), nan=0.0)


class DrawAhead:
    """Per-iteration draws ``rng.uniform(-1, 1, shape)``, drawn for many iterations at once.

    NumPy's generators fill an array one double after the other in C order, so one draw of shape
    (k, *shape) holds exactly the numbers of k consecutive per-iteration draws, in the same order.
    Iterating hands them out one iteration at a time (through ``transform``, applied to each block at
    once), at most ``iterations`` of them. ``settle`` (call it however the search ends) leaves ``rng``
    where per-iteration draws would have left it: it restores the state saved before the current block
    and draws again what was taken from it, so a run cut short by its budget, its callback or an error
    leaves the generator as it was, for the next user of the same ``rng`` (the stages of ``staged:``).
    """

    BLOCK_DOUBLES = 8192  # at most this many doubles per block (64 KiB)

    def __init__(self, rng: np.random.Generator, shape: tuple, iterations: int, transform=None):
        self.rng, self.shape, self.transform = rng, tuple(shape), transform
        self.iterations = int(iterations)
        self.size = max(1, int(np.prod(self.shape)))
        self.rows = max(1, self.BLOCK_DOUBLES // self.size)
        self.state, self.drawn, self.used = None, 0, 0  # rows in the current block, rows taken from it

    def __iter__(self):
        left = self.iterations
        while left > 0:
            k = min(self.rows, left)
            self.state = self.rng.bit_generator.state
            block = uniform_pm1(self.rng, (k, *self.shape))
            block = block if self.transform is None else self.transform(block)
            self.drawn, self.used, left = k, 0, left - k
            for row in block:
                self.used += 1
                yield row

    def settle(self) -> None:
        if self.used < self.drawn:
            self.rng.bit_generator.state = self.state
            if self.used:
                self.rng.random(self.used * self.size)  # one double per number, as uniform draws them
            self.drawn = self.used


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
        n, T = zp.n, cfg["iterations"]
        d, step = cfg["d_init"], cfg["step_init"]
        eta_d, d_floor, eta_step = cfg["eta_d"], cfg["d_floor"], cfg["eta_step"]
        cost_batch = zp.cost_batch
        # Per iteration: a few ufuncs writing into these, and two calls of the problem.
        antennae = np.empty((2, n))
        arms = np.empty((2, 1))  # (d, −d): the antennae are z + arms·b
        db = np.empty(n)
        here = z[None]  # z as a batch of one (a view: z is updated in place)
        directions = DrawAhead(rng, (n,), T, transform=unit_rows)  # the numbers of one draw per iteration
        cost_batch(here)
        try:
            for t, b in zip(range(1, T + 1), directions):
                arms[0, 0], arms[1, 0] = d, -d
                np.multiply(arms, b, out=antennae)
                clip_unit(np.add(antennae, z, out=antennae))
                f_right, f_left = cost_batch(antennae).tolist()
                f_right = f_right if f_right < np.inf else np.inf  # NaN counts as +inf
                f_left = f_left if f_left < np.inf else np.inf
                # z − δ·b·sign(f_right − f_left); a tie (both +inf included) leaves z where it is
                if f_right != f_left:
                    np.multiply(b, -step if f_right > f_left else step, out=db)
                    clip_unit(np.add(z, db, out=z))
                cost_batch(here)  # x always moves; the problem keeps the best point
                d = eta_d * d + d_floor
                step = eta_step * step
                callback(t)
        finally:
            directions.settle()
        return {"nit": T, "status": 0, "message": "maximum number of iterations reached",
                "success": True, "extra": {"step": step, "d": d}}
