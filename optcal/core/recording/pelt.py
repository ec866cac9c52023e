"""Exact PELT (Killick, Fearnhead & Eckley, JASA 2012) for the L2 cost of three-column series: the change
points of the linear-kernel cost that ruptures' ``KernelCPD(kernel="linear", min_size=1, jump=1)`` finds,
the same to the point (tests/test_segmentation_pelt.py checks both on random series and on raw recordings of
the real corpus, docs/real_data.md).

Segmentation calls :func:`pelt_ends`, which takes ruptures' compiled PELT (``ekcpd_pelt_L2``, the kernel behind
``KernelCPD(kernel="linear").predict(pen=...)``) straight from its extension file (:func:`compiled_pelt_l2`): that
file needs only NumPy and loads in milliseconds, where importing the ruptures package imports scipy.stats,
scipy.spatial and scipy.signal with it, 0.8 to 1.2 s on the project's machine, more than the whole of a
calibration from a recording of tens of thousands of samples is meant to take. The NumPy implementation below
serves when an installed ruptures lays its files out otherwise, and is the reference the tests hold the compiled
one to. Here the optimal
partition F(t) = min_{s ∈ R_t} F(s) + C(s, t) + β is computed with cumulative sums (C(s, t) = Σ‖z‖² −
‖Σz‖²/(t − s) over the blocks s..t−1) and PELT's pruning R_{t+1} = {s ∈ R_t ∪ {t}: F(s) + C(s, t) ≤ F(t)}; the
candidates are scanned in Python while few (the usual case after a change) and in NumPy while many (inside
a long rest), about 20 µs a block. :func:`pelt_l2_many` runs several series (segmentation's pieces of one
recording) in lockstep, one NumPy pass over all their candidates per block, which costs about what one series
costs alone; without the compiled kernel, ruptures' public API serves series long enough to amortise its import
(:data:`RUPTURES_FROM_BLOCKS`).
"""

from __future__ import annotations

import functools
import importlib.machinery
import importlib.util
import sys
from pathlib import Path

import numpy as np

VECTOR_FROM = 48  # candidates at which one NumPy pass beats the Python loop over them
RUPTURES_FROM_BLOCKS = 20_000  # blocks in a recording from which ruptures' compiled PELT pays for its import


def pelt_l2(Z: np.ndarray, penalty: float) -> list[int]:
    """Ends of the segments (the last one ``len(Z)``) of the penalised L2 partition of ``Z`` (n, 3), as
    ruptures' ``predict(pen=penalty)`` returns them."""
    Z = np.asarray(Z, float)
    n = len(Z)
    if Z.ndim != 2 or Z.shape[1] != 3:
        raise ValueError(f"pelt_l2 takes an (n, 3) series, got shape {Z.shape}")
    S = np.zeros((n + 1, 3))
    np.cumsum(Z, axis=0, out=S[1:])
    Q = np.zeros(n + 1)
    np.cumsum(np.einsum("ij,ij->i", Z, Z), out=Q[1:])
    sx, sy, sz = (S[:, j].tolist() for j in range(3))
    q = Q.tolist()
    F = [0.0] * (n + 1)
    F[0] = -penalty
    Fa = np.empty(n + 1)  # F as an array, for the NumPy pass
    Fa[0] = -penalty
    last = [0] * (n + 1)
    R = [0]
    for t in range(1, n + 1):
        if len(R) >= VECTOR_FROM:
            Ra = np.fromiter(R, np.int64, len(R))
            d = S[t] - S[Ra]
            c = Fa[Ra] + (q[t] - Q[Ra]) - np.einsum("ij,ij->i", d, d) / (t - Ra)
            k = int(np.argmin(c))
            best, arg = float(c[k]), R[k]
            R = Ra[c <= best + penalty].tolist()
        else:
            xt, yt, zt, qt = sx[t], sy[t], sz[t], q[t]
            costs = []
            best, arg = float("inf"), 0
            for s in R:
                dx, dy, dz = xt - sx[s], yt - sy[s], zt - sz[s]
                c = F[s] + (qt - q[s]) - (dx * dx + dy * dy + dz * dz) / (t - s)
                costs.append(c)
                if c < best:
                    best, arg = c, s
            R = [s for s, c in zip(R, costs) if c <= best + penalty]
        F[t] = Fa[t] = best + penalty
        last[t] = arg
        R.append(t)
    ends, t = [], n
    while t > 0:
        ends.append(t)
        t = last[t]
    return ends[::-1]


