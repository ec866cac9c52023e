"""Several recordings of one sensor read as one (``optcal calibrate --raw`` with more than one DATA): a lab that
writes a file per pose, or per face, has its files joined in the order given, each keeping its own samples and
their spacing, with one missing sample between two files, so that no rest found spans two of them (the detection
sets aside a block holding a missing sample, docs/segmentation.md, step 1)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from optcal.core.errors import InputError
from optcal.core.recording.reading import Recording

RATE_TOLERANCE = 0.05  # the files' sample rates must agree within this fraction


def join_recordings(recs: list[Recording]) -> Recording:
    """``recs`` joined: the samples of each after the previous one's last (the first's times as they are, each
    next one's shifted to start two steps after it: a file's clock may restart at 0), a missing sample (NaN)
    between two files; the temperature and the gyroscope's rates when every file has them. The files must agree
    in units, rate and whether they hold a gyroscope. ``reading["joined_files"]`` says how many were joined."""
    if len(recs) == 1:
        return recs[0]
    first = recs[0]
    for r in recs[1:]:
        if r.units != first.units:
            raise InputError(f"{r.path} is in {r.units} and {first.path} in {first.units}: give recordings of one "
                             "sensor in one unit")
        if np.isfinite(first.rate) and not abs(r.rate / first.rate - 1) <= RATE_TOLERANCE:
            raise InputError(f"{r.path} is sampled at {r.rate:.4g} Hz and {first.path} at {first.rate:.4g} Hz: give "
                             "recordings of one sensor at one rate")
        if (r.W is None) != (first.W is None):
            raise InputError(f"{first.path if first.W is not None else r.path} has a gyroscope and "
                             f"{r.path if first.W is not None else first.path} none: give all or none with one")
    step = 1.0 / first.rate if np.isfinite(first.rate) else 1.0
    # each file's clock from two of its steps after the previous file's last sample, the gap's sample between
    times = [np.asarray(first.t, float)]
    for r in recs[1:]:
        times.append(np.asarray(r.t, float) - float(r.t[0]) + times[-1][-1] + 2 * step)
    t = _joined(times, [tk[-1:] + step for tk in times[:-1]])
    N = _joined([r.N for r in recs], np.full((1, 3), np.nan))
    sat = _joined([r.saturated for r in recs], np.zeros(1, bool))
    temp = _joined([r.temp for r in recs], np.full(1, np.nan)) if all(r.temp is not None for r in recs) else None
    W = gsat = None
    if first.W is not None:
        W = _joined([r.W for r in recs], np.full((1, 3), np.nan))
        gsat = _joined([np.zeros(len(r), bool) if r.gyro_saturated is None else r.gyro_saturated for r in recs],
                       np.zeros(1, bool))
    path = f"{first.path} and {len(recs) - 1} more file(s)"
    return replace(first, t=t, N=N, temp=temp, saturated=sat, path=path, labels=None, W=W, gyro_saturated=gsat,
                   reading={**first.reading, "joined_files": len(recs)})


def _joined(parts: list, gap) -> np.ndarray:
    """``parts`` concatenated, ``gap`` (one row, or one row per join when a list) between two of them."""
    gaps = gap if isinstance(gap, list) else [gap] * (len(parts) - 1)
    out = [parts[0]]
    for p, g in zip(parts[1:], gaps):
        out += [g, p]
    return np.concatenate([np.asarray(x) for x in out])
