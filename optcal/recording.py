"""Raw recordings (docs/design.md §9.2) → static intervals → positions.

A raw recording is one row per sample: optionally a time column ``t`` (s), the three accelerometer outputs
``ax, ay, az`` in the sensor's units, optionally ``temp`` (°C). Files may be CSV or whitespace-separated,
with or without a header, and may start with ``key,value`` lines (an ``Fs,100`` line gives the rate).

Static intervals are found as in Tedaldi, Pretto & Menegatti, "A robust and easy to implement method for
IMU calibration without external equipments" (ICRA 2014, §IV-A; the imu_tk implementation): the
statistic of each sample is the norm of the per-axis variances over a window centred on it,
ς(t) = ‖(var_w(a_x), var_w(a_y), var_w(a_z))‖, and a sample is static when ς(t) < k·ς_init, where ς_init
is the same norm over an initial rest period. k is searched over a range (imu_tk: 2…10) and the value
whose calibration fits best is kept. Each static interval long enough becomes one position: the mean of
its samples, their number ``n``, standard deviations ``sx, sy, sz``, middle time ``t`` and mean ``temp``.

Differences from imu_tk, and why: imu_tk compares the raw final cost of fits made with different numbers
of intervals, which favours thresholds that find fewer intervals; here candidates are compared by an
upper confidence bound of the residual SD per degree of freedom divided by √n (:func:`fit_score`), and a
candidate must leave at least one degree of freedom. imu_tk averages a fixed 100 samples from the middle
of each interval; here all samples of the interval are averaged (the variance window already keeps them
half a window away from motion).
"""

from __future__ import annotations

import difflib
import itertools
import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .data import UNITS, PositionsData, check_units
from .errors import InputError
from .model import Model, get_model

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

ROLES = ("t", "ax", "ay", "az", "temp")
ALIASES = {
    "t": ("t", "time", "timestamp", "time_s", "t_s", "seconds"),
    "ax": ("ax", "acc_x", "accx", "a_x", "accel_x", "acc_x_raw"),
    "ay": ("ay", "acc_y", "accy", "a_y", "accel_y", "acc_y_raw"),
    "az": ("az", "acc_z", "accz", "a_z", "accel_z", "acc_z_raw"),
    "temp": ("temp", "temperature", "temp_c", "t_degc"),
}
POSITIONAL = {3: ("ax", "ay", "az"), 4: ("t", "ax", "ay", "az"), 5: ("t", "ax", "ay", "az", "temp")}
RATE_KEYS = ("fs", "rate", "sample rate", "sampling rate", "sample_rate", "sampling_rate", "fs_hz", "rate_hz")
INT16_RAILS = (-32768.0, 32767.0)
SNIFF_LINES = 200
DEFAULT_KS = tuple(float(k) for k in range(2, 11))  # imu_tk's threshold multipliers
NO_REST_RATIO = 20.0  # initial-rest variance this many times the quietest windows': not at rest


# -- reading -----------------------------------------------------------------------------------------
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


@dataclass
class _Layout:
    delimiter: str | None
    skiprows: int  # physical lines before the first data row
    ncol: int
    numeric: tuple[bool, ...]
    header: list[str] | None
    meta: dict
    first: list[str]  # the fields of the first data row (to check a fast reader started there)


def _is_number(s: str) -> bool:
    try:
        float(s)
    except ValueError:
        return False
    return True


def _split(line: str, delim: str | None) -> list[str]:
    return [f.strip().strip('"').strip("'") for f in (line.split(delim) if delim else line.split())]


