"""Noise of a static accelerometer recording, read from its Allan deviation.

The overlapping Allan deviation σ(τ) of each axis is computed with allantools (``allantools.oadev`` on the
samples as frequency data, at octave-spaced τ = m/f_s, m = 1, 2, 4, … up to a quarter of the stretch). Three
coefficients are read from it as IEEE Std 952-1997, Annex C, and El-Sheimy, Hou & Niu, "Analysis and
modeling of inertial sensors using Allan variance" (IEEE Trans. Instrum. Meas. 57(1), 2008) describe:

* white-noise density N (velocity random walk): the line of slope −1/2, σ(τ) = N/√τ, read at τ = 1 s.
  N is the square root of the two-sided power spectral density, in g/√Hz (= g·√s): a per-sample SD σ_d at
  rate f_s gives N = σ_d/√f_s, the SD of a mean over a dwell T is N/√T, and N is Kalibr's noise density.
  A datasheet's one-sided density is √2·N.
* bias instability B: the flat floor of σ(τ) divided by √(2 ln 2 / π) ≈ 0.664, in g (flicker noise of
  two-sided PSD B²/(2π|f|) has σ(τ) = 0.664·B for every τ).
* bias random walk K (rate random walk of the accelerometer bias): the line of slope +1/2,
  σ(τ) = K·√(τ/3), read at τ = 3 s, in g/√s (= g/s/√Hz; Kalibr's ``accelerometer_random_walk`` is K·g0 in
  m/s³/√Hz).

How the coefficients are found (a least-squares fit of the Allan-variance model, not a reading of single
points): σ²(τ) = N²/τ + (0.664·B)² + K²·τ/3 is fitted by weighted non-negative least squares (N², B², K² ≥ 0;
the terms as IEEE Std 952 Annex C and El-Sheimy et al. write them, without the quantisation, rate-ramp
and sinusoid terms) over the points from the first one on the −1/2 line (a point at or before
the minimum of σ whose local log-log slope is within ``SLOPE_TOL`` = 0.1 of −1/2; shorter τ may carry
quantisation or the low-pass filter) to the last (a curve that ends steeper than a random walk, a drift,
gets a note: K takes the drift in).
Each point is weighted by the inverse variance of its σ², 2σ⁴/ν, with σ and the noise type behind ν taken
from the fitted curve (iteratively re-weighted). The three lines of the figure are the fit's terms: the −1/2
line (N read at τ = 1 s), the floor 0.664·B and the +1/2 line (K read at τ = 3 s). B and K are reported as
upper bounds, not estimates, when σ still falls at the longest τ (the minimum is not reached: the lowest
point is the last one and the white term explains more than a quarter of its σ²) or when the fit leaves
their term at 0 or undetermined (EDF below 2): K ≤ the upper confidence limit of σ(τ)·√(3/τ) at the longest
τ, B ≤ that of the minimum of σ / 0.664 (every noise term adds to σ²). Without a white term N is missing.
The flicker floor's factor is 2 ln 2/π ≈ 0.4413 (0.664²).

Confidence intervals: the chi-square interval of an Allan variance with ν degrees of freedom,
[ν·σ²/χ²_ν((1+c)/2), ν·σ²/χ²_ν((1−c)/2)] (NIST SP 1065 eq. 45, ``allantools.confidence_interval``), with ν
from Greenhall's EDF algorithm for the overlapping ADEV (``allantools.edf_greenhall``, d = 2) for the noise
type of the local slope (per point, the error bars of the figure). For a fitted coefficient: it is linear in
the points' σ², ĉ = Σ G_i·σ̂²_i; overlapping ADEV at neighbouring τ are correlated, so its SD is bounded as if
they were fully correlated, Σ |G_i|·SD(σ̂²_i), which holds whatever the correlation; a variance-like
coefficient of relative SD r has ν = 2/r², and N, B, K get the chi-square interval of that ν. The intervals
are conservative: on synthetic noise the 68 % interval holds the truth 90–95 % of the time for N and K
(tests/test_noise.py checks N's). They cover the noise of the estimate, not a wrong model (a Gauss-Markov
bump, quantisation or a sinusoid inside the fitted range).

Units: the recording's outputs are turned into g (of 9.80665 m/s²) before anything else: g as they are,
mg/1000, m/s²/g0; counts and volts by a scale in output units per g, given, or else the magnitude of the
stretch's mean output (a static sensor reads 1 g). That default assumes equal scales on the three axes and
small biases: it is off by the bias along gravity over 1 g (about 10 % on the MPU-6050 recording in
tests/data, whose z offset is 0.11 g); give the nominal or calibrated scale when it matters.
"""

