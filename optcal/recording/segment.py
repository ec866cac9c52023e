"""Static intervals of a raw recording by change-point segmentation and a rest test (docs/segmentation.md;
docs/design.md §9.2). The default detector; the variance detector of Tedaldi et al. (2014) stays in
:mod:`optcal.recording.detection` (``method="variance"``).

1. **Blocks.** The samples are averaged in blocks of ``b`` samples (``b`` = a fifth of the shortest pose,
   :data:`BLOCKS_PER_POSE`); a block holding a saturated or non-finite sample is set aside and breaks any
   interval there.
2. **Noise, from the recording itself.** Per axis, the white noise σ of the samples and the noise σ_b of
   the block means (which includes flicker noise and hand tremor at the block's time scale) are robust
   estimates from second differences, which cancel a constant rate of turn (a slow tumble cannot pass
   for noise): the 25th percentile of |Δ²|, which lies inside the poses as long as a quarter of the
   recording is at rest, scaled to an SD (for white noise Δ² has SD σ√6, and the 25th percentile of |Δ²|
   is 0.3186·σ√6); neither is allowed below the quantisation step's q/√12.
3. **Change points.** The block means, divided by σ_b, are cut into segments of constant mean by PELT
   with the linear-kernel cost (ruptures' ``KernelCPD``, compiled; Killick, Fearnhead & Eckley, JASA 2012)
   with penalty :data:`PENALTY_PER_DIM`·3·ln(blocks), a BIC-like choice for 3 dimensions of unit noise. A
   step of the outputs (a pose that follows another without motion between them) is a change point like
   the edges of a motion. PELT is quadratic in a segment's length when nothing changes, so the series is
   cut into pieces of at most :data:`PIECE_BLOCKS` blocks first (the cut is healed by step 5).
4. **Rest test, per segment.** A segment is at rest when (a) the spread of its block-mean differences is
   at most :data:`NOISE_RATIO` times the recording's σ_b (no shaking), and (b) in each consecutive test
   window of ``window_s`` inside it the least-squares slope of the block means is not significant:
   Σ_axes (slope/SE)² ≤ :data:`TREND_CHI2` (χ² with 3 degrees of freedom at p = 1e-6), the SE taken with
   the larger of the segment's own and the recording's block noise. A slow continuous rotation is cut by
   PELT into pieces of the length that balances the penalty against a constant's misfit of the ramp,
   L³·r²/12 ≈ pen/2 per piece (slope r per block), so each piece's slope is about √(pen/2) standard errors,
   on the order of the threshold, so (c) each segment is also tested with its contiguous neighbours (both,
   and each one alone): if one straight line through them fits within the noise (residual χ² within :data:`LINE_SIGMAS` SDs
   of its degrees of freedom) and its slope is significant, the segment is a piece of a smooth motion.
   A slow continuous rotation is refused as motion whatever its rate; a pose between steps or motions
   is not on one line with its neighbours.
5. **Merging.** Neighbouring rest segments whose means differ by less than :data:`MERGE_SIGMA` white-noise
   SDs (per axis, as a norm) are joined when the joined segment passes the rest test too: PELT splits a
   rest at a piece boundary or where flicker noise moves its mean; a new pose differs by far more.
6. **Intervals.** A rest segment of at least ``min_static_s`` becomes an interval, less one block at each
   end that borders another segment (a block where a step or a motion starts mixes both sides).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from .detection import DetectionResult
from .reading import Recording

BLOCKS_PER_POSE = 5  # blocks in the shortest pose: the block is a fifth of min_static_s (and ≤ MAX_BLOCK s)
MAX_BLOCK_S = 0.1  # s: blocks never longer (a fifth of 0.5 s, the default shortest pose)
PIECE_BLOCKS = 4096  # PELT runs on pieces of at most this many blocks (quadratic in a piece without change)
PENALTY_PER_DIM = 2.0  # PELT penalty per dimension, in units of ln(blocks): 3 axes → 6·ln(blocks)
NOISE_RATIO = 3.0  # a segment whose block means scatter more than this × the recording's: shaking, not rest
TREND_CHI2 = 30.7  # χ²(3) upper 1e-6 quantile (scipy.stats.chi2.isf(1e-6, 3) = 30.66): a slope is a motion
LINE_SIGMAS = 3.0  # a straight line explains a stretch when its residual χ² is within this many SDs of its dof
MERGE_SIGMA = 1.0  # neighbouring rests closer than this many sample-noise SDs (norm over axes) are one pose
Q25_HALF_NORMAL = 0.31864  # the 25th percentile of |x| for x ~ N(0, 1)
DEFAULT_MIN_STATIC_S = 0.5  # s: the shortest pose found by default
DEFAULT_WINDOW_S = 1.0  # s: the rest test's window
NO_RATE_SAMPLES = 50  # samples: the shortest pose of a recording without a rate (its window: twice that)


@dataclass
class Segmentation:
    """The segments of a recording and what the rest test made of each (blocks of ``block`` samples)."""

    block: int  # samples per block
    window: int  # blocks per rest-test window
    segments: np.ndarray  # (k, 2) [start, end) in blocks
    rest: np.ndarray  # (k,) bool
    reason: np.ndarray  # (k,) str: "", "trend", "noisy"
    sigma: np.ndarray  # (3,) white noise SD of a sample, sensor units
    sigma_block: np.ndarray  # (3,) noise SD of a block mean
    n_bad_blocks: int


def _q25_sd(d2: np.ndarray) -> np.ndarray:
    """Per column, the SD of white noise x from its second differences d2 = x_i − 2x_{i+1} + x_{i+2} (SD
    σ√6), by their 25th percentile of |d2|. Second differences cancel a constant rate of change: a slow
    rotation does not pass for noise."""
    return np.percentile(np.abs(d2), 25.0, axis=0) / (Q25_HALF_NORMAL * np.sqrt(6.0))


def _quantum(N: np.ndarray) -> np.ndarray:
    """Per axis, the smallest non-zero step between consecutive outputs (the quantisation step of a coarse
    ADC; for fine outputs just a small number)."""
    d = np.abs(np.diff(N, axis=0))
    d = np.where(d > 0, d, np.inf)
    q = d.min(axis=0)
    return np.where(np.isfinite(q), q, 0.0)


def _sums(x: np.ndarray) -> np.ndarray:
    """Cumulative sums with a leading zero row, for sums over any [a, b) by difference."""
    return np.concatenate([np.zeros((1,) + x.shape[1:]), np.cumsum(x, axis=0)])


def _rest_test(M: np.ndarray, seg: np.ndarray, w: int) -> np.ndarray:
    """For each segment [a, b) of block means ``M`` (in units of the recording's block noise, so σ_b = 1
    per axis): "" at rest, "noisy" or "trend" (step 4 of the module docstring). Vectorised over segments
    and windows through cumulative sums."""
    k = len(seg)
    out = np.full(k, "", dtype=object)
    if not k:
        return out
    a, b = seg[:, 0], seg[:, 1]
    L = b - a
    # (a) the scatter of the block-mean differences inside each segment, per axis (a ramp's slope is the
    # differences' mean and is left to (b))
    D = np.diff(M, axis=0)
    cD, cD2 = _sums(D), _sums(D * D)
    nd = np.maximum(L - 1, 1)[:, None]
    sD = cD[b - 1] - cD[a]
    sD2 = cD2[b - 1] - cD2[a]
    var_d = np.where(L[:, None] > 2, (sD2 - sD * sD / nd) / np.maximum(nd - 1, 1), sD2 / nd)
    sigma_loc = np.sqrt(np.maximum(var_d, 0.0) / 2.0)  # in units of σ_b
    noisy = (L > 1) & (sigma_loc.max(axis=1) > NOISE_RATIO)
    # (b) windows of w blocks from each segment's start; a remainder shorter than w/2 joins the last window
    nwin = np.maximum(1, np.where(L % w >= (w + 1) // 2, L // w + 1, L // w))
    seg_of = np.repeat(np.arange(k), nwin)
    first = np.concatenate([[0], np.cumsum(nwin)[:-1]])
    j = np.arange(len(seg_of)) - first[seg_of]
    ws = a[seg_of] + j * w
    we = np.where(j == nwin[seg_of] - 1, b[seg_of], ws + w)
    n = (we - ws).astype(float)
    idx = np.arange(len(M), dtype=float)[:, None]
    c0, c1 = _sums(M), _sums(idx * M)
    sy, siy = c0[we] - c0[ws], c1[we] - c1[ws]
    # centred index sums of a window: Σ(i − ī) y = Σ i y − ī Σ y; Σ(i − ī)² = n(n² − 1)/12
    ibar = (ws + we - 1) / 2.0
    sxx = n * (n * n - 1) / 12.0
    ok = n >= 3
    slope = (siy - ibar[:, None] * sy) / np.where(ok, sxx, 1.0)[:, None]
    noise = np.maximum(sigma_loc[seg_of], 1.0)
    z2 = np.sum((slope / noise) ** 2, axis=1) * np.where(ok, sxx, 0.0)
    trend = np.zeros(k, bool)
    np.logical_or.at(trend, seg_of, z2 > TREND_CHI2)
    # (c) a piece of a smooth motion: PELT cuts a ramp into pieces whose own slope stays near √(pen/2)
    # standard errors, so each piece is also tested with its contiguous neighbours: one straight line
    # through the three (χ² of its residuals within noise) with a significant slope is a motion. Poses
    # between steps or motions are not on one line with their neighbours.
    left = np.concatenate([[False], a[1:] == b[:-1]])
    right = np.concatenate([a[1:] == b[:-1], [False]])
    c2 = _sums(M * M)
    for lo, hi in ((np.where(left, np.roll(a, 1), a), np.where(right, np.roll(b, -1), b)),  # both sides
                   (np.where(left, np.roll(a, 1), a), b), (a, np.where(right, np.roll(b, -1), b))):  # one
        trend |= _on_a_line(c0, c1, c2, lo, hi) & ((lo < a) | (hi > b))
    out[trend] = "trend"
    out[noisy & ~trend] = "noisy"
    return out


def _on_a_line(c0, c1, c2, lo, hi) -> np.ndarray:
    """Whether the block means in [lo, hi) (cumulative sums c0, c1, c2 of M, i·M, M²; unit noise) lie on one
    straight line within the noise and its slope is significant (step 4c)."""
    n = (hi - lo).astype(float)
    sy, siy, syy = c0[hi] - c0[lo], c1[hi] - c1[lo], c2[hi] - c2[lo]
    ibar = (lo + hi - 1) / 2.0
    ok = n >= 4
    sxx = np.where(ok, n * (n * n - 1) / 12.0, 1.0)
    sxy = siy - ibar[:, None] * sy
    slope2 = np.sum(sxy * sxy, axis=1) / sxx  # Σ_axes (slope/SE)²
    rss = np.sum(syy - sy * sy / np.maximum(n, 1)[:, None], axis=1) - slope2
    dof = 3 * np.maximum(n - 2, 1)
    return ok & (slope2 > TREND_CHI2) & (rss <= dof + LINE_SIGMAS * np.sqrt(2 * dof))


def _change_points(Z: np.ndarray, good: np.ndarray) -> np.ndarray:
    """Segments [start, end) (blocks) of the good blocks of ``Z`` (normalised block means) by PELT with a
    linear kernel (ruptures' compiled KernelCPD) on pieces of at most :data:`PIECE_BLOCKS` blocks."""
    import ruptures  # here: importing optcal.recording stays light

    d = np.diff(np.concatenate([[0], good.astype(np.int8), [0]]))
    runs = np.column_stack([np.flatnonzero(d == 1), np.flatnonzero(d == -1)])
    pen = PENALTY_PER_DIM * Z.shape[1] * np.log(max(int(good.sum()), 3))
    bounds = []
    for s, e in runs:  # runs of good blocks (one without drops), each cut into pieces
        cuts = np.linspace(s, e, -(-(e - s) // PIECE_BLOCKS) + 1).round().astype(int)
        for ps, pe in zip(cuts[:-1], cuts[1:]):
            if pe - ps < 4:
                bounds.append([ps, pe])
                continue
            bk = ruptures.KernelCPD(kernel="linear", min_size=1, jump=1).fit(Z[ps:pe]).predict(pen=pen)
            edges = np.concatenate([[0], bk]) + ps
            bounds.extend(np.column_stack([edges[:-1], edges[1:]]).tolist())
    return np.array(bounds, dtype=np.int64).reshape(-1, 2)


def _merge(M: np.ndarray, seg: np.ndarray, rest: np.ndarray, w: int, gap_ok: np.ndarray,
           step_norm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Join neighbouring rest segments (step 5): returns the new segments and their rest flags."""
    c = _sums(M)
    means = (c[seg[:, 1]] - c[seg[:, 0]]) / (seg[:, 1] - seg[:, 0])[:, None]
    close = np.linalg.norm((means[1:] - means[:-1]) / step_norm, axis=1) < MERGE_SIGMA
    join = rest[:-1] & rest[1:] & close & (seg[1:, 0] == seg[:-1, 1]) & gap_ok
    if not join.any():
        return seg, rest
    group = np.concatenate([[0], np.cumsum(~join)])
    starts = np.flatnonzero(np.concatenate([[True], ~join]))
    ends = np.concatenate([starts[1:], [len(seg)]])
    merged = np.column_stack([seg[starts, 0], seg[ends - 1, 1]])
    multi = ends - starts > 1
    passes = _rest_test(M, merged, w) == ""
    keep_group = multi & passes  # a joined group that passes replaces its members
    take = keep_group[group]
    out = np.concatenate([merged[keep_group], seg[~take]])
    flags = np.concatenate([np.ones(int(keep_group.sum()), bool), rest[~take]])
    order = np.argsort(out[:, 0], kind="stable")
    return out[order], flags[order]


def segment_recording(rec: Recording, min_static_s: float | None = None,
                      window_s: float | None = None) -> Segmentation:
    """Segments of ``rec`` and their rest flags (steps 1-5 of the module docstring)."""
    N = np.asarray(rec.N, float)
    n = len(N)
    rate = float(rec.rate)
    if np.isfinite(rate) and rate > 0:
        m = _seconds(min_static_s, DEFAULT_MIN_STATIC_S, rate, "min_static_s")
        win = _seconds(window_s, DEFAULT_WINDOW_S, rate, "window_s")
        b = max(1, min(m // BLOCKS_PER_POSE, int(round(MAX_BLOCK_S * rate)) or 1))
    else:  # no rate: sample counts (seconds cannot be converted)
        if min_static_s is not None or window_s is not None:
            raise InputError("`min_static_s` and `window_s` are in seconds, and this recording has no rate; "
                             "give the sample rate with `rate`")
        m, win = NO_RATE_SAMPLES, 2 * NO_RATE_SAMPLES
        b = m // BLOCKS_PER_POSE
    nb = n // b
    if nb < 2 * BLOCKS_PER_POSE or n < m:
        raise InputError(f"{rec.path}: {n} samples are too few to find poses of at least {m} samples; "
                         "record longer, or lower `min_static_s`")
    bad = ~np.isfinite(N).all(axis=1) | np.asarray(rec.saturated, bool)
    Nf = np.where(np.isfinite(N), N, 0.0)
    M = Nf[: nb * b].reshape(nb, b, 3).mean(axis=1)
    good = ~bad[: nb * b].reshape(nb, b).any(axis=1)
    if good.sum() < 2:
        raise InputError(f"{rec.path}: no stretch of {b} samples without a saturated or missing sample; "
                         "record within the sensor's range (or declare its range with `saturation`)")
    # noise from the recording: first differences of good samples and of consecutive good blocks
    ok_pair = ~bad[2:] & ~bad[1:-1] & ~bad[:-2]
    ds = np.diff(Nf, 2, axis=0)[ok_pair]
    q = _quantum(Nf[~bad])
    sigma = np.maximum(_q25_sd(ds) if len(ds) else q, q / np.sqrt(12.0))
    ok_block = good[2:] & good[1:-1] & good[:-2]
    dm = np.diff(M, 2, axis=0)[ok_block]
    sigma_b = np.maximum(_q25_sd(dm) if len(dm) else sigma, sigma / np.sqrt(b))
    if not np.any(sigma > 0) or not np.ptp(Nf[~bad], axis=0).any():
        raise InputError(f"{rec.path}: the outputs never change; this is not a recording of a sensor being turned")
    scale = np.where(sigma_b > 0, sigma_b, np.max(sigma_b))  # an axis that never moves keeps unit scale
    Z = M / scale
    seg = _change_points(Z, good)
    w = max(3, int(round(win / b)))
    reason = _rest_test(Z, seg, w)
    # neighbours are joined only across a cut of PELT's, never across a set-aside block
    gap_ok = seg[1:, 0] == seg[:-1, 1]
    step = np.where(sigma > 0, sigma, np.max(sigma)) / scale  # a sample's noise SD, in block-noise units
    seg2, rest2 = _merge(Z, seg, reason == "", w, gap_ok, step)
    if len(seg2) != len(seg):  # joined groups passed the test; the other segments keep their reasons
        seg, reason = seg2, np.where(rest2, "", _rest_test(Z, seg2, w)).astype(object)
    rest = reason == ""
    return Segmentation(b, w, seg, rest, reason, sigma, sigma_b, int((~good).sum()))


def _seconds(value: float | None, default: float, rate: float, param: str) -> int:
    value = default if value is None else value
    if not (isinstance(value, (int, float)) and np.isfinite(value) and value > 0):
        raise InputError(f"`{param}` must be a positive number of seconds, got {value}")
    return max(3, int(round(value * rate)))


def segment_static(recording: Recording, *, min_static_s: float | None = None,
                   window_s: float | None = None) -> DetectionResult:
    """Static intervals of ``recording`` by change-point segmentation and a rest test (module docstring):
    poses of at least ``min_static_s`` (default 0.5 s) with or without motion between them, each at rest
    within every ``window_s`` (default 1 s) at the recording's own noise level. Fewer intervals than a model
    needs is the caller's to refuse (:func:`segment_diagnosis` says why)."""
    sg = segment_recording(recording, min_static_s, window_s)
    b = sg.block
    rate = float(recording.rate)
    m = (_seconds(min_static_s, DEFAULT_MIN_STATIC_S, rate, "min_static_s") if np.isfinite(rate)
         else NO_RATE_SAMPLES)
    seg, rest = sg.segments, sg.rest
    long_enough = (seg[:, 1] - seg[:, 0]) * b >= m
    keep = rest & long_enough
    iv = seg[keep] * b
    # less one block at each end that borders another segment (not at the recording's ends)
    nb = len(recording) // b
    iv[:, 0] += np.where(seg[keep, 0] > 0, b, 0)
    iv[:, 1] -= np.where(seg[keep, 1] < nb, b, 0)
    if seg[keep, 1].size and seg[keep, 1][-1] == nb:  # the last rest runs to the end: keep the tail samples
        iv[-1, 1] = len(recording)
    iv = iv[iv[:, 1] > iv[:, 0]]
    notes = []
    n_short = int(np.sum(rest & ~long_enough))
    if n_short:
        notes.append(f"{n_short} rest segment(s) shorter than {m} samples ignored")
    moving = ~rest
    if moving.any():
        blocks = int(np.sum((seg[moving, 1] - seg[moving, 0])))
        notes.append(f"{int(moving.sum())} segment(s) ({blocks * b} samples) not at rest: "
                     f"{int(np.sum(sg.reason == 'trend'))} trend, {int(np.sum(sg.reason == 'noisy'))} too noisy")
    if sg.n_bad_blocks:
        notes.append(f"{sg.n_bad_blocks} block(s) of {b} samples set aside (saturated or missing samples)")
    res = DetectionResult(recording, iv.astype(np.int64), "segment", None, sg.window * b, m, notes=notes)
    res.noise = sg.sigma
    res.block = b
    res.segmentation = sg
    return res


def segment_diagnosis(det: DetectionResult, needed: int) -> tuple[str, str]:
    """Why segmentation found fewer than ``needed`` intervals, and what to do: (counts, advice) for
    :func:`optcal.recording.detection.too_few`. A recording in which no segment long enough is at rest
    (a continuous rotation) is said to be one."""
    sg: Segmentation = det.segmentation
    rec = det.recording
    b = sg.block
    L = (sg.segments[:, 1] - sg.segments[:, 0]) * b
    rate = float(rec.rate)
    sec = (lambda s: f"{s / rate:.3g} s") if np.isfinite(rate) else (lambda s: f"{s} samples")
    trend = sg.reason == "trend"
    noisy = sg.reason == "noisy"
    short_rest = sg.rest & (L < det.min_samples)
    moving_s = int(L[~sg.rest].sum())
    counts = (f"{int(trend.sum())} segment(s) trend (the outputs drift: the sensor turns), {int(noisy.sum())} "
              f"shake beyond {NOISE_RATIO:g} × the noise, {int(short_rest.sum())} at rest but shorter than "
              f"`min_static_s` = {sec(det.min_samples)}, {sec(sg.n_bad_blocks * b)} set aside as saturated "
              "or missing")
    if det.n_intervals == 0 and moving_s >= 0.9 * len(rec):
        advice = ("no part of the recording is at rest (the outputs change throughout: a continuous rotation); "
                  "record poses held still for at least `min_static_s`, or give the intervals with `intervals`")
    elif short_rest.sum() >= needed - det.n_intervals and short_rest.any():
        advice = f"lower `min_static_s` to {max(np.floor(L[short_rest].max() / max(rate, 1e-9) * 10) / 10, 0.1):g} s" \
            if np.isfinite(rate) else "lower `min_static_s`"
    else:
        advice = ("record more poses, each held still for longer than `min_static_s`, or use the variance "
                  "detector (`method` variance) or intervals given with `intervals`")
    return counts, advice
