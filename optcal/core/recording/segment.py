"""Static intervals of a raw recording by change-point segmentation and a rest test (docs/segmentation.md;
docs/design.md, "Raw recordings"). The default detector; the variance detector of Tedaldi et al. (2014) stays in
:mod:`optcal.core.recording.detection` (``method="variance"``). No model is fitted.

1. **Blocks.** The samples are averaged in blocks of ``b`` samples (an eighth of the shortest pose,
   :data:`BLOCKS_PER_POSE`, at most :data:`MAX_BLOCK_S`); a block holding a saturated or non-finite sample
   is set aside and breaks any interval there.
2. **Noise, from the recording itself** (:func:`_noise_sd`): per axis, the white noise SD of a sample and
   of a block mean from second differences, which cancel a constant rate of turn (a slow tumble does not
   pass for noise), over the quiet part of the recording; never below the quantisation step's q/√12. The
   same over means of 2, 4, 8, … blocks gives the slow-noise excess per scale (:func:`_slow_noise_excess`).
3. **Change points** (:func:`_change_points`): the block means in units of their noise are cut into
   segments of constant mean by PELT (Killick, Fearnhead & Eckley, JASA 2012) with ruptures' compiled
   linear-kernel cost, penalty :data:`PENALTY`, on pieces of at most :data:`PIECE_BLOCKS` blocks (PELT is
   quadratic in a stretch without change). A step of the outputs is a change point like a motion's edge.
4. **Rest test** (:func:`_rest_test`, :func:`_continues_motion`): (a) the block differences scatter at most
   :data:`NOISE_RATIO` × the recording's; (b) in every window of up to ``window_s`` the slope is not a
   motion, i.e. not both significant (χ² > :data:`TREND_CHI2` against the larger of the window's own
   scatter and the slow-noise excess at its scale) and larger than :data:`DRIFT_SIGMAS` sample SDs across
   the window; (c) the segment does not continue a straight motion into a touching neighbour. PELT cuts a
   steady turn into pieces whose own slope is only about √(pen/2) standard errors (each balances the
   penalty against a constant's misfit of the ramp, L³r²/12 ≈ pen/2); (c) sees the turn through them.
5. **Merging** (:func:`_merge`): neighbouring rests closer than :data:`MERGE_SIGMA` sample SDs are joined
   when the joined segment passes the rest test.
6. **Intervals** (:func:`segment_static`): a rest of at least ``min_static_s`` (counting its two end blocks)
   less one block at each end that borders another segment, and less the start of a slow motion that a
   hinge finds within :data:`HINGE_S` of either end (:func:`_hinge_trim`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from optcal.core.errors import InputError, listing
from optcal.core.recording.attitude import gyro_scale, slow_motions
from optcal.core.recording.detection import DetectionResult, group_medians, range_rows, runs
from optcal.core.recording.jumps import jump_bounded, jump_samples, tremor_within
from optcal.core.recording.pelt import pelt_ends
from optcal.core.recording.reading import Recording

BLOCKS_PER_POSE = 8  # blocks in the shortest pose: the block is an eighth of min_static_s (and ≤ MAX_BLOCK_S)
MAX_BLOCK_S = 0.0625  # s: blocks never longer (an eighth of 0.5 s, the default shortest pose)
PIECE_BLOCKS = 1024  # PELT runs on pieces of at most this many blocks (quadratic in a piece without change)
TREND_CHI2 = 30.7  # χ²(3) upper 1e-6 quantile (scipy.stats.chi2.isf(1e-6, 3) = 30.66): a slope is a motion
PENALTY = 16 * TREND_CHI2  # PELT's penalty (unit noise): a ramp's pieces then show a slope of χ² ≈ pen/2
NOISE_RATIO = 3.0  # a segment whose block means scatter more than this × the recording's: shaking, not rest
LINE_SLACK = 1.5  # a line fits when its residual χ² is at most this × its dof (+ LINE_SIGMAS SDs): flicker
LINE_SIGMAS = 3.0  # a straight line explains a stretch when its residual χ² is within this many SDs of its dof
HINGE_S = 2.0  # s: the stretch at each end of a rest searched for the start of a slow motion
TREND_BIAS_SE = 0.5  # ... and when the slow turn it means shortens the pose's mean by this many standard errors
DRIFT_SIGMAS = 3.0  # a significant slope is a motion when it moves the outputs by more than this many SDs:
# a hand settling moves a pose by 1.4-2.7 SDs (three of the MPU-6050 log's poses), which turns the
# direction by a fraction of a degree and biases the mean's norm by (Δθ)²/24, micro-g; a turn that PELT
# cut into pieces moves each piece by far more, and (c) still finds it on a line with its neighbours
MERGE_SIGMA = 1.0  # neighbouring rests closer than this many sample-noise SDs (norm over axes) are one pose
Q10_HALF_NORMAL = 0.12566  # the 10th percentile of |x| for x ~ N(0, 1)
ROUNDING = 1e-9  # a difference below this fraction of the largest is a float's rounding residue, 0: outputs on a
# decimal grid (0.01 m/s²) leave 1e-17 where they repeat, which read as a noise SD of 1e-18 (a log of another lab:
# z's noise taken for 0.0029 m/s², its quantisation floor, against 0.014, and its six faces cut into slivers)
GYRO_ROUNDING = 0.0  # the gyroscope's rates: every non-zero difference counts (see gyro_turning)
TRUNCATED_VARIANCE_3SD = 0.97334  # the variance of N(0, 1) cut to ±3, relative to 1
DEFAULT_MIN_STATIC_S = 0.5  # s: the shortest pose found by default
MIN_POSE_SAMPLES = BLOCKS_PER_POSE  # samples: never a shorter pose (at 5 Hz, 0.5 s is 3 samples, too few to tell a
# rest from a slow turn's piece: a turntable log at 5 Hz gave 27 "rests" of 1-5 samples inside its turns)
DEFAULT_WINDOW_S = 10.0  # s: the rest test's longest window (a slow turn's pieces are tested whole)
LOCAL_MIN_DOF = 30  # degrees of freedom (3 per block) before a window's own noise may raise the recording's
NO_RATE_SAMPLES = 50  # samples: the shortest pose of a recording without a rate (its window: twice that)
LOUD_SIGMAS = 6.0  # a block-to-block step of the means beyond this many block-noise SDs (norm over the axes,
# χ²(3) p ≈ 4e-4 for white noise) is motion: a segment rejected as shaking is cut at such steps into its parts
GYRO_WINDOW_S = 0.25  # s: the gyroscope's rate is averaged over this before it is judged (tremor averages out)
GYRO_Z = 8.0  # an averaged rate this many noise SDs from the level at rest (any axis) is a turn ...
TURN_FRACTION = 0.005  # ... when it is also this fraction of the recording's turns (the 99th percentile of the
# averaged rate): about 1 °/s for hand turns at 200 °/s, above a hand's sway in a held pose (tenths of °/s)
SHAKING_HOLD_POSES = 2  # a shaking segment the gyroscope sees still is a rest when it lasts this many shortest poses
CORRELATED_RATE = 400.0  # Hz: a gyroscope sampled this fast is behind a low-pass filter of a few hundred Hz at
# most (MEMS parts' bandwidths), so its samples are correlated: the averaged rate is judged by its own scatter
ORIENTATION_DEG = 5.0  # °: rests whose outputs point within this of each other are one orientation (a refusal's count)
SETTLE_S = 0.15  # s: samples this long after a turn are left out of a rest (a settling fades under the noise)
GYRO_MARGIN_S = 0.05  # s: and this long before one (the turn's first samples)


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
    kept: np.ndarray  # (k,) bool: at rest and at least min_static_s long (before the ends are trimmed)
    short: np.ndarray  # (k,) bool: at rest but shorter than min_static_s
    n_split: int = 0  # segments cut into their still parts (a rest sharing a segment with part of a motion)
    turning: np.ndarray | None = None  # (n,) bool: samples the gyroscope sees turning (None without one)


def _noise_sd(d2: np.ndarray, rounding: float = ROUNDING) -> np.ndarray:
    """Per column, the SD of white noise x from its second differences d2 = x_i − 2x_{i+1} + x_{i+2} (SD
    σ√6), over the quiet part of a recording that also moves. A first guess from the 10th percentile of
    |d2| (robust while a tenth of the recording is at rest) sets a cut at 3 SDs; the SD is then the RMS of
    the differences inside the cut, corrected for the cut (a normal cut at ±3σ keeps 97.33 % of its
    variance). Second differences cancel a constant rate of change: a slow turn does not pass for noise."""
    a = np.abs(np.ascontiguousarray(np.asarray(d2, float).T))  # (3, n): each axis one contiguous row (faster)
    if rounding > 0:  # outputs on a decimal grid (0.01 m/s²) leave differences of 1e-17 where they are 0: those are 0
        a[a <= rounding * np.max(a, axis=1, initial=0.0)[:, None]] = 0.0
    s0 = np.percentile(a, 10.0, axis=1) / (Q10_HALF_NORMAL * np.sqrt(6.0))
    if not np.all(s0 > 0):
        # coarse outputs (a gyroscope at 0.06 °/s per count, sampled faster than it changes) can hold a tenth of
        # their second differences at exactly 0: then the median, 0.6745 SDs of |d2|, sets the first guess
        s0 = np.where(s0 > 0, s0, np.percentile(a, 50.0, axis=1) / (0.6745 * np.sqrt(6.0)))
    inside = a <= (3.0 * np.sqrt(6.0) * s0)[:, None]
    ms = np.sum(np.where(inside, a * a, 0.0), axis=1) / np.maximum(inside.sum(axis=1), 1)
    return np.sqrt(ms / (6.0 * TRUNCATED_VARIANCE_3SD))


def _quanta(N: np.ndarray, roundings=(ROUNDING,)) -> np.ndarray:
    """Per rounding and axis (len(roundings), 3), the smallest non-zero step between consecutive outputs (the
    quantisation step of a coarse ADC; for fine outputs just a small number), a step below that rounding of the
    largest being a float's rounding residue (0 counts every step); one pass over the steps for all of them."""
    d = np.abs(np.diff(N, axis=0))
    big = np.max(d, axis=0, initial=0.0)
    q = np.array([np.min(np.where(d > r * big, d, np.inf), axis=0) for r in roundings])  # a residue is no step
    return np.where(np.isfinite(q), q, 0.0)


