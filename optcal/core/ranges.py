"""Ranges of rows [start, end) of an array: their members, means and standard deviations, for all ranges at
once. A recording's rests, motions and pieces are tens to hundreds of ranges; one NumPy pass over their
members replaces a Python loop over them (each slice reduced on its own costs tens of microseconds of call
overhead, which dominates for short ranges)."""

from __future__ import annotations

import numpy as np


def range_rows(r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The rows of every range [start, end) of ``r`` (k, 2), in order, and the range each belongs to: the one
    way optcal lists ranges' members without a loop over them."""
    lens = r[:, 1] - r[:, 0]
    which = np.repeat(np.arange(len(r)), lens)
    return np.arange(int(lens.sum())) - np.repeat(np.cumsum(lens) - lens, lens) + np.repeat(r[:, 0], lens), which


def pooled(x: np.ndarray, r: np.ndarray):
    """The rows of the non-empty ranges ``r`` (m, 2) of ``x`` (n, k) one after another, each about its range's
    mean; the ranges' lengths, where each starts among the pooled rows, and their means (m, k)."""
    r = np.asarray(r, np.int64).reshape(-1, 2)
    rows, _ = range_rows(r)
    lengths = r[:, 1] - r[:, 0]
    first = np.cumsum(lengths) - lengths
    y = np.asarray(x, float)[rows]
    means = np.add.reduceat(y, first, axis=0) / lengths[:, None]
    return y - np.repeat(means, lengths, axis=0), lengths, first, means


def range_means(x: np.ndarray, r: np.ndarray) -> np.ndarray:
    """The mean of ``x`` (n,) or (n, k) over each non-empty range of ``r`` (m, 2): (m,) or (m, k)."""
    x = np.asarray(x, float)
    means = pooled(x.reshape(len(x), -1), r)[3]
    return means[:, 0] if x.ndim == 1 else means


def pooled_sds(y: np.ndarray, lengths: np.ndarray, first: np.ndarray, ddof: int = 1) -> np.ndarray:
    """The standard deviations (m, k) of the ranges of :func:`pooled`'s rows ``y`` (each about its mean), with
    ``ddof``; 0 for a range of at most ``ddof`` rows."""
    dof = lengths - ddof
    ss = np.add.reduceat(y * y, first, axis=0)
    return np.sqrt(ss / np.where(dof > 0, dof, 1)[:, None]) * (dof > 0)[:, None]


def range_means_sds(x: np.ndarray, r: np.ndarray, ddof: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """The means of ``x`` (n, k) over the non-empty ranges of ``r`` (m, 2), and the standard deviations about
    them with ``ddof`` (two passes, as ``numpy.std``: the deviations are taken from each range's own mean)."""
    y, lengths, first, means = pooled(x, r)
    return means, pooled_sds(y, lengths, first, ddof)
