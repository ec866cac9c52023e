"""The order of the poses and the rotation of each motion that minimise a criterion of the gyroscope's
information (docs/planning.md, "Planning the rotations"; the candidates and their information in :mod:`.gyro`).

The information of a plan is the rests' (which do not depend on the order) plus one term per motion, so a
plan is a path through the poses with one candidate rotation on each step. The search is a local search
with whole neighbourhoods scored in one batch (after the exchange algorithm of :mod:`.design`: Fedorov 1972,
Cook and Nachtsheim 1980):

* rotations: every other candidate on every step, F − F_k + F_c for all of them at once; the best
  replacement is made while one improves the criterion;
* order: every swap of two poses, every move of one pose elsewhere and every reversal of a stretch (2-opt),
  each new step taking the candidate of its pair that adds most to the current information (a step kept
  from the current path keeps its rotation); the best move is made, then the rotations again, while one
  improves the criterion.

A step that no candidate joins (opposite poses; with turns about the sensor's axes only, two poses that share
no component along an axis) counts before the criterion: a starting order that has such steps is first
repaired by the same moves. It starts from the given order and from ``restarts`` − 1 random orders (drawn
from the user's generator) and keeps the best plan. The habitual plan, for comparison, is the given order
with the shortest rotation between consecutive poses.
"""

from __future__ import annotations

import numpy as np

from optcal.core.errors import InputError
from optcal.core.gyro.plan import Candidates, MotionPlan, criterion, information

CHUNK = 256  # plans scored per batch (memory: CHUNK·N·p² numbers)
# A weak prior, this share of the mean information per motion on every parameter, orders plans that do not
# determine the model yet (as the planner's ridge for positions, :mod:`.design`); the plan is scored without it.
RIDGE = 1e-8
ORDERS = ("plan", "given")
ROTATIONS = ("plan", "axes", "shortest")


