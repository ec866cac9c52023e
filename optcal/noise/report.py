"""The noise analysis's result (:class:`NoiseReport`, one :class:`AxisNoise` per axis) and its outputs: the
text table, the JSON record (units in the keys) and Kalibr's ``imu.yaml`` accelerometer fields in SI. The
figure is :func:`optcal.plots.noise.noise_figure`."""

from __future__ import annotations

import io
import math
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from ..errors import InputError
from ..gravity import G0
from .fit import FLICKER_FACTOR, RW_TAU_S, WHITE_TAU_S, Coefficient, Fit

UNIT_SCALE = {"g": 1.0, "mg": 1e3, "m/s2": G0}  # output units per g


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
    white_tau_s: ClassVar[float] = WHITE_TAU_S  # N is σ of the white term at this τ
    rw_tau_s: ClassVar[float] = RW_TAU_S  # K is σ of the random-walk term at this τ

    def term_adev_g(self, term: str, tau) -> np.ndarray:
        """σ(τ) in g of one term of the fit alone, at τ in s (a bound's coefficient gives its bound line):
        ``"white"`` N/√τ, ``"floor"`` 0.664·B (flat), ``"random_walk"`` K·√(τ/3)."""
        tau = np.asarray(tau, float)
        if term == "white":
            return self.white.value / np.sqrt(tau)
        if term == "floor":
            return np.full(tau.shape, self.bias_instability.value * FLICKER_FACTOR)
        return self.random_walk.value * np.sqrt(tau / 3.0)

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
    # -- figure -------------------------------------------------------------------------------------
    def figure(self):
        """The log-log Allan-deviation figure (:func:`optcal.plots.noise.noise_figure`), a
        :class:`matplotlib.figure.Figure`."""
        from ..plots.noise import noise_figure

        return noise_figure(self)

    def figure_bytes(self, fmt: str = "png") -> bytes:
        """The figure rendered in memory, in the format ``fmt`` (a suffix matplotlib writes)."""
        buf = io.BytesIO()
        self.figure().savefig(buf, format=fmt, dpi=120)
        return buf.getvalue()


METHOD = ("overlapping Allan deviation (allantools.oadev) at octave τ; weighted non-negative least-squares fit of "
          "σ²(τ) = N²/τ + (0.664·B)² + K²·τ/3 (IEEE Std 952-1997 Annex C; El-Sheimy, Hou & Niu 2008): N is the −1/2 "
          "line at τ = 1 s, B the floor / sqrt(2 ln 2 / pi), K the +1/2 line at τ = 3 s; intervals: chi-square with "
          "Greenhall's EDF, the points taken as fully correlated (optcal/noise/)")


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

