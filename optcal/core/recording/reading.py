"""Reading a raw recording (docs/design.md, "Raw recordings"): one row per sample, optionally a time column ``t`` (s,
ms, µs or ns, told apart by the sample interval), the three accelerometer outputs ``ax, ay, az`` in the sensor's
units, optionally ``temp`` (°C). Files may be CSV (comma, semicolon or tab; decimal point or comma) or
whitespace-separated, gzip/bz2/xz-compressed, with or without a header, and may start with ``key,value``
lines; their layout is read by :mod:`optcal.core.recording.sniff`. MATLAB ``.mat`` files (level 5, and v7.3 through
h5py) hold the same table as a matrix or named variables. Integer counts may be signed or unsigned
(offset-binary); saturation is found from the ADC's rails (declared, or inferred from the data) and from runs
at the recording's own extremes (:func:`saturation_of`). ROS bags and PX4 ULog (:mod:`optcal.core.recording.robotlogs`)
are read as a table of the same columns (:func:`read_log`).
"""

from __future__ import annotations

import io
import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from optcal.core.data import UNITS, PositionsData, check_units
from optcal.core.errors import InputError, listing
from optcal.core.fixed_width import read_fixed_width
from optcal.core.recording.clock import CLOCK_TIME
from optcal.core.recording.sniff import (
    KIND_ROWS,
    ROLES,
    SAMPLE_JUMP,
    Layout,
    compression,
    is_mat,
    jump_ratio,
    mat_layout,
    open_binary,
    positions_file_reason,
    rate_from_meta,
    resolve_column,
    role_columns,
    sniff_layout,
    table_kind,
    units_from_names,
)
from optcal.core.tablefile import COMMENT, DECODE_ERRORS, column_key, is_comment, open_text

INT16_RAILS = (-32768.0, 32767.0)
TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}  # to seconds
STEADY_NORM = 0.7  # an accelerometer's magnitude: its median at least this × its 95th percentile (_swapped)
RATE_NORM = 0.3  # a gyroscope's: its median under this × its 95th percentile (at rest most of the time)
RATE_RANGE = (1.0, 1e5)  # Hz: a time column's unit is the first that gives a rate above 1 Hz, up to 100 kHz
LIKELY_RATE = (5.0, 10e3)  # Hz: an IMU's rate; a unit that gives less while the next gives this is ambiguous
EPOCH_YEARS = (946684800.0, 4102444800.0)  # s: Unix times from 2000 to 2100 (a time column that is a date)
RAIL_RUN = 10  # samples in a row at one extreme value: a rail (saturation_of)
RAIL_PILE = 3  # a rate's extreme value held by this many samples, and this many times as many as ...
RAIL_PILE_NEAR = 5  # ... any of this many values nearest inside it: a rail the rate returns to (piled_extremes)
RAIL_PILE_SPREAD = 20.0  # ... lying beyond this many robust SDs of the rate from its median: out in the turns' tail
# (a gyroscope at rest that reads 0.02 or 0.03 °/s piles up at its extremes too, within a count of its median)
HELD_FRACTION = 0.2  # rows equal to the one before on every axis: at least this fraction of all rows, and of the
# fifth of the rows where the outputs move most: the log repeats the sensor's samples (it runs faster than the
# sensor outputs), where a quantised sensor repeats itself at rest only (the corpus: at most 5 % of all rows, 0.3 %
# of the moving ones; a 400-Hz loop over a 100-Hz sensor: 74 % and 49 %)
# a time column whose stamps wander about an even grid by more than JITTER_STEPS of a step (at most a step), while
# their level over JITTER_BLOCK samples stays within JITTER_LOST of a step (a lost or doubled sample moves it by
# one), holds a host's arrival times of evenly spaced samples (a serial link's 10.24-ms ticks with 5-ms catch-ups
# about an even 100 Hz): the samples are taken on the grid (the corpus: at most 0.05 of a step, or a gap; such a
# log: 0.30-0.36)
EPOCH_S = 1e6  # s: a time column starting this late holds dates (Unix times), which are shown from the first sample
JITTER_STEPS = 0.1
JITTER_LOST = 0.5
JITTER_BLOCK = 50
RAIL_MARGIN = 5e-4  # of an ADC's range: codes this near a rail are at it (a sensor may clip a few codes short of
# its format's limit: ±32764 in int16, measured on a lab's gyroscope)

# optional: pyarrow.csv, a faster reader for large delimited files. Imported at the first read (pyarrow is
# heavy), then kept here; None when it is not installed (or, in tests, to force the NumPy reader).
_NOT_LOADED = object()
_arrow_csv = _NOT_LOADED


def _arrow_reader():
    """pyarrow.csv, or None without pyarrow."""
    global _arrow_csv
    if _arrow_csv is _NOT_LOADED:
        try:
            import pyarrow.csv as arrow_csv
        except ImportError:  # pragma: no cover - depends on the installation
            arrow_csv = None
        _arrow_csv = arrow_csv
    return _arrow_csv