def _layout(path: Path) -> _Layout:
    """Delimiter, header, leading key/value lines and the first data line, from the file's first lines."""
    try:
        with open(path, encoding="utf-8", errors="replace") as fh:
            head = list(itertools.islice(fh, SNIFF_LINES))
    except OSError as exc:
        raise InputError(f"cannot read {path}: {exc.strerror or exc}") from None
    lines = [(i, ln.strip()) for i, ln in enumerate(head) if ln.strip() and not ln.lstrip().startswith("#")]
    if not lines:
        raise InputError(f"{path} is empty; a raw recording needs one row per sample (t, ax, ay, az)")
    last = lines[-1][1]
    delim = next((d for d in (",", ";", "\t") if d in last), None)
    rows = [(i, _split(ln, delim)) for i, ln in lines]
    pattern = [(len(f), tuple(_is_number(x) for x in f)) for _, f in rows]
    ref = pattern[-1]
    if not any(ref[1]):
        raise InputError(f"{path} has no numeric rows; a raw recording needs one row per sample (t, ax, ay, az)")
    start = len(rows) - 1
    while start > 0 and pattern[start - 1] == ref:
        start -= 1
    header = None
    before = rows[:start]
    # A header has text wherever the data have numbers; a line with the data's width and numbers in it is
    # a data row that does not parse (an empty or text cell), and must not be skipped silently.
    if before and len(before[-1][1]) == ref[0] and not any(
            d and _is_number(x) for x, d in zip(before[-1][1], ref[1])):
        header = before[-1][1]
        before = before[:-1]
    for i, f in reversed(before):  # the last such line is the one that breaks the run of data rows
        if len(f) == ref[0] and any(_is_number(x) for x in f):
            raise InputError(
                f"{path}: line {i + 1} ({','.join(f)}) has the width of a data row but not its numbers "
                "(an empty or text cell?); fix or remove it"
            )
    meta = {f[0].strip().lower(): f[1].strip() for _, f in before if len(f) >= 2}
    return _Layout(delim, rows[start][0], ref[0], ref[1], header, meta, rows[start][1])


def _resolve(ref: str, lay: _Layout, path: Path) -> int:
    ref = ref.strip()
    if lay.header is not None:
        if ref in lay.header:
            return lay.header.index(ref)
        low = [h.lower() for h in lay.header]
        if ref.lower() in low:
            return low.index(ref.lower())
    if ref.lstrip("-").isdigit():
        j = int(ref)
        if not 0 <= j < lay.ncol:
            raise InputError(f"{path}: column index {j} is out of range; the file has {lay.ncol} columns (0-based)")
        return j
    names = lay.header or []
    close = difflib.get_close_matches(ref, names, n=1, cutoff=0.5)
    hint = f" (did you mean {close[0]!r}?)" if close else ""
    where = f"its columns are {', '.join(names)}" if names else "it has no header, so give column indices"
    raise InputError(f"{path}: no column {ref!r}{hint}; {where}")


def _columns(spec, lay: _Layout, path: Path) -> dict[str, int]:
    """Role → column index from ``--columns`` (positional ``t,ax,ay,az`` or ``role=column`` items)."""
    if spec is None:
        if lay.header is not None:
            low = [h.lower() for h in lay.header]
            found = {r: low.index(a) for r in ROLES for a in ALIASES[r] if a in low}
            out = {r: found[r] for r in ROLES if r in found}
            if all(r in out for r in ("ax", "ay", "az")):
                return out
            raise InputError(
                f"{path}: cannot tell which columns are ax, ay, az (columns: {', '.join(lay.header)}); "
                "pass --columns, e.g. --columns t,ax,ay,az with names or 0-based indices"
            )
        numeric = [j for j, isnum in enumerate(lay.numeric) if isnum]
        if len(numeric) in POSITIONAL:
            return dict(zip(POSITIONAL[len(numeric)], numeric))
        raise InputError(
            f"{path}: {lay.ncol} columns and no header; pass --columns (0-based indices for t,ax,ay,az or ax,ay,az)"
        )
    items = [s for s in (spec.split(",") if isinstance(spec, str) else list(spec)) if str(s).strip()]
    if all("=" in str(s) for s in items):
        pairs = [str(s).split("=", 1) for s in items]
        bad = [r for r, _ in pairs if r.strip() not in ROLES]
        if bad:
            raise InputError(f"--columns: unknown role(s) {', '.join(bad)}; roles are {', '.join(ROLES)}")
        out = {r.strip(): _resolve(c, lay, path) for r, c in pairs}
    elif len(items) in POSITIONAL:
        out = {r: _resolve(str(c), lay, path) for r, c in zip(POSITIONAL[len(items)], items)}
    else:
        raise InputError(
            f"--columns {spec!r}: give 3 (ax,ay,az), 4 (t,ax,ay,az) or 5 (t,ax,ay,az,temp) columns, "
            "or role=column items"
        )
    missing = [r for r in ("ax", "ay", "az") if r not in out]
    if missing:
        raise InputError(f"--columns lacks {', '.join(missing)}")
    for r, j in out.items():
        if not lay.numeric[j]:
            name = lay.header[j] if lay.header else j
            raise InputError(f"{path}: column {name!r} (for {r}) is not numeric; choose another with --columns")
    return out


