"""What a gyroscope fit determines: observability (through :mod:`optcal.core.analysis`, on the whitened
residuals' Jacobian) and the likelihood-ratio test for g-sensitivity.

The residuals are whitened (:mod:`optcal.core.gyro.data`), so twice the negative log-likelihood is the cost
up to a constant, and the drop of the cost from the model without G to the model with it is, when the
sensor has no g-sensitivity, χ²-distributed with 9 degrees of freedom (Wilks). G is reported only when
the drop exceeds the χ²₉ quantile at 1 − ``alpha``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from optcal.core import analysis
from optcal.core.errors import InputError

ALPHA = 1e-3  # false-detection probability of the g-sensitivity test


@dataclass(frozen=True)
class GSensitivityTest:
    statistic: float  # cost(without G) − cost(with G), χ² units
    dof: int
    p_value: float
    detected: bool

    def to_dict(self) -> dict:
        return {"statistic": self.statistic, "dof": self.dof, "p_value": self.p_value, "detected": self.detected}


def g_sensitivity_test(cost_without: float, cost_with: float, alpha: float = ALPHA) -> GSensitivityTest:
    """Likelihood-ratio test of G = 0 from the optimal costs of the two nested fits on the same data."""
    from scipy.stats import chi2  # at first use: scipy.stats costs about a second to import

    stat = max(float(cost_without) - float(cost_with), 0.0)
    p = float(chi2.sf(stat, 9))
    return GSensitivityTest(stat, 9, p, p < alpha)


def check_observable(problem, x_full: np.ndarray) -> analysis.Observability:
    """The observability of ``problem`` at ``x_full``; an InputError naming the parameters the motions
    leave undetermined, and the way out, when any are."""
    obs = analysis.observability(problem, x_full)
    if obs.rank < obs.n_parameters:
        # the parameters that carry each undetermined direction (weight 0.1 or more of its unit vector; the
        # others in it move by a few thousandths, through the correlations of the fit)
        lead = {w["name"] for d in obs.unobservable for w in d if abs(w["weight"]) >= 0.1}
        names = [n for n in obs.names if n in lead]
        raise InputError(f"the motions do not determine gyroscope parameter(s) {', '.join(names)} "
                         f"(rank {obs.rank} of {obs.n_parameters}): rotate the sensor about all three axes "
                         "between rests (--force-weak cannot: no one fit exists)")
    return obs


# == The gates: what a gyroscope fit must look like to be written (docs/gyroscope.md, "The gates: fits refused, scales
# noted (issue #29)") ====================
# A MEMS gyroscope's sensitivity tolerance (MPU-9250 ±3 % at 25 °C, BMI270 and ICM-20948 tighter) and its
# cross-axis sensitivity (±2 %) plus the accelerometer's (±2 %: the angles place the gyroscope's axes in the
# accelerometer's frame), in rad: a calibration whose standard error exceeds them tells less than the datasheet.
SCALE_TOLERANCE = 0.03
CROSS_AXIS = 0.04
# No gyroscope's three axes differ in sensitivity by a quarter (the tolerance allows about 6 % between two).
MAX_AXES_RATIO = 1.25
# A misalignment beyond 0.1 rad (5.7°) is 2.5 times the two sensors' cross-axis together: not the axes of one
# board, but a fit that failed or gyroscope columns that are not the accelerometer's axes.
MAX_MISALIGNMENT = 0.1
# Outputs in deg/s or rad/s were converted with a datasheet sensitivity: the scale is their factor to a few %.
# A range or rate slip makes it 2, 4 or 8 times that (a note, NOMINAL_NOTE); unit mix-ups make it 14 or more
# (counts of a ±2000 °/s part: 14.3–16.4 per °/s; deg/s for rad/s: 57.3): refused beyond 10 times.
NOMINAL_RANGE = 10.0
NOMINAL_NOTE = 0.10
# χ²/dof far above the rests' white noise (an SD 30 times theirs) with the motions carried more than 5° off (RMS):
# the rotations do not match the gravity turns. χ²/dof alone does not tell: imucal's hand-held rests understate
# the noise, χ²/dof 1,556–1,665 with its motions 0.35–0.48° off and its 360° turns right to 0.25–0.9 %. 5° is
# what a gyroscope within its datasheet's 3 % misses a 90–180° turn by: such a calibration does no better.
MAX_CHI2_DOF = 1000.0
MAX_RESIDUAL_DEG = 5.0
# Below the refusal, χ²/dof above this (residuals more than about 3 times the rests' white noise) is said in a note:
# the fit stands, its standard errors scaled by √(χ²/dof), and the user learns what the excess usually is.
CHI2_NOTE = 10.0

_FAILED = ("likely a wrong rate or time column (`rate`, `time_unit`), motion in rests, saturation, or wrong "
           "`gyro_units` or `gyro_columns`")
_CAUSE = {"sign": _FAILED, "chi2": _FAILED, "axes": _FAILED, "misalignment": _FAILED,
          "nominal": "the outputs are not in these units: declare theirs (`gyro_units`)",
          "undetermined": "record more rests with turns about all three axes between them"}
_FORCE = "`force_weak` keeps it, marked as forced"


@dataclass(frozen=True)
class GyroRefusal:
    kind: str  # sign, nominal, chi2, axes, misalignment, undetermined
    reason: str


class GyroRefused(InputError):
    """A gyroscope fit refused by its gates: the one line of :func:`refusal_line`, and the ``refusals`` behind it
    (for a caller that words the line its own way)."""

    def __init__(self, refusals: list[GyroRefusal]):
        super().__init__(refusal_line(refusals))
        self.refusals = refusals


def _fmt(v: float) -> str:
    return f"{v:.3g}"


def plausibility(names, x, stderr, *, chi2_dof: float, residual_deg: float, units: str,
                 nominal: float | None = None) -> list[GyroRefusal]:
    """Why a gyroscope fit (parameters ``x`` named ``names``, standard errors ``stderr``) cannot be written,
    first the most telling: a scale factor not positive, a scale beyond :data:`NOMINAL_RANGE` times the
    declared units' ``nominal`` (deg/s, rad/s), χ²/dof above :data:`MAX_CHI2_DOF` with motions' residual RMS
    ``residual_deg`` above :data:`MAX_RESIDUAL_DEG`, axes' scales apart by more than :data:`MAX_AXES_RATIO`,
    a misalignment beyond :data:`MAX_MISALIGNMENT` rad, and scales or angles the data determine no better
    than a datasheet (standard error above :data:`SCALE_TOLERANCE` relative, :data:`CROSS_AXIS` rad)."""
    names = list(names)
    x, se = np.asarray(x, float), np.asarray(stderr, float)
    ks = [i for i, n in enumerate(names) if n.startswith("K_")]
    ts = [i for i, n in enumerate(names) if n.startswith("T_")]
    K = x[ks]
    out = []
    bad = [i for i in ks if not (np.isfinite(x[i]) and x[i] > 0)]
    if bad:
        out.append(GyroRefusal("sign", "scale " + ", ".join(f"{names[i]} {_fmt(x[i])}" for i in bad)
                               + " ≤ 0"))
    good = K[np.isfinite(K) & (K > 0)]
    if nominal and len(good):
        r = good / nominal
        if np.any(r > NOMINAL_RANGE) or np.any(r < 1 / NOMINAL_RANGE):
            out.append(GyroRefusal("nominal", f"scale {_fmt(good.min())}–{_fmt(good.max())} is "
                                   f"{_fmt(r.min())}–{_fmt(r.max())}× the {nominal:.4g} of {units}"))
    if chi2_dof > MAX_CHI2_DOF and residual_deg > MAX_RESIDUAL_DEG:
        out.append(GyroRefusal("chi2", f"χ²/dof {chi2_dof:.0f}, motions off by {residual_deg:.1f}° RMS"))
    if len(good) == len(K) and K.max() / K.min() > MAX_AXES_RATIO:
        out.append(GyroRefusal("axes", f"axes' scales {K.max() / K.min():.2f}× apart"))
    far = [i for i in ts if not abs(x[i]) <= MAX_MISALIGNMENT]
    if far:
        out.append(GyroRefusal("misalignment", "misalignment " + ", ".join(f"{names[i]} {x[i]:.2f}" for i in far)
                               + f" rad beyond {MAX_MISALIGNMENT:g}"))
    loose = ([names[i] for i in ks if np.isfinite(se[i]) and se[i] > SCALE_TOLERANCE * abs(x[i])]
             + [names[i] for i in ts if np.isfinite(se[i]) and se[i] > CROSS_AXIS])
    if loose:
        out.append(GyroRefusal("undetermined", f"{', '.join(loose)} known no better than a datasheet gives "
                               f"(standard error above {SCALE_TOLERANCE:.0%}, {CROSS_AXIS:g} rad)"))
    return out


def refusal_line(refusals: list[GyroRefusal], limit: int = 280) -> str:
    """One line of at most ``limit`` characters: as many reasons as fit, the likely cause of the first and the
    way out (``optcal imu: error: `` takes the rest of 300)."""
    tail = f": {_CAUSE[refusals[0].kind]}; {_FORCE}"
    head = "gyroscope fit refused: "
    for n in range(len(refusals), 0, -1):
        more = f" (+{len(refusals) - n} more)" if n < len(refusals) else ""
        text = head + "; ".join(r.reason for r in refusals[:n]) + more + tail
        if len(text) <= limit or n == 1:
            return text
    return text  # pragma: no cover


def chi2_note(chi2_dof: float, residual_deg: float) -> str | None:
    """A note when the gyroscope's χ²/dof exceeds :data:`CHI2_NOTE` (and the fit was not refused for it): how
    far the motions' residuals exceed the rests' white noise, what usually causes it, and that the standard
    errors carry it (scaled by √(χ²/dof), the Birge ratio)."""
    if not (np.isfinite(chi2_dof) and chi2_dof > CHI2_NOTE):
        return None
    ratio = float(np.sqrt(chi2_dof))
    return (f"gyroscope χ²/dof {chi2_dof:.3g}: the motions' residuals are {ratio:.3g} times what the rests' white "
            f"noise explains (motions {residual_deg:.2f}° off, RMS), usually motion left in the rests, a time base "
            f"that jitters or a bias that drifts during the turns; the standard errors are scaled by {ratio:.3g}")


def scale_note(K, units: str, nominal: float | None, *, declared: bool) -> str | None:
    """A note when a scale factor ``K`` (3,) lands more than :data:`NOMINAL_NOTE` from ``nominal`` (the
    declared units' factor when ``declared``, else the nominal scale given), naming the likely cause."""
    K = np.asarray(K, float)
    if not nominal or not np.all(np.isfinite(K) & (K > 0)):
        return None
    r = K / nominal
    if np.max(np.abs(r - 1.0)) <= NOMINAL_NOTE:
        return None
    unit = f"({units})/(rad/s)" if "/" in units else f"{units}/(rad/s)"
    said = f"gyroscope scale {_fmt(K.min())}–{_fmt(K.max())} {unit}, {r.min():.2f}–{r.max():.2f}× the "
    if declared:
        return (said + f"{nominal:.4g} of {units}: is the file's rate or time column off by that factor, or were "
                "its outputs converted with another range's sensitivity? The calibration corrects the latter; with "
                "a wrong rate its rates are wrong by that factor")
    return (said + f"nominal {nominal:.4g} given: the nominal (datasheet sensitivity, range) or the file's rate or "
            "time column is off")
