"""Rests labelled independently of the detectors, and detections scored against them (issue #29, item 8).

**Labels from the gyroscope's stillness** (:func:`gyro_labels`). The gyroscope sees a turn hundreds of times
above its noise, where the accelerometer sees the gravity direction move by about its noise; its stillness is
the benchmark's truth on real recordings. "Still" means the sensor's attitude stays put within a few tenths of
a degree: a hand's tremor (8-12 Hz, rates up to a few °/s but a few hundredths of a degree) and its wobble in a
hand-held pose (a tenth or two of a degree) are not motion; a turn, a settling after it and a slow drift are.

1. *Bias*, from the quietest stretches: the recording is cut into blocks of :data:`BLOCK_S`; the blocks whose
   scatter (the sum of the three axes' variances) is at most :data:`QUIET_RATIO` times its
   :data:`QUIET_PERCENTILE`-th percentile are quiet; the bias is, per axis, the median of the quiet blocks'
   medians.
2. *White noise*, per axis, from the first differences inside the quiet blocks (the median absolute
   difference, then the RMS of the differences within 4 of its SDs), never below the quantisation step's
   q/√12.
3. *Motions*: the rate (bias removed) averaged over :data:`SMOOTH_S` (a tremor averages out) whose χ² in
   noise units is above :data:`CHI2_CORE` (χ²(3) at p = 10⁻⁸) and whose norm is above :data:`FAST_DPS`, or
   averaged over :data:`CORE_S` (a wobble averages out) with χ² above the same and a norm above
   :data:`CORE_DPS`, is a motion's core; saturated and missing samples too. A motion extends from its core
   while the rate averaged over :data:`SMOOTH_S` stays significant (χ² > :data:`CHI2_GROW`, p = 10⁻²) and
   above :data:`GROW_DPS`.
4. *Margins*: the motions are dilated by :data:`SETTLE_MARGIN_S` after them (a settling fades under the
   noise) and ``margin_s`` (default :data:`MARGIN_S`) before them; a still run shorter than :data:`FILL_S`
   between two motions is part of them (an oscillation turning back).
5. *Slow motions*: in each still run, the attitude (the rate integrated, the run's median rate removed) is
   compared with its median over pieces of at most :data:`CHUNK_S`; a sample off it by more than
   :data:`SLOW_DEG` and :data:`SLOW_SIGMAS` times the walk of the integrated white noise over the piece moves;
   so does the centre of a window of :data:`WINDOWS_S` inside the run over which the attitude (the means of its
   first and last quarters) turns by as much (the middle of a slow turn, near the median). But an excursion of
   at most :data:`SMOOTH_S` (one period of a tremor) after which the attitude, over up to :data:`LEVEL_S` either
   side (medians of at least :data:`SMOOTH_S`), is back within :data:`SLOW_DEG` is a wobble and stays still, as
   a knock does in step 6: a rest is not split where its pose comes back. Step 4's filling follows again. The
   run's median rate is removed because a rate offset that changes with the pose (a gyroscope's
   g-sensitivity: 0.05-0.2 °/s on imu_tk's Xsens, where the accelerometer shows no turn) is not a turn; nor,
   to a gyroscope alone, is a turn at one constant rate through a whole rest.
6. *Re-seats without motion* (with the accelerometer): a still run is split where the accelerometer's outputs
   step, i.e. the medians of :data:`STEP_SAMPLES` samples (at least 0.05 s) before and after a sample differ
   by χ² > :data:`CHI2_STEP` in units of that difference's own robust scatter inside the still runs (a
   median ignores a single-sample spike); the split is at the largest step. Steps less than :data:`LEVEL_S`
   apart are one disturbance, which splits the run only when it lasts: the levels (medians over up to
   :data:`LEVEL_S`) before and after it differ by as much. A knock steps out and back and leaves the pose
   where it was. The gyroscope sees nothing of a sensor re-seated while logging paused, or of a recording cut
   and joined.

The rests are the still runs, split at steps. The thresholds are set so that noise alone never moves a
sample, so a labelled rest can be trusted to be still; its ends are conservative (a few hundredths of a second
inside the true rest before a motion, a tenth or more after one).

**Labels from a source's intervals** (:func:`interval_labels`): the rests are the source's intervals (its
static sections, the parts of its label column, a re-run of its own detector, the logger's blocks). Those are
often shorter than the true rests (people choose sections inside their poses), so the samples outside them
cannot all be called moving. Which samples are still, for precision: the gyroscope's labels where the
recording has a gyroscope; otherwise a **conservative** rule that calls moving only what surely moved: in
each gap between two intervals, the samples from the first to the last whose output lies off both neighbouring
intervals' means by χ² > :data:`CHI2_OFF_POSE` in units of the output noise (measured inside the intervals);
the rest of the gap, near a pose and within its noise, counts as still; before the first interval and after
the last, where only one pose is known, nothing is counted as moving. A precision by this rule is an upper
bound of the precision against the true stillness; against gyroscope labels it is the measured one.

**Scores** (:func:`score_rests`):

- *recall*: the fraction of labelled rests at least ``min_static`` samples long that are recalled. Each kept
  interval is attributed to the one labelled rest it overlaps most; a labelled rest is recalled when the kept
  intervals attributed to it cover at least half of it. (An interval that joins two labelled rests counts for
  one of them: short rests back to back must stay apart.)
- *precision by sample*: the fraction of the samples inside kept intervals that are labelled still (all still
  samples, in rests of any length).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from optcal.core.errors import InputError
from optcal.core.recording.detection import chunks, group_medians, range_rows, runs
from optcal.core.recording.reading import Recording

BLOCK_S = 0.25  # s: blocks for the quiet stretches (bias, noise)
QUIET_PERCENTILE = 20.0  # the blocks' scatter percentile that is the reference of quiet
QUIET_RATIO = 2.5  # a block is quiet when its scatter is at most this × that percentile
SMOOTH_S = 0.1  # s: the rate is averaged over this (centred), about one period of a hand's tremor
CORE_S = 0.25  # s: and over this (a hand's wobble at a few Hz)
CHI2_CORE = 40.0  # χ²(3) upper 10⁻⁸ quantile (scipy.stats.chi2.isf(1e-8, 3) = 40.0): the mean rate moves
FAST_DPS = 3.0  # °/s: ... and its norm over SMOOTH_S is above this (a tremor's, averaged, stays below)
CORE_DPS = 1.0  # °/s: ... or its norm over CORE_S is above this (a hand's wobble, averaged, stays below)
CHI2_GROW = 11.3  # χ²(3) upper 10⁻² quantile: a motion extends over its neighbours while above this
GROW_DPS = 0.5  # °/s: ... and above this
WINDOWS_S = (0.5, 1.0)  # s: windows whose centre moves when they turn by as much
CHUNK_S = 4.0  # s: a still run's attitude is compared with its median over pieces of at most this
SLOW_DEG = 0.2  # °: a sample off that median by more than this moves (a hand's wobble stays within it)
SLOW_SIGMAS = 5.0  # ... and by more than this × the walk of the integrated white noise over the piece
SETTLE_MARGIN_S = 0.1  # s: moving samples dilated by this after a motion (a settling fades under the noise)
MARGIN_S = 0.03  # s: and by this before one (at least one sample each)
FILL_S = 0.25  # s: a still run shorter than this between motions moves (an oscillation turning back)
LEVEL_S = 1.0  # s: a step lasts when the levels over up to this either side of it differ (a knock comes back)
STEP_SAMPLES = 5  # samples each side whose medians are compared for a step of the accelerometer
CHI2_STEP = 60.0  # a step of the accelerometer's outputs (χ² of the median difference in noise units)
CHI2_OFF_POSE = 30.7  # χ²(3) upper 10⁻⁶ quantile: a sample off a pose's mean (interval labels without a gyro)
STEADY_SAMPLES = 2 * STEP_SAMPLES  # samples: a change of the outputs moves this window around it (a stretch
# off both poses without such a change is a pause)
MAD_SD = 1.4826  # SD of a normal variable per median absolute deviation


@dataclass
class RestLabels:
    """Labelled rests of a recording: which samples are still, and the rests as intervals."""

    still: np.ndarray  # (n,) bool: labelled still (precision counts the kept samples outside it as moving)
    rests: np.ndarray  # (k, 2) int [start, end): the labelled rests (recall)
    source: str  # what the labels come from
    info: dict = field(default_factory=dict)  # gyroscope: bias, noise (units), thresholds; steps split

    @property
    def n(self) -> int:
        return len(self.still)


def _cover(iv: np.ndarray, n: int) -> np.ndarray:
    """(n,) bool: the samples inside any of the intervals ``iv``."""
    iv = np.clip(np.asarray(iv, np.int64).reshape(-1, 2), 0, n)
    d = np.zeros(n + 1, np.int64)
    np.add.at(d, iv[:, 0], 1)
    np.add.at(d, iv[:, 1], -1)
    return np.cumsum(d)[:n] > 0


def _dilate(mask: np.ndarray, before: int, after: int | None = None) -> np.ndarray:
    """``mask`` dilated by ``before`` samples before each True sample and ``after`` (default the same)
    after it."""
    after = before if after is None else after
    if (before <= 0 and after <= 0) or not mask.any():
        return mask.copy()
    c = np.concatenate([[0], np.cumsum(mask)])
    n = len(mask)
    i = np.arange(n)
    return c[np.minimum(i + before + 1, n)] - c[np.maximum(i - after, 0)] > 0


def _quantum(X: np.ndarray) -> np.ndarray:
    d = np.abs(np.diff(X, axis=0))
    d = np.where(d > 0, d, np.inf)
    q = d.min(axis=0)
    return np.where(np.isfinite(q), q, 0.0)


def _white_sd(d: np.ndarray, X: np.ndarray) -> np.ndarray:
    """Per column, the white noise SD of a sample from first differences ``d`` (SD σ√2): the median absolute
    difference sets a cut at 4 SDs, inside which the RMS is the estimate; at least q/√12 of ``X``."""
    floor = _quantum(X) / np.sqrt(12.0)
    if not len(d):
        return floor
    s0 = np.maximum(MAD_SD * np.median(np.abs(d), axis=0) / np.sqrt(2.0), floor)
    inside = np.abs(d) <= 4.0 * np.sqrt(2.0) * np.maximum(s0, 1e-300)
    ms = np.sum(np.where(inside, d * d, 0.0), axis=0) / np.maximum(inside.sum(axis=0), 1)
    return np.maximum(np.sqrt(ms / 2.0), floor)


def _quiet_blocks(X: np.ndarray, ok: np.ndarray, b: int):
    """Block medians and a quiet flag per block of ``b`` samples (blocks with a bad sample are not quiet),
    and the per-sample flag of lying in a quiet block."""
    n = len(X)
    nb = n // b
    B = X[: nb * b].reshape(nb, b, 3)
    good = ok[: nb * b].reshape(nb, b).all(axis=1)
    scatter = np.where(good, np.nanvar(np.where(good[:, None, None], B, 0.0), axis=1).sum(axis=1), np.inf)
    if not good.any():
        raise InputError("no stretch of the gyroscope's samples is finite and unsaturated")
    ref = np.percentile(scatter[good], QUIET_PERCENTILE)
    quiet = good & (scatter <= QUIET_RATIO * ref)
    if not quiet.any():  # every block equal (a constant output): all quiet
        quiet = good
    med = np.median(np.where(good[:, None, None], B, 0.0), axis=1)
    in_quiet = np.zeros(n, bool)
    in_quiet[: nb * b] = np.repeat(quiet, b)
    return med, quiet, in_quiet


def _centred_mean(X: np.ndarray, L: int) -> np.ndarray:
    """Per column, the mean of the L samples centred on each sample (fewer at the ends)."""
    if L <= 1:
        return X.copy()
    n = len(X)
    c = np.concatenate([np.zeros((1, X.shape[1])), np.cumsum(X, axis=0)])
    i = np.arange(n)
    lo = np.clip(i - L // 2, 0, n)
    hi = np.clip(lo + L, 0, n)
    return (c[hi] - c[lo]) / (hi - lo)[:, None]


def _run_medians(X: np.ndarray, r: np.ndarray) -> np.ndarray:
    """(n, 3): per column, the median of ``X`` over the run [start, end) of ``r`` each sample lies in; 0
    outside the runs."""
    out = np.zeros_like(X)
    rows, which = range_rows(r)
    out[rows] = group_medians(X, r)[which]
    return out


def _fill(still: np.ndarray, length: float) -> np.ndarray:
    """The still runs shorter than ``length`` samples between two moving samples."""
    r = runs(still)
    return _cover(r[(r[:, 1] - r[:, 0] < length) & (r[:, 0] > 0) & (r[:, 1] < len(still))], len(still))


def _turning_windows(Phi: np.ndarray, still: np.ndarray, L: int, thr: float) -> np.ndarray:
    """The centres of the windows of ``L`` samples inside one still run over which the attitude ``Phi`` (°)
    turns by more than ``thr``: between the means over the window's first and last quarters (a tremor
    averages out)."""
    n = len(Phi)
    if n < L:
        return np.zeros(n, bool)
    cp = np.concatenate([np.zeros((1, 3)), np.cumsum(Phi, axis=0)])
    cs = np.concatenate([[0], np.cumsum(still)])
    i = np.arange(n - L + 1)
    q = L // 4
    angle = np.linalg.norm((cp[i + L] - cp[i + L - q]) - (cp[i + q] - cp[i]), axis=1) / q
    out = np.zeros(n, bool)
    out[i[(cs[i + L] - cs[i] == L) & (angle > thr)] + L // 2] = True
    return out


def _wobbles_back(slow: np.ndarray, moving: np.ndarray, Phi: np.ndarray, short: int, L: int) -> np.ndarray:
    """``slow`` less its excursions that come back: a run of at most ``short`` samples inside a still run whose
    attitude ``Phi`` (°) over up to ``L`` still samples after it is within :data:`SLOW_DEG` of that before it
    (medians, not beyond the neighbouring excursions, and over at least ``short`` samples each) is a wobble,
    not a motion (step 5)."""
    n = len(slow)
    r = runs(slow)
    clean = runs(~moving & ~slow)
    if not len(r) or not len(clean):
        return slow
    # the clean stretch that ends where an excursion starts, and the one that starts where it ends
    i = np.searchsorted(clean[:, 1], r[:, 0])
    j = np.searchsorted(clean[:, 0], r[:, 1])
    i, j = np.minimum(i, len(clean) - 1), np.minimum(j, len(clean) - 1)
    ok = ((r[:, 1] - r[:, 0] <= short) & (r[:, 0] > 0) & (r[:, 1] < n)
          & (clean[i, 1] == r[:, 0]) & (clean[j, 0] == r[:, 1])
          & (r[:, 0] - clean[i, 0] >= short) & (clean[j, 1] - r[:, 1] >= short))
    if not ok.any():
        return slow
    r, i, j = r[ok], i[ok], j[ok]
    before = group_medians(Phi, np.column_stack([np.maximum(clean[i, 0], r[:, 0] - L), r[:, 0]]))
    after = group_medians(Phi, np.column_stack([r[:, 1], np.minimum(clean[j, 1], r[:, 1] + L)]))
    back = np.linalg.norm(after - before, axis=1) < SLOW_DEG
    out = slow.copy()
    out[_cover(r[back], n)] = False
    return out


def _acc_steps(N: np.ndarray, still: np.ndarray, k: int, level: int) -> np.ndarray:
    """Samples s inside still runs at which the accelerometer steps: the medians of N[s−k:s] and N[s:s+k]
    differ by χ² > CHI2_STEP in units of that difference's own scatter inside the still runs (robust: most
    boundaries are not steps; measured, not assumed, as a sensor's filter correlates its noise); one per run of
    such samples, at its largest."""
    n = len(N)
    if n < 2 * k + 1:
        return np.zeros(0, np.int64)
    ok = np.isfinite(N).all(axis=1)
    Nf = np.where(ok[:, None], N, 0.0)
    med = np.median(np.lib.stride_tricks.sliding_window_view(Nf, k, axis=0), axis=2)  # med[j]: N[j:j+k]
    s = np.arange(k, n - k + 1)  # the boundary before sample s: medians of [s−k, s) and [s, s+k)
    diff = med[s] - med[s - k]
    cs = np.concatenate([[0], np.cumsum(still & ok)])
    inside = cs[s + k] - cs[s - k] == 2 * k
    if inside.sum() < 10:
        return np.zeros(0, np.int64)
    sd = MAD_SD * np.median(np.abs(diff[inside] - np.median(diff[inside], axis=0)), axis=0)
    sd = np.maximum(sd, _quantum(Nf[ok]) / np.sqrt(6.0))
    sd = np.where(sd > 0, sd, np.inf)
    chi = np.sum((diff / sd) ** 2, axis=1)
    hit = inside & (chi > CHI2_STEP)
    if not hit.any():
        return np.zeros(0, np.int64)
    j = np.flatnonzero(hit)
    grp = np.cumsum(np.diff(np.concatenate([[-2], j])) > 1) - 1  # runs of consecutive hits
    order = np.lexsort((-chi[j], grp))
    _, first = np.unique(grp[order], return_index=True)
    return _lasting(Nf, still, s[j[order[first]]].astype(np.int64), sd, level)


def _lasting(N: np.ndarray, still: np.ndarray, at: np.ndarray, sd: np.ndarray, L: int) -> np.ndarray:
    """The steps ``at`` after which the outputs stay at a new level. Steps of one still run less than ``L``
    samples apart are one disturbance; it lasts when the medians of up to ``L`` still samples before its first
    step and after its last (not beyond the neighbouring disturbances or the run's ends) differ by χ² >
    CHI2_STEP in units ``sd`` (the step test's own). A knock that shakes the sensor and leaves it where it was
    (a rocket board tapped on its bench) steps out and back: its steps are dropped; a re-seat keeps them all."""
    if not len(at):
        return at
    r = runs(still)
    run = np.searchsorted(r[:, 0], at, side="right") - 1
    new = np.concatenate([[True], (run[1:] != run[:-1]) | (np.diff(at) >= L)])  # a disturbance's first step
    group = np.cumsum(new) - 1
    first, last = at[new], at[np.concatenate([new[1:], [True]])]
    grun = run[new]
    same_prev = np.concatenate([[False], grun[1:] == grun[:-1]])
    same_next = np.concatenate([grun[:-1] == grun[1:], [False]])
    lo = np.where(same_prev, np.concatenate([[0], last[:-1]]), r[grun, 0])
    hi = np.where(same_next, np.concatenate([first[1:], [0]]), r[grun, 1])
    j = np.arange(L)
    before = first[:, None] - 1 - j[None, :]
    after = last[:, None] + j[None, :]
    left = np.where((before >= lo[:, None])[..., None], N[np.clip(before, 0, len(N) - 1)], np.nan)
    right = np.where((after < hi[:, None])[..., None], N[np.clip(after, 0, len(N) - 1)], np.nan)
    diff = np.nanmedian(right, axis=1) - np.nanmedian(left, axis=1)
    return at[(np.sum((diff / sd) ** 2, axis=1) > CHI2_STEP)[group]]


def _split(rests: np.ndarray, at: np.ndarray) -> np.ndarray:
    """``rests`` cut at the samples ``at`` (each a new rest's start)."""
    if not len(at) or not len(rests):
        return rests
    inside = (at[:, None] > rests[None, :, 0]) & (at[:, None] < rests[None, :, 1])
    at = at[inside.any(axis=1)]
    starts = np.sort(np.concatenate([rests[:, 0], at]))
    ends = np.sort(np.concatenate([rests[:, 1], at]))
    return np.column_stack([starts, ends]).astype(np.int64)


def gyro_labels(gyro: Recording, acc: Recording | None = None, *, units_per_dps: float = 1.0,
                margin_s: float | None = None) -> RestLabels:
    """Rests labelled by the gyroscope's stillness (module docstring, steps 1-6). ``gyro.N`` holds the rates
    in any units, ``units_per_dps`` of them per °/s (1 for °/s, π/180 for rad/s, the sensitivity for counts;
    only the floors use it); ``acc``, at the same samples, splits rests where its outputs step.
    ``margin_s``: the dilation of the moving samples (default :data:`MARGIN_S`)."""
    W = np.asarray(gyro.N, float)
    n = len(W)
    rate = float(gyro.rate)
    if not (np.isfinite(rate) and rate > 0):
        raise InputError("the gyroscope's labels need the sample rate")
    if not (units_per_dps > 0):
        raise InputError("`units_per_dps` must be positive")
    if acc is not None and len(acc) != n:
        raise InputError(f"the accelerometer has {len(acc)} samples and the gyroscope {n}")
    sat = np.asarray(gyro.saturated, bool) if gyro.saturated is not None else np.zeros(n, bool)
    ok = np.isfinite(W).all(axis=1) & ~sat
    b = max(3, int(round(BLOCK_S * rate)))
    if n < 2 * b:
        raise InputError(f"{n} gyroscope samples are too few to label")
    med, quiet, in_quiet = _quiet_blocks(W, ok, b)
    bias = np.median(med[quiet], axis=0)
    pair = in_quiet[1:] & in_quiet[:-1]
    Wf = np.where(ok[:, None], W, bias)
    sigma = _white_sd(np.diff(Wf, axis=0)[pair], Wf[in_quiet])
    sigma = np.where(sigma > 0, sigma, np.max(sigma) if np.max(sigma) > 0 else 1.0)
    R = (Wf - bias) / units_per_dps  # °/s, bias removed
    Z = (Wf - bias) / sigma  # in units of the white noise
    # 3. motions: the rate averaged over SMOOTH_S and over CORE_S (a tremor's oscillation averages out)
    Ls = max(1, int(round(SMOOTH_S * rate)))
    Lc = max(1, int(round(CORE_S * rate)))
    mr, mz = _centred_mean(R, Ls), _centred_mean(Z, Ls)
    chi = Ls * np.sum(mz * mz, axis=1)
    speed = np.linalg.norm(mr, axis=1)
    mrc, mzc = _centred_mean(R, Lc), _centred_mean(Z, Lc)
    chic = Lc * np.sum(mzc * mzc, axis=1)
    speedc = np.linalg.norm(mrc, axis=1)
    core = ((chi > CHI2_CORE) & (speed > FAST_DPS)) | ((chic > CHI2_CORE) & (speedc > CORE_DPS)) | ~ok
    grow = ((chi > CHI2_GROW) & (speed > GROW_DPS)) | core
    g = runs(grow)
    c = np.concatenate([[0], np.cumsum(core)])
    moving = _cover(g[c[g[:, 1]] > c[g[:, 0]]], n)
    # 4. margins, and still runs too short to be a rest (an oscillation's turning points) filled
    m = max(1, int(round((MARGIN_S if margin_s is None else margin_s) * rate)))
    m_after = max(1, int(round(SETTLE_MARGIN_S * rate)))
    moving = _dilate(moving, m, m_after)
    moving |= _fill(~moving, FILL_S * rate)
    # 5. slow motions: in each still run, the attitude (the rate integrated, the run's median rate removed)
    # off its median over the piece of at most CHUNK_S around it. A rate offset that changes with the pose (a
    # gyroscope's g-sensitivity) is not a turn; nor, to a gyroscope, is a turn at one constant rate through
    # a whole rest, which only the accelerometer could tell.
    r = runs(~moving)
    slow = np.zeros(n, bool)
    if len(r):
        Rl = R - _run_medians(R, r)
        Phi = np.cumsum(Rl, axis=0) / rate  # °
        pieces = chunks(r, max(4, int(round(CHUNK_S * rate))))
        dev = np.linalg.norm(Phi - _run_medians(Phi, pieces), axis=1)
        size = pieces[:, 1] - pieces[:, 0]
        walk = np.linalg.norm(sigma / units_per_dps) / rate * np.sqrt(size / 4.0)  # °: the noise's walk
        thr = np.zeros(n)
        thr[_cover(pieces, n)] = np.repeat(np.maximum(SLOW_DEG, SLOW_SIGMAS * walk), size)
        slow = ~moving & (dev > thr)
        # ... and the middle of a slow turn inside a run: the centre of a window that turns
        noise = np.linalg.norm(sigma / units_per_dps) / rate
        for L in sorted({max(8, int(round(w * rate))) for w in WINDOWS_S}):
            slow |= _turning_windows(Phi, ~moving, L, max(SLOW_DEG, SLOW_SIGMAS * noise * np.sqrt(L / 4.0)))
        slow = _wobbles_back(slow, moving, Phi, int(round(SMOOTH_S * rate)), int(round(LEVEL_S * rate)))
    moving |= slow
    moving |= _fill(~moving, FILL_S * rate)
    still = ~moving
    rests = runs(still)
    steps = np.zeros(0, np.int64)
    if acc is not None:
        k = max(STEP_SAMPLES, int(round(0.05 * rate)))
        steps = _acc_steps(np.asarray(acc.N, float), still, k, max(k, int(round(LEVEL_S * rate))))
        rests = _split(rests, steps)
    info = {"bias": bias, "noise": sigma, "units_per_dps": units_per_dps, "margin": m, "steps": steps,
            "moving_samples": int(moving.sum()), "slow_motion_samples": int(slow.sum())}
    return RestLabels(still, rests, "gyroscope", info)


def interval_labels(intervals, n: int, *, still: np.ndarray | None = None, outputs: np.ndarray | None = None,
                    source: str = "source intervals") -> RestLabels:
    """Rests labelled by a source's own intervals ([start, end) samples). Which samples are still (for
    precision): ``still`` (the gyroscope's labels) when given; else, from the recording's ``outputs`` (n, 3),
    the conservative rule of the module docstring; with neither, the intervals alone."""
    iv = np.asarray(intervals, np.int64).reshape(-1, 2)
    iv = iv[np.argsort(iv[:, 0], kind="stable")]
    iv = np.clip(iv, 0, n)
    iv = iv[iv[:, 1] > iv[:, 0]]
    if still is not None:
        mask = np.asarray(still, bool)
        how = "gyroscope"
    elif outputs is not None:
        mask = ~_off_pose(iv, np.asarray(outputs, float), n)
        how = "off-pose (conservative)"
    else:
        mask = _cover(iv, n)
        how = "intervals"
    return RestLabels(mask, iv, source, {"still_from": how})


def _off_pose(iv: np.ndarray, N: np.ndarray, n: int) -> np.ndarray:
    """(n,) bool: the samples that surely moved, between intervals ``iv`` (conservative rule)."""
    inside = _cover(iv, n)
    ok = np.isfinite(N).all(axis=1)
    Nf = np.where(ok[:, None], N, 0.0)
    k = len(iv)
    if not k:
        return np.zeros(n, bool)
    c = np.concatenate([np.zeros((1, 3)), np.cumsum(Nf, axis=0)])
    means = (c[iv[:, 1]] - c[iv[:, 0]]) / (iv[:, 1] - iv[:, 0])[:, None]
    which = np.searchsorted(iv[:, 0], np.arange(n), "right") - 1  # the interval at or before each sample
    res = Nf - means[np.clip(which, 0, k - 1)]
    sigma = _white_sd(np.diff(Nf, axis=0)[inside[1:] & inside[:-1]], Nf[inside])
    sigma = np.where(sigma > 0, sigma, 1.0)
    # scatter about the means inside the intervals (includes a hand's tremor and wander), if larger
    sd_in = MAD_SD * np.median(np.abs(res[inside]), axis=0) if inside.any() else sigma
    sigma = np.maximum(sigma, sd_in)
    prev = np.clip(which, 0, k - 1)
    nxt = np.clip(which + 1, 0, k - 1)
    d_prev = np.sum(((Nf - means[prev]) / sigma) ** 2, axis=1)
    d_next = np.sum(((Nf - means[nxt]) / sigma) ** 2, axis=1)
    # gap index: the interval it precedes (0 before the first, k after the last: one pose known, not counted)
    gap = np.where(inside, -1, np.clip(which + 1, 0, k))
    off = ~inside & (gap > 0) & (gap < k) & ((d_prev > CHI2_OFF_POSE) & (d_next > CHI2_OFF_POSE) | ~ok)
    # a sample off both poses surely moved unless it lies in a steady stretch: the sensor may pause at a pose
    # the source did not use (an intermediate rest), and that pause is not surely moving. Steady: the medians
    # of STEP_SAMPLES samples before and after it agree (χ² ≤ CHI2_OFF_POSE in units of their difference's
    # SD), over the whole run of STEADY_SAMPLES samples around it
    h = STEP_SAMPLES
    pad = np.pad(Nf, ((h, h), (0, 0)), mode="edge")
    win = np.lib.stride_tricks.sliding_window_view(pad, h, axis=0)  # (n + h + 1, 3, h)
    med = np.median(win, axis=2)
    change = np.sum(((med[h:h + n] - med[:n]) / (sigma * np.sqrt(np.pi / h))) ** 2, axis=1) > CHI2_OFF_POSE
    moving_near = _dilate(change, STEADY_SAMPLES // 2)
    return off & (moving_near | ~ok)


def score_rests(found, labels: RestLabels, *, min_static: int = 1) -> dict:
    """Recall of ``labels``' rests of at least ``min_static`` samples and precision by sample of the kept
    intervals ``found`` ([start, end) samples), by the rules of the module docstring."""
    n = labels.n
    found = np.clip(np.asarray(found, np.int64).reshape(-1, 2), 0, n)
    found = found[found[:, 1] > found[:, 0]]
    rests = labels.rests[(labels.rests[:, 1] - labels.rests[:, 0]) >= min_static]
    kept = _cover(found, n)
    n_kept = int(kept.sum())
    moving_kept = int((kept & ~labels.still).sum())
    precision = 1.0 - moving_kept / n_kept if n_kept else float("nan")
    recalled = np.zeros(len(rests), bool)
    if len(rests) and len(found):
        # every kept interval against every labelled rest (of any length: an interval on a short rest is
        # attributed to it, not to a long neighbour)
        allr = labels.rests
        ov = np.clip(np.minimum(found[:, None, 1], allr[None, :, 1])
                     - np.maximum(found[:, None, 0], allr[None, :, 0]), 0, None)
        best = np.argmax(ov, axis=1)
        has = ov[np.arange(len(found)), best] > 0
        covered = np.zeros(len(allr), np.int64)
        np.add.at(covered, best[has], ov[np.arange(len(found)), best][has])
        long = (allr[:, 1] - allr[:, 0]) >= min_static
        recalled = 2 * covered[long] >= (allr[long, 1] - allr[long, 0])
    return {"n_labelled": len(rests), "n_found": len(found), "n_recalled": int(recalled.sum()),
            "recall": float(recalled.mean()) if len(rests) else float("nan"), "precision": precision,
            "kept_samples": n_kept, "moving_kept_samples": moving_kept}
