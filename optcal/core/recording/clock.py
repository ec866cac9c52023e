"""Times of day as a recording's time column (issue #29: WitMotion's exports and other loggers write
``14:25:31.123`` or ``2024-5-1 14:25:31.123`` rather than seconds).

A text column whose name holds "time" (Time, Chip Time(), timestamp, DateTime; 时间) is read as clock times when
every row is one: ``[date ]hh:mm:ss[.fff]``, the date ``yyyy-m-d`` (also with ``/`` or ``.``; ISO's ``T`` between
date and time too). The seconds count from
the first row; a day's date carries them across midnight, and without a date a step back of more than half a
day is taken as midnight passed. Whether the times increase is the reader's to check, as for any time column.
"""

from __future__ import annotations

import datetime as _dt
import re

import numpy as np

from optcal.core.tablefile import column_key

DATE = re.compile(r"(\d{4})[-/.](\d{1,2})[-/.](\d{1,2})")  # yyyy-m-d, also with / or .
DAY_S = 86400.0
CLOCK_TIME = "clock (hh:mm:ss)"  # the reading's time unit when a time-of-day column gave the times


def is_clock_name(name: str) -> bool:
    """Whether a column's name may be a clock time: its key (case, units and separators aside) holds "time"."""
    return "time" in (key := column_key(name)) or "时间" in key


def clock_seconds(values) -> np.ndarray | None:
    """Seconds (n,) since the first of ``values`` (strings), or None when any is not a clock time. Vectorised
    over the rows with NumPy's string functions; only the distinct dates go through :data:`DATE` one by one."""
    v = np.asarray(values, dtype=str).ravel()
    if not v.size:
        return None
    v = np.strings.replace(np.strings.strip(v), "T", " ")
    date, _, tod = np.strings.rpartition(v, " ")
    h, _, rest = np.strings.partition(tod, ":")
    m, _, sec = np.strings.partition(rest, ":")
    sec = np.strings.replace(sec, ",", ".")  # a decimal comma
    whole, dot, frac = np.strings.partition(sec, ".")
    n_h = np.strings.str_len(h)
    ok = (np.strings.isdigit(h) & (n_h >= 1) & (n_h <= 2) & np.strings.isdigit(m) & (np.strings.str_len(m) == 2)
          & np.strings.isdigit(whole) & (np.strings.str_len(whole) == 2)
          & ((dot == "") | np.strings.isdigit(frac)))
    if not ok.all():
        return None
    out = h.astype(float) * 3600.0 + m.astype(float) * 60.0 + sec.astype(float)
    date = np.strings.strip(date)
    dated = date != ""
    if dated.any():
        if not dated.all():
            return None  # some rows with a date, some without: not one clock
        days, which = np.unique(date, return_inverse=True)
        ordinals = []
        for d in days:  # the distinct dates: a handful
            match = DATE.fullmatch(str(d))
            if match is None:
                return None
            try:
                ordinals.append(_dt.date(*map(int, match.groups())).toordinal())
            except ValueError:
                return None
        # days since the first row's date: seconds since an epoch would keep no milliseconds in a float
        ordinal = np.asarray(ordinals)[which.ravel()]
        out += (ordinal - ordinal[0]) * DAY_S
    else:  # midnight passed: a step back of more than half a day
        back = np.diff(out) < -DAY_S / 2
        out[1:] += DAY_S * np.cumsum(back)
    return out - out[0]
