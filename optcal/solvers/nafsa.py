"""Novel artificial fish swarm algorithm, ``nafsa`` (Gao, Guan & Wang, "Triaxial accelerometer error
coefficients identification with a novel artificial fish swarm algorithm", Journal of Sensors 2015,
509143, §4; after Yazdani et al. 2013).

docs/algorithms.md, "Novel artificial fish swarm (`nafsa`)", in the problem's normalised coordinates. Step and crowd
factor are gone; the visual is a vector with one entry per dimension, set per parameter group (§4.1 and §6.1: the paper
gives each category of coefficients its own visual). One generation:

1. Individual behaviour (§4.2.1, prey + free move): each fish makes up to ``try_number`` probes
   Xj = Xi + visual ⊙ U(−1, 1)^D (Eq. 1 with the vector visual) and moves *to* the first probe with
   f(Xj) < f(Xi) (Eq. 10: "the movement distance would be less than or equal to visual in the same
   dimension"; reading chosen: the fish takes the improving probe itself, already evaluated); if no
   probe improves, it moves at random within its visual (Eq. 11), whatever the cost there.
2. Group behaviour (§4.2.2, swarm + follow over the whole school, no neighbourhood search): Xc is the
   centre of the school (Eq. 3). Where f(Xc) < f(Xi) the fish moves Xi + rand ⊙ (Xc − Xi) (Eq. 12,
   rand ~ U(0, 1)^D); otherwise towards the best, Xi + rand ⊙ (Xbest − Xi) (Eq. 13). If the centre
   is better than the best, it becomes the best (Eq. 14). Fish always move; the bulletin board is
   never overwritten with a worse point (§4.2.1).
3. Contraction (§4.1, Eqs. 8-9): CF ~ U(CF_min, CF_max) drawn once per generation, and
   visual ← CF · visual (reading chosen: recursive, as docs/algorithms.md, "Novel artificial fish swarm (`nafsa`)"
   states, not CF · visual_0; the geometric mean of U(0, 1) is 1/e, so the visual shrinks by about e per generation and
   the late generations are driven by the group behaviour). The paper's CF_min, CF_max = 1e-6, 0.999999.

The school starts uniformly within the visual of the start point (the presets or the initialiser;
§6.1 starts from the conventional calibration), one fish on it. Evaluations per generation, in at
most ``try_number + 2`` batched calls: the probes (one call per try, only the fish still searching),
the random moves together with the centre, and the N group moves.

Defaults: the paper's 50 fish, 60 iterations and CF range; its visual and try number (Table 1) are
lost, so visual = 0.05 of the box half-width for every group (as ``afsa``) and 20 tries. The try
number matters more than for AFSA: with CF ~ U(1e-6, 0.999999) applied recursively the visual shrinks
by about e per generation (and for good after one small draw), so the first generations' probes are
the method's only local search. Measured median cost / optimum − 1 over 10 seeds, visual 0.05, on the
24-position ``nonlinear12`` problem from presets (tests/test_fish.py): 5 tries → 2.4, 10 → 1.6,
20 → 1.15, 40 → 1.16; on its scale+bias restriction (the conformance suite's): 5 → 2.9, 10 → 0.67,
20 → 0.32, 40 → 0.37. The results are heavy-tailed (an early small CF freezes the school; worst of
10 seeds at 20 tries: 1.3 on the restriction), a property of the paper's CF range, not of the tries.
"""

from __future__ import annotations

import json

import numpy as np

from optcal.core.errors import InputError
from optcal.core.model import TERMS
from optcal.solvers import _fish
from optcal.solvers._unitbox import clip_unit
from optcal.solvers.afsa import FISH_OPTIONS
from optcal.solvers.base import Option, Solver, positive
from optcal.solvers.registry import register

GROUPS = tuple(dict.fromkeys(t.group for t in TERMS.values()))


def _parse_visual(value, solver: str):
    """A positive number, or {group: positive number}; strings "0.1", "scale=0.1,bias=0.2" or JSON."""
    if isinstance(value, str):
        text = value.strip()
        try:
            value = json.loads(text) if text.startswith("{") else float(text)
        except ValueError:
            try:
                value = {k.strip(): float(v) for k, v in (p.split("=", 1) for p in text.split(","))}
            except ValueError:
                raise InputError(f"solver {solver}: option visual={text!r} must be a number or "
                                 "GROUP=VALUE,... (groups: " + ", ".join(GROUPS) + ")") from None
    if isinstance(value, dict):
        bad = sorted(set(value) - set(GROUPS))
        if bad:
            raise InputError(f"solver {solver}: option visual names unknown group(s) {', '.join(bad)}; "
                             f"groups are {', '.join(GROUPS)}")
        try:
            value = {k: float(v) for k, v in value.items()}
        except (TypeError, ValueError):
            raise InputError(f"solver {solver}: option visual must map groups to numbers") from None
        if not all(np.isfinite(v) and v > 0 for v in value.values()):
            raise InputError(f"solver {solver}: every visual entry must be a positive number, got {value}")
        return value
    if not (np.isfinite(value) and value > 0):
        raise InputError(f"solver {solver}: option visual={value!r} is invalid; it must be > 0")
    return float(value)


