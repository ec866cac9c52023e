"""Next-best pose and "enough yet?" (docs/planning.md, "Next-best pose and "enough yet?"").

Given the directions recorded so far (estimated from the data by the closed-form linear fit, which needs no
solver), the next pose is the candidate whose information, added to what is recorded, most lowers the
criterion: F(c) = F₀ + f_c f_cᵀ for every candidate at once, then (hand-held) refined on the sphere with the
recorded directions held. Before the model is determined (F₀ singular) a ridge of RIDGE of the mean
information per position stands in for the missing information, so the first poses still have an order
(the regularised criterion of Bayesian design); hand-held, the first poses then come from the D-optimal
design of r positions (r the observable dimension, ``plan:D<r>``): the pose of that design farthest from
every recorded direction, until the model is determined. "Enough yet?" compares the Cramér-Rao SD of the recorded
directions, each parameter against its target.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from optcal.core.data import PositionsData
from optcal.core.errors import InputError
from optcal.core.plan.criteria import Criterion
from optcal.core.plan.design import RIDGE, moved, tangent_frame
from optcal.core.plan.fixtures import candidates
from optcal.core.problem import CalibrationProblem


def recorded_directions(model, data: PositionsData, g_local: float = 1.0) -> np.ndarray:
    """Unit specific-force directions (n, 3) of recorded positions, from the closed-form linear fit (the
    problem's centre without presets): the calibration's own start, good to the sensor's linear errors."""
    problem = CalibrationProblem(model, data, g_local=g_local, check=False, fix_gauge=False)
    A = problem.specific_force(problem.centre)
    return A / np.linalg.norm(A, axis=1, keepdims=True)


@dataclass(frozen=True)
class Progress:
    n: int
    value: float  # the criterion of the recorded directions (inf: not determined yet)
    sd: np.ndarray  # (p,) Cramér-Rao SD of each parameter, in its unit (inf: not determined)
    met: np.ndarray | None  # targets met, per parameter (None without targets)

    @property
    def enough(self) -> bool:
        return self.met is not None and bool(np.all(self.met))


def progress(crit: Criterion, recorded: np.ndarray) -> Progress:
    d = np.asarray(recorded, float)
    if len(d) == 0:
        p = crit.info.model.n_params
        return Progress(0, np.inf, np.full(p, np.inf), None if not crit.targets else np.zeros(len(crit.targets), bool))
    F = crit.info.information(d[None])
    sd = crit.info.sd(F)[0]
    met = None
    if crit.targets:
        idx, t = crit.target_index
        met = sd[idx] <= t
    return Progress(len(d), float(crit.of_information(F)[0]), sd, met)


def next_best(crit: Criterion, recorded: np.ndarray, fixture: str = "free", grid: int = 1000,
              refine: bool = True) -> tuple[np.ndarray, float]:
    """The next direction (3,) and the criterion after adding it (with the ridge while undetermined)."""
    cands, continuous = candidates(fixture, grid)
    d0 = np.asarray(recorded, float).reshape(-1, 3)
    if continuous and not np.isfinite(progress(crit, d0).value):
        from optcal.core.plan.design import planned_directions

        base = planned_directions("D", crit.info.n_observable, crit.info.model.name)
        if len(d0):
            gap = np.min(np.arccos(np.clip(base @ d0.T, -1.0, 1.0)), axis=1)
            pick = base[int(np.argmax(gap))]
        else:
            pick = base[int(np.argmax(base[:, 2]))]  # start with the pose closest to "z up"
        F = crit.info.information(np.vstack([d0, pick])[None])
        return pick, float(crit.of_information(F, smooth=True, ridge=_ridge(crit, cands))[0])
    R = crit.info.projected_rows(cands)
    outer = R[:, :, None] * R[:, None, :]
    r = R.shape[1]
    ridge = RIDGE * np.trace(outer.mean(axis=0)) / r
    F0 = crit.info.information(d0[None])[0] if len(d0) else np.zeros((r, r))
    vals = crit.of_information(F0 + outer, smooth=True, ridge=ridge)
    c = int(np.argmin(vals))
    best, val = cands[c], float(vals[c])
    if refine and continuous:
        from scipy.optimize import minimize

        e1, e2 = tangent_frame(best[None])
        step = 1e-6 * np.eye(2)

        def f(t):
            T = np.vstack([t, t + step, t - step])
            dd = moved(best[None], e1, e2, T)[:, 0]
            Rn = crit.info.projected_rows(dd)
            with np.errstate(divide="ignore"):
                v = np.log(crit.of_information(F0 + Rn[:, :, None] * Rn[:, None, :], smooth=True, ridge=ridge))
            g = (v[1:3] - v[3:]) / 2e-6
            return float(v[0]), (g if np.all(np.isfinite(g)) else np.zeros(2))

        res = minimize(f, np.zeros(2), jac=True, method="L-BFGS-B", bounds=[(-0.5, 0.5)] * 2)
        if np.isfinite(res.fun) and np.exp(res.fun) < val:
            best, val = moved(best[None], e1, e2, res.x[None])[0, 0], float(np.exp(res.fun))
    return best, val


def _ridge(crit: Criterion, cands: np.ndarray) -> float:
    R = crit.info.projected_rows(cands)
    return RIDGE * float(np.sum(R * R)) / len(R) / R.shape[1]


def check_reachable(crit: Criterion, n_max: int = 200, fixture: str = "free") -> None:
    """Refuse targets that no number of positions up to ``n_max`` reaches (they would never be met): the
    bound falls as 1/√N for a fixed design, so targets are reachable at N positions when a design of
    r positions (r the observable dimension) reaches them scaled by √(N/r)."""
    if crit.kind != "targets":
        return
    from optcal.core.plan.design import plan

    r = crit.info.n_observable
    d = plan(crit, max(r, 12), fixture=fixture, rng=np.random.default_rng(0), starts=1)
    best = d.value * np.sqrt(d.n / n_max)
    if best > 1.0:
        raise InputError(f"the targets are out of reach: even {n_max} well-spread positions give SDs "
                         f"{best:.2g} times the tightest target at this noise; loosen the targets or lower "
                         "the noise (longer dwell per position)")
