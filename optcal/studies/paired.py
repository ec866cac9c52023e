"""Paired comparisons between a study's solvers over the same Monte-Carlo runs.

Run i of every solver sees the same data (:mod:`optcal.studies.trial`), so two solvers' per-run accuracies are
paired, and a paired test compares them without the run-to-run scatter of the data. In each model × scheme
every solver is compared with the cell's best (its first in the report's ranking) by the Wilcoxon signed-rank
test on the per-run differences (Wilcoxon 1945; ``scipy.stats.wilcoxon``, two-sided, exact for small samples
without ties), and the cell's p-values are adjusted together by Holm's step-down procedure (Holm 1979), which
holds the family-wise error rate at the level without assuming the tests independent. The effect size is
the matched-pairs rank-biserial correlation r = (W₊ − W₋) / (W₊ + W₋) of the same signed ranks (Kerby 2014):
+1 when the solver is worse than the best in every run, 0 when neither is ahead; with the median paired
difference, it says how large a significant difference is.

The per-run value compared is the one the report ranks on: the RMS over parameters of |error| / bound, with
the bound of data and presets together when the study has presets (:func:`optcal.studies.scoring.crlb_with_presets`,
the ``crlb_presets`` column) and the observable part against the data's bound otherwise (the ``accuracy``
column). A run where either trial failed is left out of that pair (n says how many remain).
"""

from __future__ import annotations

import numpy as np

LEVEL = 0.05  # family-wise error rate of a cell's comparisons


def run_value(row: dict, presets: bool) -> float:
    """The per-run accuracy a comparison uses (see the module docstring); NaN for a failed trial."""
    if row.get("status") != "ok":
        return float("nan")
    if presets:
        err, sd = row.get("err"), row.get("crlb_presets")
        if not err or not sd:
            return float("nan")
        return float(np.sqrt(np.mean((np.asarray(err, float) / np.asarray(sd, float)) ** 2)))
    v = row.get("accuracy")
    return float("nan") if v is None else float(v)


def holm(p) -> np.ndarray:
    """Holm's step-down adjusted p-values (Holm 1979): the k-th smallest of m is multiplied by m − k + 1,
    then made monotone; NaN stays NaN."""
    p = np.asarray(p, float)
    out = np.full(p.shape, np.nan)
    ok = np.flatnonzero(np.isfinite(p))
    if not ok.size:
        return out
    order = ok[np.argsort(p[ok], kind="stable")]
    m = len(order)
    adj = np.minimum(1.0, np.maximum.accumulate(p[order] * (m - np.arange(m))))
    out[order] = adj
    return out


def signed_rank(d) -> tuple[float, float]:
    """The Wilcoxon signed-rank p-value (two-sided) and the matched-pairs rank-biserial correlation of the
    paired differences ``d`` (zeros dropped, as Wilcoxon's test does); (1, 0) when every difference is 0."""
    from scipy import stats

    d = np.asarray(d, float)
    d = d[np.isfinite(d) & (d != 0)]
    if not d.size:
        return 1.0, 0.0
    ranks = stats.rankdata(np.abs(d))
    w_plus, w_minus = ranks[d > 0].sum(), ranks[d < 0].sum()
    r = float((w_plus - w_minus) / (w_plus + w_minus))
    p = float(stats.wilcoxon(d, zero_method="wilcox", alternative="two-sided").pvalue)
    return p, r


def compare_to_best(groups: list, presets: bool) -> list[dict]:
    """One record per solver of a cell against ``groups[0]`` (the cell's best, the report's ranking): the
    number of paired runs, the median paired difference (solver − best), the rank-biserial r, the raw and
    Holm-adjusted p-values, and a verdict at :data:`LEVEL` ("worse", "better", or "no difference")."""
    if not groups:
        return []
    best = groups[0]
    base = {int(r["run"]): run_value(r, presets) for r in best.rows}
    recs = []
    for g in groups[1:]:
        pairs = [(run_value(r, presets), base.get(int(r["run"]), np.nan)) for r in g.rows]
        d = np.array([a - b for a, b in pairs if np.isfinite(a) and np.isfinite(b)], float)
        p, r = signed_rank(d) if d.size else (float("nan"), float("nan"))
        recs.append({"solver": g.solver, "best": best.solver, "n": int(d.size),
                     "median_diff": float(np.median(d)) if d.size else float("nan"), "rank_biserial": r, "p": p})
    adj = holm([x["p"] for x in recs])
    for x, a in zip(recs, adj):
        x["p_holm"] = float(a)
        if not np.isfinite(a):
            x["verdict"] = "–"
        elif a < LEVEL:
            x["verdict"] = "worse" if x["median_diff"] > 0 or x["rank_biserial"] > 0 else "better"
        else:
            x["verdict"] = "no difference"
    return recs
