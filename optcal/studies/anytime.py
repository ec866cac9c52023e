"""Anytime performance of a study's solvers, as optimisation benchmarks report it.

Every in-field trial records, at the evaluation grid 1, 1.26, 1.58, ... (ten points per decade), its best
cost so far, the accuracy of the best point so far and the solver time at which that point was found
(:func:`optcal.studies.scoring.anytime_on_grid`, :func:`optcal.studies.scoring.seconds_on_grid`), and the optimum cost
``f_opt`` of its data set (a reference least-squares fit). From these:

*Targets.* A trial reaches

- the cost target Δ when its relative gap (f − f_opt) / f_opt ≤ Δ, for Δ in :data:`COST_TARGETS`
  (a trial that ends below f_opt has a gap of 0 and reaches every cost target);
- the accuracy target a when its accuracy ≤ a, for a in :data:`ACCURACY_TARGETS`. The accuracy of one
  trial is the RMS over the parameters of |error| / CRLB, the error's observable part against its
  Cramér-Rao bound (the ``accuracy`` column; a study's RMSE/CRLB is the same ratio with the RMSE over runs).
  An efficient estimate's value scatters around 1: the least-squares optimum itself scores above 1 in
  40 % of the compare study's runs and above 1.2 in 12 %, and at most 1.5 in all of them, so 1.2 is about
  the tightest target worth setting.

The evaluations to reach a target are the first grid point at which it is met (an upper bound within a
factor 1.26 of the exact count); a target never met, and every target of a failed trial, count as never
reached. Turntable (reference) configurations fit another cost to other data and are left out.

*Runtime ECDF* (COCO, IOHprofiler): per solver, the fraction of (trial, target) pairs reached within x
evaluations, over runs, models, schemes and targets. *Data profile* (Moré & Wild 2009): the fraction of
problems (data sets: model × scheme × run) solved within κ budget units, κ = evaluations / (n + 1) with n
the number of parameters. *Performance profile* (Dolan & Moré 2002): the fraction of problems on which a
solver's evaluations to the target are within a factor τ of the fastest solver's (a solver that never
reaches it has ratio ∞). The profiles use one cost and one accuracy target (:data:`PROFILE_TARGETS`).

*Confidence intervals*: percentile bootstrap over the Monte-Carlo runs (:data:`RESAMPLES` resamples of
the runs with replacement, seeded from the spec's seed, so a report is reproducible); every solver of a
run is resampled together.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

COST_TARGETS = (1e2, 1e1, 1.0, 1e-1, 1e-2, 1e-3)  # relative gaps (f − f_opt) / f_opt
ACCURACY_TARGETS = (10.0, 3.0, 2.0, 1.5, 1.2)  # per-trial RMS over parameters of |error| / CRLB
# The one target of each kind the profiles use. Δ = 1e-2 puts the cost within Δχ² ≈ 0.1-0.2 of the
# optimum's (f_opt / σ² is about the degrees of freedom, 12-24 in the compare study): statistically the
# optimum. Accuracy 1.5: the optimum itself meets it in every run of the compare study.
PROFILE_TARGETS = (("cost", 1e-2), ("accuracy", 1.5))
RESAMPLES = 1000
LEVEL = 0.95
_BOOT = 0xB0075  # the bootstrap's spawn key under the spec's seed

KINDS = {"cost": COST_TARGETS, "accuracy": ACCURACY_TARGETS}


# -- the building blocks (plain arrays in, plain arrays out) ------------------------------------------

def first_hits(evals, values, targets) -> np.ndarray:
    """The first of ``evals`` at which ``values`` ≤ each target (∞ where never); NaN values never reach."""
    evals = np.asarray(evals, float)
    values = np.asarray(values, float)
    t = np.asarray(targets, float)
    if not evals.size:
        return np.full(t.shape, np.inf)
    with np.errstate(invalid="ignore"):
        hit = values[None, :] <= t[:, None]  # (targets, grid)
    first = np.argmax(hit, axis=1)
    return np.where(hit.any(axis=1), evals[first], np.inf)


def ecdf(times, x) -> np.ndarray:
    """The fraction of ``times`` (∞ = never) that are ≤ each x; NaN times (no record) are left out."""
    t = np.asarray(times, float).ravel()
    t = t[~np.isnan(t)]
    x = np.asarray(x, float)
    if not t.size:
        return np.full(x.shape, np.nan)
    return np.searchsorted(np.sort(t[np.isfinite(t)]), x, side="right") / t.size


def ecdf_area(times, top: float) -> float:
    """The area under the runtime ECDF over log10(evaluations) from 1 to ``top``, normalised to [0, 1]: 1
    when every target is met at the first evaluation, 0 when none is met within ``top``."""
    return float(np.mean(area_terms(times, top))) if np.size(times) else float("nan")


def area_terms(times, top: float) -> np.ndarray:
    """Each time's share of :func:`ecdf_area` (the mean of these is the area)."""
    t = np.asarray(times, float)
    L = math.log10(max(top, 10.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        a = 1.0 - np.log10(np.maximum(t, 1.0)) / L
    return np.where(t <= top, np.clip(a, 0.0, 1.0), 0.0)


def data_profile(times, n, kappas) -> np.ndarray:
    """Moré & Wild (2009): the fraction of problems solved within κ (n + 1) evaluations, for each κ.
    ``times``: evaluations to solve each problem (∞ = never); ``n``: each problem's number of parameters."""
    t = np.asarray(times, float)
    return ecdf(t / (np.asarray(n, float) + 1.0), kappas)


def performance_ratios(T) -> np.ndarray:
    """Dolan & Moré (2002): each solver's evaluations over the fastest solver's on each problem. ``T``:
    (problems, solvers), ∞ = never solved; a problem nobody solves gives every solver ∞."""
    T = np.asarray(T, float)
    best = np.min(T, axis=1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        R = T / best
    return np.where(np.isfinite(best) & np.isfinite(T), R, np.inf)


def performance_profile(T, taus) -> np.ndarray:
    """The fraction of problems on which each solver is within a factor τ of the fastest; (solvers, taus)."""
    R = performance_ratios(T)
    return np.array([ecdf(R[:, s], taus) for s in range(R.shape[1])])


# -- bootstrap ------------------------------------------------------------------------------------

def resample(n: int, seed: int, resamples: int = RESAMPLES) -> np.ndarray:
    """(resamples, n) indices of n runs drawn with replacement; the same for every statistic of a study
    with n runs (paired between solvers)."""
    rng = np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=(_BOOT, n)))
    return rng.integers(0, n, size=(resamples, n))


def counts(idx: np.ndarray, n: int) -> np.ndarray:
    """How often each of n runs appears in each resample: (resamples, n)."""
    B = idx.shape[0]
    return np.bincount((np.arange(B)[:, None] * n + idx).ravel(), minlength=B * n).reshape(B, n).astype(float)


def percentile_ci(samples, level: float = LEVEL) -> tuple[float, float]:
    s = np.asarray(samples, float)
    s = s[np.isfinite(s)]
    if not s.size:
        return (float("nan"), float("nan"))
    q = 50 * (1 - level)
    lo, hi = np.percentile(s, [q, 100 - q])
    return float(lo), float(hi)


def bootstrap_ci(stat, n: int, seed: int, resamples: int = RESAMPLES, level: float = LEVEL) -> tuple[float, float]:
    """The percentile bootstrap interval of a statistic of n runs. ``stat`` takes the (resamples, n)
    index array and returns the statistic of each resample (vectorised)."""
    if n < 2:
        return (float("nan"), float("nan"))
    return percentile_ci(stat(resample(n, seed, resamples)), level)


def mean_ci(values, seed: int, resamples: int = RESAMPLES, level: float = LEVEL) -> tuple[float, float]:
    """The bootstrap interval of the mean of per-run values."""
    v = np.asarray(values, float)
    return bootstrap_ci(lambda idx: v[idx].mean(axis=1), len(v), seed, resamples, level)


def run_mean_ci(values, runs, seed: int, resamples: int = RESAMPLES, level: float = LEVEL) -> tuple[float, float]:
    """The bootstrap interval of the mean of ``values`` (any number per run), resampling whole runs."""
    v = np.asarray(values, float)
    r = np.asarray(runs)
    keep = ~np.isnan(v)
    v, r = v[keep], r[keep]
    ids, inv = np.unique(r, return_inverse=True)
    sums = np.bincount(inv, weights=v, minlength=len(ids))
    num = np.bincount(inv, minlength=len(ids)).astype(float)

    def stat(idx):
        W = counts(idx, len(ids))
        with np.errstate(invalid="ignore", divide="ignore"):
            return (W @ sums) / (W @ num)

    return bootstrap_ci(stat, len(ids), seed, resamples, level)


def group_ci(g, seed: int, resamples: int = RESAMPLES, level: float = LEVEL) -> dict[str, tuple[float, float]]:
    """Bootstrap intervals over runs of a :class:`optcal.studies.metrics.Group`'s summary numbers: success rate,
    RMSE/CRLB (``accuracy``), RMSE/CRLB with presets, median runtime. Each resample draws the group's
    runs with replacement and recomputes the statistic exactly as the group does (failed runs count as
    not converged; RMSE and CRLB over the resampled runs that did not fail)."""
    rows = g.rows
    n = len(rows)
    ok = np.array([r["status"] == "ok" for r in rows], bool)
    conv = np.array([r["converged"] or 0 for r in rows], float)
    rt = np.array([r["runtime_s"] if ok[i] and r.get("runtime_s") is not None else np.nan
                   for i, r in enumerate(rows)], float)
    out = {}

    def rms_ratio(idx, err_key, crlb_key, all_finite):
        okr = [r for r in rows if r["status"] == "ok"]
        if not okr or any(r.get(crlb_key) is None for r in okr):
            return np.full(idx.shape[0], np.nan)
        E2 = np.zeros((n, len(g.names)))
        C2 = np.zeros((n, len(g.names)))
        E2[ok] = np.array([r[err_key] for r in okr], float) ** 2
        C2[ok] = np.array([r[crlb_key] for r in okr], float) ** 2
        W = counts(idx, n) * ok
        m = W.sum(axis=1, keepdims=True)
        with np.errstate(invalid="ignore", divide="ignore"):
            ratio2 = (W @ E2) / (W @ C2)  # (RMSE / CRLB)² per parameter; the m's cancel
            ratio2[(m[:, 0] == 0)] = np.nan
        fin = np.isfinite(ratio2)
        if all_finite:
            return np.where(fin.all(axis=1), np.sqrt(np.mean(ratio2, axis=1)), np.nan)
        with np.errstate(invalid="ignore"):
            return np.sqrt(np.nanmean(np.where(fin, ratio2, np.nan), axis=1))

    def nanmedian_rows(idx):
        import warnings

        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            return np.nanmedian(rt[idx], axis=1)

    out["success_rate"] = bootstrap_ci(lambda idx: conv[idx].mean(axis=1), n, seed, resamples, level)
    out["accuracy"] = bootstrap_ci(lambda idx: rms_ratio(idx, "err_proj", "crlb", False), n, seed, resamples, level)
    out["accuracy_presets"] = bootstrap_ci(lambda idx: rms_ratio(idx, "err", "crlb_presets", True), n, seed,
                                           resamples, level)
    out["runtime_median_s"] = bootstrap_ci(nanmedian_rows, n, seed, resamples, level)
    return out


# -- a study's anytime data ------------------------------------------------------------------------

@dataclass
class Anytime:
    """Evaluations to reach every target, per problem (model, scheme, run) and solver.

    ``hits[kind]``: (problems, solvers, targets), ∞ = never reached, NaN = not known (no trial, a trial
    from before anytime records, or no optimum for the cost targets)."""

    solvers: list[str]
    problems: list[tuple[str, str, int]]
    n: np.ndarray  # parameters per problem
    hits: dict[str, np.ndarray]
    top: float  # the largest evaluation count of any trial (the ECDFs' right end)
    missing: int = 0  # in-field trials without an anytime record (written before it existed)
    no_optimum: int = 0  # in-field trials without f_opt
    targets: dict = field(default_factory=lambda: dict(KINDS))
    # the same hitting times in seconds of solver time (NaN: a record without times, written before them)
    hits_s: dict = field(default_factory=dict)
    top_s: float = float("nan")  # the longest solver time of any trial

    def ecdf_s(self, kind: str, s: int, x) -> np.ndarray:
        """The runtime ECDF of solver s against seconds of solver time."""
        return ecdf(self.hits_s[kind][:, s, :], x)

    def reached_s(self, kind: str, s: int) -> float:
        return float(ecdf(self.hits_s[kind][:, s, :], np.inf))

    @property
    def runs(self) -> np.ndarray:
        return np.array([p[2] for p in self.problems])

    @property
    def empty(self) -> bool:
        return not self.problems or all(np.all(np.isnan(h)) for h in self.hits.values())

    def times(self, kind: str, s: int, target: float | None = None) -> np.ndarray:
        """Hitting times of solver s: (problems, targets), or (problems,) for one target."""
        h = self.hits[kind][:, s, :]
        return h if target is None else h[:, list(self.targets[kind]).index(target)]

    def ecdf(self, kind: str, s: int, x) -> np.ndarray:
        return ecdf(self.times(kind, s), x)

    def area(self, kind: str, s: int) -> float:
        t = self.times(kind, s)
        return ecdf_area(t[~np.isnan(t)], self.top)

    def reached(self, kind: str, s: int) -> float:
        """The fraction of (trial, target) pairs reached within the trial's budget."""
        return float(ecdf(self.times(kind, s), np.inf))

    def profile_matrix(self, kind: str, target: float) -> np.ndarray:
        """(problems, solvers) evaluations to ``target``, problems some solver lacks a record for left out."""
        T = self.hits[kind][:, :, list(self.targets[kind]).index(target)]
        return T[~np.isnan(T).any(axis=1)]

    def profile_n(self, kind: str, target: float) -> np.ndarray:
        T = self.hits[kind][:, :, list(self.targets[kind]).index(target)]
        return self.n[~np.isnan(T).any(axis=1)]

    def profile_runs(self, kind: str, target: float) -> np.ndarray:
        T = self.hits[kind][:, :, list(self.targets[kind]).index(target)]
        return self.runs[~np.isnan(T).any(axis=1)]

    # per-problem values of the table's numbers, for bootstrap intervals over runs
    def table(self, seed: int, resamples: int = RESAMPLES, level: float = LEVEL) -> list[dict]:
        """One record per solver: for each kind the fraction of (trial, target) pairs reached and the
        ECDF area; for each profile target the fraction of problems solved within the budget and the
        fraction on which the solver is (one of) the fastest (performance profile at τ = 1); each with its
        bootstrap interval over runs."""
        runs = self.runs
        out = []
        prof = {}
        for kind, target in PROFILE_TARGETS:
            T = self.profile_matrix(kind, target)
            prof[kind, target] = (T, performance_ratios(T), self.profile_runs(kind, target))
        for s, name in enumerate(self.solvers):
            rec = {"solver": name}
            for kind in self.targets:
                t = self.times(kind, s)  # (problems, targets)
                rr = np.repeat(runs, t.shape[1])
                flat = t.ravel()
                hit = np.where(np.isnan(flat), np.nan, np.isfinite(flat).astype(float))
                area = np.where(np.isnan(flat), np.nan, area_terms(flat, self.top))
                rec[f"{kind}_reached"] = float(np.nanmean(hit)) if np.any(~np.isnan(hit)) else float("nan")
                rec[f"{kind}_reached_ci"] = run_mean_ci(hit, rr, seed, resamples, level)
                rec[f"{kind}_area"] = float(np.nanmean(area)) if np.any(~np.isnan(area)) else float("nan")
                rec[f"{kind}_area_ci"] = run_mean_ci(area, rr, seed, resamples, level)
            for (kind, target), (T, R, pr) in prof.items():
                key = f"{kind}_{target:g}"
                solved = np.isfinite(T[:, s]).astype(float)
                fastest = (R[:, s] <= 1.0).astype(float)
                nan = float("nan")
                rec[f"solved_{key}"] = float(solved.mean()) if solved.size else nan
                rec[f"solved_{key}_ci"] = run_mean_ci(solved, pr, seed, resamples, level) if solved.size else (nan, nan)
                rec[f"fastest_{key}"] = float(fastest.mean()) if fastest.size else nan
                rec[f"fastest_{key}_ci"] = (run_mean_ci(fastest, pr, seed, resamples, level) if fastest.size
                                            else (nan, nan))
            out.append(rec)
        return out


def collect(rows: list[dict], order: list[str] | None = None) -> Anytime:
    """The hitting times of every in-field trial of a study's rows (turntable trials left out)."""
    rows = [r for r in rows if not r.get("reference")]
    names = list(dict.fromkeys(r["solver"] for r in sorted(rows, key=lambda r: r["solver"])))
    if order:
        rank = {s: i for i, s in enumerate(order)}
        names.sort(key=lambda s: (rank.get(s, len(rank)), s))
    problems = sorted({(r["model"], r["scheme"], int(r["run"])) for r in rows})
    pi = {p: i for i, p in enumerate(problems)}
    si = {s: i for i, s in enumerate(names)}
    hits = {k: np.full((len(problems), len(names), len(t)), np.nan) for k, t in KINDS.items()}
    hits_s = {k: np.full((len(problems), len(names), len(t)), np.nan) for k, t in KINDS.items()}
    n = np.zeros(len(problems))
    top = 1.0
    top_s = 0.0
    missing = no_opt = 0
    for r in rows:
        p, s = pi[r["model"], r["scheme"], int(r["run"])], si[r["solver"]]
        n[p] = len(r["names"]) if r.get("names") else n[p]
        if r["status"] != "ok":  # a failed trial reaches nothing
            for k in hits:
                hits[k][p, s] = hits_s[k][p, s] = np.inf
            continue
        a = r.get("anytime")
        if not a:
            missing += 1
            continue
        A = np.array([[np.nan if v is None else v for v in x] for x in a], float)
        secs = r.get("anytime_s") or []
        timed = len(secs) == len(A)  # a record from before the seconds were kept has none
        A = np.column_stack([A, np.asarray(secs, float) if timed else np.full(len(A), np.nan)])
        if timed:
            top_s = max(top_s, float(A[-1, 3]), float(r.get("runtime_s") or 0.0))
        if (r.get("at_target") or r.get("stop_reason") == "stagnation") and r.get("max_evals"):
            # Stopped at the final target (optcal.studies.trial.FINAL_GAP) or by the stagnation rule
            # (optcal.studies.trial.STAGNATION): its record is flat from there to its budget, as COCO counts a run
            # that stops at the last target. Its last grid point (the first at or after the stop) stands as
            # it is, as it would in the run that went on, and the ECDFs' right end stays its budget, where a
            # trial that ran its budget out puts it.
            top = max(top, float(r["max_evals"]))
        elif r.get("nfev"):  # the grid's last point may lie past the last evaluation
            A[:, 0] = np.minimum(A[:, 0], r["nfev"])
        top = max(top, float(A[-1, 0]))
        hits["accuracy"][p, s] = first_hits(A[:, 0], A[:, 2], ACCURACY_TARGETS)
        if timed:
            hits_s["accuracy"][p, s] = first_hits(A[:, 3], A[:, 2], ACCURACY_TARGETS)
        f_opt = r.get("f_opt")
        if f_opt is None or not f_opt > 0:
            no_opt += 1
            continue
        gap = np.maximum(A[:, 1] - f_opt, 0.0) / f_opt
        hits["cost"][p, s] = first_hits(A[:, 0], gap, COST_TARGETS)
        if timed:
            hits_s["cost"][p, s] = first_hits(A[:, 3], gap, COST_TARGETS)
    return Anytime(names, problems, n, hits, top, missing, no_opt, hits_s=hits_s,
                   top_s=top_s if top_s > 0 else float("nan"))


def grid(top: float, per_decade: int = 20) -> np.ndarray:
    """Evaluation counts from 1 to ``top`` for drawing ECDFs."""
    decades = math.log10(max(top, 10.0))
    return np.unique(np.round(np.logspace(0, decades, int(per_decade * decades) + 1)))