@dataclass
class Recording:
    """Samples of a raw recording in the sensor's units, with time in seconds."""

    t: np.ndarray  # (n,) s, strictly increasing
    N: np.ndarray  # (n, 3) raw outputs
    temp: np.ndarray | None
    units: str
    rate: float  # Hz (given, from the file's Fs line, or 1 / median step of t)
    saturated: np.ndarray  # (n,) bool: a sample at a rail on any axis (saturation_of)
    path: str | None = None
    columns: dict = field(default_factory=dict)  # role -> column used
    labels: np.ndarray | None = None  # (n,) str, from a label column
    meta: dict = field(default_factory=dict)  # key,value lines before the data
    reading: dict = field(default_factory=dict)  # what the reader found: format, time unit, ADC, rails
    # (n, 3) angular rate from the gyroscope's columns gx, gy, gz, in the file's units (rad/s, °/s or counts:
    # not converted), or None; and (n,) bool, a sample at a rail of the gyroscope (gyro_saturation_of)
    W: np.ndarray | None = None
    gyro_saturated: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.N)

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0]) if len(self) else 0.0

    @property
    def origin(self) -> float:
        """The time (s) that shown times count from: the first sample's when it is a date's (a Unix time, at
        least :data:`EPOCH_S`), else 0, the file's own zero."""
        return float(self.t[0]) if len(self) and self.t[0] >= EPOCH_S else 0.0

    @property
    def shown_t(self) -> np.ndarray:
        """The times (s) as reports, notes and figures show them: from :attr:`origin`."""
        return self.t - self.origin