def visual_vector(problem, visual, default: float) -> np.ndarray:
    """One visual entry per free parameter of ``problem``, from its model's groups (unit-box units).

    ``visual`` is a number (every group) or {group: value}; groups it does not name take ``default``."""
    per_group = visual if isinstance(visual, dict) else {}
    fill = default if isinstance(visual, dict) else visual
    group_of = {i: g for g, idx in problem.model.groups().items() for i in idx}
    return np.array([per_group.get(group_of[int(i)], fill) for i in problem.free])


@register
class NAFSA(Solver):
    """Novel AFSA (the 2015 paper §4): individual and group behaviour, per-group visual vector and a
    random contraction factor; see the module docstring for the readings chosen where the paper's
    equations are lost."""

    name = "nafsa"
    family = "metaheuristic"
    default_budget = 50000
    VISUAL_DEFAULT = 0.05
    options = {
        **FISH_OPTIONS,
        "try_number": Option(20, int, "individual-behaviour probes per fish and generation", check=positive,
                             check_doc="> 0"),
        "visual": Option(VISUAL_DEFAULT, (float, dict, str),
                         "initial visual per dimension (unit-box units): a number, or {group: number} "
                         f"for the groups {', '.join(GROUPS)} (others take {VISUAL_DEFAULT})"),
        "cf_min": Option(1e-6, float, "lower end of the contraction factor CF ~ U(cf_min, cf_max)",
                         check=lambda v: 0 < v < 1, check_doc="in (0, 1)"),
        "cf_max": Option(0.999999, float, "upper end of the contraction factor",
                         check=lambda v: 0 < v < 1, check_doc="in (0, 1)"),
    }

    def check_config(self) -> None:
        c = self.config
        c["visual"] = _parse_visual(c["visual"], self.name)
        if c["cf_min"] > c["cf_max"]:
            raise InputError(f"solver {self.name}: cf_min={c['cf_min']} is above cf_max={c['cf_max']}; "
                             "give cf_min <= cf_max")

    def _solve(self, problem, x0, rng, callback):
        c = self.config
        zp = problem.normalised()
        z0 = _fish.start_z(problem, zp, x0)
        visual = visual_vector(zp, c["visual"], self.VISUAL_DEFAULT)
        board = _fish.Board(z0)
        ev = _fish.Evaluator(zp, board)
        N = c["n_fish"]
        # The last solve's contraction factors and visuals (a run stopped by its budget returns no extra).
        self.history = {"cf": [], "visual": [visual.copy()]}
        X = _fish.initial_school(z0, visual, N, rng)
        f = ev(X)
        for it in range(1, c["iterations"] + 1):
            # Individual behaviour: prey, then a random move for the fish whose probes all failed.
            X, f, found = _fish.prey(ev, X, f, visual, c["try_number"], rng)
            lost = np.flatnonzero(~found)
            X[lost] = _fish.free_move(X[lost], visual, rng)
            Xc = X.mean(axis=0)  # the centre after every fish has moved, evaluated with the random moves
            fr = ev(np.vstack([X[lost], Xc]))
            f[lost], fc = fr[:-1], fr[-1]  # the board took the centre if it beats the best (Eq. 14)
            # Group behaviour: towards the centre where it is better, else towards the best.
            target = np.where((fc < f)[:, None], Xc, board.x)
            move = rng.random(X.shape)  # rand ~ U(0, 1)^D per fish: the numbers of rng.uniform(0, 1, X.shape)
            move *= np.subtract(target, X, out=target)
            X = clip_unit(np.add(X, move, out=move))
            f = ev(X)
            cf = rng.uniform(c["cf_min"], c["cf_max"])
            visual = cf * visual
            self.history["cf"].append(cf)
            self.history["visual"].append(visual.copy())
            callback(it)
        return {"nit": c["iterations"], "message": f"completed {c['iterations']} iterations",
                "extra": dict(self.history)}
