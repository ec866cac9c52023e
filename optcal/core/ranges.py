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


def range_means(x: np.ndarray, r: np.ndarray) -> np.ndarray:
    """The mean of ``x`` (n,) or (n, k) over each non-empty range of ``r`` (m, 2): (m,) or (m, k)."""
    r = np.asarray(r, np.int64).reshape(-1, 2)
    rows, _ = range_rows(r)
    lens = r[:, 1] - r[:, 0]
    first = np.cumsum(lens) - lens
    x = np.asarray(x, float)
    sums = np.add.reduceat(x[rows], first, axis=0)
    return sums / (lens if x.ndim == 1 else lens[:, None])


def range_means_sds(x: np.ndarray, r: np.ndarray, ddof: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """The means of ``x`` (n, k) over the non-empty ranges of ``r`` (m, 2), and the standard deviations about
    them with ``ddof`` (two passes, as ``numpy.std``: the deviations are taken from each range's own mean; 0
    for a range of at most ``ddof`` rows)."""
    r = np.asarray(r, np.int64).reshape(-1, 2)
    rows, which = range_rows(r)
    lens = r[:, 1] - r[:, 0]
    first = np.cumsum(lens) - lens
    y = np.asarray(x, float)[rows]
    means = np.add.reduceat(y, first, axis=0) / lens[:, None]
    y -= means[which]
    ss = np.add.reduceat(y * y, first, axis=0)
    dof = lens - ddof
    sds = np.sqrt(ss / np.where(dof > 0, dof, 1)[:, None]) * (dof > 0)[:, None]
    return means, sds
