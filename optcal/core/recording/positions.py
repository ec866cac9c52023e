"""Averaging static intervals into positions: each interval of a recording becomes one row of the positions
data set of docs/design.md, "Positions CSV" (mean output, n, per-axis SD, the standard error of the mean with the
sensor's correlated noise, middle time, mean temperature); poses that check themselves (:func:`recheck_poses`);
and a positions file stored as a MATLAB matrix (:func:`mat_positions`).

Poses that check themselves (issue #29; docs/segmentation.md, step 10): a position of a raw recording that lies
far off the fit of the others is looked at again sample by sample, through the fitted calibration. Its
samples' specific force, averaged over :data:`SMOOTH_S`, is compared with the pose's own direction (the median
of its central half): a run of samples at either end that departs from it by more than :data:`DEPART_SIGMAS`
noise SDs is the end of a motion and is cut off; a pose whose first and last quarters differ by more than
:data:`DRIFT_SIGMAS` standard errors of their means turned while it was held, and is dropped. What survives is
averaged again (:func:`positions_from_recording`). No model is fitted here: the calibration is the caller's
(:func:`optcal.app.fit.calibrate` refits on what survives).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from optcal.core.data import PositionsData
from optcal.core.errors import InputError
from optcal.core.ranges import range_means, range_means_sds
from optcal.core.recording.detection import runs
from optcal.core.recording.floor import FLICKER_FACTOR, noise_floor
from optcal.core.recording.sniff import mat_table

if TYPE_CHECKING:
    from optcal.core.recording.detection import DetectionResult
    from optcal.core.recording.reading import Recording


def positions_from_recording(recording: Recording, detection: DetectionResult, *, floor_like=None) -> PositionsData:
    """One position per interval: mean output, n, per-axis SD, the standard error of the mean ``sem``
    (:func:`optcal.core.recording.floor.noise_floor`: the Allan model of the recording's static intervals, never below
    SD/√n; ``floor_like``: a floor of the same recording whose noise model is kept), middle time and mean
    temperature. The detection, the recording's path and the noise floor
    (:class:`optcal.core.recording.floor.NoiseFloor`) are kept in ``extra`` (``detection``, ``source``,
    ``noise_floor``), with :func:`recheck_poses` as ``recheck``: the fit (:func:`optcal.app.fit.calibrate`) re-examines
    outlying poses through it without importing the recording path."""
    iv = detection.intervals
    if not len(iv):
        raise InputError("no static intervals to average into positions")
    N, sd = range_means_sds(recording.N, iv)
    t = range_means(recording.t, iv)
    temp = None if recording.temp is None else range_means(recording.temp, iv)
    floor = noise_floor(recording.N, iv, recording.t[iv[:, 0]], recording.rate, recording.units, like=floor_like)
    return PositionsData(N=N, t=t, temp=temp, n_samples=(iv[:, 1] - iv[:, 0]).astype(float), std=sd, sem=floor.sem,
                         units=recording.units,
                         extra={"detection": detection, "source": recording.path, "noise_floor": floor,
                                "recheck": recheck_poses})


SMOOTH_S = 0.1  # s: the samples' force is averaged over this before it is judged (the noise of one sample is large)
DEPART_SIGMAS = 5.0  # an averaged sample this many noise SDs from the pose's direction is not at rest
DRIFT_SIGMAS = 5.0  # first and last quarters this many standard errors apart: the pose turned while it was held
TRIM_SIGMAS = 1.0  # a pose is trimmed only when that moves its mean by this many standard errors or more


def recheck_poses(data, model, x, suspects, name=None):
    """Positions ``data`` (from a raw recording: ``extra["detection"]``) with the poses ``suspects`` (row indices)
    re-examined through the calibration ``model`` at ``x``: (new data or None when nothing changed, notes).
    A pose cut to its still part keeps its row; a pose that moved throughout is dropped. ``name(i)`` names row
    i in the notes (the fit's diagnostics name positions; default "position i")."""
    name = name or (lambda i: f"position {i}")
    det = data.extra.get("detection") if data.extra else None
    if det is None or not len(suspects):
        return None, []
    rec = det.recording
    iv = det.intervals.copy()
    keep = np.ones(len(iv), bool)
    K = np.abs(np.asarray(x, float)[:3])  # output per g of each axis: the noise of a sample in g
    noise_g = np.asarray(det.noise if det.noise is not None else rec.N[iv[0, 0]:iv[0, 1]].std(axis=0), float) / K
    rate = float(rec.rate) if np.isfinite(rec.rate) else 50.0
    w = max(1, int(round(SMOOTH_S * rate)))
    floor = data.extra.get("noise_floor")
    notes = []
    # a handful of suspects (outliers of one fit), each judged on its own samples by NumPy
    for i in np.asarray(suspects, int):
        a, b = iv[i]
        F = model.inverse(np.asarray(x, float)[None], rec.N[a:b])[0]
        m = len(F)
        q = max(m // 4, 1)
        first, last = F[:q].mean(axis=0), F[-q:].mean(axis=0)
        se = _with_flicker(noise_g * np.sqrt(2.0 / q), floor, K)  # first and last quarters' difference
        c = np.concatenate([np.zeros((1, 3)), np.cumsum(F, axis=0)])
        lo = np.clip(np.arange(m) - w // 2, 0, max(m - w, 0))
        Fs = (c[lo + min(w, m)] - c[lo]) / min(w, m)
        ref = np.median(F[m // 4: m - m // 4], axis=0)
        dev = np.max(np.abs(Fs - ref) / _with_flicker(noise_g / np.sqrt(min(w, m)), floor, K), axis=1)
        still = dev <= DEPART_SIGMAS
        # the longest run of still samples: the pose without the motions at its ends
        starts, stops = runs(still).T
        when = f"{rec.shown_t[a]:.1f}-{rec.shown_t[b - 1]:.1f} s"
        if len(starts):
            j = int(np.argmax(stops - starts))
            s0, s1 = int(starts[j]), int(stops[j])
        else:
            s0 = s1 = 0
        # a trim keeps at least half the pose (and a shortest pose): less is a pose that moved throughout (an
        # interval inside a turn kept 2 of its 100 samples)
        least = max(det.min_samples, m // 2)
        if s1 - s0 >= least and (s0 > 0 or s1 < m):
            Fk = F[s0:s1]
            qk = max(len(Fk) // 4, 1)
            drift = np.abs(Fk[:qk].mean(axis=0) - Fk[-qk:].mean(axis=0))
            if np.all(drift <= DRIFT_SIGMAS * _with_flicker(noise_g * np.sqrt(2.0 / qk), floor, K)):
                # a trim that moves the pose's mean by less than its own noise changes nothing the fit sees
                if np.all(np.abs(Fk.mean(axis=0) - F.mean(axis=0)) < TRIM_SIGMAS * noise_g / np.sqrt(len(Fk))):
                    continue
                iv[i] = (a + s0, a + s1)
                cut = " and ".join(f"{n / rate:.2g} s at its {end}" for n, end in ((s0, "start"), (m - s1, "end")) if n)
                notes.append(f"{name(i)} ({when}) re-examined sample by sample: {cut} moved, left out")
                continue
        if np.any(np.abs(last - first) > DRIFT_SIGMAS * se) or s1 - s0 < least:
            keep[i] = False
            notes.append(f"{name(i)} ({when}) re-examined sample by sample: it moved while held "
                         f"(its force drifts by {np.max(np.abs(last - first)) * 1e3:.3g} mg), dropped")
    if not notes:
        return None, []
    new = replace(det, intervals=iv[keep], notes=list(det.notes))
    # the recording's noise model is kept: a pose's ends trimmed do not change it; the positions keep their numbers
    # (a dropped pose leaves a gap: position 9 stays the interval the report numbers 9)
    out = positions_from_recording(rec, new, floor_like=floor)
    return replace(out, position=np.asarray(data.position)[keep]), notes


def _with_flicker(white: np.ndarray, floor, K: np.ndarray) -> np.ndarray:
    """SD (3,) in g of a difference of averages of a pose held still, whose white part is ``white``: with the
    flicker of the recording's noise floor ``floor`` added, √2 × 0.664 B (σ_A² = N²/τ + (0.664 B)²,
    :mod:`optcal.core.recording.floor`; outputs per g ``K``). White noise alone made a phone's 20-s pose whose
    force wandered 0.4 mg (its flicker B is 0.2 mg) a pose that "moved while held", and dropped it."""
    B = getattr(floor, "bias_instability", None)
    if B is None:
        return white
    return np.sqrt(white**2 + 2.0 * (FLICKER_FACTOR * np.asarray(B, float) / K) ** 2)


def mat_positions(path, units: str = "g") -> PositionsData:
    """Positions from a MATLAB ``.mat`` file (docs/design.md, "Positions CSV"): one n × 3 (or 3 × n) matrix of the mean
    outputs ax, ay, az, one row per position, or variables named ``ax``, ``ay``, ``az``."""
    header, table = mat_table(Path(path))
    if header is not None:
        low = [h.lower() for h in header]
        if not all(c in low for c in ("ax", "ay", "az")):
            raise InputError(f"{path}: its variables are {', '.join(header)}; a positions MAT file holds one n × 3 "
                             "matrix or variables ax, ay, az")
        table = table[:, [low.index(c) for c in ("ax", "ay", "az")]]
    if table.shape[1] != 3:
        raise InputError(f"{path} holds a {table.shape[0]} × {table.shape[1]} matrix; a positions MAT file holds "
                         "one n × 3 matrix of mean outputs ax, ay, az")
    return PositionsData(N=table, units=units, extra={"source": str(path)})


def read_positions_file(path, units: str = "g") -> PositionsData:
    """A positions file (a CSV or a MATLAB file of one mean per pose, docs/design.md, "Positions CSV"), read the same
    way by ``optcal calibrate`` and :func:`optcal.calibrate`: a raw recording given as positions is named as one, by the
    one decision of :func:`optcal.core.recording.sniff.table_kind`, with the option that reads it (and the sample rate
    when it has no time column)."""
    from optcal.core.data import check_units, read_positions
    from optcal.core.recording.reading import raw_file_reason
    from optcal.core.recording.sniff import is_mat

    path = Path(path)
    found = raw_file_reason(path) if path.exists() else None
    if found:
        reason, timed = found
        raise InputError(f"{path} looks like a raw recording, not a positions file ({reason}); pass `raw`"
                         + ("" if timed else " with `rate` HZ (it has no time column)"))
    data = mat_positions(path, units=units) if is_mat(path) else read_positions(path, units=units)
    check_units(data, units)
    return data