def _rate_from_meta(meta: dict) -> float | None:
    for k in RATE_KEYS:
        if k in meta and _is_number(meta[k]):
            return float(meta[k])
    return None


def read_recording(path, columns=None, rate: float | None = None, units: str = "g", *,
                   saturation: float | None = None, labels: str | None = None,
                   need_time: bool = True) -> Recording:
    """Read a raw recording. ``columns``: ``"t,ax,ay,az"`` (names or 0-based indices; 3 entries mean
    ax,ay,az, 5 add temp) or ``"ax=acc_x,..."``; ``rate`` (Hz) when there is no time column; ``units``
    of the outputs; ``saturation``: |value| at which a sample is saturated (default for counts: the int16
    rails); ``labels``: a column of section labels (kept as strings); ``need_time=False`` accepts a file
    without time or rate (time is then the sample index and the rate NaN). Every problem is an InputError."""
    path = Path(path)
    if units not in UNITS:
        raise InputError(f"unknown units {units!r}; use one of {', '.join(UNITS)}")
    lay = _layout(path)
    if lay.ncol == 1:
        raise InputError(
            f"{path} has a single column; a raw recording needs ax, ay, az (and t, or --rate) on each row"
        )
    cols = _columns(columns, lay, path)
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
    meta_rate = _rate_from_meta(lay.meta)
    if rate is not None and not rate > 0:
        raise InputError(f"--rate {rate} must be a positive sample rate in Hz")
    if "t" in data:
        t = data["t"]
        steps = np.diff(t)
        if np.any(steps <= 0):
            i = int(np.flatnonzero(steps <= 0)[0])
            raise InputError(
                f"{path}: the time column does not increase from sample {i} (t = {t[i]:g}) to {i + 1} "
                f"(t = {t[i + 1]:g}); "
                "sort the samples, or drop the time column from --columns and give --rate"
            )
        t_rate = 1.0 / float(np.median(steps))
        given = rate if rate is not None else meta_rate
        if given is not None and abs(t_rate / given - 1) > 0.05:
            raise InputError(
                f"{path}: the time column gives {t_rate:.6g} Hz but the rate is {given:g} Hz; "
                "the time column must be in seconds (or drop it from --columns)"
            )
        fs = t_rate
    else:
        fs = rate if rate is not None else meta_rate
        if fs is None and need_time:
            raise InputError(f"{path} has no time column; give the sample rate with --rate HZ")
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


def _load_numeric(path: Path, lay: _Layout, usecols: list[int]) -> np.ndarray:
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


def _load_arrow(path: Path, lay: _Layout, usecols: list[int]) -> np.ndarray | None:
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


def _read_labels(path: Path, lay: _Layout, column: str, n: int) -> np.ndarray:
    j = _resolve(column, lay, path)
    lab = np.loadtxt(path, delimiter=lay.delimiter, skiprows=lay.skiprows, usecols=[j], dtype=str,
                     comments="#", ndmin=1)
    if len(lab) != n:  # pragma: no cover - the same rows were read as numbers
        raise InputError(f"{path}: label column {column!r} has {len(lab)} rows, the data {n}")
    return lab