from __future__ import annotations

import io
import json
import logging
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import InputError

log = logging.getLogger(__name__)

G0 = 9.80665  # m/s² per g
FLICKER_FACTOR = math.sqrt(2.0 * math.log(2.0) / math.pi)  # σ(τ) = 0.664·B on the flicker plateau
WHITE_TAU_S = 1.0  # N is read on the −1/2 line at τ = 1 s
RW_TAU_S = 3.0  # K is read on the +1/2 line at τ = 3 s
SLOPE_TOL = 0.1  # a point is on a line of slope p when its local slope is within this of p
MIN_AVERAGES = 4  # the longest τ is at most a quarter of the stretch
MIN_TAUS = 3  # a stretch must give at least this many octave τ (16 samples)
DEFAULT_CI = 0.6826894921370859  # one-sigma
UNIT_SCALE = {"g": 1.0, "mg": 1e3, "m/s2": G0}  # output units per g
AXES = ("x", "y", "z")
NONSTATIC_RATIO = 25.0  # a 1-s window variance this many times the median's: motion
MAX_STATIC_G = 3.0  # a mean output above this many g is not a sensor at rest: wrong units
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


@dataclass
class AxisNoise:
    axis: str
    tau_s: np.ndarray
    adev_g: np.ndarray
    adev_low_g: np.ndarray
    adev_high_g: np.ndarray
    edf: np.ndarray
    slope: np.ndarray  # local log-log slope of σ(τ)
    white: Coefficient  # N, g/√Hz
    bias_instability: Coefficient  # B, g
    random_walk: Coefficient  # K, g/√s
    fit: Fit | None = None
    notes: list = field(default_factory=list)

    def to_dict(self) -> dict:
        return {
            "white_noise_density_g_per_sqrt_hz": self.white.scaled(1.0),
            "white_noise_density_ug_per_sqrt_hz": self.white.scaled(1e6),
            "bias_instability_ug": self.bias_instability.scaled(1e6),
            "random_walk_ug_per_sqrt_s": self.random_walk.scaled(1e6),
            "allan": {"tau_s": self.tau_s.tolist(), "adev_ug": (self.adev_g * 1e6).tolist(),
                      "adev_low_ug": (self.adev_low_g * 1e6).tolist(),
                      "adev_high_ug": (self.adev_high_g * 1e6).tolist(),
                      "edf": self.edf.tolist(), "local_slope": self.slope.tolist(),
                      "fitted": (self.fit.region.tolist() if self.fit else None),
                      "fit_adev_ug": (np.sqrt(self.fit.variance(self.tau_s)) * 1e6).tolist() if self.fit else None},
        }