def pelt_l2_many(series: list[np.ndarray], penalty: float) -> list[list[int]]:
    """:func:`pelt_l2` of each (n_i, 3) series, the series' candidates side by side in flat arrays (grouped by
    series) so that each block t is one NumPy pass for all series: per series the minimum of
    F(s) + C(s, t) (the first in candidate order, as :func:`pelt_l2` takes it) and the same pruning."""
    if len(series) < 2:
        return [pelt_l2(Z, penalty) for Z in series]
    P = len(series)
    n = np.array([len(Z) for Z in series])
    W = int(n.max()) + 1  # a series' row in the flat arrays: sums after 0..n blocks
    S = np.zeros((P, W, 3))
    Q = np.zeros((P, W))
    for p, Z in enumerate(series):
        Z = np.asarray(Z, float)
        if Z.ndim != 2 or Z.shape[1] != 3:
            raise ValueError(f"pelt_l2 takes an (n, 3) series, got shape {Z.shape}")
        np.cumsum(Z, axis=0, out=S[p, 1:n[p] + 1])
        np.cumsum(np.einsum("ij,ij->i", Z, Z), out=Q[p, 1:n[p] + 1])
    Sx, Sy, Sz = (np.ascontiguousarray(S[:, :, j]).ravel() for j in range(3))
    Q = Q.ravel()
    F = np.zeros(P * W)
    last = np.zeros(P * W, np.int64)
    F[::W] = -penalty
    rows = np.flatnonzero(n > 0) * W  # each candidate: its series' row offset and its start s, grouped by series
    cand = np.zeros(len(rows), np.int64)
    for t in range(1, W):
        if t > n.min():  # drop the series that have ended
            live = n[rows // W] >= t
            rows, cand = rows[live], cand[live]
        g, at = rows + cand, rows + t
        dx, dy, dz = Sx[at] - Sx[g], Sy[at] - Sy[g], Sz[at] - Sz[g]
        c = F[g] + (Q[at] - Q[g]) - (dx * dx + dy * dy + dz * dz) / (t - cand)
        head = np.flatnonzero(np.concatenate(([True], rows[1:] != rows[:-1])))
        best = np.minimum.reduceat(c, head)
        best_each = np.repeat(best, np.diff(np.append(head, len(c))))
        at_min = np.flatnonzero(c == best_each)
        arg = at_min[np.concatenate(([True], rows[at_min][1:] != rows[at_min][:-1]))]
        now = rows[head] + t
        F[now] = best + penalty
        last[now] = cand[arg]
        keep = c <= best_each + penalty
        # the kept candidates, then t for every series, back in series order
        rows = np.concatenate((rows[keep], rows[head]))
        cand = np.concatenate((cand[keep], np.full(len(head), t)))
        order = np.argsort(rows, kind="stable")
        rows, cand = rows[order], cand[order]
    out = []
    for p in range(P):
        ends, t = [], int(n[p])
        while t > 0:
            ends.append(t)
            t = int(last[p * W + t])
        out.append(ends[::-1])
    return out


EKCPD = "ruptures.detection._detection.ekcpd"  # the extension module that holds ruptures' compiled kernel CPD


@functools.cache
def compiled_pelt_l2():
    """ruptures' compiled PELT for the linear kernel, ``ekcpd_pelt_L2(signal, penalty, min_size)`` (it returns, for
    each end t, the start of the last segment), or None. Taken from ``sys.modules`` when ruptures is imported;
    otherwise its extension file is loaded on its own, without the package's ``__init__`` and the scipy modules
    that come with it (the extension itself imports only NumPy). None when ruptures is not installed or its files
    are laid out otherwise (:func:`pelt_ends` then uses :func:`pelt_l2_many`)."""
    if EKCPD in sys.modules:
        return getattr(sys.modules[EKCPD], "ekcpd_pelt_L2", None)
    spec = importlib.util.find_spec("ruptures")  # finds the package without importing it
    if spec is None or not spec.submodule_search_locations:
        return None
    folder = Path(next(iter(spec.submodule_search_locations))) / "detection" / "_detection"
    files = [f for f in folder.glob("ekcpd*") if f.name.endswith(tuple(importlib.machinery.EXTENSION_SUFFIXES))]
    if len(files) != 1:
        return None
    try:
        loader = importlib.machinery.ExtensionFileLoader(EKCPD, str(files[0]))
        module = importlib.util.module_from_spec(importlib.util.spec_from_file_location(EKCPD, files[0],
                                                                                      loader=loader))
        loader.exec_module(module)
    except ImportError:
        return None
    return getattr(module, "ekcpd_pelt_L2", None)


def pelt_ends(series: list[np.ndarray], penalty: float) -> list[list[int]]:
    """:func:`pelt_l2` of each (n_i, 3) series: by ruptures' compiled kernel (:func:`compiled_pelt_l2`) when it
    loads, else :func:`pelt_l2_many` for series of fewer than :data:`RUPTURES_FROM_BLOCKS` blocks in all and
    ruptures' public API for longer ones."""
    kernel = compiled_pelt_l2()
    if kernel is None:
        if sum(len(Z) for Z in series) < RUPTURES_FROM_BLOCKS:
            return pelt_l2_many(series, penalty)
        import ruptures  # here: its import costs a second, repaid only on long recordings

        return [ruptures.KernelCPD(kernel="linear", min_size=1, jump=1).fit(Z).predict(pen=penalty) for Z in series]
    out = []
    for Z in series:  # one compiled call per piece: a handful per recording
        start = kernel(np.ascontiguousarray(Z, dtype=float), float(penalty), 1)
        ends, t = [], len(Z)
        while t > 0:
            ends.append(t)
            t = int(start[t])
        out.append(ends[::-1])
    return out
