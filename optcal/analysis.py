"""Observability, Cramér-Rao bounds and goodness of fit of a calibration problem.

The norm ‖A‖ does not change when the body frame rotates, so with the norm cost only six of the nine
entries of diag(K)·T are observable (docs/design.md §6): ``seed15`` holds three unobservable directions, which
only the small nonlinear terms tie down. They show up here as near-zero singular values of the Jacobian,
after each column is put in natural units (relative scale change, g, rad, ...), so that the threshold
does not depend on the sensor's output units (the linear algebra is in :mod:`optcal.gauge`, which the
problem also uses for its gauge rows).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .gauge import RTOL, n_position_residuals, natural_units, null_space
from .problem import CalibrationProblem

__all__ = ["GoodnessOfFit", "Observability", "covariance", "crlb", "fisher", "goodness_of_fit", "natural_units",
           "observability", "standard_errors"]


@dataclass(frozen=True)
class Observability:
    names: tuple[str, ...]
    rank: int
    singular_values: np.ndarray  # of the Jacobian in natural units, relative to the largest
    null_space: np.ndarray  # (p, p - rank) directions in natural units, sparse basis
    rtol: float

    @property
    def n_parameters(self) -> int:
        return len(self.names)

    @property
    def unobservable(self) -> list[list[dict]]:
        """Each unobservable direction as a list of {name, weight} (weights of unit norm, largest first)."""
        out = []
        for v in self.null_space.T:
            idx = [i for i in np.argsort(-np.abs(v)) if abs(v[i]) > 1e-3]
            out.append([{"name": self.names[i], "weight": round(float(v[i]), 6)} for i in idx])
        return out

    def observable_mask(self) -> np.ndarray:
        """True for parameters that the data determine on their own (no weight in any null direction)."""
        if self.null_space.size == 0:
            return np.ones(len(self.names), bool)
        return np.max(np.abs(self.null_space), axis=1) < 1e-3

    def to_dict(self) -> dict:
        return {"rank": self.rank, "n_parameters": self.n_parameters, "unobservable": self.unobservable}

    def describe(self) -> str:
        if self.rank == self.n_parameters:
            return f"all {self.n_parameters} parameters observable (rank {self.rank})"
        lines = [f"rank {self.rank} of {self.n_parameters}: {self.n_parameters - self.rank} unobservable "
                 "direction(s), set by the presets, not by the data:"]
        for d in self.unobservable:
            lines.append("  " + " ".join(f"{w['weight']:+.3f}·{w['name']}" for w in d))
        return "\n".join(lines)


def observability(problem: CalibrationProblem, x_full: np.ndarray | None = None, rtol: float = RTOL) -> Observability:
    """Rank and null space of the residual Jacobian at ``x_full`` (default: the problem's centre).

    A direction is unobservable when its singular value, in natural units, is below ``rtol`` times the
    largest (Fisher information below rtol² of the best-determined direction).
    """
    x = problem.centre if x_full is None else np.asarray(x_full, float)
    rank, rel, null, _ = null_space(problem, x, rtol)
    return Observability(problem.model.names, rank, rel, null, rtol)


def fisher(problem: CalibrationProblem, x_full: np.ndarray, sigma_g: float) -> np.ndarray:
    J = problem.jacobian_full(x_full)[: n_position_residuals(problem)]
    return J.T @ J / sigma_g**2


def crlb(problem: CalibrationProblem, x_full: np.ndarray | None = None, sigma_g: float | None = None,
         rtol: float = RTOL) -> tuple[np.ndarray, np.ndarray]:
    """Cramér-Rao standard deviations of every parameter, and a mask of those that are observable.

    Noise is white, input-referred, ``sigma_g`` (g) per axis on each position's mean, so each norm
    residual has SD sigma_g. Unobservable directions are projected out (the bound is that of the gauge
    the presets fix); parameters with weight in them are marked not observable and their SD is NaN.
    """
    x = problem.centre if x_full is None else np.asarray(x_full, float)
    sigma = sigma_g if sigma_g is not None else problem.noise_g
    if sigma is None:
        raise ValueError("crlb needs the noise level: give sigma_g or data with n and sx, sy, sz")
    obs = observability(problem, x, rtol)
    u = natural_units(problem, x)
    J = problem.jacobian_full(x)[: n_position_residuals(problem)] * u
    F = J.T @ J / sigma**2
    if obs.null_space.size:
        P = np.eye(len(u)) - obs.null_space @ np.linalg.pinv(obs.null_space)
        F = P @ F @ P
        cov = np.linalg.pinv(F, rcond=rtol**2)
    else:
        cov = np.linalg.inv(F)
    sd = np.sqrt(np.clip(np.diag(cov), 0, None)) * u
    mask = obs.observable_mask()
    sd[~mask] = np.nan
    return sd, mask


def covariance(problem: CalibrationProblem, x_full: np.ndarray, sigma_g: float) -> np.ndarray:
    """Parameter covariance σ²(JᵀJ)⁻¹ (pseudo-inverse over observable directions)."""
    u = natural_units(problem, x_full)
    J = problem.jacobian_full(x_full)[: n_position_residuals(problem)] * u
    cov = np.linalg.pinv(J.T @ J, rcond=1e-12) * sigma_g**2
    return cov * np.outer(u, u)


@dataclass(frozen=True)
class GoodnessOfFit:
    rms_g: float
    cost: float
    dof: int
    sigma_g: float  # noise used (given, or estimated from the residuals)
    chi2: float | None
    p_value: float | None

    def to_dict(self) -> dict:
        return {k: getattr(self, k) for k in ("rms_g", "cost", "dof", "sigma_g", "chi2", "p_value")}


def goodness_of_fit(problem: CalibrationProblem, x_full: np.ndarray, sigma_g: float | None = None) -> GoodnessOfFit:
    """Residual RMS, and χ² with its p-value when the noise is known."""
    from scipy import stats  # here, not at module level: importing optcal stays light

    r = problem.position_residuals(x_full)
    obs = observability(problem, x_full)
    dof = max(len(r) - obs.rank, 1)
    cost = float(r @ r)
    sigma = sigma_g if sigma_g is not None else problem.noise_g
    if sigma is None:
        return GoodnessOfFit(float(np.sqrt(np.mean(r**2))), cost, dof, float(np.sqrt(cost / dof)), None, None)
    chi2 = cost / sigma**2
    return GoodnessOfFit(float(np.sqrt(np.mean(r**2))), cost, dof, float(sigma), chi2, float(stats.chi2.sf(chi2, dof)))


def standard_errors(problem: CalibrationProblem, x_full: np.ndarray, sigma_g: float | None = None) -> np.ndarray:
    """Standard errors of the fitted parameters: σ̂·sqrt(diag((JᵀJ)⁺)); NaN for unobservable ones."""
    gof = goodness_of_fit(problem, x_full, sigma_g)
    sigma = gof.sigma_g if sigma_g is None and problem.noise_g is None else (sigma_g or problem.noise_g)
    sd, _ = crlb(problem, x_full, sigma)
    return sd
