"""Standard artificial fish swarm algorithm, ``afsa`` (Li Xiaolei, Shao Zhijiang & Qian Jixin, "An
optimizing method based on autonomous animats: fish-swarm algorithm", Systems Engineering — Theory &
Practice 22(11), 2002; the 2015 seed paper §2 as SAFSA).

Update rules: docs/algorithms.md, "Standard artificial fish swarm (`afsa`)", in the problem's normalised coordinates
(the unit box
around the presets or the initialiser; 2020 paper §3.4). The behaviours are in :mod:`optcal.solvers._fish`.
"""

from __future__ import annotations

from optcal.core.errors import InputError
from optcal.solvers import _fish
from optcal.solvers.base import Option, Solver, positive
from optcal.solvers.registry import register

FISH_OPTIONS = {
    "n_fish": Option(50, int, "number of fish N (the 2015 paper: 50)", check=positive, check_doc="> 0"),
    "iterations": Option(60, int, "generations (the 2015 paper: 60)", check=positive, check_doc="> 0"),
    "try_number": Option(5, int, "prey probes per behaviour", check=positive, check_doc="> 0"),
}


class AFSABase(Solver):
    """Common set-up of the school for ``afsa`` and ``oafsa``."""

    family = "metaheuristic"
    default_budget = 100000

    def check_config(self) -> None:
        if self.config["n_fish"] < 2:
            raise self._error("n_fish", "at least 2 (the swarm and follow behaviours need neighbours)")

    def _error(self, name, need):
        return InputError(f"solver {self.name}: option {name}={self.config[name]!r} is invalid; it must be {need}")

    def _school(self, problem, x0, rng, spread):
        zp = problem.normalised()
        z0 = _fish.start_z(problem, zp, x0)
        board = _fish.Board(z0)
        ev = _fish.Evaluator(zp, board)
        X = _fish.initial_school(z0, spread, self.config["n_fish"], rng)
        return ev, board, X, ev(X)


@register
class AFSA(AFSABase):
    """Standard AFSA: prey, swarm, follow and free move with a fixed visual, step, crowd factor δ and try
    number; each fish tries swarm and follow and keeps the better; a bulletin board keeps the best.

    The school starts uniformly within ``visual`` (per coordinate) of the start point, with one fish on
    it. Per generation it evaluates the neighbourhood centres, the prey probes of the behaviours that
    fall back on prey (one batched call per try), and the 2N behaviour results.

    Defaults: the 2015 paper's 50 fish and 60 iterations; its visual, step and try number did not
    survive in the stored copy, so visual = 0.05 of the box half-width (the scale of the presets'
    error on the 24-position problem, shared by the family), step = visual/2, δ = 0.618, 5 tries. The
    fixed visual decides what the method can reach (measured on a 24-position ``nonlinear12`` problem
    from presets, median cost / optimum − 1 over 5 seeds: visual 0.01 → 1.3, 0.02 → 2.3, 0.05 → 8.9,
    ≥ 0.1 → no progress). With a Euclidean visual in 12 dimensions and the school spread over ±visual,
    fish seldom see a neighbour, so prey and free move do most of the work: that is the standard
    algorithm's behaviour, not a defect of this implementation.
    """

    name = "afsa"
    options = {
        **FISH_OPTIONS,
        "visual": Option(0.05, float, "visual range (unit-box units, Euclidean)", check=positive, check_doc="> 0"),
        "step": Option(0.025, float, "maximum step (unit-box units)", check=positive, check_doc="> 0"),
        "crowd": Option(0.618, float, "crowd factor δ: a target is accepted when nf/N < δ",
                        check=lambda v: 0 < v <= 1, check_doc="in (0, 1]"),
    }

    def _solve(self, problem, x0, rng, callback):
        c = self.config
        ev, board, X, f = self._school(problem, x0, rng, c["visual"])
        for it in range(1, c["iterations"] + 1):
            X, f = _fish.afsa_generation(ev, X, f, c["visual"], c["step"], c["crowd"], c["try_number"], rng)
            callback(it)
        return {"nit": c["iterations"], "message": f"completed {c['iterations']} iterations"}
