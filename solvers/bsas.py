"""Beetle swarm antennae search, BSAS (Wang & Chen, "BSAS: Beetle Swarm Antennae Search Algorithm for
Optimization Problems", arXiv:1807.10470, 2018), as in ``docs/ALGORITHMS.md`` §BSAS, with the parameters
the 2020 calibration paper names (m, p_pos, p_st, η, s0, d0)."""

from __future__ import annotations

import numpy as np

from .bas import finite_costs, normalised_start, unit_directions
from .base import Option, Solver, positive, probability
from .registry import register


def _sign2(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """sign(a − b) with 0 read as +1 (the toolbox's ``sign2``); a tie of two infinite costs is a tie too."""
    with np.errstate(invalid="ignore"):
        s = np.sign(a - b)
    return np.where(s == 0.0, 1.0, np.nan_to_num(s, nan=1.0))


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
    d = δ/c (rBAS ``BSAS_WPT``; ALGORITHMS.md's "tuned" variant), replaces d's own schedule: ``d_init``
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
        zp, z = normalised_start(problem, x0)
        n = zp.n
        step = cfg["step_init"]
        d = cfg["d_init"] if c is None else step / c
        f_best = finite_costs(zp.cost_batch(z[None]))[0]
        flag = 0
        for t in range(1, cfg["iterations"] + 1):
            b = unit_directions(rng, m, n)
            antennae = np.clip(np.concatenate([z + b * (d / 2), z - b * (d / 2)]), -1.0, 1.0)
            f_ant = finite_costs(zp.cost_batch(antennae))
            s = _sign2(f_ant[:m], f_ant[m:])
            moves = np.clip(z - step * b * s[:, None], -1.0, 1.0)
            f_moves = finite_costs(zp.cost_batch(moves))
            better = np.flatnonzero(f_moves < f_best)
            if better.size:
                i = int(np.argmin(f_moves)) if rng.random() < cfg["p_pos"] else int(rng.choice(better))
                z, f_best = moves[i], f_moves[i]
            elif rng.random() < cfg["p_st"] or flag > cfg["n_flag"]:
                step = cfg["eta"] * step + cfg["s0"]
                d = cfg["eta"] * d + cfg["d0"] if c is None else step / c
                flag = 0
            else:
                flag += 1
            callback(t)
            if step < cfg["step_tol"]:
                return {"nit": t, "status": 0, "message": f"step {step:.3g} below step_tol", "success": True,
                        "extra": {"step": step, "d": d}}
        return {"nit": cfg["iterations"], "status": 0, "message": "maximum number of iterations reached",
                "success": True, "extra": {"step": step, "d": d}}