# -- detection ---------------------------------------------------------------------------------------
@dataclass
class DetectionResult:
    """Static intervals of a recording, as [start, end) sample indices, and how they were found."""

    recording: Recording
    intervals: np.ndarray  # (m, 2) int, end exclusive
    method: str  # "variance", "given" or "labels"
    names: list[str] | None = None
    window: int | None = None  # samples in the variance window
    min_samples: int = 1
    init_samples: int | None = None
    init_variance: float | None = None  # ς_init, the variance norm of the initial rest period
    statistic: np.ndarray | None = None  # ς(t) per sample (NaN at the edges)
    k: float | None = None
    threshold: float | None = None
    notes: list[str] = field(default_factory=list)
    search: list[dict] = field(default_factory=list)  # per k: n_intervals, score (or note)

    @property
    def n_intervals(self) -> int:
        return len(self.intervals)

    @property
    def n_static_samples(self) -> int:
        return int(np.sum(self.intervals[:, 1] - self.intervals[:, 0])) if len(self.intervals) else 0


def variance_statistic(N: np.ndarray, window: int) -> np.ndarray:
    """ς per sample: norm of the per-axis variances over a centred window of ``window`` samples (odd);
    NaN where the window does not fit. Running sums in C (scipy.ndimage), no per-sample Python loop."""
    n = len(N)
    h = window // 2
    # Centred (the running sums of squares keep their precision) and one contiguous row per axis (the
    # filter then runs along memory: three times faster than along axis 0 of an (n, 3) array).
    from scipy.ndimage import uniform_filter1d  # here, not at module level: importing optcal stays light

    X = np.ascontiguousarray((N - N.mean(axis=0)).T)
    m = uniform_filter1d(X, window, axis=1, mode="nearest")
    m2 = uniform_filter1d(X * X, window, axis=1, mode="nearest")
    var = m2 - m * m
    # Below this the difference is rounding of the running sums, not signal: a window of constant
    # (quantised) samples must come out exactly 0.
    var[var < 1e-12 * float(np.mean(X * X))] = 0.0
    s = np.sqrt(np.einsum("ij,ij->j", var, var))
    s[:h] = np.nan
    s[n - h:] = np.nan
    return s


def _runs(mask: np.ndarray) -> np.ndarray:
    """[start, end) of each run of True."""
    d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return np.column_stack([np.flatnonzero(d == 1), np.flatnonzero(d == -1)])


def _drop_saturated(rec: Recording, iv: np.ndarray, notes: list[str], names=None):
    if not rec.saturated.any() or not len(iv):
        return iv, names
    c = np.concatenate([[0], np.cumsum(rec.saturated)])
    nsat = c[iv[:, 1]] - c[iv[:, 0]]
    for (s, e), k in zip(iv[nsat > 0], nsat[nsat > 0]):
        notes.append(f"interval {rec.t[s]:.2f}–{rec.t[e - 1]:.2f} s dropped: {k} saturated sample(s)")
    keep = nsat == 0
    return iv[keep], (None if names is None else [nm for nm, ok in zip(names, keep) if ok])


def _samples(rec: Recording, seconds: float, what: str) -> int:
    if not seconds > 0:
        raise InputError(f"{what} must be a positive number of seconds, got {seconds}")
    return max(1, int(round(seconds * rec.rate)))


