"""Slow motions the gyroscope sees inside its still runs (issue #29; docs/segmentation.md, "Slow motions"): the
attitude straying by more than :data:`SLOW_DEG` while the rate stays under the turn threshold of
:func:`optcal.core.recording.segment.gyro_turning` (a hand letting a held pose sag at a few tenths of a degree per
second, a settling that creeps on).

The rule needs the rates in physical units, which a raw recording does not give. The accelerometer gives them
(:func:`gyro_scale`). First from above (:func:`scale_bound`): a motion between two rests turns the gravity
direction by θ, the angle between the rests' mean specific forces, and the gyroscope's outputs, less their level
at rest, integrate over it to at least K·θ for a scale factor of K output units per rad/s (a turn about gravity
adds to the path and not to θ); the least ratio over the motions that turn gravity by :data:`SCALE_MIN_TURN_DEG`
or more is K's bound (a turn the gyroscope did not see, in a recording cut and joined, left out: no turning
sample between the rests, or a ratio under half the others' median). The bound is K where a motion turns about
one axis across gravity, and above it otherwise (far above where the motions turn about gravity;
docs/segmentation.md gives the corpus's), which would make the rule lenient. Then the one K under which the motions, the
rates integrated as rotations (:class:`optcal.core.motion_integrator.MotionIntegrator`), best carry each rest's
gravity direction onto the next's (the residual of imu_tk's gyroscope fit, Tedaldi et al. ICRA 2014 §IV-B,
with a single scale): on a grid near the bound, else over the whole bracket below it, refined by a parabola's
vertex; it is kept when it explains the turns (what is left of them at most :data:`SCALE_FIT_MAX_LEFT` of their
size), else the bound. The accelerometer is not calibrated yet: its axes'
scale errors (a few %) move the gravity directions by as much, so K is known within a few %
(tests/test_attitude.py).

Within each still run the attitude is the rate integrated, the run's median rate taken out first (a rate
offset that changes with the pose, a gyroscope's g-sensitivity, is not a turn). A sample moves when (a) the
attitude lies off its median over the piece of the run around it (pieces of at most :data:`SLOW_CHUNK_S`) by
more than :data:`SLOW_DEG` and :data:`SLOW_SIGMAS` times the walk of the integrated white noise over the piece,
or (b) it is the centre of a window of :data:`SLOW_WINDOWS_S` inside the run whose last quarter's mean attitude
lies that far from its first quarter's (the middle of a slow turn, which (a) misses near the median).
"""

from __future__ import annotations

import numpy as np

from optcal.core.motion_integrator import MotionIntegrator, log_vertex, rotate_back
from optcal.core.recording.detection import chunks, group_medians, range_rows, runs

NOISE_PATH = 3.0  # a motion's path must exceed this many times the rests' noise path over as long (scale_bound)
SLOW_DEG = 0.2  # °: the attitude straying more than this inside a still run moves (a hand's wobble stays within)
SLOW_SIGMAS = 5.0  # ... and more than this × the walk of the integrated white noise over the stretch judged
SLOW_CHUNK_S = 4.0  # s: a still run's attitude is compared with its median over pieces of at most this
SLOW_WINDOWS_S = (0.5, 1.0)  # s: windows whose centre moves when they turn by as much
SCALE_MIN_TURN_DEG = 20.0  # °: motions that turn gravity less than this give no useful bound on the scale
SCALE_FIT_MOTIONS = 8  # the scale is fitted on this many motions, those that turn gravity the most
SCALE_FIT_BRACKET = (0.2, 1.1)  # × the bound: the fit's candidates (a bound 4 × K seen on turns about gravity)
SCALE_FIT_NEAR = (0.88, 1.1)  # × the bound: the candidates tried first (5.7 % apart)
SCALE_FIT_POINTS = (14, 5)  # candidates of the whole bracket (14 % apart), and of a fine grid
SCALE_FIT_PAD_S = 0.25  # s: each motion is integrated from this before its first turning sample to this after its last
SCALE_FIT_MAX_LEFT = 0.25  # the fit is kept when the RMS angle it leaves is at most this × the turns' RMS


