"""The parts of the raw-recording path that fit a model, and so run a solver (application layer,
CONTRIBUTING.md "Layers"; docs/design.md, "Raw recordings"): the search over the variance detector's threshold
multiplier k, and a recording file to positions in one call. The default detector, change-point segmentation
(:mod:`optcal.core.recording.segment`, docs/segmentation.md), fits no model: the threshold search runs only
when the variance detector is asked for (``method="variance"``, or its ``threshold_k`` or ``init_s``).

The search follows Tedaldi, Pretto & Menegatti (ICRA 2014, §IV-A; imu_tk tries k = 2…10): each k gives a
set of static intervals, each set is calibrated, and the k whose calibration fits best is kept.
Differences from imu_tk, and why: imu_tk compares the raw final cost of fits made with different numbers
of intervals, which favours thresholds that find fewer intervals; here candidates are compared by how
precisely their calibrations are known (:func:`fit_score`: the parameters' standard errors at an upper
confidence bound of the residual SD), and a candidate must leave at least one degree of freedom. imu_tk
averages a fixed 100 samples from the middle of each interval; here all samples of the interval are
averaged (the variance window already keeps them half a window away from motion;
:func:`optcal.core.recording.positions.positions_from_recording`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from optcal.core.data import PositionsData, check_units
from optcal.core.determination import MIN_DOF
from optcal.core.errors import InputError
from optcal.core.model import get_model
from optcal.core.recording.detection import DEFAULT_KS, DetectionResult, Detector, detect_static, parse_ks, too_few
from optcal.core.recording.intervals import given_intervals, label_intervals, read_intervals
from optcal.core.recording.options import RawOptions
from optcal.core.recording.positions import positions_from_recording
from optcal.core.recording.reading import Recording
from optcal.core.recording.segment import segment_diagnosis, segment_static


def fit_score(data: PositionsData, model, g_local: float = 1.0, solver: str = "lm",
              alpha: float = 0.10) -> float:
    """Score of a candidate set of intervals (smaller is better): how precisely its calibration is known, the
    RMS over the parameters of their standard errors as fractions of the output (a scale factor's and a
    second-order term's relative to the axis' scale, an offset in g, a misalignment in rad), at the (1 − α)
    upper confidence bound of the residual SD, σ_up = sqrt(cost / χ²_α(dof)).

    A threshold that keeps fewer intervals fits tighter but knows the parameters less well (σ/√n, and worse
    when the orientations it keeps leave a direction weak); one that takes a motion into an interval fits
    worse. imu_tk compares raw final costs, and an earlier score here compared σ_up/√n: both could prefer a
    threshold that found 14 intervals where others found 26 (issue #29), and give a scale factor 4 % off.
    The upper bound stops a fit with few degrees of freedom from winning on luck; a fit that would be refused
    (implausible parameters, a parameter known no better than a datasheet) scores infinity. The fit goes through
    :func:`optcal.app.fit.calibrate` (the registry, at run time)."""
    from optcal.app.fit import calibrate
    from optcal.core.distributions import chi2_isf

    # scoring a candidate writes no calibration, and the score itself weighs few degrees of freedom
    cal = calibrate(data, model, solver=solver, g_local=g_local, force_weak=True, recheck=False)
    units = cal.model.units(data.units)
    x = np.asarray(cal.x, float)
    scale = {n[-1]: abs(v) for n, v in zip(cal.model.names, x) if n.startswith("K_")}
    rel = np.array([se / scale[n[-1]] if units[n].startswith(data.units) and n[-1] in scale else se
                    for n, se in zip(cal.model.names, np.asarray(cal.stderr, float))])
    sigma = np.sqrt(cal.fit.cost / max(cal.fit.dof, 1))
    sigma_up = np.sqrt(cal.fit.cost / chi2_isf(1.0 - alpha, max(cal.fit.dof, 1)))
    inflate = sigma_up / sigma if sigma > 0 else 1.0
    if cal.forced or not np.all(np.isfinite(rel)):  # a calibration the data do not determine, or implausible:
        return float("inf")  # kept only when no candidate does better
    return float(np.sqrt(np.mean(rel**2)) * inflate)


def choose_threshold(recording: Recording, model, fit_cost_fn=None, *, ks=DEFAULT_KS, g_local: float = 1.0,
                     solver: str = "lm", window_s: float = 1.0, min_static_s: float = 1.0,
                     init_s: float | None = None) -> DetectionResult:
    """Search the threshold multiplier k over ``ks`` and keep the one whose calibration fits best
    (Tedaldi et al. 2014, §IV-A; imu_tk tries k = 2…10). ``fit_cost_fn(positions) -> float`` scores a
    candidate (default :func:`fit_score` of ``model`` fitted with ``solver``). Interval sets met before
    are not refitted. A candidate needs more positions than the model has parameters; if none has, the
    error says how many were found and why (:meth:`~optcal.core.recording.detection.Detector.diagnosis`)."""
    model = get_model(model)
    det = Detector.of(recording, window_s, min_static_s, init_s)
    cost_fn = fit_cost_fn or (lambda d: fit_score(d, model, g_local, solver))
    seen: dict[bytes, tuple[float | None, str]] = {}
    search, best = [], None
    for k in ks:
        res = det.result(k)
        key = res.intervals.tobytes()
        m = res.n_intervals
        if key not in seen:
            if m <= model.n_params:
                seen[key] = (None, f"{m} intervals, need more than {model.n_params}")
            else:
                try:
                    seen[key] = (float(cost_fn(positions_from_recording(recording, res))), "")
                except InputError as exc:
                    seen[key] = (None, str(exc))
        score, note = seen[key]
        search.append({"k": float(k), "n_intervals": m, "score": score, "note": note})
        if score is not None and (best is None or score < best[0]):
            best = (score, res)
    if best is None:
        most = max(search, key=lambda r: r["n_intervals"])
        if most["n_intervals"] < model.n_params:
            raise too_few(most["n_intervals"], model, f"at best (k = {most['k']:g})",
                          det.diagnosis(most["k"], model.n_params + MIN_DOF))
        fits = [r for r in search if r["n_intervals"] >= model.n_params]
        if all(r["n_intervals"] == model.n_params for r in fits):  # no spare degree of freedom: take it
            res = det.result(most["k"])
            res.notes.append(f"no threshold gave more intervals than the {model.n_params} parameters")
            res.search = search
            return res
        raise InputError(f"no threshold gave intervals that {model.name} can be fitted to: {fits[-1]['note']}")
    res = best[1]
    res.search = search
    return res


METHODS = ("segment", "variance")


def detection_method(method: str | None, threshold_k, init_s) -> str:
    """The detector to use: ``method`` when given; else the variance detector when one of its own
    settings (``threshold_k`` other than the default search, or ``init_s``) is given, else segmentation.
    Settings of the variance detector with ``method="segment"`` are refused in one line."""
    if method is not None and method not in METHODS:
        raise InputError(f"`method` {method!r}: use segment (change points, the default) or variance "
                         "(Tedaldi et al.'s threshold)")
    variance_only = [name for name, v in (("threshold_k", threshold_k), ("init_s", init_s))
                     if v is not None and not (name == "threshold_k" and parse_ks(v) == DEFAULT_KS)]
    if method == "segment" and variance_only:
        raise InputError(f"{' and '.join(f'`{n}`' for n in variance_only)} set the variance detector's threshold, "
                         "which segmentation does not have (it tests each segment for rest at the recording's "
                         "own noise); drop them, or set `method` to variance")
    return method or ("variance" if variance_only else "segment")


def positions_from_raw(path: str | Path, options: RawOptions | None = None, *, model="diag6", g_local: float = 1.0,
                       gyro=None, **kw) -> PositionsData:
    """Positions from a raw recording: read (``options``' first seven,
    :class:`~optcal.core.recording.options.RawOptions`, :func:`~optcal.core.recording.read_recording`'s), then its
    static intervals: from the file ``intervals`` (:func:`~optcal.core.recording.read_intervals`), else from the runs
    of ``label_values`` (all labels if None) in the column ``labels``, else from a detector (:func:`detection_method`):

    - ``method="segment"`` (the default): change points and a rest test
      (:func:`~optcal.core.recording.segment.segment_static`, docs/segmentation.md), poses of at least
      ``min_static_s`` (default 0.5 s), the rest test's longest window ``window_s`` (default 10 s); no
      model is fitted to find them;
    - ``method="variance"``: Tedaldi et al.'s variance detector with window ``window_s`` (default 1 s),
      shortest interval ``min_static_s`` (default 1 s) and initial rest ``init_s``: one threshold
      multiplier ``threshold_k`` (:func:`~optcal.core.recording.parse_ks`) is used as it is, several (default
      2…10) are searched for the best fit of ``model`` at local gravity ``g_local``
      (:func:`choose_threshold`).

    Keyword arguments ``kw`` are options too (``columns="ax,ay,az"``, ``units="counts"``, ...), over ``options``.
    Segmentation judges stillness on the gyroscope too: the recording's own gyroscope columns (gx, gy, gz), or
    ``gyro``, a :class:`~optcal.core.recording.Recording` whose ``N`` holds the rates at the same samples (``optcal
    imu``'s second file).

    Fewer intervals than ``model`` has parameters (a recording without rest among them, said so), or
    outputs whose magnitude does not fit ``units``, are an InputError."""
    opts = (options or RawOptions()).but("positions_from_raw", **kw)
    return positions_from_raw_recording(opts.read(path), opts, gyro=gyro, model=model, g_local=g_local)


def positions_from_raw_recording(rec: Recording, options: RawOptions | None = None, *, gyro=None, model="diag6",
                                 g_local: float = 1.0, **kw) -> PositionsData:
    """:func:`positions_from_raw` for a recording already read (``rec``; ``gyro`` a Recording of the
    gyroscope's rates at the same samples, or None for ``rec``'s own gyroscope columns); of ``options`` (and
    ``kw``), the choice of the rests."""
    o = (options or RawOptions()).but("positions_from_raw_recording", **kw)
    intervals, labels, label_values, method = o.intervals, o.labels, o.label_values, o.method
    threshold_k, window_s, min_static_s, init_s = o.threshold_k, o.window_s, o.min_static_s, o.init_s
    model = get_model(model)
    if intervals is not None:
        det = given_intervals(rec, *read_intervals(intervals))
    elif labels is not None:
        det = label_intervals(rec, label_values)
    elif detection_method(method, threshold_k, init_s) == "segment":
        rates = None if gyro is None else gyro.N
        if rates is not None and len(rates) != len(rec):
            raise InputError(f"the accelerometer has {len(rec)} samples and the gyroscope {len(rates)}: the two "
                             "files must share their sample times; cut them to the same samples")
        det = segment_static(rec, min_static_s=min_static_s, window_s=window_s, gyro=rates)
        if det.n_intervals < model.n_params:
            raise too_few(det.n_intervals, model, "by segmentation", segment_diagnosis(det, model.n_params + MIN_DOF))
    else:
        ks = parse_ks(threshold_k)
        window_s = 1.0 if window_s is None else window_s
        min_static_s = 1.0 if min_static_s is None else min_static_s
        if len(ks) == 1:
            det = detect_static(rec, ks[0], window_s=window_s, min_static_s=min_static_s, init_s=init_s)
            if det.n_intervals < model.n_params:
                detector = Detector.of(rec, window_s, min_static_s, init_s)
                raise too_few(det.n_intervals, model, f"(k = {ks[0]:g})",
                              detector.diagnosis(ks[0], model.n_params + MIN_DOF))
        else:
            det = choose_threshold(rec, model, ks=ks, g_local=g_local, window_s=window_s,
                                   min_static_s=min_static_s, init_s=init_s)
    if det.n_intervals < model.n_params:
        raise too_few(det.n_intervals, model)
    data = positions_from_recording(rec, det)
    check_units(data, rec.units)
    return data
