"""Reading a static stretch and its overlapping Allan deviation (the method: the docstring of
:mod:`optcal.core.noise`): the samples turned into g, the octave τ, σ(τ) per axis with allantools and the
chi-square interval of each point, a warning when the stretch does not look static, a stretch of a
recording file, and the white-noise density of a recording or of a saved analysis (:func:`load_white_noise`).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from optcal.core.errors import InputError
from optcal.core.jsonfile import read_json_object
from optcal.core.noise.fit import DEFAULT_CI, chi2_interval, greenhall_edf, noise_type, read_terms
from optcal.core.noise.report import UNIT_SCALE, AxisNoise, NoiseReport

log = logging.getLogger("optcal.noise")

MIN_AVERAGES = 4  # the longest τ is at most a quarter of the stretch
MIN_TAUS = 3  # a stretch must give at least this many octave τ (16 samples)
AXES = ("x", "y", "z")
NONSTATIC_RATIO = 25.0  # a 1-s window variance this many times the median's: motion
MAX_STATIC_G = 3.0  # a mean output above this many g is not a sensor at rest: wrong units


def octave_m(n: int, max_m: int | None = None) -> np.ndarray:
    """Averaging factors 1, 2, 4, … up to ``max_m`` (default: a quarter of ``n``)."""
    top = n // MIN_AVERAGES if max_m is None else max_m
    return 2 ** np.arange(int(math.floor(math.log2(top))) + 1) if top >= 1 else np.array([], int)


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
    edf = np.array([greenhall_edf(noise_type(s), k, n_phase) for s, k in zip(slope, mm)])
    bounds = np.array([chi2_interval(d, e, ci) for d, e in zip(adev, edf)])
    white, bias, rw, fit, notes = read_terms(taus, adev, slope, mm, n_phase, ci)
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


def noise_from_recording(path, *, columns=None, rate: float | None = None, units: str | None = "g",
                         interval=None, scale: float | None = None, ci: float = DEFAULT_CI,
                         tau_max_s: float | None = None, topic: str | None = None) -> NoiseReport:
    """Read a raw recording (:func:`optcal.core.recording.read_recording`: the same columns, units, rate and
    ``topic`` rules as a calibration recording) and analyse the stretch ``interval`` = (start, end) in seconds from
    its first sample (either may be None; default the whole file)."""
    from optcal.core.recording.reading import (
        read_recording,  # the core reader (the package also re-exports its workflow)
    )

    rec = read_recording(path, columns, rate, units, topic=topic)
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
        obj = read_json_object(p, "noise analysis")
        if obj.get("kind") != "optcal noise":
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