class _Search:
    """The candidates, the criterion, the ridge, the motion budget (s; inf: none) and the rotations allowed
    (``options``: all, or only the turns about the sensor's axes) of one search."""

    def __init__(self, cands: Candidates, kind: str, budget_s: float, rotations: str):
        self.c, self.kind, self.budget, self.rotations = cands, kind, budget_s, rotations
        self.ridge = RIDGE * float(np.trace(cands.info.mean(axis=0))) / cands.info.shape[1]
        n = len(cands.U)
        self.shortest = cands.shortest_of(*np.meshgrid(np.arange(n), np.arange(n), indexing="ij"))
        O = cands.options
        self.options = O if rotations != "axes" else np.where(cands.about_axis[np.maximum(O, 0)], O, -1)
        T = np.where(self.options >= 0, cands.duration[np.maximum(self.options, 0)], np.inf)
        self.quickest = np.where(np.isfinite(T.min(axis=-1)),
                                 np.take_along_axis(self.options, np.argmin(T, axis=-1)[..., None], -1)[..., 0], -1)

    def scores(self, choices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The number of steps without a rotation (−1: opposite poses, or no turn about a sensor axis joins them)
        and the criterion with the ridge, those steps adding nothing, of plans (B, N − 1) of candidate ids
        (inf where the motions take longer than the budget). Plans compare by the first, then the second."""
        missing = np.sum(choices < 0, axis=1)
        ch = np.where(choices < 0, 0, choices)
        time = np.where(choices < 0, 0.0, self.c.duration[ch]).sum(axis=1)
        out = np.empty(len(ch))
        for s in range(0, len(ch), CHUNK):
            F = information(self.c, ch[s:s + CHUNK]) - missing[s:s + CHUNK, None, None] * self.c.info[0]
            out[s:s + CHUNK] = criterion(F, self.kind, self.ridge)
        out[time > self.budget * (1 + 1e-12)] = np.inf
        return missing, out

    def polish(self, order: np.ndarray, choice: np.ndarray) -> tuple[np.ndarray, float]:
        """Best replacement of one step's rotation at a time (within the budget), while one improves the
        criterion."""
        c = self.c
        v = c.vertex[order]
        O = self.options[v[:-1], v[1:]]
        p = c.info.shape[1]
        choice = choice.copy()
        F = information(c, choice[None])[0]
        cur = float(self.scores(choice[None])[1][0])
        while True:
            Fc = F[None, None] - c.info[choice][:, None] + c.info[np.maximum(O, 0)]
            vals = criterion(Fc.reshape(-1, p, p), self.kind, self.ridge).reshape(O.shape)
            total = c.duration[choice].sum() - c.duration[choice][:, None] + c.duration[np.maximum(O, 0)]
            vals[(O < 0) | (total > self.budget * (1 + 1e-12))] = np.inf
            k, o = np.unravel_index(int(np.argmin(vals)), vals.shape)
            if not vals[k, o] < cur * (1 - 1e-12):
                return choice, cur
            F = F - c.info[choice[k]] + c.info[O[k, o]]
            choice[k] = O[k, o]
            cur = float(vals[k, o])

    def best_options(self, F: np.ndarray) -> np.ndarray:
        """For every ordered pair of directions, the candidate that adds most to F (−1: none), by the D gain
        log det(F + RᵀR) − log det F = log det(I₂ + R·F⁻¹·Rᵀ) of its two rows R (the matrix determinant lemma:
        one 2 × 2 determinant per candidate; a ranking, for any criterion)."""
        R = self.c.rows
        Fi = np.linalg.inv(F + self.ridge * np.eye(len(F)))
        G = np.einsum("mrp,pq,msq->mrs", R, Fi, R)
        gain = np.log((1 + G[:, 0, 0]) * (1 + G[:, 1, 1]) - G[:, 0, 1] * G[:, 1, 0])
        O = self.options
        vals = np.where(O >= 0, gain[np.maximum(O, 0)], -np.inf)
        best = np.take_along_axis(O, np.argmax(vals, axis=-1)[..., None], -1)[..., 0]
        return np.where(np.isfinite(vals.max(axis=-1)), best, -1)

    def local(self, order: np.ndarray, move_order: bool) -> tuple[np.ndarray, np.ndarray, float]:
        """Local search from ``order``: the plan and its criterion (with the ridge)."""
        v = self.c.vertex
        # each step starts as its pair's best rotation; with a budget, as its quickest (shortest: always)
        base = self.shortest if self.rotations == "shortest" else self.quickest if np.isfinite(self.budget) else None
        first = base if base is not None else self.best_options(self.c.rest_info[v].sum(axis=0))
        choice = first[v[order[:-1]], v[order[1:]]]
        miss, cur = (float(x[0]) for x in self.scores(choice[None]))
        if self.rotations != "shortest" and miss == 0 and np.isfinite(cur):
            choice, cur = self.polish(order, choice)
        while move_order:
            edge = (base.copy() if base is not None
                    else self.best_options(information(self.c, np.maximum(choice, 0)[None])[0]))
            ok = choice >= 0
            edge[v[order[:-1]][ok], v[order[1:]][ok]] = choice[ok]  # a step the move keeps keeps its rotation
            P = neighbours(order)
            C = edge[v[P[:, :-1]], v[P[:, 1:]]]
            missing, vals = self.scores(C)
            k = int(np.lexsort((vals, missing))[0])
            if not (missing[k] < miss or (missing[k] == miss and vals[k] < cur * (1 - 1e-12))):
                break
            order, choice, miss, cur = P[k], C[k], float(missing[k]), float(vals[k])
            if self.rotations != "shortest" and miss == 0:
                choice, cur = self.polish(order, choice)
        return order, choice, cur


def neighbours(order: np.ndarray) -> np.ndarray:
    """Every swap of two poses, reversal of a stretch and move of one pose to another place of ``order``."""
    n = len(order)
    i, j = np.triu_indices(n, 1)
    swaps = np.tile(order, (len(i), 1))
    swaps[np.arange(len(i)), i], swaps[np.arange(len(i)), j] = order[j], order[i]
    pos = np.arange(n)[None]
    inside = (pos >= i[:, None]) & (pos <= j[:, None])
    reversals = order[np.where(inside, i[:, None] + j[:, None] - pos, pos)]
    a, b = np.nonzero(~np.eye(n, dtype=bool))  # the pose at place a moved to place b
    rest = np.delete(np.tile(order, (n, 1)), np.arange(n) * (n + 1)).reshape(n, n - 1)[a]
    src = np.clip(np.where(pos < b[:, None], pos, pos - 1), 0, n - 2)
    moves = np.take_along_axis(rest, src, axis=1)
    moves[np.arange(len(a)), b] = order[a]
    return np.vstack([swaps, reversals, moves])


def habitual(cands: Candidates, order: np.ndarray | None = None, kind: str = "D") -> MotionPlan:
    """The poses in ``order`` (default: the scheme's), each motion the shortest rotation."""
    order = np.arange(len(cands.poses)) if order is None else np.asarray(order, int)
    v = cands.vertex[order]
    choice = cands.shortest_of(v[:-1], v[1:])
    if np.any(choice < 0):
        k = int(np.flatnonzero(choice < 0)[0])
        raise InputError(f"poses {k + 1} and {k + 2} of the given order are opposite: no single turn of less than "
                         "180° joins them (its axis would be ambiguous); plan the order, or put a pose between them")
    return MotionPlan(cands, order, choice, kind)


def search(cands: Candidates, kind: str = "D", *, order: str = "plan", rotations: str = "plan", restarts: int = 3,
           budget_s: float | None = None, given: np.ndarray | None = None,
           rng: np.random.Generator) -> MotionPlan:
    """The best plan found: the poses' order (``order`` "plan", or "given": ``given``, default the scheme's)
    and the rotations (``rotations`` "plan": any candidate; "axes": turns about the sensor's own axes, which a
    hand or a dividing head makes most easily; "shortest") minimising criterion ``kind``, the motions taking
    at most ``budget_s`` seconds in all (None: no limit)."""
    if order not in ORDERS:
        raise InputError(f"unknown order {order!r}; use {' or '.join(ORDERS)}")
    if rotations not in ROTATIONS:
        raise InputError(f"unknown rotations {rotations!r}; use {' or '.join(ROTATIONS)}")
    if not (isinstance(restarts, int | np.integer) and 1 <= restarts <= 100):
        raise InputError(f"restarts = {restarts!r}: give 1 to 100 starting orders")
    if budget_s is not None and not (np.isfinite(budget_s) and budget_s > 0):
        raise InputError(f"the motion budget must be a positive number of seconds, got {budget_s!r}")
    n = len(cands.poses)
    start = np.arange(n) if given is None else np.asarray(given, int)
    if order == "given" and rotations == "shortest" and budget_s is None:
        return habitual(cands, start, kind)
    run = _Search(cands, kind, np.inf if budget_s is None else float(budget_s), rotations)
    starts = [start] + ([rng.permutation(n) for _ in range(restarts - 1)] if order == "plan" else [])
    o, c, v = min((run.local(s, order == "plan") for s in starts), key=lambda r: (np.sum(r[1] < 0), r[2]))
    if np.any(c < 0):
        turn = "a turn about a sensor axis" if rotations == "axes" else "a single turn of less than 180°"
        if order == "given":
            raise InputError(f"the given order has consecutive poses that no {turn[2:]} joins; plan the order "
                             "(--order plan)" + (", or allow any rotation (--rotations plan)" if rotations == "axes"
                                                 else ", or put a pose between opposite ones"))
        raise InputError(f"no order of these poses joins every two consecutive ones by {turn}; "
                         + ("allow any rotation (--rotations plan)" if rotations == "axes"
                            else "put a pose between opposite ones"))
    if not np.isfinite(v):
        raise InputError(f"no plan of these poses fits the motion budget of {budget_s:g} s at this rate limit; "
                         "allow more time, or raise the rate limit")
    return MotionPlan(cands, o, c, kind)
