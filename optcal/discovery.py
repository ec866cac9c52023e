"""Model discovery: find where a fitted model and the measurements disagree, name the missing effect,
add it, and show the gap shrink (docs/design.md §12).

Forward selection over the candidate terms of docs/design.md §3.1. At each step every term not yet in the model is
added in turn, the extended model is refitted by least squares (warm-started from the current fit with
the new parameters at zero) and scored against the current model with the F-test for nested
least-squares models,

    F = ((RSS0 − RSS1) / q) / (RSS1 / (m − p1)),   p = P[F(q, m − p1) > F],

with m residuals (the norm residuals e_j = ‖A_j‖ − g_local of the 2020 paper, Eq. 12), p0 and p1 the ranks
of the two models (their observable dimensions) and q = p1 − p0 (Seber & Wild, *Nonlinear Regression*,
1989, §5.3: the F-test for nested least-squares models; Schwarz 1978 for BIC).
With 24 positions and 12–15 parameters the residual degrees of freedom are few, so the asymptotic
likelihood-ratio χ² test over-fits; the F-test is exact for a linear model with Gaussian noise (and very
nearly so here, where the noise is small). The likelihood-ratio statistic m·ln(RSS0/RSS1) and the change
in the Bayesian information criterion ΔBIC = m·ln(RSS1/RSS0) + q·ln(m) are reported beside it.

The *best* candidate is the one with the lowest p-value (ties, e.g. p-values that underflow to 0, broken
by the most negative ΔBIC). It is added only when p < α/k (Bonferroni over the k candidates tested at
that step, so the chance of adding anything to a correct model is at most α) and ΔBIC < the BIC
threshold. The loop stops when the best candidate fails either test.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .analysis import crlb, observability
from .data import PositionsData
from .errors import InputError
from .model import AXES, TERMS, Model, get_model
from .problem import CalibrationProblem

CANDIDATES = ("quadratic", "cubic", "scale_asymmetry", "cross_coupling", "temperature_bias",
              "temperature_scale", "bias_drift", "misalignment")

# Family-wise false-addition rate per step (before the Bonferroni split) and the BIC threshold; measured
# false-addition rate on data without a hidden effect: see docs/discovery.md.
DEFAULT_ALPHA = 0.01
DEFAULT_BIC_THRESHOLD = -2.0
EXPLAINED = "explained down to noise"
REMAINS = "something remains"
UNKNOWN = "noise floor unknown"
NO_DOF = "untestable: no residual degrees of freedom"


# -- regressors --------------------------------------------------------------------------------

def regressors(term: str, A: np.ndarray, problem: CalibrationProblem) -> list[tuple[str, str, int, np.ndarray]]:
    """The regressor of each of ``term``'s parameters at specific force ``A`` (n, 3):
    ``(parameter, label, axis, values)``. The term adds K_axis·parameter·values to output ``axis``
    (docs/design.md §3.1): A_i² (quadratic), A_i³ (cubic), min(A_i, 0) (scale asymmetry), A_i·A_j (cross coupling),
    T − T0 (temperature bias), (T − T0)·A_i (temperature scale), t − t0 (drift), A_j (misalignment)."""
    data, out = problem.data, []
    dtemp = None if data.temp is None else data.temp - np.mean(data.temp)
    dt = None if data.t is None else data.t - data.t[0]
    for k, p in enumerate(TERMS[term].params):
        if term == "cross_coupling" or term == "misalignment":
            i, j = "xyz".index(p[-2]), "xyz".index(p[-1])
            if term == "cross_coupling":
                out.append((p, f"A_{AXES[i]}·A_{AXES[j]}", i, A[:, i] * A[:, j]))
            else:  # S_ab multiplies A_b... in row a of T: S_yz → A_x in y, S_zy → A_x in z, S_zx → A_y in z
                row, col = {"S_yz": (1, 0), "S_zy": (2, 0), "S_zx": (2, 1)}[p]
                out.append((p, f"A_{AXES[col]}", row, A[:, col]))
            continue
        i = k
        a = AXES[i]
        if term == "quadratic":
            out.append((p, f"A_{a}²", i, A[:, i] ** 2))
        elif term == "cubic":
            out.append((p, f"A_{a}³", i, A[:, i] ** 3))
        elif term == "scale_asymmetry":
            out.append((p, f"min(A_{a}, 0)", i, np.minimum(A[:, i], 0.0)))
        elif term == "temperature_bias" and dtemp is not None:
            out.append((p, "T − T0", i, dtemp))
        elif term == "temperature_scale" and dtemp is not None:
            out.append((p, f"(T − T0)·A_{a}", i, dtemp * A[:, i]))
        elif term == "bias_drift" and dt is not None:
            out.append((p, "t − t0", i, dt))
    return out


def projected(A: np.ndarray, axis: int, values: np.ndarray) -> np.ndarray:
    """A regressor as the norm residual sees it: an output change on ``axis`` moves ‖A‖ by â_axis·change."""
    return A[:, axis] / np.linalg.norm(A, axis=1) * values


# -- fits and scores ---------------------------------------------------------------------------

@dataclass
class Fit:
    """A least-squares fit of one model: parameters, residuals, rank (observable dimension)."""

    model: Model
    problem: CalibrationProblem
    x: np.ndarray
    residuals: np.ndarray
    rank: int
    nfev: int

    @property
    def rss(self) -> float:
        return float(self.residuals @ self.residuals)

    @property
    def rms(self) -> float:
        return float(np.sqrt(np.mean(self.residuals**2)))

    @property
    def specific_force(self) -> np.ndarray:
        return self.problem.specific_force(self.x)


@dataclass
class Score:
    """One candidate at one step: tested (with its statistics) or skipped (with the reason)."""

    term: str
    note: str = ""
    fit: Fit | None = None
    q: int = 0
    dof: int = 0
    f_statistic: float = float("nan")
    p_value: float = float("nan")
    lr_statistic: float = float("nan")
    delta_bic: float = float("nan")

    @property
    def tested(self) -> bool:
        return self.fit is not None

    def to_dict(self) -> dict:
        d = {"term": self.term, "tested": self.tested}
        if self.tested:
            d.update(rms_after_g=self.fit.rms, statistic=_num(self.f_statistic), df=[self.q, self.dof],
                     p_value=_num(self.p_value), lr_statistic=_num(self.lr_statistic), delta_bic=_num(self.delta_bic))
        else:
            d["note"] = self.note
        return d


def _corr(a: np.ndarray, b: np.ndarray) -> float | None:
    if np.std(a) == 0 or np.std(b) == 0:
        return None
    return float(np.corrcoef(a, b)[0, 1])


def _num(v) -> float | None:
    return float(v) if v is not None and np.isfinite(v) else None


def _solve(problem: CalibrationProblem, x0, solver: str, budget: int) -> tuple[np.ndarray, int]:
    from .fit import get_solver  # the registry, at run time (optcal never imports solvers)

    res = get_solver(solver).solve(problem, x0=x0, budget=budget, rng=np.random.default_rng(0))
    return problem.to_full(res.x)[0], res.nfev


def fit_model(model: Model, data: PositionsData, g_local: float, x0=None, *, solver: str = "scipy-lm",
              budget: int = 2000, rank: int | None = None) -> Fit:
    problem = CalibrationProblem(model, data, g_local=g_local)
    x, nfev = _solve(problem, x0, solver, budget)
    if rank is None:
        rank = observability(problem, x).rank
    return Fit(model, problem, x, problem.residuals_full(x)[0], rank, nfev)


def score(current: Fit, term: str, *, solver: str = "scipy-lm", budget: int = 2000) -> Score:
    """Refit with ``term`` added (warm start: current fit, new parameters zero) and test the gain."""
    from scipy import stats  # here, not at module level: importing optcal stays light

    data = current.problem.data
    missing = [c for c in TERMS[term].needs if getattr(data, c) is None]
    if missing:
        return Score(term, note=f"needs column(s) {', '.join(missing)} that the data lack")
    model = current.model.with_term(term)
    m = current.problem.n_residuals
    q_raw = model.n_params - current.model.n_params
    if m - (current.rank + q_raw) < 1:
        return Score(term, note=f"{m} residuals leave no degrees of freedom for {model.n_params} parameters")
    problem = CalibrationProblem(model, data, g_local=current.problem.g_local)
    x0 = model.from_dict(current.model.to_dict(current.x), model.default_vector(0.0))
    obs = observability(problem, x0)
    q = obs.rank - current.rank
    if q < q_raw:
        dirs = "; ".join(" ".join(f"{w['weight']:+.2f}·{w['name']}" for w in d[:4]) for d in obs.unobservable)
        return Score(term, note=f"unobservable on these positions (rank {obs.rank} of {model.n_params}: {dirs})")
    x, nfev = _solve(problem, x0, solver, budget)
    r = problem.residuals_full(x)[0]
    if not np.all(np.isfinite(r)):
        return Score(term, note="the refit failed (non-finite residuals)")
    fit = Fit(model, problem, x, r, obs.rank, nfev)
    rss0, rss1 = current.rss, max(fit.rss, np.finfo(float).tiny)
    dof = m - obs.rank
    f_stat = max(rss0 - rss1, 0.0) / q / (rss1 / dof)
    return Score(term, fit=fit, q=q, dof=dof, f_statistic=f_stat, p_value=float(stats.f.sf(f_stat, q, dof)),
                 lr_statistic=m * np.log(rss0 / rss1), delta_bic=m * np.log(rss1 / rss0) + q * np.log(m))


def best_of(scores: list[Score]) -> Score | None:
    """The tested candidate with the lowest p-value; ties broken by the most negative ΔBIC."""
    tested = [s for s in scores if s.tested]
    return min(tested, key=lambda s: (s.p_value, s.delta_bic)) if tested else None


# -- report ------------------------------------------------------------------------------------

def _sigma(fit: Fit, noise_g: float | None) -> float:
    if noise_g is not None:
        return noise_g
    return float(np.sqrt(fit.rss / max(fit.problem.n_residuals - fit.rank, 1)))


@dataclass
class Step:
    """One added term: its fitted parameters with standard errors, the gap before and after, the test."""

    term: str
    before: Fit
    after: Fit
    chosen: Score
    scores: list[Score]
    p_threshold: float
    stderr: dict[str, float]
    alternatives: list[str]

    @property
    def parameters(self) -> dict[str, float]:
        names = TERMS[self.term].params
        return {n: float(self.after.x[self.after.model.index(n)]) for n in names}

    def added_variable(self) -> np.ndarray:
        """The added term as a single regressor of the residual (an added-variable plot's abscissa, g).

        The term's fitted effect on each norm residual, c_j = Σ_i â_i·ΔN_i/K_i at the specific force of
        the fit before the step, with its projection on the base model's Jacobian columns removed (that
        part the base absorbs by moving its own parameters). Before the step the residuals scatter along
        slope one against it; after the step they should scatter about zero."""
        b, f = self.before, self.after
        x0 = f.x.copy()
        x0[f.model.term_slices()[self.term]] = 0.0
        A = b.specific_force
        dN = f.model.forward(f.x, A, f.problem.ctx)[0] - f.model.forward(x0, A, f.problem.ctx)[0]
        c = np.sum(A / np.linalg.norm(A, axis=1, keepdims=True) * dN / f.x[f.model.groups()["scale"]], axis=1)
        J = b.problem.jacobian_full(b.x)
        return c - J @ np.linalg.lstsq(J, c, rcond=None)[0]

    def correlations(self) -> dict[str, dict]:
        """Correlation of the residuals with each of the term's regressors (as the norm residual sees them,
        at the specific force before the step), before and after the step."""
        A = self.before.specific_force
        out = {}
        for name, label, axis, values in regressors(self.term, A, self.before.problem):
            r = projected(A, axis, values)
            out[name] = {"regressor": label, "before": _corr(r, self.before.residuals),
                         "after": _corr(r, self.after.residuals)}
        return out

    def to_dict(self) -> dict:
        c = self.chosen
        return {
            "added": self.term,
            "parameters": self.parameters,
            "stderr": {n: _num(s) for n, s in self.stderr.items()},
            "rms_before_g": self.before.rms, "rms_after_g": self.after.rms,
            "statistic": _num(c.f_statistic), "test": "F", "df": [c.q, c.dof],
            "p_value": _num(c.p_value), "p_threshold": self.p_threshold,
            "delta_bic": _num(c.delta_bic), "lr_statistic": _num(c.lr_statistic),
            "alternatives": self.alternatives,
            "correlations": self.correlations(),
            "candidates": [s.to_dict() for s in self.scores],
        }


@dataclass
class DiscoveryReport:
    base: str
    initial: Fit
    final: Fit
    steps: list[Step]
    last_round: list[Score]  # the round in which nothing was added (why the search stopped)
    alpha: float
    bic_threshold: float
    noise_g: float | None  # RMS over positions of σ_j
    sigma_j: np.ndarray | None  # noise of each norm residual, g (from noise_g or the data's n and sx, sy, sz)
    notes: list[str] = field(default_factory=list)

    @property
    def final_model(self) -> Model:
        return self.final.model

    @property
    def added(self) -> list[str]:
        return [s.term for s in self.steps]

    @property
    def m(self) -> int:
        return self.final.problem.n_residuals

    @property
    def dof(self) -> int:
        return self.m - self.final.rank

    @property
    def expected_rms(self) -> float | None:
        """The RMS a correct model leaves: σ·√((m − p)/m)."""
        return None if self.noise_g is None else self.noise_g * np.sqrt(self.dof / self.m)

    @property
    def chi2(self) -> tuple[float, int, float] | None:
        """χ² goodness of fit of the final model against the known noise, Σ (e_j/σ_j)²: (χ², dof, p-value)."""
        from scipy import stats

        if self.sigma_j is None or self.dof < 1:
            return None
        c = float(np.sum((self.final.residuals / self.sigma_j) ** 2))
        return c, self.dof, float(stats.chi2.sf(c, self.dof))

    @property
    def verdict(self) -> str:
        """χ² test of the final residual against the noise floor at level α (needs the noise)."""
        if self.dof < 1:
            return NO_DOF
        chi = self.chi2
        if chi is None:
            return UNKNOWN
        return EXPLAINED if chi[2] >= self.alpha else REMAINS

    def final_stderr(self) -> np.ndarray:
        f = self.final
        sd, _ = crlb(f.problem, f.x, _sigma(f, self.noise_g))
        return sd

    def to_dict(self) -> dict:
        chi = self.chi2
        f = self.final
        return {
            "base": self.base,
            "steps": [s.to_dict() for s in self.steps],
            "final_terms": list(f.model.terms),
            "final_model": f.model.name,
            "final_parameters": f.model.to_dict(f.x),
            "final_stderr": {n: _num(s) for n, s in zip(f.model.names, self.final_stderr())},
            "rms_initial_g": self.initial.rms,
            "rms_final_g": f.rms,
            "noise_floor_g": self.noise_g,
            "noise_per_position_g": None if self.sigma_j is None else [float(v) for v in self.sigma_j],
            "expected_rms_g": self.expected_rms,
            "chi2": None if chi is None else {"value": chi[0], "dof": chi[1], "p_value": chi[2]},
            "verdict": self.verdict,
            "n_positions": len(f.problem.data), "n_residuals": self.m, "rank": f.rank,
            "alpha": self.alpha, "bic_threshold": self.bic_threshold,
            "last_round": [s.to_dict() for s in self.last_round],
            "residuals_initial_g": [float(v) for v in self.initial.residuals],
            "residuals_final_g": [float(v) for v in f.residuals],
            "notes": self.notes,
        }

    def summary(self) -> str:
        """A plain-text report (what the CLI prints)."""
        u = 1e6
        f = self.final
        lines = [f"base {self.base}: {len(f.problem.data)} positions, residual RMS {self.initial.rms * u:.3f} µg; "
                 f"a term is added when p < α/k (α = {self.alpha:g}, k candidates tested) and "
                 f"ΔBIC < {self.bic_threshold:g}"]
        for k, s in enumerate(self.steps, 1):
            c = s.chosen
            lines.append(f"step {k}: add {s.term}: RMS {s.before.rms * u:.3f} → {s.after.rms * u:.3f} µg, "
                         f"F({c.q},{c.dof}) = {c.f_statistic:.4g}, p = {c.p_value:.3g} (threshold "
                         f"{s.p_threshold:.3g}), ΔBIC = {c.delta_bic:.2f}, LR = {c.lr_statistic:.2f}")
            for n, v in s.parameters.items():
                se = s.stderr[n]
                lines.append(f"    {n:8s} {v: .6e} ± {se:.2e}" if np.isfinite(se) else f"    {n:8s} {v: .6e}")
            if s.alternatives:
                lines.append("    nearly as good (ΔBIC within 2: confounded on these data): "
                             + ", ".join(s.alternatives))
            lines.append("    candidates this round:")
            lines += _round_lines([x for x in s.scores if x is not c], u)
        lines.append("last round (nothing added):" if self.last_round else "no candidate left to test")
        lines += _round_lines(self.last_round, u)
        floor = "unknown (no n, sx, sy, sz in the data)" if self.noise_g is None else (
            f"σ = {self.noise_g * u:.3f} µg (RMS over positions), expected RMS {self.expected_rms * u:.3f} µg")
        lines.append(f"final model {f.model.name}: residual RMS {f.rms * u:.3f} µg; noise floor {floor}")
        chi = self.chi2
        detail = "" if chi is None else f" (χ² = {chi[0]:.1f} on {chi[1]} dof, p = {chi[2]:.3g})"
        lines.append(f"verdict: {self.verdict}{detail}")
        lines += [f"note: {n}" for n in self.notes]
        return "\n".join(lines)

    def plot(self, path):
        """Residuals per position (initial and final fit), then one panel per step: the residuals against
        the added term's regressor (its fitted combination, :meth:`Step.added_variable`) before and after
        the term is added."""
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        n = 1 + len(self.steps)
        cols = min(n, 3)
        rows = -(-n // cols)
        fig = Figure(figsize=(4.6 * cols, 3.6 * rows), layout="constrained")
        FigureCanvasAgg(fig)
        axes = fig.subplots(rows, cols, squeeze=False).ravel()
        u = 1e6
        ax = axes[0]
        pos = np.arange(len(self.initial.residuals))
        ax.plot(pos, self.initial.residuals * u, "o-", ms=3, lw=0.6, color="0.55", label=f"{self.base}")
        ax.plot(pos, self.final.residuals * u, "o-", ms=3, lw=0.8, color="C3", label=self.final.model.name)
        if self.noise_g is not None:
            ax.axhspan(-self.noise_g * u, self.noise_g * u, color="C0", alpha=0.12, label="±1σ noise")
        ax.set(xlabel="position", ylabel="residual ‖A‖ − g (µg)", title=f"residuals per position ({self.verdict})")
        ax.legend(fontsize=7)
        for k, (s, ax) in enumerate(zip(self.steps, axes[1:]), 1):
            xr = s.added_variable() * u
            ax.plot(xr, s.before.residuals * u, "o", ms=4, color="0.55",
                    label=f"before (RMS {s.before.rms * u:.2f} µg)")
            ax.plot(xr, s.after.residuals * u, "o", ms=4, color="C3", label=f"after (RMS {s.after.rms * u:.2f} µg)")
            lim = np.array([xr.min(), xr.max()])
            ax.plot(lim, lim, "--", color="0.3", lw=0.7, label="slope 1")
            ax.axhline(0, color="k", lw=0.5)
            ax.set(xlabel=f"fitted {s.term} term, base part removed (µg)", ylabel="residual (µg)",
                   title=f"step {k}: add {s.term} (p = {s.chosen.p_value:.2g})")
            ax.legend(fontsize=7)
        for ax in axes[n:]:
            ax.set_visible(False)
        fig.savefig(path, dpi=110)
        return fig


def _round_lines(scores: list[Score], u: float) -> list[str]:
    out = []
    for s in sorted(scores, key=lambda s: (not s.tested, s.p_value if s.tested else 0)):
        if s.tested:
            out.append(f"    {s.term:18s} p = {s.p_value:.3g}, ΔBIC = {s.delta_bic:+.2f}, "
                       f"RMS would be {s.fit.rms * u:.3f} µg")
        else:
            out.append(f"    {s.term:18s} skipped: {s.note}")
    return out


# -- the workflow ------------------------------------------------------------------------------

def noise_per_position(fit: Fit, noise_g: float | None, notes: list[str]) -> np.ndarray | None:
    """σ_j, the noise of each norm residual in g: ``noise_g`` if given, else each position's standard error
    per axis (sx, sy, sz over √n) referred to the input with the fitted scale factors and projected on the
    measured direction, σ_j² = Σ_i â_ji²·(s_ji / (K_i·√n_j))²; None when neither is known."""
    m = fit.problem.n_residuals
    if noise_g is not None:
        return np.full(m, float(noise_g))
    se = fit.problem.data.noise_of_mean()
    if se is None:
        return None
    A = fit.specific_force
    u = A / np.linalg.norm(A, axis=1, keepdims=True)
    K = np.abs(fit.x[fit.model.groups()["scale"]])
    sigma = np.sqrt(np.sum((u * se / K) ** 2, axis=1))
    bad = ~(sigma > 0)
    if bad.all():
        notes.append("every position has zero sample SD; the noise floor is unknown")
        return None
    if bad.any():
        notes.append(f"{int(bad.sum())} position(s) with zero sample SD (one sample?) take the median noise")
        sigma[bad] = np.median(sigma[~bad])
    return sigma


def _candidates(model: Model, candidates) -> list[str]:
    if candidates is None:
        out = [t for t in CANDIDATES if not (t == "misalignment" and "misalignment6" in model.terms)]
    else:
        out = [str(c).strip() for c in candidates]
        bad = [c for c in out if c not in CANDIDATES]
        if bad:
            extra = " (misalignment6 adds three unobservable directions)" if "misalignment6" in bad else ""
            raise InputError(f"unknown candidate term(s) {', '.join(bad)}{extra}; choose from {', '.join(CANDIDATES)}")
        if "misalignment" in out and "misalignment6" in model.terms:
            raise InputError("the base already has misalignment6; drop 'misalignment' from the candidates")
    return [t for t in out if t not in model.terms]


def discover(data: PositionsData, base: str | Model = "linear9", candidates=None, g_local: float = 1.0,
             alpha: float = DEFAULT_ALPHA, bic_threshold: float = DEFAULT_BIC_THRESHOLD, *,
             noise_g: float | None = None, max_steps: int | None = None, solver: str = "scipy-lm",
             budget: int = 2000) -> DiscoveryReport:
    """Forward selection of the missing terms (see the module docstring for the tests).

    ``noise_g``: input-referred noise of each position's mean per axis, in g; by default from the data's
    ``n`` and ``sx, sy, sz`` (else unknown, and the verdict says so).
    """
    if not 0.0 < alpha < 1.0:
        raise InputError(f"alpha must be between 0 and 1, got {alpha}")
    if noise_g is not None and not noise_g > 0:
        raise InputError(f"noise_g must be positive, got {noise_g}")
    model = get_model(base)
    pool = _candidates(model, candidates)
    current = fit_model(model, data, g_local, solver=solver, budget=budget)
    notes = []
    if current.rank < model.n_params:
        notes.append(f"base {model.name} has {model.n_params - current.rank} unobservable direction(s) on these "
                     "positions; degrees of freedom use its rank")
    initial, steps, last_round = current, [], []
    while pool and (max_steps is None or len(steps) < max_steps):
        scores = [score(current, t, solver=solver, budget=budget) for t in pool]
        best = best_of(scores)
        k = sum(s.tested for s in scores)
        threshold = alpha / max(k, 1)
        if best is None or not (best.p_value < threshold and best.delta_bic < bic_threshold):
            last_round = scores
            break
        sigma = _sigma(best.fit, noise_g if noise_g is not None else current.problem.noise_g)
        sd, _ = crlb(best.fit.problem, best.fit.x, sigma)
        stderr = {n: float(sd[best.fit.model.index(n)]) for n in TERMS[best.term].params}
        alternatives = [s.term for s in scores if s.tested and s is not best and s.delta_bic < best.delta_bic + 2.0]
        steps.append(Step(best.term, current, best.fit, best, scores, threshold, stderr, alternatives))
        current = best.fit
        pool = [t for t in pool if t != best.term]
    sigma_j = noise_per_position(current, noise_g, notes)
    floor = None if sigma_j is None else float(np.sqrt(np.mean(sigma_j**2)))
    return DiscoveryReport(model.name, initial, current, steps, last_round, alpha, bic_threshold, floor, sigma_j,
                           notes)
