"""Averaging static intervals into positions: each interval of a recording becomes one row of the positions
data set of docs/design.md §9.1 (mean output, n, per-axis SD, middle time, mean temperature)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..data import PositionsData
from ..errors import InputError

if TYPE_CHECKING:
    from .detection import DetectionResult
    from .reading import Recording


def positions_from_recording(recording: Recording, detection: DetectionResult) -> PositionsData:
    """One position per interval: mean output, n, per-axis SD, middle time and mean temperature. The
    detection and the recording's path are kept in ``extra`` (``detection``, ``source``)."""
    iv = detection.intervals
    if not len(iv):
        raise InputError("no static intervals to average into positions")
    # A loop over intervals (tens), not samples: each slice is reduced by numpy.
    N = np.array([recording.N[s:e].mean(axis=0) for s, e in iv])
    sd = np.array([recording.N[s:e].std(axis=0, ddof=1) if e - s > 1 else np.zeros(3) for s, e in iv])
    t = np.array([recording.t[s:e].mean() for s, e in iv])
    temp = None if recording.temp is None else np.array([recording.temp[s:e].mean() for s, e in iv])
    return PositionsData(N=N, t=t, temp=temp, n_samples=(iv[:, 1] - iv[:, 0]).astype(float), std=sd,
                         units=recording.units, extra={"detection": detection, "source": recording.path})