@dataclass
class NoiseReport:
    """The Allan-deviation noise analysis of one static stretch, per axis."""

    axes: list[AxisNoise]
    rate_hz: float
    n_samples: int
    start_s: float  # the stretch, seconds from the recording's first sample
    end_s: float
    units: str  # the recording's output units
    scale: float  # output units per g
    scale_source: str
    ci: float
    source: str | None = None
    notes: list[str] = field(default_factory=list)

    @property
    def duration_s(self) -> float:
        return self.n_samples / self.rate_hz

    def density_g(self) -> float:
        """The white-noise density of the three axes together, g/√Hz: the RMS over the axes (the
        Cramér-Rao bounds take one noise level for every axis, as the calibration problem's own does)."""
        vals = [a.white.value for a in self.axes if a.white.value is not None]
        if len(vals) < len(self.axes):
            missing = ", ".join(a.axis for a in self.axes if a.white.value is None)
            raise InputError(f"no white-noise (−1/2 slope) region in the Allan deviation of axis {missing}"
                             f"{' of ' + self.source if self.source else ''}; the white-noise density is unknown")
        return float(np.sqrt(np.mean(np.square(vals))))

    def to_dict(self) -> dict:
        return {
            "kind": "optcal noise",
            "source": self.source,
            "interval_s": [self.start_s, self.end_s],
            "n_samples": self.n_samples,
            "duration_s": self.duration_s,
            "rate_hz": self.rate_hz,
            "units": self.units,
            "scale_units_per_g": self.scale,
            "scale_source": self.scale_source,
            "ci_level": self.ci,
            "method": METHOD,
            "white_noise_density_rms_g_per_sqrt_hz": _or_none(self.density_g),
            "axes": {a.axis: a.to_dict() for a in self.axes},
            "notes": list(self.notes),
        }

    # -- text ---------------------------------------------------------------------------------------
    def table(self) -> str:
        pct = f"{100 * self.ci:.3g}%"
        head = (f"{self.source or 'recording'}: {self.n_samples} samples, {self.duration_s:.6g} s at "
                f"{self.rate_hz:.6g} Hz ({self.start_s:.6g}–{self.end_s:.6g} s), units {self.units}"
                + ("" if self.units in UNIT_SCALE else f", {self.scale:.6g} {self.units} per g ({self.scale_source})"))
        taus = self.axes[0].tau_s
        lines = [head, f"overlapping Allan deviation at {len(taus)} octave τ from {taus[0]:.3g} to {taus[-1]:.3g} s; "
                 f"{pct} intervals (chi-square, Greenhall EDF)", ""]
        cols = ("white-noise density [µg/√Hz]", "bias instability [µg]", "random walk [µg/√s]")
        lines.append(f"{'axis':<5}" + "".join(f"{c:>32}" for c in cols))
        for a in self.axes:
            cells = [_cell(a.white, 1e6), _cell(a.bias_instability, 1e6), _cell(a.random_walk, 1e6)]
            lines.append(f"{a.axis:<5}" + "".join(f"{c:>32}" for c in cells))
        lines.append("")
        lines.append("fit σ² = N²/τ + (0.664·B)² + K²·τ/3: N the −1/2 line at τ = 1 s, B the floor / 0.664, K the "
                     "+1/2 line at τ = 3 s; ≤: an upper bound")
        lines.append("")
        lines.append(f"{'τ [s]':>10}" + "".join(f"{'σ_' + a.axis + ' [µg]':>14}" for a in self.axes))
        for i, t in enumerate(taus):
            lines.append(f"{t:10.4g}" + "".join(f"{a.adev_g[i] * 1e6:14.4g}" for a in self.axes))
        lines += [f"note: {n}" for n in self.notes]
        return "\n".join(lines)

    def kalibr_yaml(self) -> str:
        """Kalibr's imu.yaml accelerometer fields, in SI: the largest axis's N·g0 and K·g0 (Kalibr takes
        one isotropic value; the largest is the conservative choice)."""
        n_axis = max(self.axes, key=lambda a: a.white.value if a.white.value is not None else math.inf)
        if n_axis.white.value is None:
            self.density_g()  # raises, naming the axis
        k_axis = max(self.axes, key=lambda a: a.random_walk.value)
        bound = k_axis.random_walk.kind != "estimate"
        lines = [
            f"# accelerometer noise measured by optcal noise from {self.source or 'a recording'}",
            f"# ({self.n_samples} samples, {self.duration_s:.6g} s at {self.rate_hz:.6g} Hz); the largest axis of "
            "each.",
            "# Kalibr also needs gyroscope_noise_density, gyroscope_random_walk and rostopic; Kalibr's",
            "# documentation advises inflating measured values for real use (unmodelled effects).",
            f"accelerometer_noise_density: {n_axis.white.value * G0:.6e}  # [m/s^2/sqrt(Hz)] "
            f"(axis {n_axis.axis}: {n_axis.white.value * 1e6:.4g} ug/sqrt(Hz))",
            f"accelerometer_random_walk: {k_axis.random_walk.value * G0:.6e}  # [m/s^3/sqrt(Hz)] "
            f"(axis {k_axis.axis}: {k_axis.random_walk.value * 1e6:.4g} ug/sqrt(s)"
            + (", an upper bound: the +1/2 slope is not reached in this recording)" if bound else ")"),
            f"update_rate: {self.rate_hz:.6g}  # [Hz]",
        ]
        return "\n".join(lines) + "\n"

    # -- figure -------------------------------------------------------------------------------------
    def figure(self):
        """A log-log figure of σ(τ) per axis with its intervals, the fitted curve and its three lines (−1/2 with
        N marked at τ = 1 s, the floor 0.664·B, +1/2 with K marked at τ = 3 s; ▼ marks an upper bound), as a
        :class:`matplotlib.figure.Figure` (no pyplot, no backend switch)."""
        from matplotlib.figure import Figure

        fig = Figure(figsize=(7.5, 5.4), layout="constrained")
        ax = fig.add_subplot()
        colours = ("tab:blue", "tab:orange", "tab:green")
        shown = []
        for a, c in zip(self.axes, colours):
            y = a.adev_g * 1e6
            err = np.vstack([y - a.adev_low_g * 1e6, a.adev_high_g * 1e6 - y])
            ax.errorbar(a.tau_s, y, yerr=err, fmt="o", ms=3.5, color=c, capsize=2, label=f"σ_{a.axis}(τ)")
            shown += [*(a.adev_low_g * 1e6), *(a.adev_high_g * 1e6)]
            tt = np.geomspace(min(a.tau_s[0], WHITE_TAU_S), max(a.tau_s[-1], RW_TAU_S), 60)
            if a.fit is not None:
                tf = np.geomspace(a.tau_s[a.fit.region][0], a.tau_s[a.fit.region][-1], 60)
                ax.plot(tf, np.sqrt(a.fit.variance(tf)) * 1e6, "-", color=c, lw=1.2, alpha=0.8)
            if a.white.value is not None:
                ax.plot(tt, a.white.value * 1e6 / np.sqrt(tt), "--", color=c, lw=0.8,
                        label=f"{a.axis}: N = {a.white.value * 1e6:.3g} µg/√Hz")
                ax.plot([WHITE_TAU_S], [a.white.value * 1e6], "s", color=c, mfc="none", ms=7)
                shown.append(a.white.value * 1e6)
            b = a.bias_instability
            if b.kind == "estimate":
                ax.axhline(b.value * FLICKER_FACTOR * 1e6, color=c, ls=":", lw=0.9,
                           label=f"{a.axis}: B = {b.value * 1e6:.3g} µg (floor / 0.664)")
            else:
                ax.plot(b.tau_s, [b.value * FLICKER_FACTOR * 1e6], "v", color=c, ms=6,
                        label=f"{a.axis}: B ≤ {b.value * 1e6:.3g} µg")
            k = a.random_walk
            if k.kind == "estimate":
                ax.plot(tt, k.value * 1e6 * np.sqrt(tt / 3.0), "-.", color=c, lw=0.8,
                        label=f"{a.axis}: K = {k.value * 1e6:.3g} µg/√s")
                ax.plot([RW_TAU_S], [k.value * 1e6], "D", color=c, mfc="none", ms=6)
                shown.append(k.value * 1e6)
            else:
                ax.plot(k.tau_s, [k.value * 1e6 * math.sqrt(k.tau_s[0] / 3.0)], "^", color=c, mfc="none", ms=6,
                        label=f"{a.axis}: K ≤ {k.value * 1e6:.3g} µg/√s")
        ax.set_xscale("log")
        ax.set_yscale("log")
        pos = [v for v in shown if v > 0 and np.isfinite(v)]
        ax.set_ylim(min(pos) / 1.6, max(pos) * 1.6)
        ax.grid(True, which="both", lw=0.3, alpha=0.6)
        ax.set_xlabel("averaging time τ [s]")
        ax.set_ylabel("overlapping Allan deviation [µg]")
        name = Path(self.source).name if self.source and Path(self.source).is_file() else (self.source or "recording")
        ax.set_title(f"{name}: {self.duration_s:.4g} s at {self.rate_hz:.4g} Hz ({100 * self.ci:.3g}% intervals)",
                     fontsize=9)
        ax.text(0.01, 0.01, "fit: σ² = N²/τ + (0.664·B)² + K²·τ/3", transform=ax.transAxes, fontsize=7,
                color="0.3")
        ax.legend(fontsize=7, ncol=2, loc="best")
        return fig

    def figure_bytes(self, fmt: str = "png") -> bytes:
        buf = io.BytesIO()
        self.figure().savefig(buf, format=fmt, dpi=120)
        return buf.getvalue()


