"""The outlier scan and the pose groups on many positions (a new user's file of 5,200 reference rows took over
15 minutes and 5.5 GB; docs/design.md, "Per-position residuals"): the hat matrix is carried as its factor
U (m, rank), H = UUᵀ, and the downdate over the set-aside positions goes through Woodbury's identity. These
tests hold the factored scan to the dense textbook downdate (Belsley, Kuh & Welsch 1980, §2.1) on data with
several displaced positions, with the noise stated and unknown, plain and with a reference."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from optcal import solvers
from optcal.core.analysis import _hat_factor, _scan, pose_groups
from optcal.core.model import get_model
from optcal.core.presets import PAPER_TRUTH
from optcal.core.problem import CalibrationProblem
from optcal.core.simulate import simulate

MODEL = get_model("nonlinear12")
TRUTH = {k: v for k, v in PAPER_TRUTH.items() if k in MODEL.names}
SIGMA = 10e-6
BAD = (3, 11, 17)


def _dense_scan(r, H, sigma, d, dof, alpha1):
    """The backward scan with H as a dense matrix and p-values of every position at each step: the reference."""
    from optcal.core.distributions import chi2_sf, f_sf

    m = len(r)
    n = m // d
    D: list[int] = []
    while True:
        rows = np.array([k for i in D for k in range(i * d, i * d + d)], int)
        if rows.size:
            A = np.linalg.inv(np.eye(rows.size) - H[np.ix_(rows, rows)])
            rr = r + H[:, rows] @ (A @ r[rows])
            HH = H + H[:, rows] @ A @ H[rows, :]
        else:
            A, rr, HH = None, r, H
        e2 = rr**2 / (1.0 - np.diag(HH))
        keep = np.ones(m, bool)
        keep[rows] = False
        nu = dof - rows.size
        if sigma is None:
            rss = float(np.sum(rr[keep] ** 2))
            per = np.add.reduceat(np.where(keep, e2, 0.0), np.arange(0, m, d))
            sig = np.repeat(np.sqrt(np.clip(rss - per, 0.0, None) / max(nu - d, 1)), d)
            q = np.add.reduceat(e2 / sig**2, np.arange(0, m, d))
            pv = f_sf(q / d, d, nu - d)
        else:
            q = np.add.reduceat(e2 / sigma**2, np.arange(0, m, d))
            pv = chi2_sf(q, d)
        off = rr.copy()
        if D:
            eD = A @ r[rows]
            off[rows] = eD
            sD = np.full(rows.size, np.sqrt(rss / max(nu, 1))) if sigma is None else sigma[rows]
            qD = (eD**2 / (np.diag(A) * sD**2)).reshape(-1, d).sum(axis=1)
            q[D] = qD
            pv[D] = f_sf(qD / d, d, max(nu, 1)) if sigma is None else chi2_sf(qD, d)
        cand = [i for i in range(n) if i not in D]
        if not cand or len(D) >= n // 2 or (sigma is None and nu - 2 * d < 1):
            return D, np.sqrt(q), pv, off
        j = max(cand, key=lambda i: q[i])
        if pv[j] >= alpha1:
            return D, np.sqrt(q), pv, off
        D.append(j)


@pytest.mark.parametrize("reference", [False, True], ids=["magnitude", "reference"])
@pytest.mark.parametrize("stated", [True, False], ids=["stated", "unknown"])
def test_factored_scan_is_the_dense_downdate(reference, stated):
    sim = simulate(MODEL, TRUTH, np.random.default_rng(5), scheme="36", noise_g=SIGMA, reference=reference)
    N = sim.data.N.copy()
    for k, i in enumerate(BAD):  # three displaced positions, 0.5-1.5 mg
        N[i] += (0.5e-3 * (k + 1)) * N[i] / np.linalg.norm(N[i])
    p = CalibrationProblem(MODEL, replace(sim.data, N=N), reference=reference)
    x = solvers.get("scipy-lm").solve(p, rng=0).x
    r = p.position_residuals(x)
    d = p.rows_per_position
    U, dof = _hat_factor(p, x)
    assert U.shape == (len(r), MODEL.n_params)  # the factor, a column per parameter: never m × m
    sigma = np.full(len(r), SIGMA) if stated else None
    alpha1 = 1.0 - (1.0 - 0.01) ** (1.0 / len(p.data))
    D, stat, pv, off, _ = _scan(r, U, sigma, d, dof, alpha1, True)
    D0, stat0, pv0, off0 = _dense_scan(r, U @ U.T, sigma, d, dof, alpha1)
    assert sorted(D) == sorted(BAD) and D == D0  # the three, in the same order
    np.testing.assert_allclose(stat, stat0, rtol=1e-8)
    np.testing.assert_allclose(pv, pv0, rtol=1e-6, atol=1e-300)
    np.testing.assert_allclose(off, off0, rtol=1e-8, atol=1e-12)


def test_pose_groups_follow_chains_and_separate_poses_across_blocks():
    """Single linkage at 1°: a chain of directions 0.5° apart over 30° is one pose however long (the pointer
    jumping ends it in a few rounds), a pose 5° away is another, and blocks of GROUP_BLOCK rows change nothing."""
    ang = np.radians(np.arange(0.0, 30.0, 0.5))
    chain = np.column_stack([np.sin(ang), np.zeros_like(ang), np.cos(ang)])
    far = np.array([[0.0, np.sin(np.radians(5.0)), -np.cos(np.radians(5.0))]])
    other = far * np.array([1, -1, 1])  # 10° from `far`
    A = np.vstack([chain, far, far * 1.001, other])
    g = pose_groups(A)
    assert len(set(g[: len(chain)])) == 1
    assert g[len(chain)] == g[len(chain) + 1] != g[0]
    assert g[-1] not in (g[0], g[len(chain)])
    # 3,000 positions in 3 poses (more than one block): 3 groups
    rng = np.random.default_rng(0)
    poses = np.eye(3)[rng.integers(0, 3, 3000)] + rng.normal(0, 1e-3, (3000, 3))
    g = pose_groups(poses)
    assert len(np.unique(g)) == 3
