"""The noise floor of a position: the standard error of each static interval's mean when the sensor's noise is
correlated (docs/noise.md, "The noise floor of a position").

σ/√n is the standard error of a mean of n samples only when they are independent. A MEMS accelerometer's bias
wanders (flicker noise): the mean of an interval then differs from the others' by more than σ/√n, and a fit
whose residuals are compared with σ/√n looks worse than its noise. The calibration sees each position's mean
against the others (a constant offset per axis is the bias it fits), so the floor of position i is the SD of
its mean about the mean of all positions,

    sem_i² = p/(p − 1) · [P C P]_ii,   P = I − 11ᵀ/p,

with C the covariance of the p interval means under the sensor's noise and p/(p − 1) the factor that makes
the floor exactly σ/√n for independent means. The noise is white plus flicker, the first two terms of the
power law of :mod:`optcal.core.noise` (IEEE Std 952-1997 Annex C; El-Sheimy, Hou & Niu 2008): two-sided PSD
S(f) = N² + B²/(2π|f|), Allan variance σ²(τ) = N²/τ + (0.664·B)². N and B are fitted per axis to the
overlapping Allan variance of all the recording's static intervals pooled (:func:`pooled_avar`: every second
difference of τ-averages that lies inside one interval, from all of them) by weighted least squares
(:func:`fit_white_flicker`). The covariance of two means over [a_i, a_i + T_i] and [a_j, a_j + T_j] is exact
for that PSD, in closed form (:func:`flicker_covariance`): with the flicker's generalised autocovariance
R(x) = −(B²/π)·ln|x| (defined up to a constant, which P removes) and Φ its second antiderivative,
C_ij = [Φ(b_i − a_j) + Φ(a_i − b_j) − Φ(b_i − b_j) − Φ(a_i − a_j)] / (T_i·T_j), b = a + T; white noise adds
N²/T_i to the diagonal.

Why not the Allan deviation at τ = T alone: it is the SD of the difference of two *adjacent* means, but the
positions of a calibration are spread over minutes, and with flicker noise the scatter of p means about their
average grows with the span (Allan's p-sample variance; Barnes' bias function B₁(p, μ = 0) =
p·ln p / (2(p − 1)·ln 2) = 2.39 for 24 contiguous means, which :func:`flicker_covariance` reproduces). The
model's Allan deviation at τ = T is kept beside the floor (``adev_at_interval``) for comparison.

The rule beyond the data: the pooled intervals reach τ of half the longest interval (with at least
:data:`MIN_PAIRS` pairs), while the floor depends on the noise up to the recording's span. Beyond the longest
τ fitted, σ(τ) is held flat at the fitted flicker level: a curve that still falls there is taken to flatten
no lower, and one that rises (a random walk, warm-up drift) is not extrapolated: a drift over the recording
that the intervals do not show is the model's to explain (``bias_drift``, ``optcal discover``), not noise.
The flicker level B² is fitted without a sign constraint (an unbiased estimate; a negative one means none is
seen), and the floor is never below the white-noise value: sem_i = max(√(p/(p − 1)·[PCP]_ii), s_i/√n_i) per
axis, with s_i the interval's own sample SD.

The fit re-weights each point by its variance under the fitted curve with a negative flicker level taken as
none (as the floor takes it): with the curve a/τ + b itself, a b < 0 that brings it near 0 at the longest τ gave
that one point an unbounded weight, and the passes swung between b < 0 and a b > 0 with a vanishing standard
error, a confident flicker level that the points did not hold (docs/noise.md, "The floor on hand-held logs").

A pose that turns: the residual sees each mean along its specific force only, and a pose turning while it is
held moves the output across the force (to first order), which the per-axis Allan variance counts as noise.
Each axis's Allan variance is read again from the components along the force alone (:func:`along_avar`: the
projections on each interval's force direction, :func:`force_directions`, solved for the three axes by least
squares at each τ; consistent whether the pose turns or not, less precise), and the white + flicker model
fitted to it over the same τ. Where the per-axis flicker level lies more than :data:`TURN_Z` standard errors
(the along-force fit's) above the along-force one, the poses turned: a note says so (``turned``, ``turn_z``,
``along_bias_instability``, ``axis_bias_instability``) and that axis's floor takes the along-force level and
its standard error, the noise the residual sees (docs/noise.md, "A pose that turns").

The floor is an estimate: B² from a few seconds of data has a standard error (the fit's), which the span
multiplies. Its effective degrees of freedom (``edf``, Satterthwaite: 2·(Σ sem²)²/Var(Σ sem²)) let the χ²
test of a fit become the F test of an estimated variance (:func:`optcal.core.analysis.goodness_of_fit`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from optcal.core.errors import InputError
from optcal.core.ranges import pooled, pooled_sds

# The constants of optcal.core.noise.fit, spelled here because optcal.noise reads recordings (optcal.core.recording),
# so this module may not import it (no import cycles); tests/test_noise_floor.py checks that they agree.
FLICKER_FACTOR = math.sqrt(2.0 * math.log(2.0) / math.pi)  # σ_A = 0.664·B on the flicker plateau
SLOPE_TOL = 0.1  # a point is on the −1/2 line when its local log-log slope is within this of −1/2

MIN_PAIRS = 8.0  # a τ is fitted when the pooled intervals hold this many independent pairs of τ-averages at it
FIT_PASSES = 6  # iterative re-weighting of the power-law fit (as optcal.core.noise.fit.fit_terms)
MIN_STATIC = 64  # static samples (pooled) below which the Allan deviation says nothing: the floor is σ/√n
TURN_Z = 3.0  # an axis's flicker level this many SE (the along-force fit's) above the along-force one: the pose turned
MAX_COND = 100.0  # condition number of the along-force regression beyond which the poses do not tell the axes apart
MAX_RADIUS_SPREAD = 0.1  # relative SD of the fitted ellipsoid's radius at the means beyond which they are no poses
ESTIMATORS = {
    "allan": "Allan model of the static intervals (white + flicker noise; each mean's scatter about all "
             "positions' mean)",
    "white": "within-interval scatter σ/√n (white noise)",
}


@dataclass(frozen=True)
class NoiseFloor:
    """The standard error of each position's mean and how it was found, in the recording's output units."""

    sem: np.ndarray  # (p, 3) the floor: SD of each mean about all positions' mean, correlated noise included
    white: np.ndarray  # (p, 3) σ/√n, each interval's sample SD over √n
    estimator: str  # a key of ESTIMATORS
    units: str
    rate_hz: float  # the rate the coefficients' seconds refer to (NaN: the recording has none; seconds are samples)
    density: np.ndarray | None = None  # (3,) N, units/√Hz
    bias_instability: np.ndarray | None = None  # (3,) B, units (0: none seen)
    tau_s: np.ndarray | None = None  # the τ fitted
    adev: np.ndarray | None = None  # (len(tau_s), 3) pooled overlapping Allan deviation, units
    adev_at_interval: np.ndarray | None = None  # (p, 3) the model's Allan deviation at τ = each interval's length
    notes: list = field(default_factory=list)
    edf: float = math.inf  # effective degrees of freedom of the floor's Σ sem² (Satterthwaite): its estimation noise
    flicker: np.ndarray | None = None  # (p, p) p/(p − 1)·P C P of unit flicker (B = 1); its diagonal is g
    b2: np.ndarray | None = None  # (3,) the flicker level B² per axis used in the covariance (≥ 0)
    turned: np.ndarray | None = None  # (3,) bool: the per-axis flicker exceeds the along-force one (the poses turned)
    turn_z: np.ndarray | None = None  # (3,) that excess in standard errors of the along-force level (NaN: untested)
    along_bias_instability: np.ndarray | None = None  # (3,) B read along the force alone, units (NaN: untested)
    coef: np.ndarray | None = None  # (3, 2) the Allan model's white and flicker coefficients as fitted (B² unclipped)
    coef_sd: np.ndarray | None = None  # (3,) the flicker coefficient's standard error
    # (3,) B as each axis's own Allan variance gives it, units: the floor's but where the poses turned (``turned``:
    # there the floor takes the along-force level)
    axis_bias_instability: np.ndarray | None = None

    def covariance(self, k: int) -> np.ndarray:
        """Covariance (p, p) of the means of axis ``k`` about their average, as the floor models it: the
        flicker part B²·p/(p − 1)·PCP and a diagonal that makes its diagonal sem² (the white noise and the
        guard at σ/√n); output units². Without a flicker model, diag(sem²)."""
        if self.flicker is None:
            return np.diag(self.sem[:, k] ** 2)
        F = self.b2[k] * self.flicker
        return F + np.diag(self.sem[:, k] ** 2 - np.diag(F))

    @property
    def ratio(self) -> float:
        """RMS of the floor over RMS of the white-noise value (1 for white noise)."""
        w = float(np.sqrt(np.mean(self.white**2)))
        return float(np.sqrt(np.mean(self.sem**2))) / w if w > 0 else math.nan

    def describe(self) -> str:
        """One line: the estimator, its coefficients and the floor against σ/√n, in the output units."""
        u = self.units
        rms = float(np.sqrt(np.mean(self.sem**2)))
        head = (f"noise floor of a position {rms:.4g} {u} RMS ({ESTIMATORS[self.estimator]}; σ/√n alone "
                f"{float(np.sqrt(np.mean(self.white**2))):.4g} {u}, ×{self.ratio:.3g})")
        if self.estimator != "allan":
            return head
        per = "s" if math.isfinite(self.rate_hz) else "sample"

        def axes(v, fmt=".3g"):
            return "/".join(format(float(x), fmt) for x in v)

        turned = ("" if self.turned is None or not np.any(self.turned) else
                  f"; the poses turned while held ({'/'.join(np.array(list('xyz'))[self.turned])}: B along the force "
                  f"{axes(self.along_bias_instability[self.turned])} {u}): the floor may exceed the means' noise")
        return (head + f"; per axis x/y/z N = {axes(self.density)} {u}/√Hz, B = {axes(self.bias_instability)} {u}, "
                f"fitted at τ = {self.tau_s[0]:.3g}–{self.tau_s[-1]:.3g} {per}, {self.edf:.3g} degrees of freedom"
                + turned)

    def to_dict(self) -> dict:
        """The JSON form: every key names its unit (the output units are ``units``)."""
        def lst(v):
            return None if v is None else [float(x) for x in np.ravel(v)]

        return {"estimator": self.estimator, "description": ESTIMATORS[self.estimator], "units": self.units,
                "rate_hz": None if not math.isfinite(self.rate_hz) else self.rate_hz,
                "floor_rms": float(np.sqrt(np.mean(self.sem**2))),
                "white_rms": float(np.sqrt(np.mean(self.white**2))), "ratio": self.ratio,
                "white_noise_density_per_sqrt_hz": lst(self.density), "bias_instability": lst(self.bias_instability),
                "tau_fitted_s": lst(self.tau_s), "degrees_of_freedom": None if math.isinf(self.edf) else self.edf,
                "notes": list(self.notes)}


# -- the pooled Allan variance -------------------------------------------------------------------------------

def _second_differences(y: np.ndarray, lengths: np.ndarray, m: np.ndarray):
    """For each averaging factor of ``m``: its index, m, the pooled samples ``i`` where a second difference of
    m-averages starts and lies inside one interval, and those differences (len(i), k), of ``y``, the pooled
    samples of intervals of ``lengths`` (:func:`optcal.core.ranges.pooled`)."""
    C = np.vstack([np.zeros((1, y.shape[1])), np.cumsum(y, axis=0)])  # centred: the sums stay small
    seg_end = np.repeat(np.cumsum(lengths), lengths)  # where each sample's interval ends, in the pooled samples
    total = len(y)
    for k, mm in enumerate(np.asarray(m, int)):  # octaves (tens at most), each one vectorised over samples
        n = max(total - 2 * mm + 1, 0)
        inside = seg_end[:n] >= np.arange(n) + 2 * mm
        # every start's difference from three slices of C, then those inside one interval: the same arithmetic
        # as gathering the rows of each start, without three gathers
        yield k, mm, np.flatnonzero(inside), (C[2 * mm:2 * mm + n] - 2.0 * C[mm:mm + n] + C[:n])[inside]


def pooled_avar(x: np.ndarray, intervals: np.ndarray, m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Overlapping Allan variance of each column of ``x`` (n, k) at averaging factors ``m`` (samples), pooled
    over the ``intervals`` [start, end): every second difference of the τ-averages that lies inside one
    interval, from all of them, with equal weight (on one interval it is ``allantools.oadev``'s). Returns the
    variance (len(m), k) and the number of differences at each m."""
    y, lengths, _, _ = pooled(x, intervals)
    avar, count, _, _ = _allan(y, lengths, m)
    return avar, count


