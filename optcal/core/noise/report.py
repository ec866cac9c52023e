"""The noise analysis's result (:class:`NoiseReport`, one :class:`AxisNoise` per axis) and its outputs: the
text table, the JSON record (units in the keys) and Kalibr's ``imu.yaml`` noise fields in SI. The figure is
:func:`optcal.core.plots.noise.noise_figure`.

A report is the accelerometer's (samples analysed in g: N in g/√Hz, B in g, K in g/√s) or the gyroscope's
(``sensor="gyroscope"``: samples analysed in rad/s, N in rad/s/√Hz, B in rad/s, K in rad/s/√s = rad/s²/√Hz).
The analysis is the same; only the unit of the samples differs. Kalibr's imu.yaml takes N and K of both
sensors in SI, as its IMU noise model defines them (white noise density σ and bias random walk σ_b of
ḃ = σ_b·w(t), w unit white noise; the Allan deviation's −1/2 line read at τ = 1 s, and the +1/2 line
K·√(τ/3)): accelerometer_noise_density = N·g0 [m/s²/√Hz], accelerometer_random_walk = K·g0 [m/s³/√Hz],
gyroscope_noise_density = N [rad/s/√Hz], gyroscope_random_walk = K [rad/s²/√Hz]. The table shows the
gyroscope in a datasheet's units: angle random walk N in °/√h, bias instability B in °/h and rate random
walk K in °/h/√h.
"""

from __future__ import annotations

import io
import math
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from optcal.core.errors import InputError
from optcal.core.gravity import G0
from optcal.core.noise.fit import FLICKER_FACTOR, RW_TAU_S, WHITE_TAU_S, Coefficient, Fit

