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
    between two files; the
    temperature and the gyroscope's rates when every file has them. The files must agree in units, rate and
    whether they hold a gyroscope. ``reading["joined_files"]`` says how many were joined."""
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

    def joined(get, gap):
        """The files' arrays ``get(r)`` in turn, ``gap`` (one row) between two of them."""
        parts = []
        for k, r in enumerate(recs):
            parts.append(get(r, k))
            if k < len(recs) - 1:
                parts.append(gap(k))
        return np.concatenate(parts)

    starts, end = [], None
    for r in recs:  # each file's clock from two of its steps after the previous file's last sample
        starts.append(0.0 if end is None else end + 2 * step - float(r.t[0]))
        end = float(r.t[-1]) + starts[-1]
    t = joined(lambda r, k: np.asarray(r.t, float) + starts[k],
               lambda k: np.array([float(recs[k].t[-1]) + starts[k] + step]))
    N = joined(lambda r, k: np.asarray(r.N, float), lambda k: np.full((1, 3), np.nan))
    sat = joined(lambda r, k: np.asarray(r.saturated, bool), lambda k: np.zeros(1, bool))
    temp = (joined(lambda r, k: np.asarray(r.temp, float), lambda k: np.full(1, np.nan))
            if all(r.temp is not None for r in recs) else None)
    W = gsat = None
    if first.W is not None:
        W = joined(lambda r, k: np.asarray(r.W, float), lambda k: np.full((1, 3), np.nan))
        gsat = joined(lambda r, k: np.zeros(len(r), bool) if r.gyro_saturated is None else r.gyro_saturated,
                      lambda k: np.zeros(1, bool))
    path = f"{first.path} and {len(recs) - 1} more file(s)"
    return replace(first, t=t, N=N, temp=temp, saturated=sat, path=path, labels=None, W=W, gyro_saturated=gsat,
                   reading={**first.reading, "joined_files": len(recs)})
