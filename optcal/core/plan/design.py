"""Planning N positions: the exchange algorithm over a fixture's candidates, then (hand-held) a continuous
refinement on the sphere (docs/planning.md, "Method").

Exchange: the modified Fedorov algorithm (Cook & Nachtsheim 1980, "A comparison of algorithms for
constructing exact D-optimal designs", Technometrics 22(3), after Fedorov 1972): each design point in turn is
replaced by the candidate that most improves the criterion, and passes repeat until none does. All K
replacements of one point are scored in one batched call (F − f_i f_iᵀ + f_c f_cᵀ for every candidate c),
for any criterion, not only D. A small ridge (1e-8 of the mean information per position) lets a singular
random start improve; the reported criterion has no ridge. Several random starts; the best design is kept.

Refinement: every direction moves in its own tangent plane, a_j = normalise(a⁰_j + t₁ e₁ + t₂ e₂) (smooth
everywhere, unlike polar angles at the poles), and L-BFGS-B (SciPy) minimises the criterion over the 2N
offsets (of the criterion's logarithm), with central-difference gradients evaluated as one population of
4N + 1 designs per step.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from optcal.core.errors import InputError
from optcal.core.plan.criteria import Criterion
from optcal.core.plan.fisher import InformationModel
from optcal.core.plan.fixtures import candidates, to_faces

RIDGE = 1e-8
FD_STEP = 1e-6


def _check_n(crit: Criterion, n: int) -> None:
    r = crit.info.n_observable
    if not (isinstance(n, int | np.integer) and n >= r):
        raise InputError(f"{n} positions cannot determine the {r} observable parameter combinations of model "
                         f"{crit.info.model.name}: plan at least {r} positions")
    if n > 10_000:
        raise InputError(f"{n} positions: plan at most 10,000 (a calibration uses tens)")


def exchange(crit: Criterion, cands: np.ndarray, n: int, rng: np.random.Generator, starts: int = 3,
             max_passes: int = 30, init: np.ndarray | None = None) -> tuple[np.ndarray, float]:
    """Indices (n,) into ``cands`` of the best design found and its criterion (no ridge); the exchange of
    the module docstring from ``starts`` random designs (and from ``init``, indices, when given)."""
    _check_n(crit, n)
    R = crit.info.projected_rows(cands)  # (K, r)
    outer = R[:, :, None] * R[:, None, :]
    r = R.shape[1]
    ridge = RIDGE * np.trace(outer.mean(axis=0)) / r
    K = len(cands)
    inits = [] if init is None else [np.asarray(init, int)]
    inits += [rng.choice(K, n, replace=n > K) for _ in range(starts)]
    best_idx, best_val = None, np.inf
    for idx in inits:
        idx = idx.copy()
        F = outer[idx].sum(axis=0)
        val = crit.of_information(F[None], smooth=True, ridge=ridge)[0]
        for _ in range(max_passes):
            improved = False
            for i in range(n):
                Fm = F - outer[idx[i]]
                vals = crit.of_information(Fm[None] + outer, smooth=True, ridge=ridge)
                c = int(np.argmin(vals))
                if vals[c] < val * (1 - 1e-12):
                    F = F - outer[idx[i]] + outer[c]
                    idx[i], val, improved = c, vals[c], True
            if not improved:
                break
        v = crit.of_information(F[None])[0]
        if v < best_val or best_idx is None:
            best_idx, best_val = idx, v
    return best_idx, float(best_val)


def tangent_frame(d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    helper = np.where(np.abs(d[:, [0]]) < 0.9, np.array([[1.0, 0, 0]]), np.array([[0, 1.0, 0]]))
    e1 = np.cross(d, helper)
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    return e1, np.cross(d, e1)


def moved(d0, e1, e2, T):
    """Directions (S, N, 3) from offsets T (S, 2N)."""
    T = T.reshape(len(T), -1, 2)
    v = d0[None] + T[..., :1] * e1[None] + T[..., 1:] * e2[None]
    return v / np.linalg.norm(v, axis=2, keepdims=True)


def refine(crit: Criterion, directions: np.ndarray, rounds: int = 3, maxiter: int = 200) -> tuple[np.ndarray, float]:
    """The directions after the continuous refinement of the module docstring, and their criterion."""
    from scipy.optimize import minimize  # here: importing optcal stays light

    d = start = np.asarray(directions, float).copy()
    m = 2 * len(d)
    eye = np.eye(m) * FD_STEP
    # targets: the p-norm's p grows (16, 64, 256) so the last rounds minimise nearly the maximum itself
    schedule = [True] * rounds if crit.kind != "targets" else [16] * rounds + [64, 256]
    for smooth in schedule:  # the tangent frames are re-centred after each round
        e1, e2 = tangent_frame(d)

        def f_and_g(t, e1=e1, e2=e2, d=d, smooth=smooth):
            T = np.vstack([t, t + eye, t - eye])
            with np.errstate(divide="ignore"):  # the logarithm: criteria are variances of order σ²
                v = np.log(crit(moved(d, e1, e2, T), smooth=smooth))
            g = (v[1:m + 1] - v[m + 1:]) / (2 * FD_STEP)
            return float(v[0]), (g if np.all(np.isfinite(g)) else np.zeros(m))

        v0 = f_and_g(np.zeros(m))[0]
        if not np.isfinite(v0):
            break
        res = minimize(f_and_g, np.zeros(m), jac=True, method="L-BFGS-B", bounds=[(-0.5, 0.5)] * m,
                       options={"maxiter": maxiter, "ftol": 1e-13, "gtol": 1e-10})
        if not res.fun < v0:
            continue
        d = moved(d, e1, e2, res.x[None])[0]
        if v0 - res.fun < 1e-9 and crit.kind != "targets":
            break
    v, v_start = crit(np.stack([d, start]))  # a smaller p-norm can have a larger maximum: keep the better
    return (d, float(v)) if v <= v_start else (start, float(v_start))


@dataclass
class Design:
    """A planned scheme: directions (N, 3), the criterion's value, every parameter's Cramér-Rao SD (in its
    unit) and how it was found."""

    directions: np.ndarray
    criterion: Criterion
    value: float
    sd: np.ndarray
    fixture: str
    method: str
    notes: list = field(default_factory=list)

    @property
    def n(self) -> int:
        return len(self.directions)

    def faces(self):
        return to_faces(self.directions)


def design_of(crit: Criterion, directions: np.ndarray, fixture: str, method: str) -> Design:
    d = np.asarray(directions, float)
    F = crit.info.information(d[None])
    return Design(d, crit, float(crit.of_information(F)[0]), crit.info.sd(F)[0], fixture, method)


def make_criterion(model="nonlinear12", kind: str = "D", noise_g: float = 10e-6,
                   targets: dict | None = None) -> Criterion:
    info = InformationModel.of(model, noise_g)
    return Criterion(info, kind, dict(targets or {}))


def plan(crit: Criterion, n: int, *, fixture: str = "free", rng: np.random.Generator | None = None,
         grid: int = 1000, starts: int = 3) -> Design:
    """Plan ``n`` positions for ``crit`` on ``fixture``: the exchange over its candidates, refined
    continuously when the fixture is ``free``. Deterministic for a given ``rng`` state."""
    rng = rng if rng is not None else np.random.default_rng(0)
    cands, continuous = candidates(fixture, grid)
    idx, val = exchange(crit, cands, n, rng, starts=starts)
    if not np.isfinite(val):
        raise InputError(f"no {n} positions of fixture {fixture!r} determine model {crit.info.model.name}: "
                         "its candidate directions leave parameters inseparable; use a finer fixture (e.g. "
                         "faces:15 or free) or a smaller model")
    d = cands[idx]
    method = f"exchange over {len(cands)} candidates"
    if continuous:
        d, _ = refine(crit, d)
        method += ", refined on the sphere"
    return design_of(crit, d, fixture, method)


@lru_cache(maxsize=32)
def _planned(kind: str, n: int, model: str) -> np.ndarray:
    return plan(make_criterion(model, kind), n, rng=np.random.default_rng(0)).directions


def planned_directions(kind: str, n: int, model: str = "nonlinear12") -> np.ndarray:
    """The hand-held ``kind``-optimal N positions for ``model`` at nominal parameters, seeded 0: what the
    scheme name ``plan:<kind><N>[:<model>]`` means (:func:`optcal.core.schemes.planned`); computed once per process."""
    return _planned(kind, int(n), model).copy()
