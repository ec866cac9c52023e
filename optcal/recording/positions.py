"""Averaging static intervals into positions: each interval of a recording becomes one row of the positions
data set of docs/design.md §9.1 (mean output, n, per-axis SD, the standard error of the mean with the
sensor's correlated noise, middle time, mean temperature); and a positions file stored as a MATLAB matrix
(:func:`mat_positions`)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..data import PositionsData
from ..errors import InputError
from .floor import noise_floor
from .sniff import mat_table

if TYPE_CHECKING:
    from .detection import DetectionResult
    from .reading import Recording


def positions_from_recording(recording: Recording, detection: DetectionResult) -> PositionsData:
    """One position per interval: mean output, n, per-axis SD, the standard error of the mean ``sem``
    (:func:`optcal.recording.floor.noise_floor`: the Allan model of the recording's static intervals, never below
    SD/√n), middle time and mean temperature. The detection, the recording's path and the noise floor
    (:class:`optcal.recording.floor.NoiseFloor`) are kept in ``extra`` (``detection``, ``source``, ``noise_floor``)."""
    iv = detection.intervals
    if not len(iv):
        raise InputError("no static intervals to average into positions")
    # A loop over intervals (tens), not samples: each slice is reduced by numpy.
    N = np.array([recording.N[s:e].mean(axis=0) for s, e in iv])
    sd = np.array([recording.N[s:e].std(axis=0, ddof=1) if e - s > 1 else np.zeros(3) for s, e in iv])
    t = np.array([recording.t[s:e].mean() for s, e in iv])
    temp = None if recording.temp is None else np.array([recording.temp[s:e].mean() for s, e in iv])
    floor = noise_floor(recording.N, iv, recording.t[iv[:, 0]], recording.rate, recording.units)
    return PositionsData(N=N, t=t, temp=temp, n_samples=(iv[:, 1] - iv[:, 0]).astype(float), std=sd, sem=floor.sem,
                         units=recording.units,
                         extra={"detection": detection, "source": recording.path, "noise_floor": floor})


def mat_positions(path, units: str = "g") -> PositionsData:
    """Positions from a MATLAB ``.mat`` file (docs/design.md §9.1): one n × 3 (or 3 × n) matrix of the mean
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