def scale_bound(X: np.ndarray, A: np.ndarray, rests: np.ndarray, turning: np.ndarray, rate: float) -> float:
    """Output units per rad/s, bounded from above (module docstring): ``X`` (n, 3) the rates less their level at
    rest (averaged over a fraction of a second, so that the rests' noise adds little to the path), ``A`` (k, 3)
    the mean specific force of each rest ``rests`` (k, 2) [start, end) samples in time order (offsets taken
    out), ``turning`` (n,) the samples the gyroscope sees turning. The path runs from one rest's middle to the
    next's; a motion without a turning sample there bounds nothing. NaN when no motion turns gravity by
    :data:`SCALE_MIN_TURN_DEG`."""
    if len(rests) < 2:
        return float("nan")
    # a turn the gyroscope did not see (a recording cut and joined, a sensor re-seated while logging paused) has
    # no turning sample between the rests, or next to nothing of the others' ratio: no bound
    _, theta, mid, big = _motions(A, rests, turning)
    step = np.linalg.norm(X, axis=1)
    path = np.concatenate([[0.0], np.cumsum(step)]) / rate
    moved = path[mid[1:]] - path[mid[:-1]]
    # nor does one whose path is what the rests' own noise draws in as long (poses logged apart, their gyroscope at
    # its level throughout: a flicker counted as turning gave 0.04 output units per rad/s for a gyroscope in °/s)
    at_rest = float(np.median(step[range_rows(rests)[0]])) if len(rests) else 0.0
    big &= moved > NOISE_PATH * at_rest * (mid[1:] - mid[:-1]) / rate
    if not big.any():
        return float("nan")
    ratio = moved[big] / theta[big]
    return float(np.min(ratio[ratio >= 0.5 * np.median(ratio)]))


def _motions(A: np.ndarray, rests: np.ndarray, turning: np.ndarray):
    """The rests' unit gravity directions (k, 3), the angles θ (k − 1,) between neighbours, each rest's middle
    sample, and which motions bound the scale (θ of :data:`SCALE_MIN_TURN_DEG` or more, a turning sample seen
    between the middles)."""
    u = A / np.maximum(np.linalg.norm(A, axis=1, keepdims=True), 1e-300)
    theta = np.arccos(np.clip(np.sum(u[1:] * u[:-1], axis=1), -1.0, 1.0))
    seen = np.concatenate([[0], np.cumsum(turning)])
    mid = (rests[:, 0] + rests[:, 1]) // 2
    big = (theta >= np.radians(SCALE_MIN_TURN_DEG)) & (seen[mid[1:]] > seen[mid[:-1]])
    return u, theta, mid, big


def gyro_scale(X: np.ndarray, M: np.ndarray, A: np.ndarray, rests: np.ndarray, turning: np.ndarray,
               rate: float) -> float:
    """Output units per rad/s (module docstring): the scale fitted to the motions' rotations of gravity, or, when
    that fit does not explain them, :func:`scale_bound`. ``X`` (n, 3) the rates less their level at rest, ``M``
    the same averaged (for the bound); ``A``, ``rests``, ``turning``, ``rate`` as :func:`scale_bound`. NaN
    without a motion that turns gravity by :data:`SCALE_MIN_TURN_DEG`."""
    bound = scale_bound(M, A, rests, turning, rate)
    if not (np.isfinite(bound) and bound > 0):
        return bound
    u, theta, mid, big = _motions(A, rests, turning)
    k = np.flatnonzero(big)
    k = np.sort(k[np.argsort(theta[k], kind="stable")[::-1][:SCALE_FIT_MOTIONS]])
    # each motion from its first turning sample to its last, with a margin (the rests between add nothing but
    # their noise to the rotation, and most of the integration's cost)
    on = np.flatnonzero(turning)
    pad = int(round(SCALE_FIT_PAD_S * rate))
    first = on[np.searchsorted(on, mid[k])]
    last = on[np.searchsorted(on, mid[k + 1]) - 1]
    start = np.maximum(first - pad, mid[k])
    stop = np.minimum(last + 1 + pad, mid[k + 1])
    it = MotionIntegrator(np.arange(len(X)) / rate, start, stop)
    w = np.ascontiguousarray(np.asarray(X, float)[it.samples].T)  # (3, samples)
    u0, u1 = u[k].T[:, None, :], u[k + 1].T[:, None, :]  # (3, 1, m)

    def cost(ks):  # Σ over the motions of |R(K)ᵀ u_before − u_after|², per candidate K
        v = rotate_back(it.attitudes(w[:, None, :] / ks[None, :, None]), u0)
        return np.sum((v - u1) ** 2, axis=(0, 2))

    # first near the bound, where K lies when some motion turns across gravity; else the whole bracket
    fine = np.geomspace(SCALE_FIT_NEAR[0] * bound, SCALE_FIT_NEAR[1] * bound, SCALE_FIT_POINTS[1])
    c = cost(fine)
    j = int(np.argmin(c))
    if j in (0, len(fine) - 1):
        ks = np.geomspace(SCALE_FIT_BRACKET[0] * bound, SCALE_FIT_BRACKET[1] * bound, SCALE_FIT_POINTS[0])
        i = int(np.argmin(cost(ks)))
        if i in (0, len(ks) - 1):  # the best at the bracket's edge: no minimum inside, the fit says nothing
            return bound
        fine = np.geomspace(ks[i - 1], ks[i + 1], SCALE_FIT_POINTS[1])
        c = cost(fine)
        j = int(np.argmin(c))
    left = np.sqrt(c[j] / len(k))  # the RMS chord left, about the angle in rad
    if left > SCALE_FIT_MAX_LEFT * np.sqrt(np.mean(theta[k] ** 2)):
        return bound  # the rotations do not carry gravity (a recording cut and joined, a gyroscope's other axes)
    return log_vertex(fine, c)