@dataclass
class _Detector:
    """The part of detection that does not depend on k: the statistic and the initial-rest variance."""

    rec: Recording
    window: int
    min_samples: int
    init_samples: int
    init_variance: float
    statistic: np.ndarray

    @classmethod
    def of(cls, rec: Recording, window_s: float = 1.0, min_static_s: float = 1.0, init_s: float = 2.0):
        w = _samples(rec, window_s, "the variance window") | 1
        n_init = _samples(rec, init_s, "the initial rest period")
        if len(rec) < max(2 * w, n_init + w):
            raise InputError(
                f"{rec.path}: {len(rec)} samples ({rec.duration:.1f} s) are too few for a {window_s:g} s window "
                f"and a {init_s:g} s initial rest; record longer"
            )
        stat = variance_statistic(rec.N, w)
        init_var = float(np.linalg.norm(rec.N[:n_init].var(axis=0)))
        # The level of the quietest windows: the 1st percentile of those with any variance at all (a
        # quantised sensor can hold a window exactly constant, which says nothing about its noise, and
        # a window with one changed sample is not a noise level either).
        moving = stat[stat > 0]
        if not moving.size:
            raise InputError(f"{rec.path}: the outputs never change; this is not a recording of a sensor being turned")
        quiet = float(np.percentile(moving, 1.0))
        if init_var > NO_REST_RATIO * quiet:
            raise InputError(
                f"{rec.path}: the first {init_s:g} s are not at rest (their variance is "
                f"{init_var / quiet:.3g} × that of the quietest windows); start the recording "
                "with the sensor still, or set the rest period with --init-s"
            )
        if init_var == 0.0:
            init_var = quiet  # a quantised, perfectly still start: the finest variance seen sets the scale
        return cls(rec, w, _samples(rec, min_static_s, "--min-static"), n_init, init_var, stat)

    def intervals(self, k: float, notes: list[str]) -> np.ndarray:
        static = np.nan_to_num(self.statistic, nan=np.inf) < k * self.init_variance
        iv = _runs(static)
        short = iv[:, 1] - iv[:, 0] < self.min_samples
        if short.any():
            notes.append(f"{int(short.sum())} static run(s) shorter than {self.min_samples} samples ignored")
        iv, _ = _drop_saturated(self.rec, iv[~short], notes)
        return iv

    def result(self, k: float) -> DetectionResult:
        notes: list[str] = []
        iv = self.intervals(k, notes)
        return DetectionResult(self.rec, iv, "variance", None, self.window, self.min_samples, self.init_samples,
                               self.init_variance, self.statistic, float(k), float(k * self.init_variance), notes)


def detect_static(recording: Recording, k: float = 4.0, *, window_s: float = 1.0, min_static_s: float = 1.0,
                  init_s: float = 2.0) -> DetectionResult:
    """Static intervals at threshold k·ς_init (Tedaldi et al. 2014, §IV-A)."""
    if not k > 0:
        raise InputError(f"the threshold multiplier k must be positive, got {k}")
    return _Detector.of(recording, window_s, min_static_s, init_s).result(k)


def fit_score(data: PositionsData, model, g_local: float = 1.0, solver: str = "scipy-lm",
              alpha: float = 0.10) -> float:
    """Score of a candidate set of intervals (smaller is better): σ_up/√n, where σ_up = sqrt(cost /
    χ²_α(n − rank)) is the (1 − α) upper confidence bound of the residual SD and n the number of positions.

    The residual SD from few degrees of freedom is uncertain, and a fit that leaves one degree of freedom
    can show a small residual by chance; comparing upper bounds stops such a candidate from winning on
    luck. Dividing by √n weighs what a lost interval costs: the parameters' standard errors scale as
    σ/√n. The fit goes through :func:`optcal.fit.calibrate` (the registry, at run time)."""
    from scipy.stats import chi2

    from .fit import calibrate

    cal = calibrate(data, model, solver=solver, g_local=g_local)
    return float(np.sqrt(cal.fit.cost / chi2.ppf(alpha, cal.fit.dof) / len(data)))


