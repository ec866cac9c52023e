"""Optimal artificial fish swarm algorithm, ``oafsa``: standard AFSA with attenuated visual and step and
an automatic secondary initialisation (the 2015 seed paper §3, after Gao et al. [18-20] and Wang et al. [26]).

Schedule (docs/algorithms.md, "Optimal artificial fish swarm (`oafsa`)"; the 2015 paper §3.1, whose equation did not
survive in
the stored copy): at generation t = 1..T,

    α(t) = exp(−30·(t/T)^s),  visual_t = visual_0·α(t) + visual_min,  step_t = step_0·α(t) + step_min

applied to the initial values (not recursively).

Secondary initialisation (§3.2): the paper stops the run by hand when the indicator function stalls,
stores the best coefficients and restarts the school from them. Here that manual step is automated:
when the bulletin board's best cost has not improved for ``stall_iterations`` generations, the school
is re-drawn uniformly within the current visual around the best point (one fish on it) and the run
goes on with the schedule where it was. ``stall_iterations = 0`` turns the restart off.

Defaults (the paper's values are lost): visual_0 and step_0 as ``afsa`` (0.05 and 0.025 of the box
half-width), floors a tenth of them, s = 3, restart after 8 stalled generations (the paper restarts
about 10 generations after its indicator function stops improving, Figure 5).
"""

from __future__ import annotations

import numpy as np

from optcal.solvers import _fish
from optcal.solvers.afsa import FISH_OPTIONS, AFSABase
from optcal.solvers.base import Option, positive
from optcal.solvers.registry import register


def attenuation(t, T: int, s: float):
    """α(t) = exp(−30·(t/T)^s)."""
    return np.exp(-30.0 * (np.asarray(t, float) / T) ** s)


def schedule(t, T: int, s: float, initial: float, minimum: float):
    """visual_t (or step_t) = initial·α(t) + minimum."""
    return initial * attenuation(t, T, s) + minimum


@register
class OAFSA(AFSABase):
    """Standard AFSA (``afsa``) with visual and step attenuated by α(t) and automatic restarts around
    the best point when the best cost stalls (see the module docstring)."""

    name = "oafsa"
    options = {
        **FISH_OPTIONS,
        "visual": Option(0.05, float, "initial visual visual_0 (unit-box units)", check=positive, check_doc="> 0"),
        "step": Option(0.025, float, "initial step step_0 (unit-box units)", check=positive, check_doc="> 0"),
        "visual_min": Option(5e-3, float, "visual floor visual_min", check=lambda v: v >= 0, check_doc=">= 0"),
        "step_min": Option(2.5e-3, float, "step floor step_min", check=lambda v: v >= 0, check_doc=">= 0"),
        "s": Option(3.0, float, "exponent s of the attenuation exp(-30 (t/T)^s)", check=positive,
                    check_doc="> 0"),
        "crowd": Option(0.618, float, "crowd factor δ: a target is accepted when nf/N < δ",
                        check=lambda v: 0 < v <= 1, check_doc="in (0, 1]"),
        "stall_iterations": Option(8, int, "restart around the best after this many generations without "
                                   "improvement (0: never)", check=lambda v: v >= 0, check_doc=">= 0"),
    }

    def _solve(self, problem, x0, rng, callback):
        c = self.config
        T = c["iterations"]
        ev, board, X, f = self._school(problem, x0, rng, c["visual"] + c["visual_min"])
        # The last solve's schedule, also kept on the solver since a run stopped by its budget returns no extra.
        self.history = {"visual": [], "step": [], "restarts": []}
        visuals, steps, restarts = self.history["visual"], self.history["step"], self.history["restarts"]
        best, stall = board.f, 0
        for t in range(1, T + 1):
            visual = float(schedule(t, T, c["s"], c["visual"], c["visual_min"]))
            step = float(schedule(t, T, c["s"], c["step"], c["step_min"]))
            visuals.append(visual)
            steps.append(step)
            X, f = _fish.afsa_generation(ev, X, f, visual, step, c["crowd"], c["try_number"], rng)
            stall = 0 if board.f < best else stall + 1
            best = board.f
            if c["stall_iterations"] and stall >= c["stall_iterations"] and t < T:
                X = _fish.initial_school(board.x, visual, c["n_fish"], rng)
                f = ev(X)
                restarts.append(t)
                stall = 0
            callback(t)
        return {"nit": T, "message": f"completed {T} iterations ({len(restarts)} restarts)",
                "extra": dict(self.history)}