def _quantum(N: np.ndarray, rounding: float = ROUNDING) -> np.ndarray:
    """Per axis, the quantisation step of the outputs ``N`` (:func:`_quanta` for one rounding)."""
    return _quanta(N, (rounding,))[0]


def _sums(x: np.ndarray) -> np.ndarray:
    """Cumulative sums with a leading zero row, for sums over any [a, b) by difference."""
    return np.concatenate([np.zeros((1,) + x.shape[1:]), np.cumsum(x, axis=0)])


def _shaking(M: np.ndarray, seg: np.ndarray):
    """Each segment's inner blocks [a, b) (the blocks at its ends may hold the start of a motion or a step: tested
    without them) and whether it shakes (step 4a): the scatter of its block-mean differences (``M`` in units of
    the block noise), per axis, beyond :data:`NOISE_RATIO` (a ramp's slope is the differences' mean and is left
    to step 4b)."""
    inner = (seg[:, 1] - seg[:, 0]) >= 4
    a = np.where(inner, seg[:, 0] + 1, seg[:, 0])
    b = np.where(inner, seg[:, 1] - 1, seg[:, 1])
    L = b - a
    D = np.diff(M, axis=0)
    cD, cD2 = _sums(D), _sums(D * D)
    nd = np.maximum(L - 1, 1)[:, None]
    sD = cD[b - 1] - cD[a]
    sD2 = cD2[b - 1] - cD2[a]
    var_d = np.where(L[:, None] > 2, (sD2 - sD * sD / nd) / np.maximum(nd - 1, 1), sD2 / nd)
    sigma_loc = np.sqrt(np.maximum(var_d, 0.0) / 2.0)  # in units of σ_b
    return a, b, (L > 1) & (sigma_loc.max(axis=1) > NOISE_RATIO)


def _rest_test(M: np.ndarray, seg: np.ndarray, w: int, excess=None, noise: SampleNoise | None = None) -> np.ndarray:
    """For each segment [a, b) of block means ``M`` (in units of the recording's block noise, so σ_b = 1
    per axis): "" at rest, "noisy" or "trend" (step 4 of the module docstring). Vectorised over segments
    and windows through cumulative sums."""
    k = len(seg)
    out = np.full(k, "", dtype=object)
    if not k:
        return out
    a, b, noisy = _shaking(M, seg)
    L = b - a
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
    # the noise about the window's line, when more than the recording's (slow wander of a long pose,
    # flicker noise, which second differences do not see), from at least LOCAL_MIN_DOF degrees of freedom
    c2 = _sums(M * M)
    syy = c2[we] - c2[ws]
    rss = np.sum(syy - sy * sy / np.maximum(n, 1)[:, None], axis=1) - np.sum(slope**2, axis=1) * sxx
    dof = 3 * (n - 2)
    local = np.where(dof >= LOCAL_MIN_DOF, rss / np.maximum(dof, 1), 1.0)
    # the recording's own excess of slow noise at the scale of half the window (scales F = 1, 2, 4, ...
    # blocks; excess[j] at F = 2**j, 1 where the recording is too short to measure it)
    if excess is None:
        floor = np.ones((len(n), 3))
    else:
        j = np.clip(np.floor(np.log2(np.maximum(n, 2) / 2)).astype(int), 0, len(excess) - 1)
        floor = excess[j]
    z2 = np.sum(slope**2 / np.maximum(local[:, None], floor), axis=1) * np.where(ok, sxx, 0.0)
    # and large enough to matter: the line moves by more than DRIFT_SIGMAS sample-noise SDs across the
    # window (a pose's slow wander moves its mean by a fraction of that; a turn that PELT cut into pieces
    # moves each piece by several)
    moved = _moved(slope * (n - 1)[:, None], sy / np.maximum(n, 1)[:, None], n, noise)
    trend = np.zeros(k, bool)
    np.logical_or.at(trend, seg_of, (z2 > TREND_CHI2) & moved)
    out[trend] = "trend"
    out[noisy & ~trend] = "noisy"
    return out


@dataclass(frozen=True)
class SampleNoise:
    """A sample's white noise SD per axis in block-noise units (``sd``); the blocks' length in samples; and,
    for the slope test's split of a drift (:func:`_moved`), the block-noise unit of each axis in sensor units
    (``scale``), the outputs' centre in block-noise units (``centre``: the offsets, from the outputs' range)
    and gravity's magnitude in sample-noise SDs (``g_sd``; None: unknown, every drift judged by DRIFT_SIGMAS)."""

    sd: np.ndarray
    block: int
    scale: np.ndarray | None = None
    centre: np.ndarray | None = None
    g_sd: float | None = None