UNIT_SCALE = {"g": 1.0, "mg": 1e3, "m/s2": G0}  # output units per g
SENSORS = ("accelerometer", "gyroscope")
DEG = 180.0 / math.pi
# the gyroscope's datasheet units from rad/s-based ones: N rad/√s -> °/√h (√h = 60 √s), B rad/s -> °/h,
# K rad/s/√s -> °/h/√h
ARW_DEG_PER_SQRT_H = DEG * 60.0
BI_DEG_PER_H = DEG * 3600.0
RRW_DEG_PER_H_PER_SQRT_H = DEG * 3600.0 * 60.0
# the table's columns per sensor: (heading, factor from the analysed unit), for N, B and K; then σ's unit
TABLE_UNITS = {
    "accelerometer": ((("white-noise density [µg/√Hz]", 1e6), ("bias instability [µg]", 1e6),
                       ("random walk [µg/√s]", 1e6)), ("µg", 1e6)),
    "gyroscope": ((("angle random walk [°/√h]", ARW_DEG_PER_SQRT_H), ("bias instability [°/h]", BI_DEG_PER_H),
                   ("rate random walk [°/h/√h]", RRW_DEG_PER_H_PER_SQRT_H)), ("°/h", BI_DEG_PER_H)),
}


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

    def to_dict(self, sensor: str = "accelerometer") -> dict:
        """The axis's coefficients and Allan deviation, units in the keys: the accelerometer's in g and µg,
        the gyroscope's in rad/s (SI, Kalibr's) and in a datasheet's degrees."""
        if sensor == "gyroscope":
            coefficients = {
                "white_noise_density_rad_s_per_sqrt_hz": self.white.scaled(1.0),
                "angle_random_walk_deg_per_sqrt_h": self.white.scaled(ARW_DEG_PER_SQRT_H),
                "bias_instability_rad_s": self.bias_instability.scaled(1.0),
                "bias_instability_deg_per_h": self.bias_instability.scaled(BI_DEG_PER_H),
                "random_walk_rad_s2_per_sqrt_hz": self.random_walk.scaled(1.0),
                "rate_random_walk_deg_per_h_per_sqrt_h": self.random_walk.scaled(RRW_DEG_PER_H_PER_SQRT_H),
            }
            unit, factor = "rad_s", 1.0
        else:
            coefficients = {
                "white_noise_density_g_per_sqrt_hz": self.white.scaled(1.0),
                "white_noise_density_ug_per_sqrt_hz": self.white.scaled(1e6),
                "bias_instability_ug": self.bias_instability.scaled(1e6),
                "random_walk_ug_per_sqrt_s": self.random_walk.scaled(1e6),
            }
            unit, factor = "ug", 1e6
        return {
            **coefficients,
            "allan": {"tau_s": self.tau_s.tolist(), f"adev_{unit}": (self.adev_g * factor).tolist(),
                      f"adev_low_{unit}": (self.adev_low_g * factor).tolist(),
                      f"adev_high_{unit}": (self.adev_high_g * factor).tolist(),
                      "edf": self.edf.tolist(), "local_slope": self.slope.tolist(),
                      "fitted": (self.fit.region.tolist() if self.fit else None),
                      f"fit_adev_{unit}": (np.sqrt(self.fit.variance(self.tau_s)) * factor).tolist()
                      if self.fit else None},
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
    # "accelerometer": the samples were analysed in g, ``scale`` is output units per g; "gyroscope": in rad/s,
    # ``scale`` output units per rad/s (every coefficient's "g" then reads rad/s)
    sensor: str = "accelerometer"

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

    @property
    def gyroscope(self) -> bool:
        return self.sensor == "gyroscope"

    def to_dict(self) -> dict:
        """The analysis as one JSON object, units in the keys (the gyroscope's in rad/s and degrees)."""
        unit = "rad_s" if self.gyroscope else "g"
        return {
            "kind": "optcal noise",
            "sensor": self.sensor,
            "source": self.source,
            "interval_s": [self.start_s, self.end_s],
            "n_samples": self.n_samples,
            "duration_s": self.duration_s,
            "rate_hz": self.rate_hz,
            "units": self.units,
            f"scale_units_per_{unit}": self.scale,
            "scale_source": self.scale_source,
            "ci_level": self.ci,
            "method": METHOD,
            f"white_noise_density_rms_{unit}_per_sqrt_hz": _or_none(self.density_g),
            "axes": {a.axis: a.to_dict(self.sensor) for a in self.axes},
            "notes": list(self.notes),
        }

    # -- text ---------------------------------------------------------------------------------------
    def table(self) -> str:
        pct = f"{100 * self.ci:.3g}%"
        per = "rad/s" if self.gyroscope else "g"
        head = (f"{self.sensor}, {self.source or 'recording'}: {self.n_samples} samples, {self.duration_s:.6g} s at "
                f"{self.rate_hz:.6g} Hz ({self.start_s:.6g}–{self.end_s:.6g} s), units {self.units}"
                + ("" if self.units in UNIT_SCALE and not self.gyroscope else
                   f", {self.scale:.6g} {self.units} per {per} ({self.scale_source})"))
        taus = self.axes[0].tau_s
        cols, (adev_unit, adev_factor) = TABLE_UNITS[self.sensor]
        lines = [head, f"overlapping Allan deviation at {len(taus)} octave τ from {taus[0]:.3g} to {taus[-1]:.3g} s; "
                 f"{pct} intervals (chi-square, Greenhall EDF)", ""]
        lines.append(f"{'axis':<5}" + "".join(f"{c:>32}" for c, _ in cols))
        for a in self.axes:
            cells = [_cell(c, f) for c, (_, f) in zip((a.white, a.bias_instability, a.random_walk), cols)]
            lines.append(f"{a.axis:<5}" + "".join(f"{c:>32}" for c in cells))
        lines.append("")
        lines.append("fit σ² = N²/τ + (0.664·B)² + K²·τ/3: N the −1/2 line at τ = 1 s, B the floor / 0.664, K the "
                     "+1/2 line at τ = 3 s; ≤: an upper bound")
        lines.append("")
        lines.append(f"{'τ [s]':>10}" + "".join(f"{'σ_' + a.axis + f' [{adev_unit}]':>14}" for a in self.axes))
        for i, t in enumerate(taus):
            lines.append(f"{t:10.4g}" + "".join(f"{a.adev_g[i] * adev_factor:14.4g}" for a in self.axes))
        lines += [f"note: {n}" for n in self.notes]
        return "\n".join(lines)

    def _largest(self) -> tuple[AxisNoise, AxisNoise]:
        """The axes of the largest N and the largest K (Kalibr takes one isotropic value per sensor; the
        largest is the conservative choice); no white-noise term on an axis is refused, naming it."""
        n_axis = max(self.axes, key=lambda a: a.white.value if a.white.value is not None else math.inf)
        if n_axis.white.value is None:
            self.density_g()  # raises, naming the axis
        return n_axis, max(self.axes, key=lambda a: a.random_walk.value)

    def kalibr_lines(self) -> list[str]:
        """This sensor's two fields of Kalibr's imu.yaml in SI, units and the axis in comments."""
        n_axis, k_axis = self._largest()
        bound = (", an upper bound: the +1/2 slope is not reached in this recording)"
                 if k_axis.random_walk.kind != "estimate" else ")")
        if self.gyroscope:
            return [f"gyroscope_noise_density: {n_axis.white.value:.6e}  # [rad/s/sqrt(Hz)] (axis {n_axis.axis}: "
                    f"angle random walk {n_axis.white.value * ARW_DEG_PER_SQRT_H:.4g} deg/sqrt(h))",
                    f"gyroscope_random_walk: {k_axis.random_walk.value:.6e}  # [rad/s^2/sqrt(Hz)] (axis "
                    f"{k_axis.axis}: {k_axis.random_walk.value * RRW_DEG_PER_H_PER_SQRT_H:.4g} deg/h/sqrt(h)"
                    + bound]
        return [f"accelerometer_noise_density: {n_axis.white.value * G0:.6e}  # [m/s^2/sqrt(Hz)] "
                f"(axis {n_axis.axis}: {n_axis.white.value * 1e6:.4g} ug/sqrt(Hz))",
                f"accelerometer_random_walk: {k_axis.random_walk.value * G0:.6e}  # [m/s^3/sqrt(Hz)] "
                f"(axis {k_axis.axis}: {k_axis.random_walk.value * 1e6:.4g} ug/sqrt(s)" + bound]

    def kalibr_yaml(self, gyroscope: NoiseReport | None = None) -> str:
        """Kalibr's imu.yaml noise fields, in SI: this (the accelerometer's) report's N·g0 and K·g0 and, with
        ``gyroscope`` (the gyroscope's report of the same recording), its N and K; the largest axis of each
        (:meth:`kalibr_lines`), and the update rate."""
        if self.gyroscope or (gyroscope is not None and not gyroscope.gyroscope):
            raise InputError("Kalibr's yaml takes the accelerometer's report, and the gyroscope's as `gyroscope`")
        sensors = "accelerometer" + (" and gyroscope" if gyroscope is not None else "")
        lines = [
            f"# {sensors} noise measured by optcal noise from {self.source or 'a recording'}",
            f"# ({self.n_samples} samples, {self.duration_s:.6g} s at {self.rate_hz:.6g} Hz); the largest axis of "
            "each.",
            ("# Kalibr also needs rostopic" if gyroscope is not None else
             "# Kalibr also needs gyroscope_noise_density, gyroscope_random_walk and rostopic")
            + "; Kalibr's",
            "# documentation advises inflating measured values for real use (unmodelled effects).",
            *self.kalibr_lines(),
            *(gyroscope.kalibr_lines() if gyroscope is not None else ()),
            f"update_rate: {self.rate_hz:.6g}  # [Hz]",
        ]
        return "\n".join(lines) + "\n"

    # -- figure -------------------------------------------------------------------------------------
    def figure(self):
        """The log-log Allan-deviation figure (:func:`optcal.core.plots.noise.noise_figure`), a
        :class:`matplotlib.figure.Figure`."""
        from optcal.core.plots.noise import noise_figure

        return noise_figure(self)

    def figure_bytes(self, fmt: str = "png") -> bytes:
        """The figure rendered in memory, in the format ``fmt`` (a suffix matplotlib writes)."""
        buf = io.BytesIO()
        self.figure().savefig(buf, format=fmt, dpi=120)
        return buf.getvalue()


METHOD = ("overlapping Allan deviation (allantools.oadev) at octave τ; weighted non-negative least-squares fit of "
          "σ²(τ) = N²/τ + (0.664·B)² + K²·τ/3 (IEEE Std 952-1997 Annex C; El-Sheimy, Hou & Niu 2008): N is the −1/2 "
          "line at τ = 1 s, B the floor / sqrt(2 ln 2 / pi), K the +1/2 line at τ = 3 s; intervals: chi-square with "
          "Greenhall's EDF, the points taken as fully correlated (optcal/core/noise/)")


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

