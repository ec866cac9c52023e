"""The three-term fit of the Allan variance and the intervals of its coefficients (the method: the docstring
of :mod:`optcal.core.noise`; IEEE Std 952-1997 Annex C; El-Sheimy, Hou & Niu, IEEE Trans. Instrum. Meas. 57(1),
2008; intervals: NIST SP 1065 eq. 45 with Greenhall's EDF).

σ²(τ) = N²/τ + (0.664·B)² + K²·τ/3 is fitted by weighted non-negative least squares over the points from
the first one on the −1/2 line to the last (:func:`fit_terms`, :func:`read_terms`); a term the fit leaves at
0 or undetermined, or the floor and the random walk of a curve that still falls at the longest τ, become
upper bounds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

FLICKER_FACTOR = math.sqrt(2.0 * math.log(2.0) / math.pi)  # σ(τ) = 0.664·B on the flicker plateau
WHITE_TAU_S = 1.0  # N is read on the −1/2 line at τ = 1 s
RW_TAU_S = 3.0  # K is read on the +1/2 line at τ = 3 s
SLOPE_TOL = 0.1  # a point is on a line of slope p when its local slope is within this of p
DEFAULT_CI = 0.6826894921370859  # one-sigma
RAMP_SLOPE = 0.85  # the last two local slopes above this (past the minimum): a drift, not a random walk
MIN_TERM_EDF = 2.0  # a fitted term whose EDF is below this (relative SD of its variance above 1) is a bound


@dataclass
class Coefficient:
    """One coefficient read from the Allan deviation, in g-based units (g/√Hz, g or g/√s)."""

    value: float | None
    low: float | None = None
    high: float | None = None
    kind: str = "estimate"  # "estimate", "upper bound" or "missing"
    tau_s: list = field(default_factory=list)  # the τ of the points used
    edf: float | None = None  # the EDF of the interval
    how: str = ""  # "fit", or how the bound was found

    def scaled(self, factor: float) -> dict:
        def f(v):
            return None if v is None else float(v) * factor

        return {"value": f(self.value), "low": f(self.low), "high": f(self.high), "kind": self.kind,
                "how": self.how, "tau_s": [float(t) for t in self.tau_s], "edf": self.edf}


def noise_type(slope: float) -> int:
    """Power-law noise type (S_y ∝ f^α) of a local ADEV slope: σ ∝ τ^μ/2 with μ = −α − 1."""
    return int(np.clip(round(-2.0 * slope - 1.0), -2, 2))


def greenhall_edf(alpha: int, m: int, n_phase: int) -> float:
    """Greenhall's EDF of the overlapping Allan variance at averaging factor ``m`` of ``n_phase`` phase points
    for noise type ``alpha`` (``allantools.edf_greenhall``, d = 2)."""
    import allantools

    return float(allantools.edf_greenhall(alpha=alpha, d=2, m=int(m), N=int(n_phase), overlapping=True,
                                          modified=False))


def chi2_interval(value: float, edf: float, ci: float) -> tuple[float, float]:
    """The chi-square interval at level ``ci`` of a deviation ``value`` with ``edf`` degrees of freedom
    (NIST SP 1065 eq. 45, ``allantools.confidence_interval``)."""
    import allantools

    lo, hi = allantools.confidence_interval(value, edf, ci)
    return float(lo), float(hi)


def _first_run(sel: np.ndarray) -> np.ndarray:
    """The first run of consecutive True values of ``sel``."""
    out = np.zeros_like(sel)
    idx = np.flatnonzero(sel)
    if idx.size:
        stop = idx[0]
        while stop + 1 < len(sel) and sel[stop + 1]:
            stop += 1
        out[idx[0]: stop + 1] = True
    return out


@dataclass
class Fit:
    """The weighted least-squares fit σ²(τ) = a/τ + b + c·τ (a = N², b = (0.664·B)², c = K²/3)."""

    coef: np.ndarray  # a, b, c (g²·s, g², g²/s)
    sd: np.ndarray  # upper bounds on their SDs (NaN where a coefficient is 0)
    region: np.ndarray  # bool over the τ: the points fitted
    edf: np.ndarray  # EDF of each fitted point (for the noise type of the fitted curve there)

    def variance(self, tau) -> np.ndarray:
        tau = np.asarray(tau, float)
        return self.coef[0] / tau + self.coef[1] + self.coef[2] * tau


def fit_terms(taus, adev, mm, n_phase, region) -> Fit:
    """Fit σ²(τ) = a/τ + b + c·τ with a, b, c ≥ 0 to the points of ``region`` by weighted non-negative least
    squares. The SD of a point's σ² is σ²·√(2/ν) with ν Greenhall's EDF for the noise type of the fitted curve's
    local slope there, both taken from the fitted curve (iteratively re-weighted, six passes). The coefficients
    are linear in the σ²: ĉ = G·σ̂². Overlapping ADEV at neighbouring τ are correlated, so their SDs are bounded
    as if fully correlated, SD(ĉ_k) ≤ Σ_i |G_ki|·SD(σ̂²_i), which holds whatever the correlation."""
    from scipy.optimize import nnls  # scipy comes with allantools; here, not at import

    idx = np.flatnonzero(region)
    t, y = taus[idx], adev[idx] ** 2
    X = np.column_stack([1.0 / t, np.ones_like(t), t])
    model = y.copy()
    for _ in range(6):
        local = 0.5 * np.gradient(np.log(model), np.log(t)) if len(t) > 1 else np.zeros(1)
        nu = np.array([greenhall_edf(noise_type(sl), m, n_phase) for sl, m in zip(local, mm[idx])])
        sd_y = model * np.sqrt(2.0 / nu)
        coef, _ = nnls(X / sd_y[:, None], y / sd_y)
        model = np.maximum(X @ coef, np.min(y) * 1e-6)
    active = coef > 0
    sd = np.full(3, np.nan)
    if active.any():
        Xa = X[:, active] / sd_y[:, None]
        G = np.linalg.lstsq(Xa.T @ Xa, Xa.T, rcond=None)[0] / sd_y[None, :]
        sd[active] = np.abs(G) @ sd_y
    edf = np.full(len(taus), np.nan)
    edf[idx] = nu
    return Fit(coef, sd, np.asarray(region, bool), edf)


def _term(fit: Fit, k: int, factor: float, ci: float, taus) -> Coefficient | None:
    """The k-th fitted term as a deviation-like coefficient √(factor·coef) with its chi-square interval: a
    variance-like coefficient of relative SD r has the EDF ν = 2/r². None when the term is 0 or not
    determined (ν < MIN_TERM_EDF)."""
    c, sd = fit.coef[k], fit.sd[k]
    if not c > 0 or not np.isfinite(sd):
        return None
    nu = 2.0 / (sd / c) ** 2
    if nu < MIN_TERM_EDF:
        return None
    value = math.sqrt(c * factor)
    lo, hi = chi2_interval(value, nu, ci)
    return Coefficient(value, lo, hi, "estimate", taus[fit.region].tolist(), float(nu), "fit")


def read_terms(taus, adev, slope, mm, n_phase, ci) -> tuple[Coefficient, Coefficient, Coefficient, Fit, list[str]]:
    """N, B and K of one axis: the fit over the points from the first one of the −1/2 line on (a point at or
    before the minimum of σ whose local slope is within SLOPE_TOL of −1/2: shorter τ may carry quantisation
    or the low-pass filter) to the last. Upper bounds where a term is not determined, or when σ still falls
    at the longest τ; a note when the curve ends steeper than a random walk (a drift)."""
    notes = []
    idx = np.arange(len(taus))
    i_min, last = int(np.argmin(adev)), len(taus) - 1
    run = _first_run((idx <= i_min) & (np.abs(slope + 0.5) <= SLOPE_TOL))
    start = int(np.flatnonzero(run)[0]) if run.any() else 0
    region = idx >= (start if last - start >= 2 else 0)
    if last - 1 > i_min and np.all(slope[-2:] > RAMP_SLOPE):
        notes.append(f"σ rises faster than a random walk at the longest τ (local slopes {slope[-2]:+.2f}, "
                     f"{slope[-1]:+.2f}): a drift or a temperature ramp? K takes it in and may be too large")
    fit = fit_terms(taus, adev, mm, n_phase, region)
    white = _term(fit, 0, 1.0, ci, taus) or Coefficient(None, kind="missing", how="no white-noise term")
    # Has the curve stopped falling? A minimum inside the τ range, or a lowest last point that the white
    # line no longer explains (its share of σ² below a quarter: a plateau or a rise whose noisy last point
    # happens to be the lowest). If not, B and K are bounds whatever the fit says.
    reached = i_min < last or (white.value is not None and white.value**2 / taus[last] < adev[last] ** 2 / 4)
    rw = _term(fit, 2, 3.0, ci, taus) if reached else None
    if rw is None:  # K ≤ σ(τ)·√(3/τ) at the longest τ, where a random walk shows most: its upper limit
        e_k = greenhall_edf(-2, mm[last], n_phase)
        _, hi = chi2_interval(adev[last] * math.sqrt(3.0 / taus[last]), e_k, ci)
        rw = Coefficient(hi, None, hi, "upper bound", [float(taus[last])], e_k, "upper limit of σ·√(3/τ) at the "
                         "longest τ")
    bias = _term(fit, 1, 1.0 / FLICKER_FACTOR**2, ci, taus) if reached else None
    if bias is None:  # no floor: B ≤ the minimum of σ / 0.664, its upper limit
        e_b = greenhall_edf(-1, mm[i_min], n_phase)
        _, hi = chi2_interval(adev[i_min] / FLICKER_FACTOR, e_b, ci)
        bias = Coefficient(hi, None, hi, "upper bound", [float(taus[i_min])], e_b, "upper limit of the minimum "
                           "of σ / 0.664")
    return white, bias, rw, fit, notes