def choose_threshold(recording: Recording, model, fit_cost_fn=None, *, ks=DEFAULT_KS, g_local: float = 1.0,
                     solver: str = "scipy-lm", window_s: float = 1.0, min_static_s: float = 1.0,
                     init_s: float = 2.0) -> DetectionResult:
    """Search the threshold multiplier k over ``ks`` and keep the one whose calibration fits best
    (Tedaldi et al. 2014, §IV-A; imu_tk tries k = 2…10). ``fit_cost_fn(positions) -> float`` scores a
    candidate (default :func:`fit_score` of ``model`` fitted with ``solver``). Interval sets met before
    are not refitted. A candidate needs more positions than the model has parameters; if none has, the
    error says how many were found."""
    model = get_model(model)
    det = _Detector.of(recording, window_s, min_static_s, init_s)
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
            raise too_few(most["n_intervals"], model, f"at best (k = {most['k']:g})")
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


def too_few(found: int, model: Model, how: str = "") -> InputError:
    how = f" {how}" if how else ""
    return InputError(
        f"found {found} static interval(s){how}, but model {model.name} needs at least {model.n_params} "
        "(one per parameter); record more poses, lower --min-static, or use a smaller model (e.g. diag6)"
    )


# -- intervals given by hand ---------------------------------------------------------------------------
def read_intervals(path) -> tuple[np.ndarray, list[str] | None]:
    """[start, end) sample indices from a file: JSON (a list of [start, end] or {start, end}, or imucal's
    section list {name: {start, end}}, whose ``*_rot`` rotation sections are skipped), or CSV/text with a
    ``start,end`` header, rows of start,end, or two rows (starts, ends) as in ImuCalibration's
    static_intervals.csv."""
    path = Path(path)
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read intervals file {path}: {getattr(exc, 'strerror', None) or exc}") from None
    names = None
    try:
        if path.suffix.lower() == ".json":
            obj = json.loads(text)
            if isinstance(obj, dict):
                obj = {k: v for k, v in obj.items() if not str(k).endswith("_rot")}
                names = list(obj)
                obj = list(obj.values())
            iv = np.array([[o["start"], o["end"]] if isinstance(o, dict) else list(o) for o in obj], float)
        else:
            lines = [ln for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
            delim = "," if "," in lines[0] else None
            first = _split(lines[0], delim)
            if not all(_is_number(x) for x in first):
                low = [x.lower() for x in first]
                if "start" not in low or "end" not in low:
                    raise InputError(f"intervals file {path}: its header needs columns start and end")
                rows = np.array([[float(v) for v in _split(ln, delim)] for ln in lines[1:]], ndmin=2)
                iv = rows[:, [low.index("start"), low.index("end")]]
            else:
                rows = np.array([[float(v) for v in _split(ln, delim)] for ln in lines], ndmin=2)
                transposed = rows.shape[0] == 2 and rows.shape[1] != 2
                iv = rows.T if transposed else rows
    except InputError:
        raise
    except (ValueError, KeyError, TypeError, IndexError, json.JSONDecodeError):
        raise InputError(
            f"intervals file {path} is not a list of start,end sample indices (JSON or CSV)"
        ) from None
    if iv.ndim != 2 or iv.shape[1] != 2 or not len(iv):
        raise InputError(f"intervals file {path} holds no start,end pairs")
    if np.any(iv != np.round(iv)):
        raise InputError(f"intervals file {path}: start and end must be whole sample indices")
    return iv.astype(np.int64), names


def given_intervals(recording: Recording, iv, names=None, method: str = "given") -> DetectionResult:
    """A detection result from intervals given by hand ([start, end) sample indices)."""
    iv = np.asarray(iv, np.int64).reshape(-1, 2)
    n = len(recording)
    bad = (iv[:, 0] < 0) | (iv[:, 1] > n) | (iv[:, 1] <= iv[:, 0])
    if bad.any():
        s, e = iv[np.flatnonzero(bad)[0]]
        raise InputError(
            f"interval {int(np.flatnonzero(bad)[0])} (start {s}, end {e}) is empty or outside the "
            f"recording's {n} samples; intervals are [start, end) sample indices"
        )
    notes: list[str] = []
    iv, names = _drop_saturated(recording, iv, notes, names)
    return DetectionResult(recording, iv, method, names, notes=notes)


def label_intervals(recording: Recording, values=None) -> DetectionResult:
    """Intervals from a label column: each contiguous run of one of ``values`` (all labels if None)."""
    lab = recording.labels
    if lab is None:
        raise InputError("no label column was read; pass --labels COLUMN")
    change = np.flatnonzero(lab[1:] != lab[:-1]) + 1
    starts = np.concatenate([[0], change])
    ends = np.concatenate([change, [len(lab)]])
    names = lab[starts]
    keep = np.ones(len(starts), bool) if values is None else np.isin(names, list(values))
    if values is not None:
        unknown = sorted(set(values) - set(names.tolist()))
        if unknown:
            raise InputError(f"label(s) {', '.join(unknown)} do not occur; labels are {', '.join(sorted(set(names)))}")
    iv = np.column_stack([starts, ends])[keep]
    return given_intervals(recording, iv, [str(x) for x in names[keep]], method="labels")


# -- positions -----------------------------------------------------------------------------------------
def positions_from_recording(recording: Recording, detection: DetectionResult) -> PositionsData:
    """One position per interval: mean output, n, per-axis SD, middle time and mean temperature."""
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


def positions_from_args(args, path) -> PositionsData:
    """The ``--raw`` path of every data-reading command: read, detect (or take given intervals), average."""
    from .commands._dataopts import gravity_from_args

    labels = getattr(args, "labels", None)
    rec = read_recording(path, getattr(args, "columns", None), getattr(args, "rate", None),
                         getattr(args, "units", "g") or "g", saturation=getattr(args, "saturation", None),
                         labels=labels)
    # the model the positions are for: calibrate's --model, discover's --base
    model = get_model(getattr(args, "model", None) or getattr(args, "base", None) or "diag6")
    kw = {"window_s": getattr(args, "window", 1.0), "min_static_s": getattr(args, "min_static", 1.0),
          "init_s": getattr(args, "init_s", 2.0)}
    if getattr(args, "intervals", None):
        det = given_intervals(rec, *read_intervals(args.intervals))
    elif labels is not None:
        values = labels.split("=", 1)[1].split(",") if "=" in labels else None
        det = label_intervals(rec, values)
    else:
        ks = parse_ks(getattr(args, "threshold_k", None))
        if len(ks) == 1:
            det = detect_static(rec, ks[0], **kw)
        else:
            det = choose_threshold(rec, model, ks=ks, g_local=gravity_from_args(args), **kw)
    if det.n_intervals < model.n_params:
        raise too_few(det.n_intervals, model)
    data = positions_from_recording(rec, det)
    check_units(data, rec.units)
    return data


def parse_ks(spec) -> tuple[float, ...]:
    """``--threshold-k``: one multiplier ``4``, a range ``2:10`` (integer steps) or a list ``2,3,5``."""
    if spec is None:
        return DEFAULT_KS
    try:
        if ":" in str(spec):
            a, b = (float(x) for x in str(spec).split(":"))
            ks = tuple(float(v) for v in np.arange(a, b + 0.5))
        else:
            ks = tuple(float(x) for x in str(spec).split(","))
    except ValueError:
        raise InputError(f"--threshold-k {spec!r}: give a number, a range A:B or a list A,B,C") from None
    if not ks or min(ks) <= 0:
        raise InputError(f"--threshold-k {spec!r}: multipliers must be positive")
    return ks


# -- reporting -----------------------------------------------------------------------------------------
def describe_detection(obj) -> str:
    """What detection found: intervals, samples, the threshold chosen and the notes."""
    det: DetectionResult = obj.extra["detection"] if isinstance(obj, PositionsData) else obj
    rec = det.recording
    frac = det.n_static_samples / max(len(rec), 1)
    head = (f"recording {rec.path}: {len(rec)} samples, {rec.duration:.1f} s at {rec.rate:.6g} Hz, units {rec.units}"
            + (f", {int(rec.saturated.sum())} saturated sample(s)" if rec.saturated.any() else ""))
    if det.method == "variance":
        how = (f"variance detector (Tedaldi et al. 2014): window {det.window} samples, initial rest "
               f"{det.init_samples} samples (ς_init = {det.init_variance:.4g}), threshold k = {det.k:g} × ς_init, "
               f"minimum {det.min_samples} samples")
        if det.search:
            tried = ", ".join(f"{r['k']:g}:{r['n_intervals']}" + (f"/{r['score'] * 1e6:.1f}"
                              if r["score"] is not None else "") for r in det.search)
            how += f"\n  k searched (k:intervals/score σ_up/√n in µg, smallest kept): {tried}"
    else:
        how = "intervals given by hand" if det.method == "given" else "intervals from the label column"
    lines = [head, f"{det.n_intervals} static interval(s), {det.n_static_samples} samples ({100 * frac:.0f}%); {how}"]
    for i, (s, e) in enumerate(det.intervals):
        name = f" {det.names[i]}" if det.names else ""
        lines.append(f"  {i:3d}{name}: samples {s}–{e - 1} ({rec.t[s]:.2f}–{rec.t[e - 1]:.2f} s, n = {e - s})")
    lines += [f"  note: {n}" for n in det.notes]
    return "\n".join(lines)


def plot_recording(recording: Recording, detection: DetectionResult, residuals_g, path) -> None:
    """The recording with the detected intervals shaded, the variance statistic with the threshold, and
    the residual of each interval's position (in µg). Written with matplotlib's Agg backend."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rec, det = recording, detection
    res = np.asarray(residuals_g, float).ravel()
    panels = 3 if det.statistic is not None else 2
    fig, axes = plt.subplots(panels, 1, figsize=(11, 2.6 * panels), sharex=True,
                             gridspec_kw={"height_ratios": [3, 1.5, 1.5][:panels]})
    ax = axes[0]
    step = max(1, len(rec) // 20000)  # long recordings: min/max per block keeps every spike visible
    for j, c in enumerate("xyz"):
        if step == 1:
            ax.plot(rec.t, rec.N[:, j], lw=0.6, label=f"a{c}")
        else:
            m = len(rec) // step * step
            blocks = rec.N[:m, j].reshape(-1, step)
            ax.fill_between(rec.t[:m:step], blocks.min(1), blocks.max(1), lw=0, alpha=0.8, label=f"a{c}")
    for s, e in det.intervals:
        for a in axes:
            a.axvspan(rec.t[s], rec.t[e - 1], color="tab:green", alpha=0.15, lw=0)
    if rec.saturated.any():
        ts = rec.t[rec.saturated]
        ax.plot(ts, np.full(len(ts), np.max(rec.N)), "|", color="red", label="saturated")
    ax.set_ylabel(f"output [{rec.units}]")
    ax.set_title(f"{Path(rec.path).name if rec.path else 'recording'}: {det.n_intervals} static intervals")
    ax.legend(loc="upper right", fontsize=8, ncol=4)
    if det.statistic is not None:
        a = axes[1]
        a.semilogy(rec.t[::step], det.statistic[::step], lw=0.6, color="k")
        a.axhline(det.threshold, color="tab:red", lw=0.8, label=f"threshold {det.k:g}·ς_init")
        a.set_ylabel("ς (variance norm)")
        a.legend(loc="upper right", fontsize=8)
    a = axes[-1]
    mid = np.array([rec.t[s:e].mean() for s, e in det.intervals])
    width = np.array([rec.t[e - 1] - rec.t[s] for s, e in det.intervals])
    if len(res) == len(mid):
        a.bar(mid, res * 1e6, width=np.maximum(width, rec.duration / 200), color="tab:blue")
    a.axhline(0, color="k", lw=0.5)
    a.set_ylabel("residual [µg]")
    a.set_xlabel("time [s]")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
