"""Noise of a static accelerometer (or gyroscope) recording, read from its Allan deviation.

The package: :mod:`~optcal.core.noise.allan` reads the stretch and computes σ(τ), :mod:`~optcal.core.noise.fit` fits the
three terms and their intervals, :mod:`~optcal.core.noise.report` holds the result and writes the table, the JSON
and Kalibr's yaml, :mod:`~optcal.core.noise.colored` draws noise of given N, B and K for simulations; the figure is
:mod:`optcal.core.plots.noise`. Every name is importable from ``optcal.core.noise``.

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
gets a note: K takes the drift in). Each point is weighted by the inverse variance of its σ², 2σ⁴/ν, with σ and the
noise type behind ν taken from the fitted curve (iteratively re-weighted). The three lines of the figure are the fit's
terms: the −1/2 line (N read at τ = 1 s), the floor 0.664·B and the +1/2 line (K read at τ = 3 s). B and K are reported
as upper bounds, not estimates, when σ still falls at the longest τ (the minimum is not reached: the lowest
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
small biases: it is off by the bias along gravity over 1 g (about 10 % on the MPU-6050 recording of the
real corpus, docs/real_data.md, whose z offset is 0.11 g); give the nominal or calibrated scale when it matters.

A gyroscope is analysed the same way, its samples turned into rad/s instead of g (by its output units per
rad/s: exact for deg/s and rad/s, given for counts and volts); :class:`NoiseReport` with ``sensor``
"gyroscope" then reads N in rad/s/√Hz, B in rad/s and K in rad/s/√s = rad/s²/√Hz, Kalibr's
``gyroscope_noise_density`` and ``gyroscope_random_walk`` (:mod:`~optcal.core.noise.report`). ``optcal noise``
finds the gyroscope's columns as ``optcal imu`` does.
"""

from optcal.core.noise.allan import (
    AXES,
    MAX_STATIC_G,
    MIN_AVERAGES,
    MIN_TAUS,
    NONSTATIC_RATIO,
    WhiteNoise,
    analyse,
    analyse_axis,
    load_white_noise,
    noise_from_recording,
    octave_m,
)
from optcal.core.noise.colored import colored_noise
from optcal.core.noise.fit import (
    DEFAULT_CI,
    FLICKER_FACTOR,
    MIN_TERM_EDF,
    RAMP_SLOPE,
    RW_TAU_S,
    SLOPE_TOL,
    WHITE_TAU_S,
    Coefficient,
    Fit,
    chi2_interval,
    fit_terms,
    greenhall_edf,
    noise_type,
    read_terms,
)
from optcal.core.noise.report import G0, METHOD, SENSORS, UNIT_SCALE, AxisNoise, NoiseReport

__all__ = [
    "AXES", "DEFAULT_CI", "FLICKER_FACTOR", "G0", "MAX_STATIC_G", "METHOD", "MIN_AVERAGES", "MIN_TAUS",
    "MIN_TERM_EDF", "NONSTATIC_RATIO", "RAMP_SLOPE", "RW_TAU_S", "SENSORS", "SLOPE_TOL", "UNIT_SCALE", "WHITE_TAU_S",
    "AxisNoise", "Coefficient", "Fit", "NoiseReport", "WhiteNoise", "analyse", "analyse_axis", "chi2_interval",
    "colored_noise",
    "fit_terms", "greenhall_edf", "load_white_noise", "noise_from_recording", "noise_type", "octave_m",
    "read_terms",
]
