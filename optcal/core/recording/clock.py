"""Times of day as a recording's time column (issue #29: WitMotion's exports and other loggers write
``14:25:31.123`` or ``2024-5-1 14:25:31.123`` rather than seconds).

A text column whose name holds "time" (Time, Chip Time(), timestamp, DateTime; 时间) is read as clock times when every
row is one: ``[date ]hh:mm:ss[.fff]``, the date ``yyyy-m-d`` (also with ``/`` or ``.``; ISO's ``T`` before the time
too). The seconds count from the first row; a day's date carries them across midnight, and without a date a step
back of more than half a day is taken as midnight passed. Whether the times increase is the reader's to check, as
for any time column.
"""

from __future__ import annotations

import datetime as _dt
import re

import numpy as np

from optcal.core.tablefile import column_key

CLOCK = re.compile(r"\s*(?:(\d{4})[-/.](\d{1,2})[-/.](\d{1,2})[ T]+)?(\d{1,2}):(\d{2}):(\d{2}(?:[.,]\d+)?)\s*")
DAY_S = 86400.0
CLOCK_TIME = "clock (hh:mm:ss)"  # the reading's time unit when a time-of-day column gave the times


def is_clock_name(name: str) -> bool:
    """Whether a column's name may be a clock time: its key (case, units and separators aside) holds "time"."""
    return "time" in (key := column_key(name)) or "时间" in key


def clock_seconds(values) -> np.ndarray | None:
    """Seconds (n,) since the first of ``values`` (strings), or None when any is not a clock time. Row by row:
    ``numpy.char``, the string functions NumPy 1.x (which the project supports) has too, was slower
    (docs/real_data.md gives the times)."""
    out = np.empty(len(values))
    ordinals: dict[tuple, int] = {}
    first = dated = None
    for i, v in enumerate(values):
        m = CLOCK.fullmatch(str(v))
        if m is None:
            return None
        y, mo, d, h, mi, s = m.groups()
        if dated is None:
            dated = y is not None
        if dated != (y is not None):
            return None  # some rows with a date, some without: not one clock
        day = 0
        if dated:
            if (y, mo, d) not in ordinals:
                try:
                    ordinals[y, mo, d] = _dt.date(int(y), int(mo), int(d)).toordinal()
                except ValueError:
                    return None
            # days since the first row's date: seconds since an epoch would keep no milliseconds in a float
            first = ordinals[y, mo, d] if first is None else first
            day = ordinals[y, mo, d] - first
        out[i] = day * DAY_S + int(h) * 3600.0 + int(mi) * 60.0 + float(s.replace(",", "."))
    if not len(out):
        return None
    if not dated:  # midnight passed: a step back of more than half a day
        back = np.diff(out) < -DAY_S / 2
        out[1:] += DAY_S * np.cumsum(back)
    return out - out[0]