def read_recording(path, columns=None, rate: float | None = None, units: str | None = "g", *,
                   saturation: float | None = None, labels: str | None = None, need_time: bool = True,
                   adc: str | None = None, time_unit: str | None = None,
                   refuse_positions: bool = False, topic: str | None = None, held: bool = True,
                   even: bool = True) -> Recording:
    """Read a raw recording (docs/design.md, "Raw recordings"). ``columns``: ``"t,ax,ay,az"`` (names or 0-based
    indices; 3 entries mean ax,ay,az, 5 add temp) or ``"ax=acc_x,..."``; ``rate`` (Hz) when there is no time column;
    ``units`` of the outputs (None: as the accelerometer's columns' names give them, ``ax(g)``, ``Acc X [m/s^2]``,
    else g; ``reading["units_from_names"]`` says which); ``saturation``: |value| at which a sample is saturated;
    ``adc``: the counts' format (``int16``, ``uint16``, ``int12``, ...: its rails are saturation; by default
    inferred from the data for counts, :func:`saturation_of`); ``time_unit``: s, ms, us or ns (default: inferred
    from the median step, :func:`time_scale`); ``labels``: a column of section labels, ``COLUMN`` or
    ``COLUMN=L1,L2`` (kept as strings; the labels after ``=`` are for
    :func:`~optcal.core.recording.label_intervals`); ``need_time=False`` accepts a file without time or rate (time
    is then the sample index and the rate NaN); ``refuse_positions``: a file that looks like a positions file is an
    error that says so (calibration's path); ``held``: a log that repeats the sensor's samples (rows equal to the
    one before on every axis, :func:`held_rows`) keeps each sample once, at its first row, and its rate is that of
    the sensor (``reading["held_rows"]`` says how many rows were left out; False reads every row); ``even``: a
    time column whose stamps wander about an even rate as a host's arrival times do is taken on that even grid
    (:func:`even_times`; ``reading["stamps_jitter_s"]``; False keeps the stamps as written). A ROS bag or a
    PX4 ULog is read from its IMU messages (:func:`read_log`; ``topic`` picks among them) in the units and at the
    stamps the log gives. Every problem is an
    InputError."""
    path = Path(path)
    if units is not None and units not in UNITS:
        raise InputError(f"unknown units {units!r}; use one of {', '.join(UNITS)}")
    if time_unit is not None and time_unit not in TIME_UNITS:
        raise InputError(f"`time_unit` {time_unit!r}: use one of {', '.join(TIME_UNITS)}")
    fmt = parse_adc(adc)
    table = None
    log = read_log(path, topic, rate=rate, labels=labels, adc=adc, time_unit=time_unit)
    if log is not None:
        from optcal.core.recording.robotlogs import log_layout

        lay, table = log_layout(log)
        time_unit = "s"
    elif is_mat(path):
        lay, table = mat_layout(path)
        if labels is not None:
            raise InputError(f"{path} is a MAT file, which has no text label column; drop `labels`")
    else:
        lay = sniff_layout(path)
    if lay.ncol == 1:
        raise InputError(
            f"{path} has a single column; a raw recording needs ax, ay, az (and t, or `rate`) on each row"
        )
    cols = role_columns(columns, lay, path)
    named_units = None
    if units is None:
        named_units = units_from_names([lay.header[cols[a]] for a in ("ax", "ay", "az")]) if lay.header else None
        units = named_units or "g"
    if log is not None:
        from optcal.core.recording.robotlogs import log_units

        units = log_units(lay, cols, units, path)
    order = [r for r in ROLES if r in cols]
    idx = [cols[r] for r in order]
    raw = table[:, idx] if table is not None else _load_numeric(path, lay, idx)
    other = 0
    if lay.sparse:  # the rows of the other record types hold none of the chosen sensor columns: left out
        sensors = [k for k, r in enumerate(order) if r not in ("t", "temp")]
        mine = ~np.isnan(raw[:, sensors]).all(axis=1)
        other = int((~mine).sum())
        raw = raw[mine]
    data = dict(zip(order, raw.T))
    n = len(raw)
    if n < 2:
        raise InputError(f"{path} has {n} sample(s); a raw recording needs many samples per static pose")
    if "gx" in data and columns is None and lay.header is None and _swapped(
            *(np.column_stack([data[r] for r in rs]) for rs in (("ax", "ay", "az"), ("gx", "gy", "gz")))):
        # before the positions test: a gyroscope's rates taken for the accelerometer jump like positions
        a, g = (", ".join(str(cols[r]) for r in rs) for rs in (("ax", "ay", "az"), ("gx", "gy", "gz")))
        raise InputError(
            f"{path}: {lay.ncol} columns and no header, read by position as t, ax, ay, az, gx, gy, gz; but columns "
            f"{a} vary as a gyroscope's rates do (near 0 most of the time) and {g} as an accelerometer's (a "
            f"magnitude that stays near one value); name them with `columns`, e.g. t=0,ax={cols['gx']},"
            f"ay={cols['gy']},az={cols['gz']},gx={cols['ax']},gy={cols['ay']},gz={cols['az']}")
    reason = positions_file_reason(lay, raw[:, [order.index(a) for a in ("ax", "ay", "az")]]) \
        if refuse_positions and log is None else None
    if reason:
        raise InputError(f"{path} looks like a positions file, not a raw recording ({reason}); "
                         "read it as positions (drop `raw`)")
    bad = ~np.isfinite(raw)
    if bad.any():
        r, c = np.argwhere(bad)[0]
        raise InputError(f"{path}: sample {r} has {raw[r, c]} in column {order[c]!r}; remove or fix that row")
    if table is None and log is None:
        _refuse_several_devices(path, lay)
    meta_rate = rate_from_meta(lay.meta)
    if rate is not None and not rate > 0:
        raise InputError(f"`rate` {rate} must be a positive sample rate in Hz")
    unit = clock = None
    if "t" not in data and columns is None and rate is None and meta_rate is None and table is None:
        clock = _clock_column(path, lay, n)  # a time-of-day column (hh:mm:ss.fff), when the header names one
        if clock is not None:
            data["t"] = clock[1]
            time_unit = "s"
    if "t" in data:
        t = data["t"]
        steps = np.diff(t)
        if np.any(steps <= 0):
            i = int(np.flatnonzero(steps <= 0)[0])
            way = ("give the sample rate with `rate` (the clock column is then not read)" if clock is not None
                   else "sort the samples, or drop the time column from `columns` and give `rate`")
            raise InputError(
                f"{path}: the time column does not increase from sample {i} (t = {t[i]:g}) to {i + 1} "
                f"(t = {t[i + 1]:g}); {way}"
            )
        given = rate if rate is not None else meta_rate
        unit = time_unit or time_scale(float(np.median(steps)), given, path, float(t[0]))
        t = t * TIME_UNITS[unit]
        t, jitter = even_times(t) if log is None and even else (t, 0.0)
        fs = 1.0 / float(np.median(np.diff(t)))
    else:
        fs = rate if rate is not None else meta_rate
        if fs is None and need_time:
            # rows that differ by more than samples do (not clearly either kind: table_kind) may be positions
            r = jump_ratio(N_rows := np.column_stack([data["ax"], data["ay"], data["az"]]))
            maybe = (f" (or, if its {len(N_rows)} rows are positions, drop `raw`)" if refuse_positions
                     and r is not None and r > SAMPLE_JUMP else "")
            raise InputError(f"{path} has no time column; give the sample rate in Hz with `rate`{maybe}")
        t = np.arange(n) / (fs or 1.0)
        fs = np.nan if fs is None else fs
    N = np.column_stack([data["ax"], data["ay"], data["az"]])
    repeat = held_rows(N) if held and log is None else None
    if repeat is not None:  # the sensor's samples, once each (its noise is then that of its samples)
        keep = ~repeat
        t, N = t[keep], N[keep]
        data = {k: v[keep] for k, v in data.items()}
        n = len(N)
        fs = 1.0 / float(np.median(np.diff(t))) if np.isfinite(fs) else fs
    step = max(1, n // 20000)
    check_units(PositionsData(N=N[::step], units=units), units)
    sat, how = saturation_of(N, units, saturation, fmt)
    lab = None
    if labels is not None:
        lab = _read_labels(path, lay, labels.split("=", 1)[0], len(raw))
        lab = lab if repeat is None else lab[~repeat]
    W = gyro_sat = None
    if "gx" in data:
        W = np.column_stack([data["gx"], data["gy"], data["gz"]])
        gyro_sat, gyro_how = gyro_saturation_of(W, units, fmt)
        how.update(gyro_how)
    names = {r: (lay.header[j] if lay.header else j) for r, j in cols.items()}
    if named_units is not None:
        how["units_from_names"] = True
    if repeat is not None:
        how["held_rows"] = int(repeat.sum())
    if other:
        how["other_record_rows"] = other
    if "t" in data and jitter > 0:
        how["stamps_jitter_s"] = jitter
    if len(t) and t[0] >= EPOCH_S:
        how["time_origin_s"] = float(t[0])
    if clock is not None:
        names["t"] = how["clock_column"] = lay.header[clock[0]]
        unit = CLOCK_TIME
    if log is not None:
        how.update(log.how)
    else:
        how.update(format="MAT file" if table is not None else "text", compression=compression(path),
                   delimiter=None if table is not None else (lay.delimiter or "whitespace"), decimal=lay.decimal,
                   time_unit=unit, header=_header_kind(lay, table is not None))
    return Recording(t, N, data.get("temp"), units, float(fs), sat, str(path), names, lab, lay.meta, how, W, gyro_sat)


def read_log(path: Path, topic: str | None, **options):
    """The IMU samples of a robot or drone log (:class:`~optcal.core.recording.robotlogs.LogSamples`: a ROS bag,
    :func:`~optcal.core.recording.bags.read_bag`, or a PX4 ULog, :func:`~optcal.core.recording.ulog.read_ulog`), or None
    for any other file. The reading ``options`` a log has no use for (rate, labels, adc, time_unit) are refused
    when given, and so is ``topic`` for another file."""
    from optcal.core.recording.robotlogs import log_kind, refuse_options

    kind = log_kind(path)
    if kind is None:
        if topic is not None:
            raise InputError(f"`topic` picks the IMU's topic of a ROS bag or a PX4 ULog; {path} is neither: drop "
                             "`topic`")
        return None
    refuse_options(path, **options)
    if kind == "bag":
        from optcal.core.recording.bags import read_bag

        return read_bag(path, topic)
    from optcal.core.recording.ulog import read_ulog

    return read_ulog(path, topic)


def _header_kind(lay: Layout, mat: bool) -> str:
    """Where the columns' names came from, for the report: MAT variables, a header line, a comment line
    (``# t ax ay az``), or none (columns by position)."""
    if lay.header is None:
        return "none"
    return "variables" if mat else "comment line" if lay.commented_header else "line"


def time_scale(step: float, rate: float | None, path, first: float | None = None) -> str:
    """The unit of a time column from its median ``step``: the one that gives ``rate`` (Hz) when a rate is
    known (within 5 %); else, when the column's ``first`` value is a date in one unit only (a Unix time between
    :data:`EPOCH_YEARS`) that gives a plausible rate, that unit (1.73e18 is nanoseconds: in microseconds it would
    be the year 56,800, and the rate 1 Hz where the log's is 1 kHz); else the first of s, ms, µs, ns that gives a
    plausible sample rate, above :data:`RATE_RANGE`'s 1 Hz and at most its 100 kHz, unless that rate is below
    :data:`LIKELY_RATE` and a later unit's within it (1 Hz in µs or 1 kHz in ns: refused, asking for the unit)."""
    rates = {u: 1.0 / (step * f) for u, f in TIME_UNITS.items()}
    if rate is None and first is not None and first > 0:
        dated = [u for u, f in TIME_UNITS.items() if EPOCH_YEARS[0] <= first * f <= EPOCH_YEARS[1]
                 and RATE_RANGE[0] < rates[u] <= RATE_RANGE[1]]
        if len(dated) == 1:
            return dated[0]
    said = ", ".join(f"{r:.4g} Hz in {u}" for u, r in rates.items())
    if rate is not None:
        for u, r in rates.items():
            if abs(r / rate - 1) <= 0.05:
                return u
        raise InputError(f"{path}: the time column's median step {step:g} gives {said}, none of them the rate "
                         f"{rate:g} Hz; fix the rate, set `time_unit`, or drop the time column from `columns`")
    plausible = [u for u, r in rates.items() if RATE_RANGE[0] < r <= RATE_RANGE[1]]
    if plausible:
        u = plausible[0]
        # under LIKELY_RATE[0] in one unit and within LIKELY_RATE in the next (relative stamps of a 1-kHz log in
        # ns are 1 Hz in µs: a new user's was read as a 4.6-hour recording), the data do not tell which
        likely = [v for v in plausible[1:] if LIKELY_RATE[0] <= rates[v] <= LIKELY_RATE[1]]
        if rates[u] < LIKELY_RATE[0] and likely:
            raise InputError(f"{path}: the time column's median step {step:g} is {rates[u]:.4g} Hz in {u} or "
                             f"{rates[likely[0]]:.4g} Hz in {likely[0]}; set `time_unit` (or give `rate`)")
        return u
    raise InputError(f"{path}: the time column's median step {step:g} gives {said}, none between 1 Hz and 100 kHz; "
                     "set `time_unit`, or drop the time column from `columns` and give `rate`")


def parse_adc(adc: str | None) -> tuple[bool, int] | None:
    """``int12`` → (signed, 12 bits); ``uint16`` → (unsigned, 16); None stays None."""
    if adc is None:
        return None
    m = re.fullmatch(r"(u?)int(\d+)", str(adc).strip().lower())
    if not m or not 2 <= int(m[2]) <= 32:
        raise InputError(f"`adc` {adc!r}: give the counts' format as intB or uintB with B bits, e.g. int16, "
                         "uint16, int12")
    return m[1] == "", int(m[2])


def rails_of(signed: bool, bits: int) -> tuple[float, float]:
    """The lowest and highest code of a signed (two's complement) or unsigned (offset-binary) ADC."""
    return (-(2.0 ** (bits - 1)), 2.0 ** (bits - 1) - 1) if signed else (0.0, 2.0 ** bits - 1)


def infer_adc(N: np.ndarray) -> tuple[bool, int]:
    """Signed or unsigned counts, and a width of 16, 24 or 32 bits, from the data: counts that are never
    negative are unsigned (offset-binary, zero g near mid-range: a recording of several poses has an axis
    pointing down, which a signed ADC reports below 0); the width is the narrowest that holds them."""
    lo, hi = float(N.min()), float(N.max())
    signed = lo < 0
    for bits in (16, 24, 32):
        a, b = rails_of(signed, bits)
        if a <= lo and hi <= b:
            return signed, bits
    return signed, 64


def even_times(t: np.ndarray) -> tuple[np.ndarray, float]:
    """The times ``t`` (s) and 0, or, when they wander about an even grid (the least-squares line through them) by
    more than :data:`JITTER_STEPS` of a step and at most a step, with their level (medians over
    :data:`JITTER_BLOCK` samples) within :data:`JITTER_LOST` of a step throughout (no sample lost or doubled): a
    host's arrival times of evenly spaced samples, the grid and how far they wandered from it (s)."""
    n = len(t)
    if n < 2 * JITTER_BLOCK:
        return t, 0.0
    i = np.arange(n, dtype=float)
    step, start = np.polyfit(i, t, 1)
    grid = start + step * i
    r = t - grid
    off = float(np.max(np.abs(r)))
    if not (step > 0 and JITTER_STEPS * step < off <= step):
        return t, 0.0
    m = n // JITTER_BLOCK * JITTER_BLOCK
    level = np.median(r[:m].reshape(-1, JITTER_BLOCK), axis=1)
    if np.ptp(level) >= JITTER_LOST * step:
        return t, 0.0
    return grid, off


def _swapped(N: np.ndarray, W: np.ndarray) -> bool:
    """Whether the columns read by position as the accelerometer ``N`` and the gyroscope ``W`` are the other way
    round (a lab's t, gx, gy, gz, ax, ay, az without a header): an accelerometer turned between poses reads a
    magnitude near g throughout (its median at least :data:`STEADY_NORM` of its 95th percentile), a gyroscope a
    magnitude near 0 at every rest (its median under :data:`RATE_NORM` of its 95th percentile)."""
    def ratio(X):
        m = np.linalg.norm(X[:: max(1, len(X) // 20000)], axis=1)
        top = float(np.percentile(m, 95))
        return float(np.median(m)) / top if top > 0 else np.nan

    return bool(ratio(N) < RATE_NORM and ratio(W) > STEADY_NORM)


def held_rows(N: np.ndarray) -> np.ndarray | None:
    """The rows (n,) of ``N`` equal to the one before on every axis when the log repeats the sensor's samples
    (:data:`HELD_FRACTION` of all rows and of the fifth where the outputs move most: a sample held over several
    rows repeats in a turn too, where a quantised sensor's noise repeats at rest only), else None."""
    if len(N) < 10:
        return None
    together = np.all(N[1:] == N[:-1], axis=1)
    if together.mean() < HELD_FRACTION:
        return None
    move = np.convolve(np.abs(np.diff(N, axis=0)).sum(axis=1), np.ones(9), "same")  # over the 9 rows around
    top = (move >= np.percentile(move, 80)) & (move > 0)
    if not top.any() or together[top].mean() < HELD_FRACTION:  # (outputs that never change: not a log of samples)
        return None
    return np.concatenate([[False], together])


def stuck_runs(x: np.ndarray) -> list[float]:
    """The recording's own extreme values (min, max) that ``x`` sits on for :data:`RAIL_RUN` samples or
    more in a row, where no other value is held that long: a clipped output is constant while the noise
    moves every other reading (a quantised sensor too quiet to move, whose poses all read constant, has no
    such contrast and so no rail found this way)."""
    n = len(x)
    starts = np.concatenate([[0], np.flatnonzero(np.diff(x) != 0) + 1])
    lens = np.diff(np.concatenate([starts, [n]]))
    vals = x[starts]
    ext = (vals == x.min()) | (vals == x.max())
    if lens[~ext].max(initial=0) >= RAIL_RUN:
        return []
    return sorted({float(v) for v in vals[ext & (lens >= RAIL_RUN)]})


def saturation_of(N: np.ndarray, units: str, saturation: float | None,
                  fmt: tuple[bool, int] | None, axes=("ax", "ay", "az")) -> tuple[np.ndarray, dict]:
    """Which samples are saturated, and how that was decided (a dict for the report). ``saturation``
    given: |output| at or beyond it. Otherwise a sample at an ADC rail (of ``fmt``, or for counts of the
    format :func:`infer_adc` reads from the data; within :data:`RAIL_MARGIN` of the range of it) or at a value
    an axis sticks to at its extreme (:func:`stuck_runs`) on any axis."""
    if saturation is not None:
        return np.any(np.abs(N) >= saturation, axis=1), {"saturation": float(saturation)}
    how: dict = {}
    sat = np.zeros(N.shape, bool)
    if fmt is None and units == "counts":
        fmt = infer_adc(N)
        how["adc_inferred"] = True
    if fmt is not None:
        lo, hi = rails_of(*fmt)
        how.update(adc=f"{'' if fmt[0] else 'u'}int{fmt[1]}", rails=[lo, hi])
        m = RAIL_MARGIN * (hi - lo)
        sat |= (N <= lo + m) | (N >= hi - m)
    stuck = [stuck_runs(N[:, j]) for j in range(3)]
    for j, vals in enumerate(stuck):
        if vals:
            sat[:, j] |= np.isin(N[:, j], vals)
    if any(stuck):
        how["stuck"] = {a: v for a, v in zip(axes, stuck) if v}
    return sat.any(axis=1), how


def gyro_saturation_of(W: np.ndarray, units: str, fmt: tuple[bool, int] | None) -> tuple[np.ndarray, dict]:
    """Which samples of the angular rate ``W`` (n, 3) are at a rail of the gyroscope, and how that was
    decided (``gyro_`` keys for the report). The rate's units are not known, so the rails are found as the
    accelerometer's are without a declared saturation: an ADC's when the accelerometer is read in counts
    and the rates are whole numbers too (the ``adc`` format, else the one :func:`infer_adc` reads from the
    rates), and in any units an axis's extreme held for :data:`RAIL_RUN` samples (:func:`stuck_runs`)."""
    integer = units == "counts" and bool(np.all(W == np.round(W)))
    sat, how = saturation_of(W, "counts" if integer else "g", None, fmt if integer else None, ("gx", "gy", "gz"))
    piled, where = piled_saturation(W)
    if where:
        sat, how["piled"] = sat | piled, where
    return sat, {f"gyro_{k}": v for k, v in how.items()}


def piled_saturation(W: np.ndarray) -> tuple[np.ndarray, dict]:
    """Samples (n,) of the rates ``W`` (n, 3) at an extreme value that piles up (:func:`piled_extremes`), and
    those values per axis (gx, gy, gz)."""
    piled = [piled_extremes(W[:, j]) for j in range(3)]
    sat = np.zeros(len(W), bool)
    for j, vals in enumerate(piled):
        if vals:
            sat |= np.isin(W[:, j], vals)
    return sat, {a: v for a, v in zip(("gx", "gy", "gz"), piled) if v}


def piled_extremes(x: np.ndarray) -> list[float]:
    """The extreme values (min, max) of a rate ``x`` that pile up: held by at least :data:`RAIL_PILE` samples and
    by :data:`RAIL_PILE` times as many as any of the :data:`RAIL_PILE_NEAR` values nearest inside them. A rate
    clipped at a rail returns to it on every fast turn, where an unclipped peak is a tail that the values
    beside it share (a ±250 °/s gyroscope of another lab, its counts converted to °/s and logged at 22 Hz, sat
    at ±250.004 on 3-14 samples per axis, 1 on each value beside them, in runs shorter than
    :data:`RAIL_RUN`). The extreme must lie beyond :data:`RAIL_PILE_SPREAD` robust SDs (MAD) of the median: a
    rate that never turns, a count or two either side of its level, piles up at its extremes without a rail."""
    x = x[np.isfinite(x)]
    med = float(np.median(x)) if len(x) else 0.0
    spread = RAIL_PILE_SPREAD * 1.4826 * float(np.median(np.abs(x - med))) if len(x) else 0.0
    n, k = len(x), 256
    if n <= 2 * k:
        ends = (np.sort(-x), np.sort(x))
    else:  # each end from its k most extreme values, both from one partial sort (the whole rate is not sorted)
        p = np.partition(x, [k, n - k - 1])
        ends = (np.sort(-p[:k]), np.sort(p[n - k:]))
    out = []
    for sign, y in zip((-1.0, 1.0), ends):
        vals, cnt = np.unique(y, return_counts=True)
        if len(vals) <= RAIL_PILE_NEAR + 1 and n > 2 * k:  # the least may be cut: the six at the end must be whole
            vals, cnt = np.unique(sign * x, return_counts=True)
        if len(vals) <= RAIL_PILE_NEAR:
            continue
        far = sign * vals[-1] - med if sign > 0 else med - sign * vals[-1]  # how far out the extreme lies
        if (cnt[-1] >= RAIL_PILE and cnt[-1] >= RAIL_PILE * cnt[-1 - RAIL_PILE_NEAR:-1].max()
                and far > max(spread, 0.0) and spread > 0):
            out.append(float(sign * vals[-1]))
    return sorted(out)


def _text(path: Path):
    """The file as text, decompressed, without a UTF-8 byte-order mark."""
    return io.TextIOWrapper(open_binary(path), encoding="utf-8-sig")


def _load_numeric(path: Path, lay: Layout, usecols: list[int], max_rows: int | None = None) -> np.ndarray:
    """The chosen columns as floats, (n, len(usecols)). Delimited files go through Arrow's multithreaded
    CSV reader when pyarrow is installed (several times faster than NumPy's), whitespace-separated files whose
    lines share one layout (a logger's fixed format) through :func:`optcal.core.fixed_width.read_fixed_width`;
    anything they do not read cleanly (comment lines, ragged rows, text in a number column) goes through
    numpy.loadtxt, a C reader too, whose messages name the offending row. A column asked for twice is read
    once (Arrow refuses a repeated column)."""
    cols, back = np.unique(np.asarray(usecols, int), return_inverse=True)
    if len(cols) < len(usecols):
        return _load_numeric(path, lay, cols.tolist(), max_rows)[:, back.ravel()]
    if lay.delimiter is not None and max_rows is None and _arrow_reader() is not None:
        out = _load_arrow(path, lay, usecols)
        if out is not None:
            return out
    if lay.sparse:  # interleaved record types: an empty cell is NaN (numpy.loadtxt refuses it)
        return _load_sparse(path, lay, usecols, max_rows)
    if lay.delimiter is None and max_rows is None and lay.decimal == ".":
        out = _load_fixed_width(path, lay, usecols)
        if out is not None:
            return out
    comma = {j: (lambda s: float(s.replace(",", "."))) for j in usecols} if lay.decimal == "," else None
    try:
        with _text(path) as fh, warnings.catch_warnings():
            # with max_rows, NumPy notes that blank lines do not count as rows: that is how they are meant
            warnings.filterwarnings("ignore", message=".*max_rows", category=UserWarning)
            return np.loadtxt(fh, delimiter=lay.delimiter, skiprows=lay.skiprows, usecols=usecols, ndmin=2,
                              comments=_comment_marks(path), dtype=float, converters=comma, max_rows=max_rows)
    except ValueError as exc:
        text = _text_rows(path, lay)
        if text:
            line, first = text[0]
            more = f", and {len(text) - 1} more such line(s)" if len(text) > 1 else ""
            raise InputError(f"{path}: line {line} holds text between the data rows ({first[:40]!r}){more}; remove "
                             "them (a logger's prompts or messages) and read the file again") from None
        msg = str(exc).splitlines()[0].rstrip(".")
        raise InputError(f"{path}: {msg} (data start on line {lay.skiprows + 1}); fix or remove that row") from None


def _load_sparse(path: Path, lay: Layout, usecols: list[int], max_rows: int | None) -> np.ndarray:
    """The chosen columns of a table of interleaved record types (:attr:`Layout.sparse`), an empty cell as NaN:
    numpy.genfromtxt, where Arrow is not installed or for the first ``max_rows`` rows."""
    comma = {j: (lambda s: float(s.replace(b",", b".")) if s.strip() else np.nan) for j in usecols} \
        if lay.decimal == "," else None
    try:
        with _text(path) as fh:
            out = np.genfromtxt(fh, delimiter=lay.delimiter, skip_header=lay.skiprows, usecols=usecols, dtype=float,
                                comments=None, invalid_raise=True, max_rows=max_rows, converters=comma,
                                missing_values="", filling_values=np.nan)
    except ValueError as exc:
        msg = str(exc).strip().splitlines()[0].rstrip(".")
        raise InputError(f"{path}: {msg} (data start on line {lay.skiprows + 1}); fix or remove that row") from None
    return np.atleast_2d(out).reshape(-1, len(usecols))


def _text_rows(path: Path, lay: Layout) -> list[tuple[int, str]]:
    """The lines (1-based number, text) after the header whose first field is no number: a logger's prompts or
    messages between the data rows (comment lines and blank lines aside)."""
    m = _comment_marks(path)
    marks = () if m is None else (m,) if isinstance(m, str) else tuple(m)
    out = []
    with _text(path) as fh:
        for k, line in enumerate(fh, 1):
            if k <= lay.skiprows:
                continue
            field = line.strip().split(lay.delimiter)[0].strip() if line.strip() else ""
            if not field or (marks and line.lstrip().startswith(marks)):
                continue
            try:
                float(field.replace(",", ".") if lay.decimal == "," else field)
            except ValueError:
                out.append((k, line.strip()))
    return out


def _comment_marks(path: Path, chunk: int = 1 << 20):
    """The comment marks (:data:`COMMENT`) that occur in the file: with none or one, numpy.loadtxt parses in C
    alone; with two it filters every line in Python first (0.08 s for 51,000 lines). Found in one pass over
    the bytes, a chunk at a time."""
    marks = [c.encode() for c in COMMENT]
    found: set[bytes] = set()
    with open_binary(path) as fh:
        while len(found) < len(marks) and (block := fh.read(chunk)):
            found.update(m for m in marks if m in block)
    used = tuple(m.decode() for m in marks if m in found)
    return used[0] if len(used) == 1 else (used or None)


def _load_fixed_width(path: Path, lay: Layout, usecols: list[int]) -> np.ndarray | None:
    """A whitespace-separated table whose every line has one layout (:mod:`optcal.core.fixed_width`), or None."""
    try:
        with open_binary(path) as fh:
            raw = fh.read()
    except DECODE_ERRORS:
        return None
    start = 0
    for _ in range(lay.skiprows):
        start = raw.find(b"\n", start) + 1
        if start == 0:
            return None
    return read_fixed_width(raw[start:], lay.ncol, usecols)


def _load_arrow(path: Path, lay: Layout, usecols: list[int]) -> np.ndarray | None:
    import pyarrow as pa

    arrow_csv = _arrow_reader()
    names = [f"c{j}" for j in range(lay.ncol)]
    try:
        with open_binary(path) as fh:
            table = arrow_csv.read_csv(
                fh,
                read_options=arrow_csv.ReadOptions(skip_rows=lay.skiprows, column_names=names),
                parse_options=arrow_csv.ParseOptions(delimiter=lay.delimiter),
                convert_options=arrow_csv.ConvertOptions(include_columns=[names[j] for j in usecols],
                                                          column_types={names[j]: pa.float64() for j in usecols},
                                                          decimal_point=lay.decimal),
            )
        out = np.column_stack([table.column(names[j]).to_numpy() for j in usecols]).astype(float, copy=False)
    except (pa.ArrowException, ValueError, OSError):
        return None
    first = [float(lay.first[j].replace(",", ".")) if lay.first[j].strip() else np.nan for j in usecols]
    if len(out) == 0 or not np.array_equal(out[0], first, equal_nan=True):
        return None  # it did not start on the first data row (e.g. blank lines in the preamble, a BOM)
    return out


DEVICE_KEYS = ("device", "devicename", "deviceid", "sensor", "sensorname", "sensorid", "imu", "imuid", "设备名称")


def _refuse_several_devices(path: Path, lay: Layout) -> None:
    """A column that names the device of each row (WitMotion's ``DeviceName``, a ``sensor`` or ``imu`` number)
    holding more than one: the rows interleave several sensors, which no calibration fits as one; refused, naming
    them."""
    if lay.header is None:
        return
    for j, name in enumerate(lay.header):
        if column_key(name) not in DEVICE_KEYS:
            continue
        values = _load_numeric(path, lay, [j])[:, 0] if lay.numeric[j] else _strings(path, lay, j)
        names = np.unique(values) if values is not None else ()
        if len(names) > 1:
            raise InputError(f"{path}: its rows come from {len(names)} devices (column {name}: "
                             f"{listing(names, 3)}); keep one device's rows in a file of their own")


def _clock_column(path: Path, lay: Layout, n: int) -> tuple[int, np.ndarray] | None:
    """The first text column the header names as a time (:func:`~optcal.core.recording.clock.is_clock_name`; a
    chip's clock before the others) whose every row is a time of day: its index and the seconds since the first
    row; else None."""
    if lay.header is None:
        return None
    from optcal.core.recording.clock import clock_seconds, is_clock_name  # (its re and datetime on this path only)

    # the sensor's own clock first (WitMotion's "Chip Time()" beside the PC's "Time", which stamps packets)
    order = sorted(range(len(lay.header)), key=lambda j: "chip" not in column_key(lay.header[j]))
    for j in order:
        name = lay.header[j]
        if lay.numeric[j] or not is_clock_name(name):
            continue
        values = _strings(path, lay, j)
        t = clock_seconds(values) if values is not None and len(values) == n else None
        if t is not None:
            return j, t
    return None


def _strings(path: Path, lay: Layout, j: int) -> np.ndarray | None:
    """Column ``j`` of the data rows as strings (a label, a clock, a device's name); None where the rows do not
    split into it (a quoted field holding the delimiter)."""
    with _text(path) as fh:
        try:
            return np.loadtxt(fh, delimiter=lay.delimiter, skiprows=lay.skiprows, usecols=[j], dtype=str,
                              comments=_comment_marks(path), ndmin=1)
        except ValueError:
            return None


def _read_labels(path: Path, lay: Layout, column: str, n: int) -> np.ndarray:
    lab = _strings(path, lay, resolve_column(column, lay, path))
    if lab is None:
        raise InputError(f"{path}: label column {column!r} does not split from its rows (a quoted field holding "
                         f"the delimiter?); give the labels as a file of intervals with `intervals`")
    if len(lab) != n:  # pragma: no cover - the same rows were read as numbers
        raise InputError(f"{path}: label column {column!r} has {len(lab)} rows, the data {n}")
    return lab


def raw_file_reason(path) -> tuple[str, bool] | None:
    """Why a file given as a positions file (docs/design.md, "Positions CSV") is a raw recording, and whether it has a
    time column (else reading it needs a rate), or None: the decision of
    :func:`~optcal.core.recording.sniff.table_kind` on its ax, ay, az columns as :func:`read_recording` finds
    them without `columns` (the first :data:`~optcal.core.recording.sniff.KIND_ROWS` rows are read). A file whose
    layout or columns cannot be found is left to the positions reader, whose message names the problem."""
    path = Path(path)
    from optcal.core.recording.robotlogs import log_kind

    kind = log_kind(path)
    if kind is not None:
        return f"it is a {'ROS bag' if kind == 'bag' else 'PX4 ULog'}, which holds samples", True
    try:
        if is_mat(path):
            lay, table = mat_layout(path)
            cols = role_columns(None, lay, path)
            N, nrows = table[:KIND_ROWS, [cols[a] for a in ("ax", "ay", "az")]], len(table)
        else:
            lay = sniff_layout(path)
            cols = role_columns(None, lay, path)
            with open_text(path) as fh:
                nrows = sum(1 for i, ln in enumerate(fh) if i >= lay.skiprows and ln.strip() and not is_comment(ln))
            N = _load_numeric(path, lay, [cols[a] for a in ("ax", "ay", "az")], max_rows=KIND_ROWS)
    except (InputError, ValueError, *DECODE_ERRORS):
        return None
    kind, why = table_kind(lay.header, N, nrows, None if lay.header else lay.ncol)
    return (why, "t" in cols) if kind == "samples" else None
