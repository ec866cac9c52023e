"""Static intervals of a raw recording by the variance detector of Tedaldi, Pretto & Menegatti, "A robust
and easy to implement method for IMU calibration without external equipments" (ICRA 2014, §IV-A; the
imu_tk implementation; docs/design.md, "Raw recordings").

The statistic of each sample is the norm of the per-axis variances over a window centred on it,
ς(t) = ‖(var_w(a_x), var_w(a_y), var_w(a_z))‖, and a sample is static when ς(t) < k·ς_init, where ς_init
is the same norm over an initial rest period. Runs of static samples shorter than a minimum are ignored,
and an interval holding a saturated sample is dropped. The search over k, which fits a model to each
candidate, is :func:`optcal.app.workflows.recording.choose_threshold`.

A known rest at the start is not needed. Without ``init_s``, the first :data:`DEFAULT_INIT_S` seconds
are the rest period when they are at rest (ς_init at most :data:`NO_REST_RATIO` times the level of the
quietest windows), as in imu_tk; otherwise ς_init is the noise floor of the recording itself: the
:data:`QUIET_PERCENTILE`-th percentile of ς over the windows that move at all (the quietest windows of a
recording of poses are windows inside a pose). With ``init_s`` given, the first ``init_s`` seconds must be
at rest. When too few intervals are found, :meth:`Detector.diagnosis` says why (saturated samples, runs too
short, runs just above the threshold) and what to change.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from optcal.core.errors import InputError
from optcal.core.model import Model
from optcal.core.ranges import range_rows  # noqa: F401  (the recording path's modules take it from here)
from optcal.core.recording.reading import Recording

NO_REST_RATIO = 20.0  # initial-rest variance this many times the quietest windows': not at rest
DEFAULT_INIT_S = 2.0  # s: the rest period tried at the start when `init_s` is not given
QUIET_PERCENTILE = 5.0  # the noise floor without a rest period: this percentile of the moving windows' ς
NOISY_FACTOR = 3.0  # a run under this many times the threshold, long enough, but not under it: "too noisy"
DEFAULT_KS = tuple(float(k) for k in range(2, 11))  # imu_tk's threshold multipliers, searched by default


@dataclass
class DetectionResult:
    """Static intervals of a recording, as [start, end) sample indices, and how they were found."""

    recording: Recording
    intervals: np.ndarray  # (m, 2) int, end exclusive
    method: str  # "segment" (optcal.core.recording.segment), "variance", "given" or "labels"
    names: list[str] | None = None
    window: int | None = None  # samples in the variance window
    min_samples: int = 1
    init_samples: int | None = None
    init_variance: float | None = None  # ς_init, the variance norm of the initial rest period (or noise floor)
    reference: str = "initial rest"  # what ς_init is: "initial rest" or "quietest windows"
    statistic: np.ndarray | None = None  # ς(t) per sample (NaN at the edges)
    k: float | None = None
    threshold: float | None = None
    notes: list[str] = field(default_factory=list)
    search: list[dict] = field(default_factory=list)  # per k: n_intervals, score (or note)
    noise: np.ndarray | None = None  # "segment": white noise SD of a sample per axis, sensor units
    block: int | None = None  # "segment": samples per block
    segmentation: object = None  # "segment": the optcal.core.recording.segment.Segmentation behind the intervals

    @property
    def n_intervals(self) -> int:
        return len(self.intervals)

    @property
    def n_static_samples(self) -> int:
        return int(np.sum(self.intervals[:, 1] - self.intervals[:, 0])) if len(self.intervals) else 0


def _centred_means(X: np.ndarray, window: int) -> np.ndarray:
    """Mean of each row of ``X`` over the centred window of ``window`` samples (odd), where it fits (the
    columns h … n − h − 1, h = window // 2; the others are left 0): differences of running sums."""
    h = window // 2
    c = np.zeros((X.shape[0], X.shape[1] + 1))
    np.cumsum(X, axis=1, out=c[:, 1:])
    out = np.zeros_like(X)
    out[:, h:X.shape[1] - h] = (c[:, window:] - c[:, :X.shape[1] + 1 - window]) / window
    return out


def variance_statistic(N: np.ndarray, window: int) -> np.ndarray:
    """ς per sample: norm of the per-axis variances over a centred window of ``window`` samples (odd);
    NaN where the window does not fit. Running sums in NumPy (cumulative sums), no per-sample Python loop
    and no scipy.ndimage (a third of a second to import)."""
    n = len(N)
    h = window // 2
    # Centred (the running sums of squares keep their precision) and one contiguous row per axis (the
    # sums then run along memory).
    X = np.ascontiguousarray((N - N.mean(axis=0)).T)
    m = _centred_means(X, window)
    m2 = _centred_means(X * X, window)
    var = m2 - m * m
    # Below this the difference is rounding of the running sums, not signal: a window of constant
    # (quantised) samples must come out exactly 0.
    var[var < 1e-12 * float(np.mean(X * X))] = 0.0
    s = np.sqrt(np.einsum("ij,ij->j", var, var))
    s[:h] = np.nan
    s[n - h:] = np.nan
    return s


def runs(mask: np.ndarray) -> np.ndarray:
    """[start, end) (k, 2) of each run of True in ``mask``: the one run-finder of the recording path."""
    d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return np.column_stack([np.flatnonzero(d == 1), np.flatnonzero(d == -1)])


def chunks(r: np.ndarray, m: int) -> np.ndarray:
    """The ranges ``r`` (k, 2) cut into pieces of at most ``m`` samples, equal within a range (one piece per
    row, in order)."""
    size = r[:, 1] - r[:, 0]
    k = np.maximum(1, -(-size // m))  # pieces per range
    j, run = range_rows(np.column_stack([np.zeros_like(k), k]))  # each piece's number within its range
    start = r[run, 0] + (size[run] * j) // k[run]
    end = r[run, 0] + (size[run] * (j + 1)) // k[run]
    return np.column_stack([start, end]).astype(np.int64)


# Ranges at least this long on average are partitioned one by one when that gives group_medians' own numbers:
# a partition per range then costs less than one over all of them
EACH_RANGE_FROM = 256


def group_medians(x: np.ndarray, r: np.ndarray) -> np.ndarray:
    """The median of ``x`` (n, 3) over each range of ``r`` (k, 2; non-empty, not overlapping), per column, all
    ranges in one partition: the rows of every range, keyed by range then value (the value shifted by the range's
    number times the column's span, one float key: a third of the time of a two-key lexsort), partitioned about
    the places of every range's middle (cheaper than sorting them all); a range's median is the middle of
    its run, taken from the values themselves. The key rounds where values differ by less than its last
    bit, and the medians are then the neighbours the partition meets; on whole or half numbers (counts) it is
    exact, and long ranges are partitioned one at a time (:func:`_medians_each`), to the same numbers."""
    lens = r[:, 1] - r[:, 0]
    if len(r) and lens.sum() >= EACH_RANGE_FROM * len(r) and _exact_keys(x, len(r)):
        return _medians_each(x, r)
    rows, which = range_rows(r)
    first = np.cumsum(lens) - lens
    lo, hi = first + (lens - 1) // 2, first + lens // 2
    kth = np.unique(np.concatenate([lo, hi]))
    out = np.empty((len(r), x.shape[1]))
    for j in range(x.shape[1]):  # three columns
        v = x[rows, j]
        if not len(v):
            continue
        base = v.min()
        s = v[np.argpartition((v - base) + which * (2.0 * (v.max() - base) + 1.0), kth)]
        out[:, j] = (s[lo] + s[hi]) / 2
    return out


def _exact_keys(x: np.ndarray, k: int) -> bool:
    """Whether :func:`group_medians`' keys over ``k`` ranges of ``x`` are exact: every value a whole or half
    number small enough that the key, the range's number times twice the span plus the value, stays below 2^50."""
    y = 2.0 * np.asarray(x, float)
    if not np.array_equal(y[:64], np.round(y[:64])):  # most float data say so in their first rows
        return False
    return bool(np.all(np.abs(y) < 2.0**46 / (k + 1)) and np.array_equal(y, np.round(y)))


def _medians_each(x: np.ndarray, r: np.ndarray) -> np.ndarray:
    """:func:`group_medians` by one partition of each range's rows (all columns at once)."""
    out = np.empty((len(r), x.shape[1]))
    for i, (a, b) in enumerate(r.tolist()):
        lo, hi = (b - a - 1) // 2, (b - a) // 2
        part = np.partition(x[a:b], (lo, hi), axis=0)
        out[i] = (part[lo] + part[hi]) / 2
    return out


def drop_saturated(rec: Recording, iv: np.ndarray, notes: list[str], names=None):
    """The intervals of ``iv`` (and their ``names``) that hold no saturated sample; a note per one dropped."""
    if not rec.saturated.any() or not len(iv):
        return iv, names
    c = np.concatenate([[0], np.cumsum(rec.saturated)])
    nsat = c[iv[:, 1]] - c[iv[:, 0]]
    for (s, e), k in zip(iv[nsat > 0], nsat[nsat > 0]):
        notes.append(f"interval {rec.shown_t[s]:.2f}–{rec.shown_t[e - 1]:.2f} s dropped: {k} saturated sample(s)")
    keep = nsat == 0
    return iv[keep], (None if names is None else [nm for nm, ok in zip(names, keep) if ok])


def _samples(rec: Recording, seconds: float, param: str) -> int:
    if not seconds > 0:
        raise InputError(f"`{param}` must be a positive number of seconds, got {seconds}")
    return max(1, int(round(seconds * rec.rate)))


@dataclass
class Detector:
    """The part of detection that does not depend on k: the statistic and the reference variance ς_init."""

    rec: Recording
    window: int
    min_samples: int
    init_samples: int | None  # None: ς_init is the noise floor of the quietest windows
    init_variance: float
    statistic: np.ndarray

    @classmethod
    def of(cls, rec: Recording, window_s: float = 1.0, min_static_s: float = 1.0, init_s: float | None = None):
        w = _samples(rec, window_s, "window_s") | 1
        n_init = _samples(rec, DEFAULT_INIT_S if init_s is None else init_s, "init_s")
        if len(rec) < max(2 * w, n_init + w):
            raise InputError(
                f"{rec.path}: {len(rec)} samples ({rec.duration:.1f} s) are too few for a {window_s:g} s window "
                f"and a {n_init / rec.rate:g} s initial rest; record longer"
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
            if init_s is not None:
                raise InputError(
                    f"{rec.path}: the first {init_s:g} s are not at rest (their variance is "
                    f"{init_var / quiet:.3g} × that of the quietest windows); start the recording "
                    "with the sensor still, or set the rest period with `init_s` (or leave it unset to use "
                    "the quietest windows)"
                )
            floor = float(np.percentile(moving, QUIET_PERCENTILE))
            return cls(rec, w, _samples(rec, min_static_s, "min_static_s"), None, floor, stat)
        if init_var == 0.0:
            init_var = quiet  # a quantised, perfectly still start: the finest variance seen sets the scale
        return cls(rec, w, _samples(rec, min_static_s, "min_static_s"), n_init, init_var, stat)

    def intervals(self, k: float, notes: list[str]) -> np.ndarray:
        static = np.nan_to_num(self.statistic, nan=np.inf) < k * self.init_variance
        iv = runs(static)
        short = iv[:, 1] - iv[:, 0] < self.min_samples
        if short.any():
            notes.append(f"{int(short.sum())} static run(s) shorter than {self.min_samples} samples ignored")
        iv, _ = drop_saturated(self.rec, iv[~short], notes)
        return iv

    def result(self, k: float) -> DetectionResult:
        notes: list[str] = []
        iv = self.intervals(k, notes)
        ref = "initial rest" if self.init_samples is not None else "quietest windows"
        if self.init_samples is None:
            notes.append(f"no rest at the start: ς_init is the noise floor, the {QUIET_PERCENTILE:g}th percentile "
                         "of the variance statistic")
        return DetectionResult(self.rec, iv, "variance", None, self.window, self.min_samples, self.init_samples,
                               self.init_variance, ref, self.statistic, float(k), float(k * self.init_variance),
                               notes)

    def diagnosis(self, k: float, needed: int) -> tuple[str, str]:
        """Why threshold k gives fewer than ``needed`` intervals, and what to change: (counts, advice), for
        :func:`too_few`. Counts: samples set aside as saturated (and the intervals they cost), static runs
        shorter than ``min_static_s``, and runs long enough that stay under :data:`NOISY_FACTOR` times the
        threshold but not under it (too noisy)."""
        thr = k * self.init_variance
        stat = np.nan_to_num(self.statistic, nan=np.inf)
        below = runs(stat < thr)
        lens = below[:, 1] - below[:, 0]
        short = np.sort(lens[lens < self.min_samples])[::-1]
        long_runs = below[lens >= self.min_samples]
        c = np.concatenate([[0], np.cumsum(self.rec.saturated)])
        lost = int(np.sum(c[long_runs[:, 1]] - c[long_runs[:, 0]] > 0)) if len(long_runs) else 0
        found = len(long_runs) - lost
        near = runs(stat < NOISY_FACTOR * thr)
        near = near[near[:, 1] - near[:, 0] >= self.min_samples]
        cs = np.concatenate([[0], np.cumsum(stat < thr)])
        noisy = int(np.sum(cs[near[:, 1]] - cs[near[:, 0]] == 0)) if len(near) else 0
        nsat = int(self.rec.saturated.sum())
        parts = [f"{nsat} sample(s) set aside as saturated"
                 + (f" ({lost} interval(s) dropped)" if lost else ""),
                 f"{len(short)} candidate(s) shorter than `min_static_s` = {self.min_samples / self.rec.rate:g} s"
                 + (f" (the longest {short[0] / self.rec.rate:.2g} s)" if len(short) else ""),
                 f"{noisy} too noisy for the threshold (k = {k:g})"]
        missing = needed - found
        if len(short) >= missing and short[missing - 1] >= 3:
            cut = np.floor(short[missing - 1] / self.rec.rate * 10) / 10
            advice = f"lower `min_static_s` to {max(cut, 0.1):g} s"
        elif lost and found + lost >= needed:
            advice = ("declare the ADC's range with `adc` or `saturation` if those values are not its rails, or "
                      "record within its range")
        elif noisy:
            advice = f"raise `threshold_k` (e.g. to {2 * k:g})"
        else:
            advice = "record more poses, each held still for longer than `min_static_s`"
        return ", ".join(parts), advice


def detect_static(recording: Recording, k: float = 4.0, *, window_s: float = 1.0, min_static_s: float = 1.0,
                  init_s: float | None = None) -> DetectionResult:
    """Static intervals at threshold k·ς_init (Tedaldi et al. 2014, §IV-A); ς_init from the first ``init_s``
    seconds, or without it from a rest at the start or the quietest windows (:class:`Detector`)."""
    if not k > 0:
        raise InputError(f"the threshold multiplier k must be positive, got {k}")
    return Detector.of(recording, window_s, min_static_s, init_s).result(k)


def parse_ks(spec) -> tuple[float, ...]:
    """Threshold multipliers from ``spec``: None (imu_tk's 2…10), a number, a sequence of numbers, or a
    string: one multiplier ``"4"``, a range ``"2:10"`` (integer steps) or a list ``"2,3,5"``."""
    if spec is None:
        return DEFAULT_KS
    try:
        if isinstance(spec, str) and ":" in spec:
            a, b = (float(x) for x in spec.split(":"))
            ks = tuple(float(v) for v in np.arange(a, b + 0.5))
        elif isinstance(spec, str):
            ks = tuple(float(x) for x in spec.split(","))
        else:
            ks = tuple(float(k) for k in np.atleast_1d(spec))
    except (ValueError, TypeError):
        raise InputError(f"`threshold_k` {spec!r}: give a number, a range A:B or a list A,B,C") from None
    if not ks or not min(ks) > 0:
        raise InputError(f"`threshold_k` {spec!r}: multipliers must be positive")
    return ks


def too_few(found: int, model: Model, how: str = "", diagnosis: tuple[str, str] | None = None) -> InputError:
    """The error for fewer static intervals than ``model`` has parameters, with :meth:`Detector.diagnosis`'s
    counts and advice when detection found them."""
    from optcal.core.determination import MIN_DOF  # (on a refusal only: not an import of every read)

    how = f" {how}" if how else ""
    counts, advice = diagnosis or ("", "record more poses, lower `min_static_s`, or use a smaller model (e.g. diag6)")
    # the number the fit's own refusal gives (its parameters and MIN_DOF residual degrees of freedom), so that
    # a user who records that many is not refused again for too few
    return InputError(
        f"found {found} static interval(s){how}, model {model.name} needs at least {model.n_params + MIN_DOF}"
        f"{' (' + counts + ')' if counts else ''}; {advice}"
    )