METHOD = ("overlapping Allan deviation (allantools.oadev) at octave τ; weighted non-negative least-squares fit of "
          "σ²(τ) = N²/τ + (0.664·B)² + K²·τ/3 (IEEE Std 952-1997 Annex C; El-Sheimy, Hou & Niu 2008): N is the −1/2 "
          "line at τ = 1 s, B the floor / sqrt(2 ln 2 / pi), K the +1/2 line at τ = 3 s; intervals: chi-square with "
          "Greenhall's EDF, the points taken as fully correlated (optcal/noise.py)")


def _or_none(fn):
    try:
        return fn()
    except InputError:
        return None


def _cell(c: Coefficient, factor: float) -> str:
    if c.value is None:
        return "not found"
    if c.kind == "upper bound":
        return f"≤ {c.value * factor:.4g}"
    txt = f"{c.value * factor:.4g} ({c.low * factor:.3g}–{c.high * factor:.3g})"
    return txt


# -- computation --------------------------------------------------------------------------------------
def octave_m(n: int, max_m: int | None = None) -> np.ndarray:
    """Averaging factors 1, 2, 4, … up to ``max_m`` (default: a quarter of ``n``)."""
    top = n // MIN_AVERAGES if max_m is None else max_m
    return 2 ** np.arange(int(math.floor(math.log2(top))) + 1) if top >= 1 else np.array([], int)