def _moved(drift: np.ndarray, mean: np.ndarray, n_blocks: np.ndarray, noise: SampleNoise | None) -> np.ndarray:
    """Whether a line that moves the block means by ``drift`` (k, 3) across ``n_blocks`` blocks (k,), about the
    window means ``mean`` (k, 3) (block-noise units), moves the sensor enough to be a motion. Along the pose's
    specific force a drift changes its magnitude (a linear acceleration, or a sensor that is not still): a
    motion beyond :data:`DRIFT_SIGMAS` sample SDs. Across it a drift is a tilt, which shortens the magnitude
    of the pose's mean only at second order: turning through Δθ while held shortens it by g·Δθ²/24 (the mean
    of a direction swept at a constant rate); a tilt of D sample SDs σ is Δθ = Dσ/g, and the mean's standard
    error over n samples is σ/√n, so the tilt is a motion when D > √(24·TREND_BIAS_SE·(g/σ)/√n) (and
    DRIFT_SIGMAS). Without a known gravity every drift is judged by DRIFT_SIGMAS."""
    if noise is None or noise.g_sd is None:
        sd = 1.0 if noise is None else noise.sd
        return np.linalg.norm(drift / sd, axis=1) > DRIFT_SIGMAS
    sig = float(np.exp(np.mean(np.log(noise.sd * noise.scale))))  # a sample's SD, sensor units (one number)
    d = drift * noise.scale / sig  # in sample SDs
    u = (mean - noise.centre) * noise.scale
    u = u / np.maximum(np.linalg.norm(u, axis=1, keepdims=True), 1e-300)
    along = np.sum(d * u, axis=1)
    across = np.linalg.norm(d - along[:, None] * u, axis=1)
    ns = np.maximum(n_blocks, 1) * noise.block
    tilt = np.maximum(DRIFT_SIGMAS, np.sqrt(24.0 * TREND_BIAS_SE * noise.g_sd / np.sqrt(ns)))
    return (np.abs(along) > DRIFT_SIGMAS) | (across > tilt)


def _slopes(c0, c1, lo, hi):
    """Least-squares slope per axis of the block means in each [lo, hi) (cumulative sums c0 of M and c1 of
    i·M), and Σ_axes of its inverse variance factor: slope (k, 3) and sxx (k,) (SE² = 1/sxx, unit noise)."""
    n = (hi - lo).astype(float)
    ok = n >= 2
    sxx = np.where(ok, n * (n * n - 1) / 12.0, 0.0)
    ibar = (lo + hi - 1) / 2.0
    sxy = (c1[hi] - c1[lo]) - ibar[:, None] * (c0[hi] - c0[lo])
    return sxy / np.where(ok, sxx, 1.0)[:, None], sxx


def _continues_motion(M: np.ndarray, seg: np.ndarray, excess=None, noise: SampleNoise | None = None) -> np.ndarray:
    """For each segment [a, b) of block means ``M`` (unit noise, segments in order): whether it is a piece
    of a smooth motion that runs on into a neighbour (step 4c). It is when, for the segment and a touching
    neighbour (the one before, the one after, or both), (i) one straight line through all of them fits
    within the noise (residual χ² at most :data:`LINE_SLACK` times its degrees of freedom plus
    :data:`LINE_SIGMAS` SDs), (ii) its slope is significant (Σ_axes (slope/SE)² > :data:`TREND_CHI2`), and
    (iii) the segment's own slope agrees with it (the same χ² with the segment's own SE). A pose next to
    a step or a motion fails (i); a pause in a turn is flat and fails (iii); a piece of the turn passes."""
    k = len(seg)
    out = np.zeros(k, bool)
    if k < 2:
        return out
    idx = np.arange(len(M), dtype=float)[:, None]
    c0, c1, c2 = _sums(M), _sums(idx * M), _sums(M * M)
    a, b = seg[:, 0], seg[:, 1]
    own, own_sxx = _slopes(c0, c1, a, b)
    left = np.concatenate([[False], a[1:] == b[:-1]])
    right = np.concatenate([a[1:] == b[:-1], [False]])
    prev_a, next_b = np.roll(a, 1), np.roll(b, -1)
    for lo, hi in ((np.where(left, prev_a, a), np.where(right, next_b, b)),
                   (np.where(left, prev_a, a), b), (a, np.where(right, next_b, b))):
        wider = (lo < a) | (hi > b)
        n = (hi - lo).astype(float)
        slope, sxx = _slopes(c0, c1, lo, hi)
        sy = c0[hi] - c0[lo]
        rss = (np.sum(c2[hi] - c2[lo] - sy * sy / np.maximum(n, 1)[:, None], axis=1)
               - np.sum(slope**2, axis=1) * sxx)
        dof = 3 * np.maximum(n - 2, 1)
        fits = rss <= LINE_SLACK * dof + LINE_SIGMAS * np.sqrt(2 * dof)
        # significant against the slow noise at half the stretch's length, and moving the outputs by more
        # than DRIFT_SIGMAS sample-noise SDs across it (as in _rest_test)
        if excess is None:
            floor = np.ones((k, 3))
        else:
            floor = excess[np.clip(np.floor(np.log2(np.maximum(n, 2) / 2)).astype(int), 0, len(excess) - 1)]
        significant = np.sum(slope**2 / floor, axis=1) * sxx > TREND_CHI2
        drift = slope * (n - 1)[:, None] / (1.0 if noise is None else noise.sd)
        # (a piece of a turn that runs on into its neighbours is a motion however slow: DRIFT_SIGMAS only)
        significant &= np.linalg.norm(drift, axis=1) > DRIFT_SIGMAS
        agrees = np.sum((own - slope) ** 2, axis=1) * own_sxx <= TREND_CHI2
        out |= wider & (n >= 4) & fits & significant & agrees
    return out


