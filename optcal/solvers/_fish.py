"""Shared, vectorised fish behaviours of the artificial fish swarm family (``afsa``, ``oafsa``, ``nafsa``).

Every behaviour acts on the whole school at once: positions are an (N, D) array, costs an (N,) array,
and every point a behaviour needs is evaluated in one call of the problem's batched cost. The only
Python loop is over the prey *tries* (at most ``try_number`` per behaviour), never over fish.

Conventions (docs/algorithms.md, "Conventions shared by the search methods" and "Standard artificial fish swarm
(`afsa`)", written for minimisation):
- the search runs in the problem's normalised coordinates, a unit box z ∈ [−1, 1]^D; ``clip`` keeps
  every point (probes included) inside it;
- a non-finite cost is treated as +inf, so a fish never moves to such a point by comparison;
- the bulletin board keeps the best point ever evaluated and is never overwritten with a worse one.

Prey batching (the choice the issue asks to state): the probes of try k of all fish still searching go
to the problem as ONE call; a fish that found an improving probe drops out of the next tries. The
evaluation count is therefore exactly that of the sequential algorithm (no probe is evaluated that the
one-fish-at-a-time algorithm would not evaluate), at the price of up to ``try_number`` calls per prey.
"""

from __future__ import annotations

import numpy as np

from optcal.solvers._unitbox import clip_unit, nan_to_inf, row_norms, uniform_pm1


class Board:
    """The bulletin board: the best point ever evaluated and its cost (strict improvement only)."""

    def __init__(self, z0: np.ndarray):
        self.x = np.array(z0, float)
        self.f = np.inf

    def update(self, X: np.ndarray, f: np.ndarray) -> None:
        if len(f):
            i = int(np.argmin(f))
            if f[i] < self.f:
                self.x, self.f = X[i].copy(), float(f[i])


class Evaluator:
    """Batched cost of the normalised problem: non-finite costs become +inf, the board is updated."""

    def __init__(self, problem, board: Board):
        self.problem = problem
        self.board = board

    def __call__(self, X: np.ndarray) -> np.ndarray:
        if len(X) == 0:
            return np.empty(0)
        f = self.problem.cost_batch(X)
        i = nan_to_inf(f)  # what Board.update does, with the index the NaN check found anyway
        if f[i] < self.board.f:
            self.board.x, self.board.f = X[i].copy(), float(f[i])
        return f


def clip(X: np.ndarray) -> np.ndarray:
    return np.clip(X, -1.0, 1.0)


def start_z(problem, zproblem, x0) -> np.ndarray:
    """The start point ``x0`` (in ``problem``'s coordinates) in the unit box of ``zproblem``."""
    return clip(zproblem.from_full(problem.to_full(x0)[0]))


def initial_school(z0: np.ndarray, spread, n_fish: int, rng: np.random.Generator) -> np.ndarray:
    """Fish 0 at the start point; the others uniform within ``spread`` (scalar or per dimension) of it."""
    X = clip(z0 + spread * uniform_pm1(rng, (n_fish, z0.size)))
    X[0] = z0
    return X


def free_move(X: np.ndarray, visual, rng: np.random.Generator) -> np.ndarray:
    """Free move (Li 2002): a random point within the visual, clip(Xi + visual·U(−1, 1)^D)."""
    P = uniform_pm1(rng, X.shape)
    np.multiply(P, visual, out=P)
    return clip_unit(np.add(X, P, out=P))


def moveto(X: np.ndarray, T: np.ndarray, step, rng: np.random.Generator) -> np.ndarray:
    """One step towards the targets: clip(Xi + rand·step·(Xt − Xi)/‖Xt − Xi‖), rand ~ U(0, 1) per fish."""
    d = T - X
    norm = row_norms(d)
    unit = np.divide(d, norm, out=np.zeros_like(d), where=norm > 0)
    a = rng.random((len(X), 1))  # rng.uniform(0, 1, ...): the same numbers
    a *= step
    np.multiply(a, unit, out=unit)
    return clip_unit(np.add(X, unit, out=unit))