def _alpha(slope: float) -> int:
    """Power-law noise type (S_y ∝ f^α) of a local ADEV slope: σ ∝ τ^μ/2 with μ = −α − 1."""
    return int(np.clip(round(-2.0 * slope - 1.0), -2, 2))


def _edf(alpha: int, m: int, n_phase: int) -> float:
    import allantools

    return float(allantools.edf_greenhall(alpha=alpha, d=2, m=int(m), N=int(n_phase), overlapping=True,
                                          modified=False))


def _interval(value: float, edf: float, ci: float) -> tuple[float, float]:
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
        nu = np.array([_edf(_alpha(sl), m, n_phase) for sl, m in zip(local, mm[idx])])
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
    lo, hi = _interval(value, nu, ci)
    return Coefficient(value, lo, hi, "estimate", taus[fit.region].tolist(), float(nu), "fit")


def _read(taus, adev, slope, mm, n_phase, ci) -> tuple[Coefficient, Coefficient, Coefficient, Fit, list[str]]:
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
        e_k = _edf(-2, mm[last], n_phase)
        _, hi = _interval(adev[last] * math.sqrt(3.0 / taus[last]), e_k, ci)
        rw = Coefficient(hi, None, hi, "upper bound", [float(taus[last])], e_k, "upper limit of σ·√(3/τ) at the "
                         "longest τ")
    bias = _term(fit, 1, 1.0 / FLICKER_FACTOR**2, ci, taus) if reached else None
    if bias is None:  # no floor: B ≤ the minimum of σ / 0.664, its upper limit
        e_b = _edf(-1, mm[i_min], n_phase)
        _, hi = _interval(adev[i_min] / FLICKER_FACTOR, e_b, ci)
        bias = Coefficient(hi, None, hi, "upper bound", [float(taus[i_min])], e_b, "upper limit of the minimum "
                           "of σ / 0.664")
    return white, bias, rw, fit, notes