def slow_motions(X: np.ndarray, still: np.ndarray, K: float, s: np.ndarray, rate: float) -> np.ndarray:
    """Samples (n,) of the still runs of ``still`` whose attitude strays (module docstring, rules a and b): ``X``
    (n, 3) the rates as output (each run's median is taken out: one bias per run, which does not drift in
    seconds), ``K`` output units per rad/s (:func:`gyro_scale`), ``s`` (3,) their white noise SD of a sample.
    Vectorised over runs, pieces and windows through cumulative sums."""
    n = len(X)
    out = np.zeros(n, bool)
    r = runs(still)
    r = r[r[:, 1] - r[:, 0] >= 4]
    if not len(r):
        return out
    R = X / K  # rad/s
    idx, which = range_rows(r)
    run_of = np.full(n, -1)
    run_of[idx] = which
    inside = run_of >= 0
    # the attitude (rad) from each run's start, its median rate taken out
    Rl = np.where(inside[:, None], R - group_medians(R, r)[np.maximum(run_of, 0)], 0.0)
    c = np.concatenate([np.zeros((1, 3)), np.cumsum(Rl, axis=0)]) / rate
    Phi = np.where(inside[:, None], c[1:] - c[r[np.maximum(run_of, 0), 0]], 0.0)
    noise = float(np.linalg.norm(s / K)) / rate  # rad: the integrated white noise's step
    slow = np.radians(SLOW_DEG)
    # (a) off the median of its piece
    pieces = chunks(r, max(4, int(round(SLOW_CHUNK_S * rate))))
    plen = pieces[:, 1] - pieces[:, 0]
    thr = np.maximum(slow, SLOW_SIGMAS * noise * np.sqrt(plen / 4.0))
    med = group_medians(Phi, pieces)
    at, piece_of = range_rows(pieces)
    out[at] = np.linalg.norm(Phi[at] - med[piece_of], axis=1) > thr[piece_of]
    # (b) the centres of windows inside a run that turn
    cp = np.concatenate([np.zeros((1, 3)), np.cumsum(Phi, axis=0)])
    for L in sorted({max(8, int(round(w * rate))) for w in SLOW_WINDOWS_S}):  # two window lengths
        if n < L:
            continue
        # windows inside one run (runs are contiguous: the first and last samples' run is the whole window's)
        i = np.flatnonzero((run_of[: n - L + 1] >= 0) & (run_of[: n - L + 1] == run_of[L - 1:]))
        q = L // 4
        turn = np.linalg.norm((cp[i + L] - cp[i + L - q]) - (cp[i + q] - cp[i]), axis=1) / q
        out[i[turn > max(slow, SLOW_SIGMAS * noise * np.sqrt(L / 4.0))] + L // 2] = True
    return out