def prey(ev: Evaluator, X: np.ndarray, f: np.ndarray, visual, try_number: int,
         rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Up to ``try_number`` probes Xj = clip(Xi + visual·U(−1, 1)^D) per fish; the first with
    f(Xj) < f(Xi) is kept. ``visual`` is a scalar or a per-dimension vector (NAFSA).

    Returns (targets, their costs, found mask); rows not found keep (Xi, f(Xi)). One batched call per
    try with only the fish still searching (see the module docstring)."""
    T, fT = X.copy(), f.copy()
    found = np.zeros(len(X), bool)
    open_, Xo, fo = np.arange(len(X)), X, f  # the fish still searching, in order, their positions and costs
    for _ in range(try_number):
        if open_.size == 0:
            break
        P = free_move(Xo, visual, rng)
        fp = ev(P)
        ok = fp < fo
        hit = open_[ok]
        if hit.size:
            T[hit], fT[hit], found[hit] = P[ok], fp[ok], True
            ok = ~ok
            open_, Xo, fo = open_[ok], Xo[ok], fo[ok]
    return T, fT, found


def afsa_generation(ev: Evaluator, X: np.ndarray, f: np.ndarray, visual: float, step: float, crowd: float,
                    try_number: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """One generation of standard AFSA (Li Xiaolei 2002; docs/algorithms.md, "Standard artificial fish swarm (`afsa`)").

    Every fish performs swarm and follow; each falls back on prey (and prey on a free move) when its
    condition fails; the fish keeps the better of the two results (it moves even if both are worse
    than where it was: the board keeps the best). Evaluations per generation, in at most
    ``try_number + 2`` calls: the neighbourhood centres (fish with neighbours), the prey probes of the
    fallbacks, and the 2N results.

    Crowding, rewritten for minimisation: with nf neighbours among N fish, a target is accepted when
    it is better than the fish and nf/N < δ. For follow, nf counts the neighbours *of the best
    neighbour* Xb (Li's original reads the crowding around the partner that is followed).
    """
    from scipy.spatial.distance import cdist  # here: scipy.spatial costs a quarter second to import

    N = len(X)
    dist = cdist(X, X)
    nbr = (dist > 0) & (dist < visual)
    nf = nbr.sum(axis=1)
    has = nf > 0
    not_crowded = nf / N < crowd

    # Swarm: centre of each fish's neighbours.
    Xc = (nbr @ X) / np.maximum(nf, 1)[:, None]
    fc = np.full(N, np.inf)
    fc[has] = ev(Xc[has])
    swarm_ok = has & (fc < f) & not_crowded

    # Follow: the best neighbour (its cost is known, no evaluation).
    fn = np.where(nbr, f[None, :], np.inf)
    b = np.argmin(fn, axis=1)
    fb = fn[np.arange(N), b]
    follow_ok = has & (fb < f) & not_crowded[b]

    # Prey for every failed behaviour, both kinds in the same batches.
    rows = np.concatenate([np.flatnonzero(~swarm_ok), np.flatnonzero(~follow_ok)])
    Xr = X[rows]
    T, _, found = prey(ev, Xr, f[rows], visual, try_number, rng)
    fallback = np.where(found[:, None], moveto(Xr, T, step, rng), free_move(Xr, visual, rng))

    targets = np.concatenate([Xc, X[b]])
    ok = np.concatenate([swarm_ok, follow_ok])
    Y = np.empty((2 * N, X.shape[1]))
    Y[ok] = moveto(np.concatenate([X, X])[ok], targets[ok], step, rng)
    Y[~ok] = fallback
    fY = ev(Y)
    pick_follow = fY[N:] < fY[:N]
    Xn = np.where(pick_follow[:, None], Y[N:], Y[:N])
    fn_ = np.where(pick_follow, fY[N:], fY[:N])
    return Xn, fn_