def analyse_axis(y_g: np.ndarray, rate: float, m: np.ndarray, ci: float = DEFAULT_CI, axis: str = "x") -> AxisNoise:
    """Allan deviation of one axis (samples in g at ``rate`` Hz) at averaging factors ``m``, and N, B, K."""
    import allantools

    y = np.asarray(y_g, float) - float(np.mean(y_g))
    n_phase = len(y) + 1
    taus, adev, _, _ = allantools.oadev(y, rate=rate, data_type="freq", taus=np.asarray(m, float) / rate)
    taus = np.asarray(taus, float)
    adev = np.asarray(adev, float)
    keep = adev > 0
    if keep.sum() < 2:
        raise InputError(f"axis {axis}: the samples are constant (Allan deviation zero); no noise to measure")
    taus, adev = taus[keep], adev[keep]
    mm = np.rint(taus * rate).astype(int)
    slope = np.gradient(np.log(adev), np.log(taus))
    edf = np.array([_edf(_alpha(s), k, n_phase) for s, k in zip(slope, mm)])
    bounds = np.array([_interval(d, e, ci) for d, e in zip(adev, edf)])
    white, bias, rw, fit, notes = _read(taus, adev, slope, mm, n_phase, ci)
    return AxisNoise(axis, taus, adev, bounds[:, 0], bounds[:, 1], edf, slope, white, bias, rw, fit,
                     [f"axis {axis}: {n}" for n in notes])


