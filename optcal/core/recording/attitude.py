"""Slow motions the gyroscope sees inside its still runs (issue #29; docs/segmentation.md, "Slow motions"): the
attitude straying by more than :data:`SLOW_DEG` while the rate stays under the turn threshold of
:func:`optcal.core.recording.segment.gyro_turning` (a hand letting a held pose sag at a few tenths of a degree per
second, a settling that creeps on).

The rule needs the rates in physical units, which a raw recording does not give. The accelerometer gives them
from above (:func:`scale_bound`): a motion between two rests turns the gravity direction by θ, the angle between
the rests' mean specific forces, and the gyroscope's outputs, less their level at rest, integrate over it to at
least K·θ for a scale factor of K output units per rad/s (a turn about gravity adds to the path and not to θ);
the least ratio over the motions that turn gravity by :data:`SCALE_MIN_TURN_DEG` or more is K's bound (a turn
the gyroscope did not see, in a recording cut and joined, left out: no turning sample between the rests, or a
ratio under half the others' median). The accelerometer is not calibrated yet: its axes' scale errors (a few %)
move θ by as much, so the bound is K within a few % (tests/test_attitude.py), above it where the turns are not
about axes across gravity; a bound above K makes the rule lenient, not strict.

Within each still run the attitude is the rate integrated, the run's median rate taken out first (a rate
offset that changes with the pose, a gyroscope's g-sensitivity, is not a turn). A sample moves when (a) the
attitude lies off its median over the piece of the run around it (pieces of at most :data:`SLOW_CHUNK_S`) by
more than :data:`SLOW_DEG` and :data:`SLOW_SIGMAS` times the walk of the integrated white noise over the piece,
or (b) it is the centre of a window of :data:`SLOW_WINDOWS_S` inside the run whose last quarter's mean attitude
lies that far from its first quarter's (the middle of a slow turn, which (a) misses near the median).
"""

from __future__ import annotations

import numpy as np

from optcal.core.recording.detection import chunks, group_medians, range_rows, runs

SLOW_DEG = 0.2  # °: the attitude straying more than this inside a still run moves (a hand's wobble stays within)
SLOW_SIGMAS = 5.0  # ... and more than this × the walk of the integrated white noise over the stretch judged
SLOW_CHUNK_S = 4.0  # s: a still run's attitude is compared with its median over pieces of at most this
SLOW_WINDOWS_S = (0.5, 1.0)  # s: windows whose centre moves when they turn by as much
SCALE_MIN_TURN_DEG = 20.0  # °: motions that turn gravity less than this give no useful bound on the scale


def scale_bound(X: np.ndarray, A: np.ndarray, rests: np.ndarray, turning: np.ndarray, rate: float) -> float:
    """Output units per rad/s, bounded from above (module docstring): ``X`` (n, 3) the rates less their level at
    rest (averaged over a fraction of a second, so that the rests' noise adds little to the path), ``A`` (k, 3)
    the mean specific force of each rest ``rests`` (k, 2) [start, end) samples in time order (offsets taken
    out), ``turning`` (n,) the samples the gyroscope sees turning. The path runs from one rest's middle to the
    next's; a motion without a turning sample there bounds nothing. NaN when no motion turns gravity by
    :data:`SCALE_MIN_TURN_DEG`."""
    if len(rests) < 2:
        return float("nan")
    u = A / np.maximum(np.linalg.norm(A, axis=1, keepdims=True), 1e-300)
    theta = np.arccos(np.clip(np.sum(u[1:] * u[:-1], axis=1), -1.0, 1.0))
    path = np.concatenate([[0.0], np.cumsum(np.linalg.norm(X, axis=1))]) / rate
    seen = np.concatenate([[0], np.cumsum(turning)])
    mid = (rests[:, 0] + rests[:, 1]) // 2
    moved = path[mid[1:]] - path[mid[:-1]]
    # a turn the gyroscope did not see (a recording cut and joined, a sensor re-seated while logging paused) has
    # no turning sample between the rests, or next to nothing of the others' ratio: no bound
    big = (theta >= np.radians(SCALE_MIN_TURN_DEG)) & (seen[mid[1:]] > seen[mid[:-1]])
    if not big.any():
        return float("nan")
    ratio = moved[big] / theta[big]
    return float(np.min(ratio[ratio >= 0.5 * np.median(ratio)]))


def slow_motions(X: np.ndarray, still: np.ndarray, K: float, s: np.ndarray, rate: float) -> np.ndarray:
    """Samples (n,) of the still runs of ``still`` whose attitude strays (module docstring, rules a and b): ``X``
    (n, 3) rates less their level at rest, ``K`` output units per rad/s (:func:`scale_bound`), ``s`` (3,) their
    white noise SD of a sample. Vectorised over runs, pieces and windows through cumulative sums."""
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

