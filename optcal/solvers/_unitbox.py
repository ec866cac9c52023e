"""What the search methods of this package share: the unit-box view of a problem and its start (2020 paper
§3.4: parameters of very different magnitudes must be searched at a similar scale; docs/algorithms.md, "Conventions
shared by the search methods"), the rule that a non-finite cost counts as +inf, and array helpers for populations in
that box.
"""

from __future__ import annotations

import numpy as np

EPS = np.finfo(float).eps


def normalised_start(problem, x0) -> tuple[object, np.ndarray]:
    """The problem's unit-box view z ∈ [-1, 1]^n (x = centre + halfwidth·z) and ``x0`` mapped into it.

    The view shares the problem's evaluation counter, so the budget and the best point are kept by the
    problem whichever coordinates the search works in. A start outside the box is clipped into it.
    """
    zp = problem if problem.is_normalised else problem.normalised()
    z0 = zp.from_full(problem.to_full(x0)[0])
    return zp, np.clip(z0, -1.0, 1.0)


def finite_costs(f) -> np.ndarray:
    """Costs with NaN and ±inf replaced by +inf, so that a failed evaluation never looks good."""
    f = np.asarray(f, float)
    return np.where(np.isfinite(f), f, np.inf)


def nan_to_inf(f: np.ndarray) -> int:
    """:func:`finite_costs` in place for the costs a problem returns, and the index of the lowest.

    A problem's cost is a sum of squares: finite, +inf (a candidate past the budget) or NaN (a failed
    evaluation), never −inf, so only NaN needs replacing. ``argmin`` finds the first NaN if there is
    one, which makes the common case (no NaN) a single call."""
    i = int(f.argmin())
    if f[i] != f[i]:
        f[np.isnan(f)] = np.inf
        i = int(f.argmin())
    return i


def clip_unit(a: np.ndarray) -> np.ndarray:
    """``np.clip(a, -1, 1, out=a)`` (the same numbers) without ``np.clip``'s Python layer."""
    np.maximum(a, -1.0, out=a)
    return np.minimum(a, 1.0, out=a)


def uniform_pm1(rng: np.random.Generator, shape) -> np.ndarray:
    """``rng.uniform(-1, 1, shape)``: the same numbers from the same draws, at ``rng.random``'s speed (a
    third of ``uniform``'s on this machine). ``uniform`` computes −1 + 2·u from u = ``random()``, one
    double each, and 2·u is exact, so −1 + 2·u here rounds exactly as it does there."""
    u = rng.random(shape)
    u *= 2.0
    u -= 1.0
    return u


def row_norms(r: np.ndarray) -> np.ndarray:
    """‖r‖ along the last axis, kept as an axis: ``np.linalg.norm(r, axis=-1, keepdims=True)``'s own
    arithmetic (sqrt of the summed squares) for real r, without its Python layer."""
    return np.sqrt(np.add.reduce(r * r, axis=-1, keepdims=True))


def unit_rows(r: np.ndarray) -> np.ndarray:
    """r / (ε + ‖r‖) along the last axis, written into ``r``: :func:`unit_directions` of draws already made,
    for any number of leading axes (the norm of each row is the same number whatever the array's shape)."""
    n = row_norms(r)
    n += EPS
    return np.divide(r, n, out=r)