_PA, _PB = np.array([0, 1, 2, 0, 0, 1]), np.array([0, 1, 2, 1, 2, 2])  # the products d_a·d_b, a ≤ b
_PW = np.array([1.0, 1.0, 1.0, 2.0, 2.0, 2.0])  # their weights in (u·d)²


def _allan(y: np.ndarray, lengths: np.ndarray, m: np.ndarray, u: np.ndarray | None = None):
    """:func:`pooled_avar` of the pooled samples ``y`` of intervals of ``lengths``
    (:func:`optcal.core.ranges.pooled`), and with ``u`` (p, 3) in the same pass :func:`along_avar`'s variances and
    ν (else None, None)."""
    avar = np.full((len(m), y.shape[1]), np.nan)
    count = np.zeros(len(m), int)
    along = nu = None
    if u is not None:
        u = np.asarray(u, float)
        which = np.repeat(np.arange(len(lengths)), lengths)
        W = u**2
        along, nu = np.full((len(m), 3), np.nan), np.zeros((len(m), 3))
    for k, mm, i, d in _second_differences(y, lengths, m):
        count[k] = i.size
        if not i.size:
            continue
        if u is None:
            avar[k] = np.sum(d * d, axis=0) / (2.0 * mm * mm * i.size)
            continue
        # each interval's sums of d_a·d_b (its differences are one run of i): the per-axis sums and, through
        # u_iᵀ S_i u_i, the sums of the squared projections
        wi = which[i]
        run = np.flatnonzero(np.r_[True, wi[1:] != wi[:-1]])
        S = np.add.reduceat(d[:, _PA] * d[:, _PB], run, axis=0)
        avar[k] = S[:, :3].sum(axis=0) / (2.0 * mm * mm * i.size)
        ui = u[wi[run]]
        c = np.diff(np.r_[run, i.size]).astype(float)
        mean = np.sum(S * ui[:, _PA] * ui[:, _PB] * _PW, axis=1) / (2.0 * mm * mm * c)
        A = W[wi[run]] * np.sqrt(c)[:, None]
        if len(A) < 3 or np.linalg.cond(A) > MAX_COND:  # the poses reaching this τ do not tell the axes apart
            continue
        L = np.linalg.pinv(A) * np.sqrt(c)[None, :]  # σ² = L @ mean
        along[k] = L @ mean
        var = np.sum(L**2 * (2.0 * (W[wi[run]] @ avar[k]) ** 2 / (c / mm))[None, :], axis=1)
        nu[k] = np.where(var > 0, 2.0 * avar[k] ** 2 / np.where(var > 0, var, 1.0), 0.0)
    return avar, count, along, nu