def _static_notes(N_g: np.ndarray, rate: float, start_s: float) -> list[str]:
    """Warnings when the stretch does not look static: the variance over 1-s windows jumps."""
    n = len(N_g)
    w = int(max(2, min(round(rate), n // 20)))
    k = n // w
    if k < 4:
        return []
    var = N_g[: k * w].reshape(k, w, 3).var(axis=1)
    stat = np.linalg.norm(var, axis=1)
    med = float(np.median(stat))
    if med <= 0:
        return []
    j = int(np.argmax(stat))
    ratio = float(stat[j] / med)
    if ratio > NONSTATIC_RATIO:
        return [f"the stretch does not look static: the variance over {w / rate:.3g}-s windows reaches "
                f"{ratio:.0f}× its median at t ≈ {start_s + (j + 0.5) * w / rate:.1f} s (motion?); "
                "the Allan deviation then measures the motion, not the sensor; choose a static interval"]
    return []


def analyse(N, rate: float, *, units: str = "g", scale: float | None = None, ci: float = DEFAULT_CI,
            tau_max_s: float | None = None, start_s: float = 0.0, source: str | None = None) -> NoiseReport:
    """The noise analysis of a static stretch ``N`` (n, 3) in ``units`` sampled at ``rate`` Hz.
    ``scale``: output units per g (needed for counts and volts; default: the magnitude of the mean output);
    ``tau_max_s``: the longest τ (default a quarter of the stretch); ``ci``: the confidence level."""
    N = np.asarray(N, float)
    if N.ndim != 2 or N.shape[1] != 3:
        raise InputError(f"the samples must have three axes; got shape {N.shape}")
    if not (rate is not None and np.isfinite(rate) and rate > 0):
        raise InputError("the sample rate is unknown; a noise analysis needs it (a time column or a given rate)")
    if not 0 < ci < 1:
        raise InputError(f"the confidence level {ci!r} must be between 0 and 1, e.g. 0.683 or 0.95")
    n = len(N)
    notes: list[str] = []
    # units → g
    if scale is not None:
        if not (np.isfinite(scale) and scale > 0):
            raise InputError(f"the scale {scale!r} must be a positive number of output units per g")
        how = "given"
    elif units in UNIT_SCALE:
        scale, how = UNIT_SCALE[units], f"{units}"
        mag = float(np.linalg.norm(N.mean(axis=0))) / scale
        if mag > MAX_STATIC_G:
            raise InputError(f"the mean output's magnitude is {mag:.6g} g, which no sensor at rest reads; are the "
                             f"outputs really in {units}?")
    else:
        scale = float(np.linalg.norm(N.mean(axis=0)))
        if not scale > 0:
            raise InputError(f"the mean output is zero, so the scale of {units} to g cannot be inferred; give the "
                             "scale in output units per g")
        how = "magnitude of the mean output = 1 g"
        notes.append(f"{units} turned into g by the magnitude of the mean output, {scale:.6g} {units} = 1 g "
                     "(assumes equal scales and small biases; give the scale for better)")
    # taus
    max_m = n // MIN_AVERAGES
    if tau_max_s is not None:
        if not tau_max_s > 0:
            raise InputError(f"the longest τ {tau_max_s!r} must be positive, in seconds")
        want = int(math.floor(tau_max_s * rate + 1e-9))
        if want < 2 ** (MIN_TAUS - 1):
            raise InputError(f"τ up to {tau_max_s:g} s gives fewer than {MIN_TAUS} octave τ at {rate:.6g} Hz; ask for "
                             f"at least {2 ** (MIN_TAUS - 1) / rate:g} s")
        if want > max_m:
            raise InputError(f"the stretch is too short for τ up to {tau_max_s:g} s: it has {n} samples "
                             f"({n / rate:.4g} s at {rate:.6g} Hz) and τ may be at most a quarter of it "
                             f"({max_m / rate:.4g} s); record at least {MIN_AVERAGES * tau_max_s:g} s")
        max_m = want
    m = octave_m(n, max_m)
    if len(m) < MIN_TAUS:
        raise InputError(f"the stretch is too short: {n} samples ({n / rate:.4g} s at {rate:.6g} Hz) give "
                         f"{len(m)} octave τ, and the Allan deviation needs at least {MIN_TAUS} "
                         f"({2 ** (MIN_TAUS - 1) * MIN_AVERAGES} samples; seconds to minutes for a useful curve)")
    N_g = N / scale
    for note in _static_notes(N_g, rate, start_s):
        log.warning(note)
        notes.append(note)
    axes = [analyse_axis(N_g[:, j], rate, m, ci, a) for j, a in enumerate(AXES)]
    for a in axes:
        notes += a.notes
        if a.white.value is None:
            notes.append(f"axis {a.axis}: the fit found no white-noise (−1/2) term; the white-noise density is "
                         "unknown (filtered or quantised output? a longer or faster recording may help)")
        if a.random_walk.kind != "estimate":
            notes.append(f"axis {a.axis}: no random-walk (+1/2) term up to τ = {a.tau_s[-1]:.4g} s; K is an upper "
                         "bound (a longer recording reaches it)")
        if a.bias_instability.kind != "estimate":
            notes.append(f"axis {a.axis}: no flat floor"
                         + (" (σ still falls at the longest τ)" if a.bias_instability.tau_s[0] == a.tau_s[-1] else "")
                         + "; B is an upper bound")
    return NoiseReport(axes, float(rate), n, float(start_s), float(start_s + n / rate), units, float(scale), how,
                       float(ci), source, notes)


def parse_interval(spec: str | None) -> tuple[float | None, float | None]:
    """``START:END`` seconds (either may be empty) → (start, end)."""
    if spec is None:
        return None, None
    a, sep, b = str(spec).partition(":")
    try:
        if not sep:
            raise ValueError
        start = float(a) if a.strip() else None
        end = float(b) if b.strip() else None
    except ValueError:
        raise InputError(f"interval {spec!r} must be START:END in seconds, e.g. 0:36 (either may be empty)") from None
    if start is not None and end is not None and end <= start:
        raise InputError(f"interval {spec!r}: END must be after START")
    return start, end


def noise_from_recording(path, *, columns=None, rate: float | None = None, units: str = "g",
                         interval=None, scale: float | None = None, ci: float = DEFAULT_CI,
                         tau_max_s: float | None = None) -> NoiseReport:
    """Read a raw recording (:func:`optcal.recording.read_recording`: the same columns, units and rate
    rules as a calibration recording) and analyse the stretch ``interval`` = (start, end) in seconds from
    its first sample (either may be None; default the whole file)."""
    from .recording import read_recording

    rec = read_recording(path, columns, rate, units)
    start, end = interval if interval is not None else (None, None)
    t = rec.t - rec.t[0]
    steps = np.diff(rec.t)
    gaps = steps > 1.5 * np.median(steps)
    notes = []
    lo = 0.0 if start is None else float(start)
    hi = math.inf if end is None else float(end)
    sel = (t >= lo - 1e-9) & (t < hi - 1e-9)
    if not sel.any():
        raise InputError(f"{path}: the interval {lo:g}:{'' if end is None else f'{hi:g}'} s holds no sample; the "
                         f"recording spans 0–{t[-1]:.6g} s from its first sample")
    i0, i1 = int(np.flatnonzero(sel)[0]), int(np.flatnonzero(sel)[-1]) + 1
    g = gaps[i0: max(i0, i1 - 1)]
    if g.any():
        note = (f"the time column has {int(g.sum())} gap(s) in the stretch (largest {steps[i0:i1 - 1].max():.4g} s "
                f"for a step of {np.median(steps):.4g} s); the Allan deviation assumes uniform sampling")
        log.warning(note)
        notes.append(note)
    report = analyse(rec.N[i0:i1], rec.rate, units=rec.units, scale=scale, ci=ci, tau_max_s=tau_max_s,
                     start_s=float(t[i0]), source=str(path))
    report.notes[:0] = notes
    return report


@dataclass(frozen=True)
class WhiteNoise:
    """The white-noise density of a recording or of an ``optcal noise`` JSON: what Cramér-Rao bounds need."""

    density_g: float  # g/√Hz, RMS over the axes
    rate_hz: float  # the rate of the noise recording
    source: str

    def sigma_of_mean_g(self, dwell_s) -> float:
        """SD of a position's mean over ``dwell_s`` seconds (a number or one per position), g: N/√T, the RMS
        over positions when the dwells differ (the calibration problem takes one level)."""
        d = np.atleast_1d(np.asarray(dwell_s, float))
        if d.size == 0 or not np.all(np.isfinite(d) & (d > 0)):
            raise InputError(f"the dwell time must be a positive number of seconds; got {dwell_s!r}")
        return float(self.density_g * np.sqrt(np.mean(1.0 / d)))


def load_white_noise(path, **reading) -> WhiteNoise:
    """The white-noise density from an ``optcal noise --json`` file, or from a raw recording (analysed with
    :func:`noise_from_recording` and ``reading``'s options)."""
    p = Path(path)
    try:
        head = p.read_text(errors="replace")[:4096] if p.suffix.lower() == ".json" else _head(p)
    except OSError as exc:
        raise InputError(f"cannot read {path}: {exc.strerror or exc}") from None
    if head.lstrip().startswith("{"):
        try:
            obj = json.loads(p.read_text())
        except json.JSONDecodeError as exc:
            raise InputError(f"{path} is not valid JSON ({exc.msg} at line {exc.lineno})") from None
        if not isinstance(obj, dict) or obj.get("kind") != "optcal noise":
            raise InputError(f"{path} is not the JSON of an optcal noise analysis (no \"kind\": \"optcal noise\")")
        d = obj.get("white_noise_density_rms_g_per_sqrt_hz")
        if not isinstance(d, (int, float)) or not d > 0:
            raise InputError(f"{path}: the analysis found no white-noise density "
                             "(white_noise_density_rms_g_per_sqrt_hz is missing)")
        return WhiteNoise(float(d), float(obj.get("rate_hz") or math.nan), str(path))
    report = noise_from_recording(path, **reading)
    return WhiteNoise(report.density_g(), report.rate_hz, str(path))


def _head(p: Path) -> str:
    with open(p, encoding="utf-8", errors="replace") as fh:
        return fh.read(4096)
