"""Poses logged apart: a file that holds the poses and not the motions between them (docs/segmentation.md,
"Every rest, from every channel", step 11).

Loggers that record a burst of samples per pose at a key press (CK-Explorer's 100 rows per pose, the averaged
poses of many calibration tools) join the poses back to back: between two of them the outputs step in one
sample by the angle the sensor was turned, where a motion that was recorded takes many samples (a turn by hand
at 200 °/s moves gravity by 35 mg per sample at 100 Hz, on every sample of the turn). Such a step, a **jump**,
is a change of one sample beyond :data:`JUMP_G` of gravity and :data:`JUMP_RATIO` times every step within
:data:`JUMP_SIDE` samples either side of it. A knock steps out and back (two jumps one sample apart, with
nothing between them to keep). A segment with a jump at each end is a pose logged apart: nothing of the motion
that brought the sensor there, or took it away, is in the file. Its shaking is then a hand's tremor, not a
motion, and no slow motion begins at its ends (the hinge of step 6 looks for one).
"""

from __future__ import annotations

import numpy as np

JUMP_G = 0.03  # a jump changes the outputs by more than this fraction of gravity in one sample (a hand's
# tremor moves them by a few mg from one sample to the next; the poses of a logger differ by degrees, 17 mg each)
JUMP_RATIO = 3.0  # ... and by more than this many times every step within JUMP_SIDE samples of it
JUMP_SIDE = 5  # samples either side of a jump that must not step as far (a recorded turn steps on each sample)
TREMOR_G = 0.02  # a logged pose's block means scatter within this fraction of gravity: were it all tilt, the
# pose's mean would be shortened by g·(0.02)²/2 = 0.2 mg; beyond it the sensor was not held but moved


def jump_samples(N: np.ndarray, bad: np.ndarray, g: float) -> np.ndarray:
    """Samples j (sorted) where the outputs ``N`` (n, 3) jump from sample j − 1 to j (module docstring); ``g`` is
    gravity's magnitude in the outputs' units, ``bad`` (n,) the samples set aside (never part of a jump)."""
    n = len(N)
    if n < 2 or not g > 0:
        return np.zeros(0, np.int64)
    D = np.diff(N, axis=0)
    d = np.sqrt(np.einsum("ij,ij->i", D, D))
    d[bad[1:] | bad[:-1]] = np.inf  # a change to or from a sample set aside is no jump, nor beside one
    cand = np.flatnonzero((d > JUMP_G * g) & np.isfinite(d))  # few: the neighbours are looked at for these only
    if not len(cand):
        return cand
    side = np.concatenate([np.arange(-JUMP_SIDE, 0), np.arange(1, JUMP_SIDE + 1)])
    at = cand[:, None] + side[None, :]
    near = np.where((at >= 0) & (at < n - 1), d[np.clip(at, 0, n - 2)], 0.0).max(axis=1)
    return cand[d[cand] > JUMP_RATIO * near] + 1


def jump_bounded(seg: np.ndarray, jumps: np.ndarray, b: int, n_blocks: int) -> np.ndarray:
    """Whether each segment [a, b) of ``seg`` (k, 2), in blocks of ``b`` samples, has a jump at each end: within
    the block on either side of its boundary (a jump inside a block leaves that block to neither pose, and the
    change points cut on one side of it). The recording's first or last block bounds a segment as a jump does
    when its other end is at a jump (the logger's first and last poses)."""
    at = np.zeros(n_blocks + 2, bool)
    at[np.minimum(jumps // b, n_blocks + 1)] = True
    c = np.concatenate([[0], np.cumsum(at)])

    def near(k):  # a jump in block k − 1 or k: at the boundary before block k
        return c[np.minimum(k + 1, len(at))] - c[np.maximum(k - 1, 0)] > 0

    left, right = near(seg[:, 0]), near(seg[:, 1])
    return (left | (seg[:, 0] == 0) & right) & (right | (seg[:, 1] >= n_blocks) & left)


def tremor_within(Z: np.ndarray, seg: np.ndarray, scale: np.ndarray, g: float) -> np.ndarray:
    """Whether the block means ``Z`` (unit noise; ``scale`` their unit in the outputs' units) of each segment
    of ``seg`` scatter about its mean within :data:`TREMOR_G` of gravity ``g`` (the outputs' units)."""
    c = np.concatenate([np.zeros((1, 3)), np.cumsum(Z, axis=0)])
    c2 = np.concatenate([np.zeros((1, 3)), np.cumsum(Z * Z, axis=0)])
    L = np.maximum(seg[:, 1] - seg[:, 0], 1)[:, None]
    mean = (c[seg[:, 1]] - c[seg[:, 0]]) / L
    var = np.maximum((c2[seg[:, 1]] - c2[seg[:, 0]]) / L - mean**2, 0.0)
    return np.sqrt(np.sum(var * scale**2, axis=1)) <= TREMOR_G * g
