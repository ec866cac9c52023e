"""Beetle swarm antennae search, BSAS (Wang & Chen, "BSAS: Beetle Swarm Antennae Search Algorithm for
Optimization Problems", arXiv:1807.10470, 2018), as in ``docs/algorithms.md``, "Beetle swarm antennae search
(`bsas`)", with the parameters
the 2020 calibration paper names (m, p_pos, p_st, η, s0, d0)."""

from __future__ import annotations

import numpy as np

from optcal.solvers._unitbox import clip_unit, nan_to_inf, normalised_start, unit_rows
from optcal.solvers.base import Option, Solver, positive, probability
from optcal.solvers.registry import register


class _Draws:
    """BSAS's random numbers drawn ahead for several iterations at once, the same numbers in the same order.

    An iteration draws its m directions, r ~ U(−1, 1)^(m×n), then one U(0, 1) number for its decision
    (greedy or random pick, or step update): m·n + 1 doubles, the same count every iteration. NumPy's
    generators fill arrays one double after the other, and ``uniform(-1, 1)`` is −1 + 2·``random()``
    bit for bit, so one ``random((k, m·n + 1))`` holds k iterations' numbers. The pick of a random
    better beetle (``rng.choice``) draws integers, not doubles, from wherever the generator is:
    ``sync`` first puts it where per-iteration draws would have left it (the state saved before the
    block, advanced by drawing again the doubles taken), and the next iteration starts a new block.
    ``sync`` also ends every run, so the generator is left as the per-iteration draws would leave it.
    Blocks start at 4 iterations and double, up to 64 iterations or about 16k doubles, while no sync cuts
    them short.
    """

    def __init__(self, rng: np.random.Generator, m: int, n: int, iterations: int):
        self.rng, self.m, self.n, self.width = rng, m, n, m * n + 1
        self.left = iterations  # iterations not yet drawn
        self.max_rows = max(4, min(64, 16384 // self.width))
        self.rows = 4  # iterations in the next block
        self.k = self.j = self.taken = 0  # iterations in the block, iterations done, doubles taken

    def directions(self) -> np.ndarray:
        """The next iteration's m unit directions b = r / (ε + ‖r‖) (BAS Eq. 1), (m, n)."""
        if self.j == self.k:
            self.k, self.j = min(self.rows, self.left), 0
            self.left -= self.k
            self.state = self.rng.bit_generator.state
            u = self.rng.random((self.k, self.width))
            r = np.multiply(u[:, :-1], 2.0)
            r -= 1.0  # rng.uniform(-1, 1)'s own arithmetic, −1 + 2·u (see _unitbox.uniform_pm1)
            self.b = unit_rows(r.reshape(self.k, self.m, self.n))
            self.u = u[:, -1].tolist()
            self.rows = min(2 * self.rows, self.max_rows)
        self.taken = self.j * self.width + self.width - 1
        return self.b[self.j]

    def uniform(self) -> float:
        """This iteration's U(0, 1) number (after its directions)."""
        self.j += 1
        self.taken = self.j * self.width
        return self.u[self.j - 1]

    def sync(self) -> None:
        if self.taken < self.k * self.width:
            self.rng.bit_generator.state = self.state
            if self.taken:
                self.rng.random(self.taken)
            self.left += self.k - self.j
            self.rows = 4
        self.k = self.j = self.taken = 0


@register
class BSAS(Solver):
    """Beetle swarm antennae search (Wang & Chen 2018, arXiv:1807.10470), for minimisation.

    Each iteration sends m beetles (the paper's k antenna pairs) from the current position x along
    random unit directions b_i = r_i / (ε + ‖r_i‖) (the BAS direction rule, Jiang & Li 2017 Eq. 1);
    beetle i probes its antennae x_l = x + b_i·d/2 and x_r = x − b_i·d/2 and proposes
    x_i = x − δ·b_i·sign(f(x_l) − f(x_r)) (the BAS search rule, for minimisation). The paper's swarm
    and "feedback-based step-size update strategy" make the update elitist: if some x_i beats the best
    cost, x moves to the best of them with probability p_pos, otherwise to one of the better ones picked
    uniformly, and δ, d stay; if none does, the step rule shrinks δ = η_δ·δ + s0 and d = η_d·d + d0 with
    probability p_st, or unconditionally once it has been skipped more than n_flag times in a row.
    The search stops early when δ falls below ``step_tol``.

    Toolbox choices (the first author's BASmatlab ``BSASoptim.m`` / rBAS ``BSASoptim.R``, where the paper
    leaves details open): antennae at ±d/2 (``antenna.m``); a tie of the antennae counts as sign +1
    (``sign2.m``); the greedy pick is taken when a uniform draw is below p_pos (``Pgreedy``) and the step
    update when a draw is below p_st (``PstepUpdate``); δ and d shrink together (``pupdate.m``); every
    point is clipped to the box (``bounds.m``). The 2020 paper's values (§4.1: minimum resolutions
    s0 = d0 = 2.22e-16, MATLAB's eps) and the toolbox's p_pos = p_st = 0.8, n_flag = 3, η = 0.95 are the
    defaults, with one η for step and antenna as the 2020 paper names it (the toolbox allows two);
    m = 10 is the beetle count whose convergence the 2020 paper's Fig. 3 shows best. ``step_init`` and
    ``d_init`` are optcal's choices for the unit box, the same as ``bas``'s (the paper's Table 2 did not
    survive in the stored copy). With ``c`` set, the variant that ties the antenna to the step,
    d = δ/c (rBAS ``BSAS_WPT``; docs/algorithms.md, "Beetle swarm antennae search (`bsas`)"), replaces d's own
    schedule: ``d_init``
    and ``d0`` are then unused.

    The search runs in the problem's unit-box coordinates z ∈ [-1, 1]^n from ``x0`` (the presets or the
    initialiser, 2020 paper §3.4). All 2m antennae are one batched evaluation and the m candidate moves
    another: 3m evaluations per iteration, plus one for the start.
    """

    name = "bsas"
    family = "metaheuristic"
    options = {
        "m": Option(10, int, "number of beetles (antenna pairs) per iteration, the toolbox's k",
                    check=positive, check_doc="> 0"),
        "step_init": Option(0.03, float, "initial step δ (unit-box units)", check=positive, check_doc="> 0"),
        "d_init": Option(0.03, float, "initial antenna length d (unit-box units)", check=positive,
                         check_doc="> 0"),
        "eta": Option(0.95, float, "decay η of step and antenna (η_δ = η_d, as in the 2020 paper)",
                      check=lambda v: 0.0 < v <= 1.0, check_doc="in (0, 1]"),
        "s0": Option(2.22e-16, float, "minimum step resolution added at each step update",
                     check=lambda v: v >= 0.0, check_doc=">= 0"),
        "d0": Option(2.22e-16, float, "minimum antenna resolution added at each antenna update",
                     check=lambda v: v >= 0.0, check_doc=">= 0"),
        "p_pos": Option(0.8, float, "probability of moving to the best better beetle (else a random better one)",
                        check=probability, check_doc="in [0, 1]"),
        "p_st": Option(0.8, float, "probability of updating step and antenna when no beetle improves",
                       check=probability, check_doc="in [0, 1]"),
        "n_flag": Option(3, int, "skipped step updates after which the update is forced",
                         check=lambda v: v >= 0, check_doc=">= 0"),
        "step_tol": Option(1e-12, float, "stop when the step falls below this", check=lambda v: v >= 0.0,
                           check_doc=">= 0"),
        "iterations": Option(600, int, "maximum number of iterations T", check=positive, check_doc="> 0"),
        "c": Option(None, float, "ratio δ/d of the tuned variant (None: independent d)",
                    check=lambda v: v is None or v > 0, check_doc="> 0 or None"),
    }

    def __init__(self, **options):
        super().__init__(**options)
        # Without a budget, exactly what T iterations use: 1 start + 3m per iteration.
        self.default_budget = 1 + 3 * self.config["m"] * self.config["iterations"]

    def _solve(self, problem, x0, rng, callback):
        cfg = self.config
        m, c = cfg["m"], cfg["c"]
        eta, s0, d0, p_pos, p_st, n_flag = cfg["eta"], cfg["s0"], cfg["d0"], cfg["p_pos"], cfg["p_st"], cfg["n_flag"]
        zp, z = normalised_start(problem, x0)
        n = zp.n
        step = cfg["step_init"]
        d = cfg["d_init"] if c is None else step / c
        cost_batch = zp.cost_batch
        # Per iteration: a few ufuncs on these (m, n) and (2m, n) arrays, and two calls of the problem.
        antennae = np.empty((2 * m, n))
        left, right = antennae[:m], antennae[m:]
        moves = np.empty((m, n))
        f_best = zp.cost_batch(z[None])[0]
        f_best = float(f_best) if f_best < np.inf else np.inf  # NaN counts as +inf
        flag = 0
        draws = _Draws(rng, m, n, cfg["iterations"])
        try:
            for t in range(1, cfg["iterations"] + 1):
                b = draws.directions()
                np.multiply(b, d / 2, out=left)
                np.subtract(z, left, out=right)
                np.add(z, left, out=left)
                clip_unit(antennae)
                f_ant = cost_batch(antennae)
                nan_to_inf(f_ant)
                # x − δ·b·sign2(f(x_l) − f(x_r)): sign2 is −1 where the left antenna is better, else +1
                # (a tie, two infinite costs included, counts as +1)
                np.multiply(b, step, out=moves)
                np.negative(moves, out=moves, where=(f_ant[:m] >= f_ant[m:])[:, None])
                clip_unit(np.add(z, moves, out=moves))
                f_moves = cost_batch(moves)
                i = nan_to_inf(f_moves)
                if f_moves[i] < f_best:  # some beetle beats the best: move (greedy with probability p_pos)
                    if draws.uniform() >= p_pos:
                        draws.sync()
                        i = int(rng.choice(np.flatnonzero(f_moves < f_best)))
                    z, f_best = moves[i].copy(), float(f_moves[i])
                elif draws.uniform() < p_st or flag > n_flag:
                    step = eta * step + s0
                    d = eta * d + d0 if c is None else step / c
                    flag = 0
                else:
                    flag += 1
                callback(t)
                if step < cfg["step_tol"]:
                    return {"nit": t, "status": 0, "message": f"step {step:.3g} below step_tol", "success": True,
                            "extra": {"step": step, "d": d}}
        finally:
            draws.sync()
        return {"nit": cfg["iterations"], "status": 0, "message": "maximum number of iterations reached",
                "success": True, "extra": {"step": step, "d": d}}