# -- the noise along the force ----------------------------------------------------------------------------------

def force_directions(means: np.ndarray) -> np.ndarray | None:
    """Unit vectors (p, 3), one per position, along which a change of the output changes the magnitude of the
    specific force: the gradient of an axis-aligned ellipsoid Σ α_k (y_k − c_k)² = 1 fitted to the positions'
    mean outputs (algebraically: the null vector of [y², y, 1], in centred and scaled outputs, so that offsets of
    raw counts do not matter). None when it cannot be fitted: fewer than 7 positions, α of mixed signs (the
    means lie on no ellipsoid), or an ellipsoid whose radius at the means spreads by more than
    :data:`MAX_RADIUS_SPREAD` (they are no static poses of one sensor)."""
    m = np.asarray(means, float)
    if len(m) < 7:
        return None
    s = m.std(axis=0)
    if np.any(s <= 0):
        return None
    z = (m - m.mean(axis=0)) / s
    v = np.linalg.svd(np.column_stack([z * z, z, np.ones(len(z))]))[2][-1]
    alpha, beta = (v[:3], v[3:6]) if v[:3].sum() > 0 else (-v[:3], -v[3:6])
    if np.any(alpha <= 0):
        return None
    d = z + beta / (2.0 * alpha)  # z − c
    radius = np.sqrt(np.sum(alpha * d * d, axis=1))
    if np.std(radius) > MAX_RADIUS_SPREAD * np.mean(radius):
        return None
    grad = alpha * d / s
    return grad / np.linalg.norm(grad, axis=1, keepdims=True)


