"""Scoring a trial (docs/design.md, "Metrics"): the Cramér-Rao bounds its estimate is scored against, the
per-trial accuracy, and the best cost (and accuracy) so far on the evaluation grid shared by every trial.

The bounds: :func:`optcal.core.analysis.projected_crlb` (the data alone, the error's observable part, with the
projector and natural units a study needs to score every parameter; docs/design.md, "Cramér-Rao bound"), used here as it
is, and :func:`crlb_with_presets` (data and presets together, design.md, "The bound with presets").
"""

from __future__ import annotations

import numpy as np

from optcal.core.analysis import natural_units
from optcal.core.problem import CalibrationProblem


def crlb_with_presets(problem: CalibrationProblem, x_true: np.ndarray, noise_g: float,
                      prior_sd: np.ndarray) -> np.ndarray:
    """Cramér-Rao SDs when the presets count as one more measurement of every parameter.

    Manufacturer presets are the truth plus an independent error of SD ``prior_sd``: data and presets
    together have Fisher information JᵀJ/σ² + diag(prior_sd⁻²). This is the floor for a method that
    uses the presets as information (the staged procedure keeps parameters near them), as the plain
    bound is for one that uses the data alone; it is finite for every parameter, the norm cost's
    unobservable directions included (there the presets are all the information there is).
    """
    u = natural_units(problem, x_true)
    J = problem.jacobian_full(x_true)[: len(problem.data)] * u
    F = J.T @ J / noise_g**2 + np.diag((u / prior_sd) ** 2)
    return np.sqrt(np.clip(np.diag(np.linalg.inv(F)), 0, None)) * u


def _grid_index(trace) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The evaluation grid 1, 1.26, 1.58, ... (ten points per decade, rounded) up to the trace's last
    evaluation, the best cost at each grid point, and the index of the trace entry that holds it."""
    nf = np.array([t[0] for t in trace], float)
    c = np.array([t[1] for t in trace], float)
    best = np.minimum.accumulate(c)
    # the entry of the running minimum (the trace holds improvements, so normally the entry itself)
    holder = np.maximum.accumulate(np.where(c <= best, np.arange(len(c)), -1))
    grid = np.unique(np.round(10 ** (np.arange(0, 10 * np.log10(max(nf[-1], 1.0)) + 1) / 10)))
    idx = np.searchsorted(nf, grid, side="right") - 1
    keep = idx >= 0
    idx = idx[keep]
    return grid[keep], best[idx], holder[idx]


def trace_on_grid(trace) -> list[list[float]]:
    """The best cost at evaluations 1, 1.26, 1.58, ... (ten points per decade), from a solver's trace of
    (evaluations, best cost, seconds): compact, and the same grid for every trial so curves line up."""
    if not trace:
        return []
    grid, best, _ = _grid_index(trace)
    return [[int(g), float(b)] for g, b in zip(grid, best)]


def accuracy_of(X, x_true, bound) -> np.ndarray:
    """The per-trial accuracy of estimates X (k, n) at once: the RMS over parameters of |projected
    error| / CRLB (the ``accuracy`` column's definition, :func:`_score`); ``bound`` is projected_crlb's."""
    sd, P, u = bound[0], bound[1], bound[2]
    E = (np.atleast_2d(np.asarray(X, float)) - x_true) / u
    Ep = (E @ P.T) * u  # each row's observable part, back in the parameters' units
    return np.sqrt(np.mean((Ep / sd) ** 2, axis=1))


def seconds_on_grid(trace) -> list[float]:
    """The solver time (s) at which the best point so far was found, at each point of the grid of
    :func:`trace_on_grid`: the anytime analyses count in seconds as well as in evaluations with it. Kept
    apart from the anytime record (the ``anytime_s`` column, a timing column) because it differs between
    identical runs."""
    if not trace or len(trace[0]) < 3:
        return []
    _, _, holder = _grid_index(trace)
    return [float(trace[i][2]) for i in holder]


def anytime_on_grid(trace, trace_x, x_true, bound) -> list[list[float]]:
    """[evaluations, best cost, accuracy] at the grid of :func:`trace_on_grid`: the accuracy
    (:func:`accuracy_of`) of the best point so far at each grid point, one vectorised computation per
    trial. The accuracy is None when the solver's trace carries no points (``trace_x`` shorter than it)."""
    if not trace:
        return []
    grid, best, holder = _grid_index(trace)
    if len(trace_x) != len(trace):
        return [[int(g), float(b), None] for g, b in zip(grid, best)]
    acc = accuracy_of(np.array([trace_x[i] for i in holder]), x_true, bound)
    return [[int(g), float(b), float(a) if np.isfinite(a) else None] for g, b, a in zip(grid, best, acc)]