def _hinge_trim(M: np.ndarray, seg: np.ndarray, H: int) -> np.ndarray:
    """Each rest [a, b) (blocks, unit noise) without the start of a slow motion that PELT left in it
    (step 6): over its last H blocks (mirrored, its first H) a hinge, constant up to block c and a
    straight line from there, is fitted for every c; when the best hinge fits better than a constant by
    more than :data:`TREND_CHI2`, the rest ends at c (only rests that passed the rest test are trimmed).
    Vectorised over rests and hinge points."""
    out = seg.copy()
    if not len(seg):
        return out
    H = max(H, 1)
    for end in (1, 0):
        L = seg[:, 1] - seg[:, 0]
        h = np.minimum(L // 2, H)
        j = np.arange(H)
        if end:  # the last h blocks, in time order
            pos = seg[:, 1:2] - h[:, None] + j[None, :]
        else:  # the first h blocks, reversed so that the motion is again at the far end
            pos = seg[:, 0:1] + h[:, None] - 1 - j[None, :]
        valid = j[None, :] < h[:, None]
        Y = M[np.clip(pos, 0, len(M) - 1)] * valid[..., None]  # (k, H, 3)
        n = valid.sum(axis=1)
        ybar = Y.sum(axis=1) / np.maximum(n, 1)[:, None]
        rss0 = np.sum(((Y - ybar[:, None]) * valid[..., None]) ** 2, axis=(1, 2))
        # hinge at c: regressors 1 and x = max(0, j − c), least squares per axis via 2 × 2 normal equations
        c = np.arange(H)
        X = np.maximum(0, j[None, :] - c[:, None])[None] * valid[:, None, :]  # (k, C, H)
        sx = X.sum(axis=2)
        sxx = (X * X).sum(axis=2)
        sy = Y.sum(axis=1)  # (k, 3)
        sxy = np.einsum("kch,kha->kca", X, Y)
        det = n[:, None] * sxx - sx * sx
        ok = det > 1e-9
        beta1 = (n[:, None, None] * sxy - sx[..., None] * sy[:, None, :]) / np.where(ok, det, 1.0)[..., None]
        rss = rss0[:, None] - np.sum(beta1 * (sxy - sx[..., None] * ybar[:, None, :]), axis=2)
        rss = np.where(ok & (c[None, :] < n[:, None] - 2), rss, np.inf)  # a slope over 2+ blocks
        best = np.argmin(rss, axis=1)
        gain = rss0 - rss[np.arange(len(seg)), best]
        cut = gain > TREND_CHI2
        if end:
            out[cut, 1] = seg[cut, 1] - h[cut] + best[cut] + 1
        else:
            out[cut, 0] = seg[cut, 0] + h[cut] - 1 - best[cut]
    return out


def _slow_noise_excess(Z: np.ndarray, good: np.ndarray, w: int) -> np.ndarray:
    """The recording's noise variance at scales of F = 1, 2, 4, … blocks (up to half the rest test's window
    w) relative to white noise, per axis, ≥ 1: row j is F·σ_F² for means over F = 2**j blocks (unit block
    noise), σ_F from their quiet second differences (:func:`_noise_sd`). Flicker noise and a hand's wander
    make it grow with F; a scale with fewer than 10 second differences repeats the one below it."""
    rows = [np.ones(3)]
    F = 2
    while F <= max(w // 2, 1):
        nB = len(Z) // F
        goodB = good[: nB * F].reshape(nB, F).all(axis=1)
        okB = goodB[2:] & goodB[1:-1] & goodB[:-2]
        if okB.sum() < 10:
            rows.append(rows[-1])
        else:
            ZB = Z[: nB * F].reshape(nB, F, 3).mean(axis=1)
            rows.append(np.maximum(rows[-1], F * _noise_sd(np.diff(ZB, 2, axis=0)[okB]) ** 2))
        F *= 2
    return np.array(rows)


def _change_points(Z: np.ndarray, good: np.ndarray) -> np.ndarray:
    """Segments [start, end) (blocks) of the good blocks of ``Z`` (normalised block means) by PELT with a
    linear kernel on pieces of at most :data:`PIECE_BLOCKS` blocks (:func:`optcal.core.recording.pelt.pelt_ends`:
    ruptures' compiled kernel, or the same change points in NumPy)."""
    pen = PENALTY
    pieces = []  # [start, end) of each piece: the runs of good blocks (none with drops), cut to PIECE_BLOCKS
    for s, e in runs(good):
        cuts = np.linspace(s, e, -(-(e - s) // PIECE_BLOCKS) + 1).round().astype(int)
        pieces.extend(zip(cuts[:-1].tolist(), cuts[1:].tolist()))
    long = [(ps, pe) for ps, pe in pieces if pe - ps >= 4]
    ends = pelt_ends([Z[ps:pe] for ps, pe in long], pen)
    found = dict(zip(long, ends))
    bounds = []
    for ps, pe in pieces:
        if (ps, pe) not in found:  # too short to cut
            bounds.append([ps, pe])
            continue
        edges = np.concatenate([[0], found[ps, pe]]) + ps
        bounds.extend(np.column_stack([edges[:-1], edges[1:]]).tolist())
    return np.array(bounds, dtype=np.int64).reshape(-1, 2)


def _merge(M: np.ndarray, seg: np.ndarray, rest: np.ndarray, w: int, gap_ok: np.ndarray,
           noise: SampleNoise, excess=None) -> tuple[np.ndarray, np.ndarray]:
    """Join neighbouring rest segments (step 5): returns the new segments and their rest flags."""
    c = _sums(M)
    means = (c[seg[:, 1]] - c[seg[:, 0]]) / (seg[:, 1] - seg[:, 0])[:, None]
    close = np.linalg.norm((means[1:] - means[:-1]) / noise.sd, axis=1) < MERGE_SIGMA
    join = rest[:-1] & rest[1:] & close & gap_ok
    if not join.any():
        return seg, rest
    group = np.concatenate([[0], np.cumsum(~join)])
    starts = np.flatnonzero(np.concatenate([[True], ~join]))
    ends = np.concatenate([starts[1:], [len(seg)]])
    merged = np.column_stack([seg[starts, 0], seg[ends - 1, 1]])
    multi = ends - starts > 1
    passes = _rest_test(M, merged, w, excess, noise) == ""
    keep_group = multi & passes  # a joined group that passes replaces its members
    take = keep_group[group]
    out = np.concatenate([merged[keep_group], seg[~take]])
    flags = np.concatenate([np.ones(int(keep_group.sum()), bool), rest[~take]])
    order = np.argsort(out[:, 0], kind="stable")
    return out[order], flags[order]


def segment_recording(rec: Recording, min_static_s: float | None = None,
                      window_s: float | None = None, *, W=None, refine: bool = True) -> Segmentation:
    """Segments of ``rec`` and their rest flags (steps 1-5 of the module docstring); with ``refine`` (the
    default) the rests that share a segment with a motion are cut out of it (:func:`_refine`), using the
    gyroscope's rates ``W`` (n, 3) when given. ``refine=False`` is the segmentation of issue #20 alone."""
    N = np.asarray(rec.N, float)
    n = len(N)
    rate = float(rec.rate)
    if np.isfinite(rate) and rate > 0:
        m = _min_pose(min_static_s, rate)
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
    if not np.isfinite(N).any() or not (np.nanmax(N, axis=0) > np.nanmin(N, axis=0)).any():
        raise InputError(f"{rec.path}: the outputs never change; this is not a recording of a sensor being turned")
    if good.sum() < 2:
        raise InputError(f"{rec.path}: no stretch of {b} samples without a saturated or missing sample; "
                         "record within the sensor's range (or declare its range with `saturation`)")
    # noise from the recording: first differences of good samples and of consecutive good blocks
    ok_pair = ~bad[2:] & ~bad[1:-1] & ~bad[:-2]
    ds = np.diff(Nf, 2, axis=0)[ok_pair]
    q = _quantum(Nf[~bad])
    sigma = np.maximum(_noise_sd(ds) if len(ds) else q, q / np.sqrt(12.0))
    ok_block = good[2:] & good[1:-1] & good[:-2]
    dm = np.diff(M, 2, axis=0)[ok_block]
    sigma_b = np.maximum(_noise_sd(dm) if len(dm) else sigma, sigma / np.sqrt(b))
    if not np.any(sigma > 0):
        raise InputError(f"{rec.path}: the outputs never change; this is not a recording of a sensor being turned")
    scale = np.where(sigma_b > 0, sigma_b, np.max(sigma_b))  # an axis that never moves keeps unit scale
    Z = M / scale
    seg = _change_points(Z, good)
    w = max(3, int(round(win / b)))
    # slow noise (flicker, a hand's wander) is more at a pose's length than the blocks' white noise
    # says: its excess variance there, per axis, from second differences of means over BLOCKS_PER_POSE
    excess = _slow_noise_excess(Z, good, w)
    sd = np.where(sigma > 0, sigma, np.max(sigma))
    # gravity's magnitude in the outputs' units, from their range (the sensor is turned: each axis sees about
    # ±g; a recording turned less gives less, so slow turns are judged more strictly), offsets cancelled
    hi, lo = np.percentile(M[good], 99, axis=0), np.percentile(M[good], 1, axis=0)
    g = float(np.max(hi - lo) / 2)
    step = SampleNoise(sd / scale, b, scale, (hi + lo) / 2 / scale,
                       g / float(np.exp(np.mean(np.log(sd)))) if g > 0 else None)
    reason = _rest_test(Z, seg, w, excess, step)
    n_split, turning = 0, None
    jumps = jump_samples(Nf[: nb * b], bad[: nb * b], g)
    if refine:
        seg, reason, n_split, turning = _refine(Z, seg, reason, w, excess, step, b, rate,
                                                None if W is None else np.asarray(W, float), (jumps, g))
    # neighbours are joined only across a cut of PELT's, never across a set-aside block
    gap_ok = seg[1:, 0] == seg[:-1, 1]
    seg2, rest2 = _merge(Z, seg, reason == "", w, gap_ok, step, excess)
    if len(seg2) != len(seg):  # joined groups passed the test; the other segments keep their reasons
        # a segment the merge left as it was keeps its reason (a piece the gyroscope saw turning stays "turn")
        at = np.minimum(np.searchsorted(seg[:, 0], seg2[:, 0]), len(seg) - 1)
        same = np.all(seg[at] == seg2, axis=1)
        retest = _rest_test(Z, seg2, w, excess, step)
        seg, reason = seg2, np.where(rest2, "", np.where(same, reason[at], retest)).astype(object)
    # rests are tested against their surroundings (step 4c), short ones too (a turn's pieces must not pass
    # for short rests); long enough to keep: at least min_static_s with a block at each end (a step or a
    # motion inside a block leaves that block to neither side) and, beside a turn the gyroscope sees, the
    # margins its turn was dilated by (samples of the rest set aside as a precaution, not seen moving)
    length = (seg[:, 1] - seg[:, 0] + 2) * b + _turn_margins(seg, reason, rate)
    cont = _continues_motion(Z, seg, excess, step)
    if turning is not None:  # the gyroscope sees whether a piece continues a turn
        cont &= ~_still(seg, turning[: len(Z) * b].reshape(len(Z), b).any(axis=1))
    reason[(reason == "") & cont] = "trend"
    seg = seg.copy()
    # the hinge search leaves out the end blocks (which may mix motion and rest; they are dropped at the
    # end anyway) and looks at most half way into the rest from each end
    H = max(4, int(round(HINGE_S * (rate if np.isfinite(rate) else 50.0) / b)))
    keep = (reason == "") & (length >= m)
    short = (reason == "") & ~keep
    # a pose logged apart has no motion at its ends to trim (module docstring of optcal.core.recording.jumps)
    trim = keep & ~jump_bounded(seg, jumps, b, len(Z))
    seg[trim] = _hinge_trim(Z, seg[trim] + [1, -1], H) + [-1, 1]
    rest = reason == ""
    return Segmentation(b, w, seg, rest, reason, sigma, sigma_b, int((~good).sum()), keep, short, n_split, turning)


def _turn_margins(seg: np.ndarray, reason: np.ndarray, rate: float) -> np.ndarray:
    """Samples (k,) each segment of ``seg`` lost to the margins of the turns it touches: :data:`SETTLE_S` after a
    turn before it, :data:`GYRO_MARGIN_S` before a turn after it (:func:`gyro_turning`)."""
    turn = reason == "turn"
    touch_l = np.zeros(len(seg), bool)
    touch_r = np.zeros(len(seg), bool)
    touch_l[1:] = turn[:-1] & (seg[1:, 0] == seg[:-1, 1])
    touch_r[:-1] = turn[1:] & (seg[:-1, 1] == seg[1:, 0])
    per_s = rate if np.isfinite(rate) else 50.0
    return (touch_l * int(round(SETTLE_S * per_s)) + touch_r * int(round(GYRO_MARGIN_S * per_s))).astype(np.int64)


def _refine(Z, seg, reason, w, excess, step, b, rate, W, jumps):
    """Rests that share a segment with part of a motion, cut out of it (docs/segmentation.md, "Every rest"):
    with a gyroscope ``W`` (n, 3), every segment is cut where the gyroscope sees a turn (:func:`gyro_turning`)
    and the pieces between turns of a segment that was not at rest are tested for rest again (a rest's pieces
    stay at rest: the test on a shorter piece only loses power, and the gyroscope took out what turned); then
    each segment still rejected as shaking is cut at the steps of its block means beyond :data:`LOUD_SIGMAS`
    (:func:`_loud_blocks`), and its quiet pieces are tested. Returns the segments, their reasons ("turn" for a
    piece the gyroscope sees turning, "noisy" for a loud piece), how many segments were cut, and the turning
    samples (None without a gyroscope). ``jumps``: the jump samples and gravity's magnitude (outputs' units): a
    shaking segment with a jump at each end is a pose logged apart (:mod:`optcal.core.recording.jumps`) and
    at rest when it lasts a shortest pose and shakes within its tremor's bound."""
    n_split, turning = 0, None
    nb = len(Z)
    logged = (reason == "noisy") & (seg[:, 1] - seg[:, 0] >= BLOCKS_PER_POSE)
    if logged.any():
        at, g = seg[logged], jumps[1]
        logged[logged] = jump_bounded(at, jumps[0], b, nb) & tremor_within(Z, at, step.scale, g)
        reason = np.where(logged, "", reason).astype(object)
    if W is not None:
        tb, turning = gyro_turning(W, b, seg, reason == "", rate, (Z - step.centre) * step.scale)
        seg, reason, n = _cut(Z, seg, reason, tb, ~_still(seg, tb), "turn", w, excess, step)
        n_split += n
        # a piece the gyroscope sees still throughout keeps its gravity direction: a slope of its specific force
        # is a hand letting go or the sensor settling, not a turn (the gyroscope sees far smaller turns)
        reason[(reason == "trend") & _still(seg, tb)] = ""
    loud = _loud_blocks(Z)[:nb]
    seg, reason, n = _cut(Z, seg, reason, loud, reason == "noisy", "noisy", w, excess, step)
    if W is not None:
        # a piece that still shakes (step 4a) while the gyroscope sees it still throughout is a hold that
        # vibrates (a board on a running bench), when it lasts twice the shortest pose: a shorter one beside a
        # turn is its settling as often as not (docs/segmentation.md, step 8)
        long = seg[:, 1] - seg[:, 0] >= SHAKING_HOLD_POSES * BLOCKS_PER_POSE
        reason[(reason == "noisy") & _still(seg, tb) & long] = ""
        seg, reason = _vibrating_holds(seg, reason, _still(seg, tb))
    return seg, reason, n_split + n, turning


def _vibrating_holds(seg: np.ndarray, reason: np.ndarray, still: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A hold that vibrates, cut by step 7 into loud pieces and quiet ones each shorter than a pose: a run of
    adjacent such pieces (shaking, or at rest but short) that the gyroscope sees ``still`` throughout, at least
    one of them shaking, is one rest when it lasts :data:`SHAKING_HOLD_POSES` shortest poses (as one shaking
    piece that long is, :func:`_refine`)."""
    short = seg[:, 1] - seg[:, 0] < BLOCKS_PER_POSE
    piece = still & ((reason == "noisy") | ((reason == "") & short))
    if not (piece & (reason == "noisy")).any():
        return seg, reason
    joined = piece[1:] & piece[:-1] & (seg[1:, 0] == seg[:-1, 1])
    start = np.flatnonzero(np.concatenate([[True], ~joined]))
    end = np.concatenate([start[1:], [len(seg)]])  # groups [start, end) of segments
    span = seg[end - 1, 1] - seg[start, 0]
    c = np.concatenate([[0], np.cumsum(reason == "noisy")])
    hold = (end - start > 1) & piece[start] & (c[end] > c[start]) & (span >= SHAKING_HOLD_POSES * BLOCKS_PER_POSE)
    if not hold.any():
        return seg, reason
    group = np.repeat(np.arange(len(start)), end - start)
    drop = hold[group] & (np.arange(len(seg)) != start[group])  # a hold's members after its first
    seg, reason = seg.copy(), reason.copy()
    seg[start[hold], 1] = seg[end[hold] - 1, 1]
    reason[start[hold]] = ""
    return seg[~drop], reason[~drop]


def _cut(Z, seg, reason, flag, which, flagged_reason, w, excess, step):
    """Cut the segments ``which`` at the changes of the block ``flag`` (:func:`_split_at`): the flagged pieces
    get ``flagged_reason``, the others the rest test again (:func:`_rest_test`); the other segments keep their
    reasons. Also the number of segments cut."""
    if not which.any():
        return seg, reason, 0
    new, flagged, owner = _split_at(seg, flag, which)
    out = np.where(flagged, flagged_reason, reason[owner]).astype(object)
    retest = which[owner] & ~flagged & (reason[owner] != "")  # a rest's pieces stay at rest
    if retest.any():
        out[retest] = _rest_test(Z, new[retest], w, excess, step)
    n = int(np.sum(np.bincount(owner, minlength=len(seg)) > 1))
    return new, out, n


def _split_at(seg: np.ndarray, flag: np.ndarray, which: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The segments ``seg`` (k, 2) with each one marked in ``which`` (k,) cut where the block flag ``flag``
    (blocks,) changes: returns the new segments, whether each is flagged, and the index of the segment it came
    from. Vectorised: boundaries are the segments' ends plus the flag's changes inside the marked segments."""
    nb = len(flag)
    owner = np.full(nb + 1, -1, np.int64)
    blocks, idx = range_rows(seg)
    owner[blocks] = idx
    mark = np.zeros(nb + 1, bool)
    mark[seg[:, 0]] = True
    mark[seg[:, 1]] = True
    change = np.zeros(nb + 1, bool)
    change[1:nb] = flag[1:] != flag[:-1]
    inside = np.zeros(nb + 1, bool)
    inside[blocks] = which[idx]
    mark |= change & inside & (owner == np.roll(owner, 1))
    pos = np.flatnonzero(mark)
    lo, hi = pos[:-1], pos[1:]
    keep = (owner[lo] >= 0) & (owner[lo] == owner[hi - 1])
    lo, hi = lo[keep], hi[keep]
    return np.column_stack([lo, hi]), flag[lo] & which[owner[lo]], owner[lo]


def _dilate(mask: np.ndarray, after: int, before: int | None = None) -> np.ndarray:
    """``mask`` (n,) grown by ``after`` samples after each run and ``before`` (default ``after``) before it (a
    moving maximum through cumulative sums)."""
    before = after if before is None else before
    if not mask.any() or (after <= 0 and before <= 0):
        return mask
    c = np.concatenate([[0], np.cumsum(mask)])
    i = np.arange(len(mask))
    return (c[np.minimum(i + before + 1, len(mask))] - c[np.maximum(i - after, 0)]) > 0


def _still(seg: np.ndarray, turning_blocks: np.ndarray) -> np.ndarray:
    """Whether each segment of ``seg`` (k, 2) holds no turning block."""
    c = np.concatenate([[0], np.cumsum(turning_blocks)])
    return (c[seg[:, 1]] - c[seg[:, 0]]) == 0


def _rest_level(G: np.ndarray, t: np.ndarray, seg: np.ndarray, rest: np.ndarray) -> np.ndarray:
    """The gyroscope's output at rest (its bias) at each of the times ``t``: within each accelerometer rest
    ``seg[rest]``, the line from the median of its block means ``G`` over its first half (at its start) to that
    over its second half (at its end), and between rests the line from one to the next. A median: a turn at a
    rest's edge does not move it. Each rest keeps its own level (a gyroscope's g-sensitivity shifts it by
    tenths of a degree per second from pose to pose) and a drifting bias is followed. Without a rest, the
    median of the fifth of the blocks that change least."""
    r = seg[rest & (seg[:, 1] - seg[:, 0] >= 4)]
    if not len(r):
        d = np.linalg.norm(np.diff(G, axis=0), axis=1)
        quiet = np.argsort(d)[: max(1, len(d) // 5)]
        return np.broadcast_to(np.median(G[quiet], axis=0), (len(t), 3))
    half = (r[:, 0] + r[:, 1]) // 2
    first = group_medians(G, np.column_stack([r[:, 0], half]))
    second = group_medians(G, np.column_stack([half, r[:, 1]]))
    knots = np.column_stack([r[:, 0], r[:, 1] - 1]).ravel().astype(float)
    values = np.stack([first, second], axis=1).reshape(-1, 3)
    return np.column_stack([np.interp(t, knots, values[:, i]) for i in range(3)])


def gyro_turning(W: np.ndarray, b: int, seg: np.ndarray, rest: np.ndarray, rate: float, acc=None):
    """Where the gyroscope sees the sensor turn: (blocks (nb,), samples (n,)) bool. ``W`` (n, 3) rates in any
    unit, ``seg``/``rest`` the accelerometer's segments (blocks of ``b`` samples) and rest flags.

    The rate is averaged over :data:`GYRO_WINDOW_S` (a hand's tremor averages out; the end of a turn does not)
    and taken from the level at rest (:func:`_rest_level`: a drifting bias is followed), in units of the
    average's white noise (second differences, :func:`_noise_sd`, never below the quantisation step's q/√12);
    ``z`` is the largest axis. A sample turns where ``z`` exceeds :data:`GYRO_Z` and :data:`TURN_FRACTION` of
    the recording's turns (the 99th percentile of ``z``): units-free, that is about 0.5-1 °/s for turns by hand
    at 100-200 °/s, above the sway of a pose held by hand (tenths of °/s) and hundreds of times the noise of a
    MEMS gyroscope; a turn extends by :data:`SETTLE_S` after it and :data:`GYRO_MARGIN_S` before it. With ``acc``
    (nb, 3), the accelerometer's block means less their offsets, a slow motion inside a still run turns too
    (:mod:`optcal.core.recording.attitude`: the attitude straying by more than a few tenths of a degree, in the
    units the accelerometer's view of the turns gives the rates): a turn's slow start and its settling below
    the threshold, a held pose that sags. Without ``acc`` (or without a turn of 20° between rests) the rate
    threshold alone. A block turns when it holds a turning sample.
    """
    W = np.asarray(W, float)
    n = len(W)
    nb = n // b
    finite = np.isfinite(W).all(axis=1)
    Wf = np.where(finite[:, None], W, 0.0)
    # the gyroscope's thresholds were set with a rounding residue taken for a step and for noise (GYRO_ROUNDING;
    # on a coarse gyroscope in rad/s the level is then its quantisation's, q/√12): kept as they were chosen
    # the step a turn must exceed (_turning_samples): the output's own quantum, a rounding residue being none (rates
    # printed to 0.01 °/s leave 1e-17 where they repeat: a quantum of 0 let every flicker of a count turn)
    q_noise, q = _quanta(Wf[finite], (GYRO_ROUNDING, ROUNDING))
    ok = finite[2:] & finite[1:-1] & finite[:-2]
    s = np.maximum(_noise_sd(np.diff(Wf, 2, axis=0)[ok], GYRO_ROUNDING), q_noise / np.sqrt(12.0))
    s = np.where(s > 0, s, 1.0)
    G = Wf[: nb * b].reshape(nb, b, 3).mean(axis=1)
    t = (np.arange(n, dtype=float) - (b - 1) / 2.0) / b
    w = max(1, int(round(GYRO_WINDOW_S * rate))) if np.isfinite(rate) else 5
    s_avg = _averaged_noise(Wf, finite, w, s) if np.isfinite(rate) and rate >= CORRELATED_RATE else s
    X = Wf - _rest_level(G, t, seg, rest)
    M = _moving_mean(X, w)
    samples = _turning_samples(M, s_avg, w, q) | ~finite
    # the accelerometer's rests may hold part of a turn, which moves their level (by more than the threshold
    # on a quiet gyroscope): the level again from the gyroscope's own still runs, whole blocks of them
    still = runs(~samples)
    still = np.column_stack([-(-still[:, 0] // b), still[:, 1] // b])
    still = still[still[:, 1] - still[:, 0] >= 2]
    if len(still):
        X = Wf - _rest_level(G, t, still, np.ones(len(still), bool))
        M = _moving_mean(X, w)
        samples = _turning_samples(M, s_avg, w, q) | ~finite
    per_s = rate if np.isfinite(rate) else 50.0
    turns = _dilate(samples, int(round(SETTLE_S * per_s)), int(round(GYRO_MARGIN_S * per_s)))
    if acc is not None and np.isfinite(rate):  # slow motions, in units the accelerometer's turns give
        r = seg[rest & (seg[:, 1] - seg[:, 0] >= 4)]
        c = np.concatenate([np.zeros((1, 3)), np.cumsum(acc, axis=0)])
        K = gyro_scale(X, M, (c[r[:, 1]] - c[r[:, 0]]) / (r[:, 1] - r[:, 0])[:, None], r * b, samples, rate)
        if np.isfinite(K) and K > 0:  # (no margins: a slow motion has no settling of its own)
            # the rates as output, each still run's median taken out (its bias): the level at rest, a line from
            # a rest's first half to its second, would take up part of a slow turn through the rest
            turns |= slow_motions(Wf, ~turns, K, s, rate)
    samples = turns
    blocks = samples[: nb * b].reshape(nb, b).any(axis=1)
    return blocks, samples


def _averaged_noise(W: np.ndarray, finite: np.ndarray, w: int, s: np.ndarray) -> np.ndarray:
    """A sample's noise SD (3,) as the average of ``w`` samples sees it: ``s`` (the white noise of second
    differences), or more when means of ``w`` samples scatter more than s/√w (robustly, from their second
    differences: :func:`_noise_sd`), for a gyroscope sampled at :data:`CORRELATED_RATE` or faster. Sampled far
    above its bandwidth (a 1-kHz IMU behind its low-pass filter) its noise is correlated: the white estimate
    took the averaged noise for turns, and a log of one face held still "turned" throughout. (Applied at every
    rate, it moved the labelled benchmark's hand-held logs, whose rests' wobble the averages see.)"""
    k = len(W) // w
    if k < 10 or w < 2:
        return s
    B = W[: k * w].reshape(k, w, 3).mean(axis=1)
    ok = finite[: k * w].reshape(k, w).all(axis=1)
    ok3 = ok[2:] & ok[1:-1] & ok[:-2]
    if ok3.sum() < 8:
        return s
    sd = _noise_sd(np.diff(B, 2, axis=0)[ok3], GYRO_ROUNDING)
    return np.maximum(s, sd * np.sqrt(w))


def _moving_mean(X: np.ndarray, w: int) -> np.ndarray:
    """(n, 3): each sample's mean of ``X`` over the ``w`` samples centred on it (shifted inside at the ends)."""
    n = len(X)
    w = min(w, n)
    c = np.concatenate([np.zeros((1, 3)), np.cumsum(X, axis=0)])
    m = (c[w:] - c[:-w]) / w  # m[j]: the mean of X[j:j + w]
    h = w // 2
    return np.concatenate([np.repeat(m[:1], h, axis=0), m, np.repeat(m[-1:], n - h - len(m), axis=0)])


def _turning_samples(M: np.ndarray, s: np.ndarray, w: int, q: np.ndarray | None = None) -> np.ndarray:
    """Samples (n,) of a turn, from the rates less their level at rest averaged over ``w`` samples, ``M`` (n, 3)
    (:func:`_moving_mean`), and a sample's white noise SD ``s`` (3,): the average, in units of its noise (the
    largest axis), is above the threshold (:func:`gyro_turning`), on an axis where it also exceeds the
    quantisation step ``q`` (3,): a coarse gyroscope whose output sits at its level and flickers by a count now
    and then averages anywhere within one count of it without turning (a six-face log of another lab, its
    gyroscope at 0.01 per count and 0 on 98 % of its samples, had its faces cut at such flickers)."""
    r = np.abs(M) / (s / np.sqrt(w))
    if q is not None:
        r = np.where(np.abs(M) > q, r, 0.0)
    z = np.max(r, axis=1)
    # a turn: above the noise and above a small fraction of the recording's turns (its 99th percentile); its slow
    # start and its settling, below that, are the attitude rule's (optcal.core.recording.attitude)
    return z > max(GYRO_Z, TURN_FRACTION * float(np.percentile(z, 99)))


def _loud_blocks(Z: np.ndarray) -> np.ndarray:
    """Blocks (nb,) next to a step of the block means beyond :data:`LOUD_SIGMAS` block-noise SDs (unit noise
    ``Z``), and their neighbours: the shaking of a motion's end or a jolt."""
    d = np.linalg.norm(np.diff(Z, axis=0), axis=1) > LOUD_SIGMAS
    loud = np.zeros(len(Z), bool)
    loud[1:] |= d
    loud[:-1] |= d
    return _dilate(loud, 1)


def _seconds(value: float | None, default: float, rate: float, param: str) -> int:
    value = default if value is None else value
    if not (isinstance(value, (int, float)) and np.isfinite(value) and value > 0):
        raise InputError(f"`{param}` must be a positive number of seconds, got {value}")
    return max(3, int(round(value * rate)))


def _min_pose(min_static_s: float | None, rate: float) -> int:
    """The shortest pose in samples: ``min_static_s`` (default :data:`DEFAULT_MIN_STATIC_S`), never under
    :data:`MIN_POSE_SAMPLES`."""
    return max(MIN_POSE_SAMPLES, _seconds(min_static_s, DEFAULT_MIN_STATIC_S, rate, "min_static_s"))


def segment_static(recording: Recording, *, min_static_s: float | None = None,
                   window_s: float | None = None, gyro=None, refine: bool = True) -> DetectionResult:
    """Static intervals of ``recording`` by change-point segmentation and a rest test (module docstring):
    poses of at least ``min_static_s`` (default 0.5 s) with or without motion between them, each at rest
    within every ``window_s`` (default 10 s) at the recording's own noise level. Stillness is judged on the
    accelerometer and on the gyroscope: ``gyro`` (n, 3) rates at the same samples, by default the recording's
    own gyroscope columns (``recording.W``); ``gyro=False`` ignores them. A rest that shares a segment with part
    of a motion is cut to its still part, and with a gyroscope no kept interval holds a sample it sees turning
    (:func:`gyro_turning`). ``refine=False`` is the accelerometer's segmentation of issue #20 alone (kept for
    the comparison of docs/segmentation.md). Fewer intervals than a model needs is the caller's to refuse
    (:func:`segment_diagnosis` says why)."""
    if gyro is None or gyro is True:
        gyro = recording.W
    elif gyro is False:
        gyro = None
    if gyro is not None:
        gyro = np.asarray(gyro, float)
        if gyro.shape != (len(recording), 3):
            raise InputError(f"the gyroscope's rates are {gyro.shape}, the accelerometer has {len(recording)} "
                             "samples: give them at the same samples, as (n, 3)")
    sg = segment_recording(recording, min_static_s, window_s, W=gyro if refine else None, refine=refine)
    b = sg.block
    rate = float(recording.rate)
    m = _min_pose(min_static_s, rate) if np.isfinite(rate) else NO_RATE_SAMPLES
    seg, rest = sg.segments, sg.rest
    keep = sg.kept
    iv = seg[keep] * b
    # less one block at each end that borders another segment (a block a step or a motion starts in
    # mixes both sides), not at the recording's ends
    nb = len(recording) // b
    iv[:, 0] += np.where(seg[keep, 0] > 0, b, 0)
    iv[:, 1] -= np.where(seg[keep, 1] < nb, b, 0)
    if len(iv) and seg[keep][-1, 1] == nb:  # the last rest runs to the end: keep the tail samples, up to
        tail = ~np.isfinite(recording.N[nb * b:]).all(axis=1) | recording.saturated[nb * b:]  # a bad one
        iv[-1, 1] = nb * b + (int(np.argmax(tail)) if tail.any() else len(tail))
    # what the edges and a hinge leave of a pose is kept down to half the shortest pose, as the report says (a
    # lab's hand-held sweep had "rests" of 10 and 15 samples where 20 or more were promised)
    iv = iv[iv[:, 1] - iv[:, 0] >= max(3, m // 2)]
    notes = []
    if sg.turning is not None and len(iv):  # no sample the gyroscope sees turning stays in a rest
        # a pose of at least min_static_s (decided on its segment) keeps what its edges leave, down to half that
        iv, n_cut = _still_parts(iv, sg.turning, max(3, m // 2))
        if n_cut:
            notes.append(f"{n_cut} rest(s) cut where the gyroscope turns (a motion's edge or a bump)")
    n_short = int(np.sum(sg.short))
    if n_short:
        notes.append(f"{n_short} rest segment(s) shorter than {m} samples ignored")
    moving = ~rest
    if moving.any():
        blocks = int(np.sum(seg[moving, 1] - seg[moving, 0]))
        turn = int(np.sum(sg.reason == "turn"))
        # the ones as long as a pose are where a user looks for a pose the detection refused
        long = np.flatnonzero(moving & ((seg[:, 1] - seg[:, 0]) * b >= m) & (sg.reason != "turn"))
        t = recording.shown_t
        where = ("; as long as a pose: " + listing(
            (f"{t[seg[i, 0] * b]:.1f}-{t[min(seg[i, 1] * b, len(t)) - 1]:.1f} s ({sg.reason[i]})" for i in long),
            limit=4)) if len(long) else ""
        notes.append(f"{int(moving.sum())} segment(s) ({blocks * b} samples) not at rest: "
                     f"{int(np.sum(sg.reason == 'trend'))} trend, {int(np.sum(sg.reason == 'noisy'))} too noisy"
                     + (f", {turn} turning (gyroscope)" if turn else "") + where)
    if sg.n_split:
        notes.append(f"{sg.n_split} segment(s) holding a rest and part of a motion cut to their still parts")
    if sg.n_bad_blocks:
        notes.append(f"{sg.n_bad_blocks} block(s) of {b} samples set aside (saturated or missing samples)")
    res = DetectionResult(recording, iv.astype(np.int64), "segment", None, sg.window * b, m, notes=notes)
    res.noise = sg.sigma
    res.block = b
    res.segmentation = sg
    return res


def _still_parts(iv: np.ndarray, turning: np.ndarray, m: int) -> tuple[np.ndarray, int]:
    """The parts of the intervals ``iv`` (k, 2) without a ``turning`` sample, those of at least ``m`` samples;
    and how many intervals held a turning sample. Vectorised over intervals through the runs of still samples."""
    still = runs(~turning)
    c = np.concatenate([[0], np.cumsum(turning)])
    n_cut = int(np.sum(c[iv[:, 1]] - c[iv[:, 0]] > 0))
    # each interval against each run that overlaps it (runs sorted, so a searchsorted range per interval)
    lo = np.searchsorted(still[:, 1], iv[:, 0], side="right")
    hi = np.searchsorted(still[:, 0], iv[:, 1], side="left")
    r, which = range_rows(np.column_stack([lo, lo + np.maximum(hi - lo, 0)]))
    parts = np.column_stack([np.maximum(iv[which, 0], still[r, 0]), np.minimum(iv[which, 1], still[r, 1])])
    return parts[parts[:, 1] - parts[:, 0] >= m].reshape(-1, 2), n_cut


def segment_diagnosis(det: DetectionResult, needed: int) -> tuple[str, str]:
    """Why segmentation found fewer than ``needed`` intervals, and what to do: (counts, advice) for
    :func:`optcal.core.recording.detection.too_few`. A recording in which no segment long enough is at rest
    (a continuous rotation) is said to be one."""
    sg: Segmentation = det.segmentation
    rec = det.recording
    b = sg.block
    L = (sg.segments[:, 1] - sg.segments[:, 0]) * b
    rate = float(rec.rate)
    sec = (lambda s: f"{s / rate:.3g} s") if np.isfinite(rate) else (lambda s: f"{s} samples")
    trend = sg.reason == "trend"
    noisy = sg.reason == "noisy"
    short_rest = sg.short
    turn = sg.reason == "turn"
    # the segments kept as rests first: "no segment at rest" was said of a recording that is one long rest
    parts = [(int(sg.kept.sum()), "rest"), (int(trend.sum() + turn.sum()), "turn"), (int(noisy.sum()), "shake"),
             (int(short_rest.sum()), f"rest < `min_static_s` = {sec(det.min_samples)}")]
    counts = ", ".join(f"{k} {what}" for k, what in parts if k) or "none"
    counts = "segments: " + counts + (f"; {sec(sg.n_bad_blocks * b)} saturated or missing" if sg.n_bad_blocks else "")
    longest = int(L[short_rest].max()) if short_rest.any() else 0
    moving_frac = float(L[~sg.rest].sum()) / max(len(rec), 1)
    # the rests a lower min_static_s would keep (at least half the shortest pose) and those found
    candidates = short_rest & (L >= det.min_samples // 2)
    seen = _orientations(rec, np.vstack([det.intervals, sg.segments[candidates] * b]))
    if det.n_intervals == 0 and moving_frac >= 0.5:
        advice = ("no part of the recording is at rest (a continuous motion, not held poses); hold poses still "
                  "for `min_static_s`, or give `intervals`")
    elif 0 < seen < needed:
        # its rests, and those a shorter min_static_s would keep, lie in fewer orientations than the model needs:
        # neither shorter poses nor another detector finds new ones (a lab's file of one face was told to lower
        # min_static_s, then refused again)
        advice = (f"the recording holds rests in just {seen} orientation(s); record at least {needed}, in different "
                  "orientations, each held still for `min_static_s`")
    elif short_rest.sum() >= needed - det.n_intervals and longest >= det.min_samples // 2:
        advice = (f"lower `min_static_s` to {max(np.floor(longest / rate * 10) / 10, 0.1):g} s"
                  if np.isfinite(rate) else "lower `min_static_s`")
    else:
        advice = ("record more poses, each held still for longer than `min_static_s`, or try `method` "
                  "variance or give `intervals`")
    return counts, advice


def _orientations(rec: Recording, ranges: np.ndarray) -> int:
    """How many orientations the sample ranges ``ranges`` (k, 2) of ``rec`` hold: their mean outputs' directions
    joined within :data:`ORIENTATION_DEG` (single linkage, :func:`optcal.core.analysis.pose_groups`)."""
    from optcal.core.analysis import pose_groups

    r = ranges[ranges[:, 1] > ranges[:, 0]]
    if not len(r):
        return 0
    N = np.where(np.isfinite(rec.N), rec.N, 0.0)
    c = np.concatenate([np.zeros((1, 3)), np.cumsum(N, axis=0)])
    means = (c[r[:, 1]] - c[r[:, 0]]) / (r[:, 1] - r[:, 0])[:, None]
    return len(np.unique(pose_groups(means, ORIENTATION_DEG)))


def interval_scores(found: np.ndarray, truth: np.ndarray, n: int, tol: int) -> dict:
    """Precision and recall of found intervals against true rests ([start, end) samples): a found interval
    is a true positive when it overlaps one true rest by at least half its own length and lies inside that
    rest but for ``tol`` samples at each end; a true rest is recalled when some true positive lies in it.
    Also the intersection over union of the static samples."""
    found = np.asarray(found, np.int64).reshape(-1, 2)
    truth = np.asarray(truth, np.int64).reshape(-1, 2)
    ov = np.clip(np.minimum(found[:, None, 1], truth[None, :, 1])
                 - np.maximum(found[:, None, 0], truth[None, :, 0]), 0, None)
    length = (found[:, 1] - found[:, 0])[:, None]
    inside = (found[:, None, 0] >= truth[None, :, 0] - tol) & (found[:, None, 1] <= truth[None, :, 1] + tol)
    tp_pair = (2 * ov >= length) & inside
    tp = tp_pair.any(axis=1)
    recalled = tp_pair.any(axis=0)
    a, b = np.zeros(n + 1, int), np.zeros(n + 1, int)
    for iv, arr in ((found, a), (truth, b)):
        np.add.at(arr, iv[:, 0], 1)
        np.add.at(arr, iv[:, 1], -1)
    ma, mb = np.cumsum(a)[:n] > 0, np.cumsum(b)[:n] > 0
    union = int((ma | mb).sum())
    return {"precision": float(tp.mean()) if len(found) else 1.0,
            "recall": float(recalled.mean()) if len(truth) else 1.0,
            "iou": float((ma & mb).sum() / union) if union else 1.0,
            "n_found": len(found), "n_true": len(truth), "n_false": int((~tp).sum())}
