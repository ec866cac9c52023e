"""Reading a raw recording (docs/design.md §9.2): one row per sample, optionally a time column ``t`` (s),
the three accelerometer outputs ``ax, ay, az`` in the sensor's units, optionally ``temp`` (°C). Files may be
CSV or whitespace-separated, with or without a header, and may start with ``key,value`` lines; their layout
is read by :mod:`optcal.recording.sniff`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..data import UNITS, PositionsData, check_units
from ..errors import InputError
from .sniff import ROLES, Layout, rate_from_meta, resolve_column, role_columns, sniff_layout

INT16_RAILS = (-32768.0, 32767.0)

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
    saturated: np.ndarray  # (n,) bool: a sample at a rail on any axis
    path: str | None = None
    columns: dict = field(default_factory=dict)  # role -> column used
    labels: np.ndarray | None = None  # (n,) str, from a label column
    meta: dict = field(default_factory=dict)  # key,value lines before the data

    def __len__(self) -> int:
        return len(self.N)

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0]) if len(self) else 0.0


def read_recording(path, columns=None, rate: float | None = None, units: str = "g", *,
                   saturation: float | None = None, labels: str | None = None,
                   need_time: bool = True) -> Recording:
    """Read a raw recording (docs/design.md §9.2). ``columns``: ``"t,ax,ay,az"`` (names or 0-based indices;
    3 entries mean ax,ay,az, 5 add temp) or ``"ax=acc_x,..."``; ``rate`` (Hz) when there is no time column;
    ``units`` of the outputs; ``saturation``: |value| at which a sample is saturated (default for counts:
    the int16 rails); ``labels``: a column of section labels, ``COLUMN`` or ``COLUMN=L1,L2`` (kept as
    strings; the labels after ``=`` are for :func:`~optcal.recording.label_intervals`); ``need_time=False``
    accepts a file without time or rate (time is then the sample index and the rate NaN). Every problem is
    an InputError."""
    path = Path(path)
    if units not in UNITS:
        raise InputError(f"unknown units {units!r}; use one of {', '.join(UNITS)}")
    lay = sniff_layout(path)
    if lay.ncol == 1:
        raise InputError(
            f"{path} has a single column; a raw recording needs ax, ay, az (and t, or `rate`) on each row"
        )
    cols = role_columns(columns, lay, path)
    order = [r for r in ROLES if r in cols]
    raw = _load_numeric(path, lay, [cols[r] for r in order])
    data = dict(zip(order, raw.T))
    n = len(raw)
    if n < 2:
        raise InputError(f"{path} has {n} sample(s); a raw recording needs many samples per static pose")
    bad = ~np.isfinite(raw)
    if bad.any():
        r, c = np.argwhere(bad)[0]
        raise InputError(f"{path}: sample {r} has {raw[r, c]} in column {order[c]!r}; remove or fix that row")
    meta_rate = rate_from_meta(lay.meta)
    if rate is not None and not rate > 0:
        raise InputError(f"`rate` {rate} must be a positive sample rate in Hz")
    if "t" in data:
        t = data["t"]
        steps = np.diff(t)
        if np.any(steps <= 0):
            i = int(np.flatnonzero(steps <= 0)[0])
            raise InputError(
                f"{path}: the time column does not increase from sample {i} (t = {t[i]:g}) to {i + 1} "
                f"(t = {t[i + 1]:g}); "
                "sort the samples, or drop the time column from `columns` and give `rate`"
            )
        t_rate = 1.0 / float(np.median(steps))
        given = rate if rate is not None else meta_rate
        if given is not None and abs(t_rate / given - 1) > 0.05:
            raise InputError(
                f"{path}: the time column gives {t_rate:.6g} Hz but the rate is {given:g} Hz; "
                "the time column must be in seconds (or drop it from `columns`)"
            )
        fs = t_rate
    else:
        fs = rate if rate is not None else meta_rate
        if fs is None and need_time:
            raise InputError(f"{path} has no time column; give the sample rate in Hz with `rate`")
        t = np.arange(n) / (fs or 1.0)
        fs = np.nan if fs is None else fs
    N = np.column_stack([data["ax"], data["ay"], data["az"]])
    step = max(1, n // 20000)
    check_units(PositionsData(N=N[::step], units=units), units)
    if saturation is not None:
        sat = np.any(np.abs(N) >= saturation, axis=1)
    elif units == "counts":
        sat = np.any((N <= INT16_RAILS[0]) | (N >= INT16_RAILS[1]), axis=1)
    else:
        sat = np.zeros(n, bool)
    lab = None
    if labels is not None:
        lab = _read_labels(path, lay, labels.split("=", 1)[0], n)
    names = {r: (lay.header[j] if lay.header else j) for r, j in cols.items()}
    return Recording(t, N, data.get("temp"), units, float(fs), sat, str(path), names, lab, lay.meta)


def _load_numeric(path: Path, lay: Layout, usecols: list[int]) -> np.ndarray:
    """The chosen columns as floats, (n, len(usecols)). Delimited files go through Arrow's multithreaded
    CSV reader when pyarrow is installed (several times faster than NumPy's); anything it does not read
    cleanly (comment lines, ragged rows, text in a number column, whitespace-separated files) goes through
    numpy.loadtxt, a C reader too, whose messages name the offending row."""
    if lay.delimiter is not None and _arrow_reader() is not None:
        out = _load_arrow(path, lay, usecols)
        if out is not None:
            return out
    try:
        return np.loadtxt(path, delimiter=lay.delimiter, skiprows=lay.skiprows, usecols=usecols, ndmin=2,
                          comments="#", dtype=float)
    except ValueError as exc:
        msg = str(exc).splitlines()[0].rstrip(".")
        raise InputError(f"{path}: {msg} (data start on line {lay.skiprows + 1}); fix or remove that row") from None


def _load_arrow(path: Path, lay: Layout, usecols: list[int]) -> np.ndarray | None:
    import pyarrow as pa

    arrow_csv = _arrow_reader()
    names = [f"c{j}" for j in range(lay.ncol)]
    try:
        table = arrow_csv.read_csv(
            path,
            read_options=arrow_csv.ReadOptions(skip_rows=lay.skiprows, column_names=names),
            parse_options=arrow_csv.ParseOptions(delimiter=lay.delimiter),
            convert_options=arrow_csv.ConvertOptions(include_columns=[names[j] for j in usecols],
                                                      column_types={names[j]: pa.float64() for j in usecols}),
        )
        out = np.column_stack([table.column(names[j]).to_numpy() for j in usecols]).astype(float, copy=False)
    except (pa.ArrowException, ValueError, OSError):
        return None
    if len(out) == 0 or not np.array_equal(out[0], [float(lay.first[j]) for j in usecols], equal_nan=True):
        return None  # it did not start on the first data row (e.g. blank lines in the preamble)
    return out


def _read_labels(path: Path, lay: Layout, column: str, n: int) -> np.ndarray:
    j = resolve_column(column, lay, path)
    lab = np.loadtxt(path, delimiter=lay.delimiter, skiprows=lay.skiprows, usecols=[j], dtype=str,
                     comments="#", ndmin=1)
    if len(lab) != n:  # pragma: no cover - the same rows were read as numbers
        raise InputError(f"{path}: label column {column!r} has {len(lab)} rows, the data {n}")
    return lab