def along_avar(x: np.ndarray, intervals: np.ndarray, m: np.ndarray,
               u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each axis's Allan variance (len(m), 3) read from the components of the samples along the specific force
    alone, ``u`` (p, 3) each interval's direction (:func:`force_directions`): the second differences of
    interval i projected on u_i have variance Σ_k u_ik² σ_k²(τ) when the axes' noises are independent, so the
    σ_k² at each τ are the least-squares solution over the intervals (each difference weighted equally, as
    :func:`pooled_avar`; unbiased, of either sign; NaN at a τ where the intervals long enough for it do not
    tell the axes apart: condition number above :data:`MAX_COND`). A turn of the pose while it is held moves
    the output across the force, not along it (to first order), and does not enter. Returns the variances and
    the equivalent number of independent pairs ν, 2σ_k⁴/Var(σ̂_k²) per axis and τ: each interval's mean over
    ν_i = (its differences)/m pairs has variance 2E_i²/ν_i, E_i = Σ_k u_ik² σ_k², with σ_k² the per-axis
    pooled variance (:func:`pooled_avar`'s: positive, and the same where the pose does not turn)."""
    y, lengths, _, _ = pooled(x, intervals)
    _, _, along, nu = _allan(y, lengths, m, u)
    return along, nu


# -- the power-law fit ---------------------------------------------------------------------------------------

def fit_white_flicker(tau: np.ndarray, avar: np.ndarray, nu: np.ndarray) -> tuple[np.ndarray, float]:
    """σ²(τ) = a/τ + b (a = N² ≥ 0, b = (0.664·B)² of either sign) fitted to one axis's points by weighted least
    squares, each point weighted by the inverse variance of its σ², 2σ⁴/ν, with σ² from the fitted curve
    (re-weighted :data:`FIT_PASSES` times, as :func:`optcal.core.noise.fit.fit_terms` fits one stretch). Returns
    (a, b) and the standard error of b (the points taken as independent; octave-spaced, they nearly are)."""
    X = np.column_stack([1.0 / tau, np.ones_like(tau)])
    low = np.min(avar[avar > 0]) if np.any(avar > 0) else 1.0  # a point at or below 0 (read along the force) weighs
    model = np.where(avar > 0, avar, low)  # as the smallest positive one to start with
    for _ in range(FIT_PASSES):
        sd_y = np.maximum(model, 1e-300) * np.sqrt(2.0 / nu)
        Xw = X / sd_y[:, None]
        coef = np.linalg.lstsq(Xw, avar / sd_y, rcond=None)[0]
        if coef[0] < 0:  # no white term: the flicker level alone
            coef = np.array([0.0, float(np.sum(avar / sd_y**2) / np.sum(1.0 / sd_y**2))])
        # the weights' σ² with a negative flicker level taken as none (as the floor takes it): a curve a/τ + b that
        # nears 0 at the longest τ would weight that one point without bound, and the passes would swing between
        # b < 0 and b > 0 with a vanishing standard error
        model = np.maximum(X @ np.array([coef[0], max(coef[1], 0.0)]), low * 1e-6)
    cov = np.linalg.pinv(Xw.T @ Xw)
    return coef, float(np.sqrt(max(cov[1, 1], 0.0)))


# -- the covariance of interval means ------------------------------------------------------------------------

def _phi_flicker(x):
    """Second antiderivative of −ln|x|/π, the flicker noise's generalised autocovariance for B = 1."""
    ax = np.abs(x)
    safe = np.where(ax > 0, ax, 1.0)
    return -(0.5 * x * x * np.log(safe) - 0.75 * x * x) / math.pi


def flicker_covariance(start: np.ndarray, length: np.ndarray) -> np.ndarray:
    """Covariance (p, p) of the means over [start_i, start_i + length_i] (seconds) of flicker noise of B = 1
    (two-sided PSD 1/(2π|f|)), up to a constant common to every entry (the generalised autocovariance is
    defined up to one). Exact for the continuous process; the means of samples at a rate far above
    1/length are the same."""
    a = np.asarray(start, float) - float(np.min(start))  # differences only: shift for precision
    T = np.asarray(length, float)
    b = a + T
    phi = _phi_flicker
    integral = (phi(b[:, None] - a[None, :]) + phi(a[:, None] - b[None, :]) - phi(b[:, None] - b[None, :])
                - phi(a[:, None] - a[None, :]))
    return integral / (T[:, None] * T[None, :])


def centred_covariance(C: np.ndarray) -> np.ndarray:
    """p/(p − 1)·P C P, P = I − 11ᵀ/p: the covariance of the means about the mean of all, scaled so that
    independent means keep their own variance."""
    p = len(C)
    return (C - C.mean(axis=1, keepdims=True) - C.mean(axis=0, keepdims=True) + C.mean()) * p / (p - 1)


def centred_variance(C: np.ndarray) -> np.ndarray:
    """The diagonal of :func:`centred_covariance`: the variance of each mean about the mean of all."""
    return np.diag(centred_covariance(C)).copy()


# -- the floor -------------------------------------------------------------------------------------------------

def octaves(max_m: int) -> np.ndarray:
    """Averaging factors 1, 2, 4, … up to ``max_m``."""
    return 2 ** np.arange(int(math.floor(math.log2(max_m))) + 1) if max_m >= 1 else np.array([], int)


def _fit_axes(tau: np.ndarray, avar: np.ndarray, nu: np.ndarray,
              first: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`fit_white_flicker` per axis of ``avar`` (len(tau), 3) with ``nu`` (len(tau), 3), from each axis's
    point ``first`` on (default: its first point on the −1/2 line). Returns (a, b) per axis (3, 2), the standard
    errors of b (3,) and the first points (3,)."""
    coef = np.zeros((3, 2))
    sd_b = np.zeros(3)
    firsts = np.zeros(3, int)
    for k in range(3):  # three axes, each a fit of a few points
        y = avar[:, k]
        if not np.any(y > 0):
            continue
        if first is None:
            adev = np.sqrt(np.maximum(y, 0))
            slope = np.gradient(np.log(np.maximum(adev, 1e-300)), np.log(tau))
            # from the first point on the −1/2 line (shorter τ may carry quantisation or a low-pass filter), as
            # optcal.core.noise.fit.read_terms fits one stretch
            i_min = int(np.argmin(adev))
            on_line = np.flatnonzero((np.arange(len(tau)) <= i_min) & (np.abs(slope + 0.5) <= SLOPE_TOL))
            firsts[k] = int(on_line[0]) if on_line.size and len(tau) - on_line[0] >= 3 else 0
        else:
            firsts[k] = first[k]
        f = firsts[k]
        coef[k], sd_b[k] = fit_white_flicker(tau[f:], y[f:], nu[f:, k])
    return coef, sd_b, firsts


def noise_floor(N: np.ndarray, intervals: np.ndarray, start_s: np.ndarray, rate_hz: float,
                units: str = "", like: NoiseFloor | None = None) -> NoiseFloor:
    """The floor of each interval's mean (module docstring): ``N`` (n, 3) the recording's samples,
    ``intervals`` (p, 2) [start, end) sample indices, ``start_s`` (p,) each interval's first time (s), and the
    sample rate. Without a rate (NaN) the seconds are samples. ``like``: the floor of the same recording on
    nearly the same intervals (poses re-examined and trimmed, :func:`optcal.core.recording.positions.recheck_poses`),
    whose Allan model is kept: only each mean's floor is computed again for the new intervals."""
    iv = np.asarray(intervals, int).reshape(-1, 2)
    if not len(iv) or np.any(iv[:, 1] <= iv[:, 0]):
        raise InputError("`intervals` must be [start, end) pairs of sample indices with end > start")
    p = len(iv)
    n = (iv[:, 1] - iv[:, 0]).astype(float)
    fs = float(rate_hz) if rate_hz is not None and math.isfinite(rate_hz) and rate_hz > 0 else math.nan
    per_s = fs if math.isfinite(fs) else 1.0
    y, lengths, first, means = pooled(N, iv)
    sd = pooled_sds(y, lengths, first)
    white = sd / np.sqrt(n)[:, None]

    def plain(note):
        return NoiseFloor(white.copy(), white, "white", units, fs, notes=[note])

    if p < 2:
        return plain("one position: no other to compare its mean with")
    if n.sum() < MIN_STATIC:
        return plain(f"{int(n.sum())} static samples in all (fewer than {MIN_STATIC}): too few for an Allan deviation")
    if like is not None and like.coef is not None:
        return _same_model(like, white, n / per_s, start_s)
    m = octaves(int(n.max()) // 2)
    count = np.array([np.sum(np.maximum(lengths - 2 * mm + 1, 0)) for mm in m])  # the second differences at m
    m = m[count / m >= MIN_PAIRS]  # independent pairs of τ-averages (as ν below)
    u = force_directions(means)  # for the check of turned poses
    avar, count, av_f, nu_f = _allan(y, lengths, m, u)
    nu = count / m  # independent pairs of τ-averages: a low estimate of the overlapping EDF (Greenhall's 1.1-1.5×)
    if len(m) < 3:
        return plain("the static intervals are too short for three τ of the Allan deviation")
    tau = m / per_s
    T = n / per_s
    # each mean's flicker variance about all positions' mean, per unit B²; without a rate, times are samples
    G = centred_covariance(flicker_covariance(start_s, T))
    g = np.diag(G)
    coef, sd_b, firsts = _fit_axes(tau, avar, np.repeat(nu[:, None], 3, axis=1))
    # The residual sees each mean along its force only, and a pose that turns while held moves the output across
    # the force, which the per-axis Allan variance counts as flicker. The components along the force alone (no
    # turn enters them) give a consistent, less precise flicker level; TURN_Z of its standard errors below the
    # per-axis level says the poses turned, and that axis's floor then takes it (module docstring).
    notes = []
    turn_z = np.full(3, np.nan)
    b_along = np.full(3, np.nan)
    if u is not None:
        seen = np.all(np.isfinite(av_f), axis=0) & np.all(nu_f > 0, axis=0)  # axes the poses tell apart at every τ
        coef_f, sd_f, _ = _fit_axes(tau, np.where(seen, av_f, 1.0), np.where(seen, nu_f, 1.0), firsts)
        seen &= sd_f > 0
        b_along[seen] = np.sqrt(np.maximum(coef_f[seen, 1], 0.0)) / FLICKER_FACTOR
        turn_z[seen] = (coef[seen, 1] - coef_f[seen, 1]) / sd_f[seen]
    turned = (coef[:, 1] > 0) & (np.nan_to_num(turn_z, nan=-np.inf) > TURN_Z)
    b_axis = np.sqrt(np.maximum(coef[:, 1], 0.0)) / FLICKER_FACTOR
    if turned.any():
        def fmt(v):
            return "/".join(format(float(x), ".3g") for x in v)

        notes.append(f"the poses turned while held ({'/'.join(np.array(list('xyz'))[turned])}: flicker B = "
                     f"{fmt(b_axis[turned])} {units} per axis, {fmt(b_along[turned])} {units} along the force, "
                     f"{fmt(turn_z[turned])} standard errors apart): a turn moves the output across the force, "
                     "where the residual does not look, so the floor takes the flicker along the force there")
        # the flicker the residual sees: along the force, where a turn does not enter (its fit's level and SE)
        coef, sd_b = coef.copy(), sd_b.copy()
        coef[turned, 1] = np.maximum(coef_f[turned, 1], 0.0)
        sd_b[turned] = sd_f[turned]
    B2 = coef[:, 1] / FLICKER_FACTOR**2  # B², possibly negative: the unbiased estimate
    model = coef[None, :, 0] / T[:, None] + B2[None, :] * g[:, None]
    sem = np.sqrt(np.maximum(model, white**2))
    # Satterthwaite: Σ sem² carries the estimation noise of each axis's B², SD sd_b/0.664²·Σ g
    var = np.sum((sd_b / FLICKER_FACTOR**2 * g.sum()) ** 2)
    edf = float(2.0 * np.sum(sem**2) ** 2 / var) if var > 0 else math.inf
    at_T = np.sqrt(np.maximum(coef[None, :, 0] / T[:, None] + coef[None, :, 1], 0.0))
    if not math.isfinite(fs):
        notes.append("the recording has no rate: τ and the coefficients' seconds are samples")
    return NoiseFloor(sem, white, "allan", units, fs, np.sqrt(coef[:, 0]), np.sqrt(np.maximum(B2, 0.0)), tau,
                      np.sqrt(avar), at_T, notes, edf, G, np.maximum(B2, 0.0), turned, turn_z, b_along, coef, sd_b,
                      b_axis)


def _same_model(like: NoiseFloor, white: np.ndarray, T: np.ndarray, start_s: np.ndarray) -> NoiseFloor:
    """The floor of new intervals (their σ/√n ``white``, lengths ``T`` and starts) under ``like``'s Allan model:
    the model's white and flicker terms and the flicker covariance of the new intervals, as in
    :func:`noise_floor`."""
    coef, sd_b = like.coef, like.coef_sd
    G = centred_covariance(flicker_covariance(start_s, T))
    g = np.diag(G)
    B2 = coef[:, 1] / FLICKER_FACTOR**2
    sem = np.sqrt(np.maximum(coef[None, :, 0] / T[:, None] + B2[None, :] * g[:, None], white**2))
    var = np.sum((sd_b / FLICKER_FACTOR**2 * g.sum()) ** 2)
    edf = float(2.0 * np.sum(sem**2) ** 2 / var) if var > 0 else math.inf
    at_T = np.sqrt(np.maximum(coef[None, :, 0] / T[:, None] + coef[None, :, 1], 0.0))
    return NoiseFloor(sem, white, like.estimator, like.units, like.rate_hz, like.density, like.bias_instability,
                      like.tau_s, like.adev, at_T, list(like.notes), edf, G, like.b2, like.turned, like.turn_z,
                      like.along_bias_instability, coef, sd_b, like.axis_bias_instability)
