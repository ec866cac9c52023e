"""Model discovery's statistics (docs/design.md, "Model discovery"): the candidate terms' regressors, the fits it
compares, the test that scores a candidate, and the noise of each residual. Core: nothing here runs a solver (the
refits are :mod:`optcal.app.workflows.discovery`'s).

Forward selection over the candidate terms of docs/design.md, "Terms and parameters". At each step every term not yet
in the model is added in turn, the extended model is refitted by least squares (warm-started from the current fit
with the new parameters at zero) and scored against the current model with the F-test for nested
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

from dataclasses import dataclass

import numpy as np

from optcal.core.analysis import observability
from optcal.core.distributions import f_sf
from optcal.core.errors import InputError
from optcal.core.model import AXES, TERMS, Context, Model, NumpyOps
from optcal.core.problem import CalibrationProblem

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
    (docs/design.md, "Terms and parameters"): A_i² (quadratic), A_i³ (cubic), min(A_i, 0) (scale asymmetry), A_i·A_j
    (cross coupling), T − T0 (temperature bias), (T − T0)·A_i (temperature scale), t − t0 (drift), A_j
    (misalignment)."""
    data, out = problem.data, []
    dtemp = None if data.temp is None else data.temp - np.mean(data.temp)
    dt = None if data.t is None else data.t - data.t[0]
    if TERMS[term].user:  # c·φ on each of its outputs (optcal.core.terms.Feature)
        t = TERMS[term]
        ctx = Context.from_columns(temp=data.temp, t=data.t)
        names = iter(t.params)
        for i in t.axes:
            for kind in t.feature.kinds:
                values = t.feature.values((A[:, 0], A[:, 1], A[:, 2]), ctx, kind, NumpyOps)
                out.append((next(names), t.feature.text(kind), i, np.broadcast_to(values, (len(A),))))
        return out
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
            d.update(rms_after_g=self.fit.rms, statistic=num(self.f_statistic), df=[self.q, self.dof],
                     p_value=num(self.p_value), lr_statistic=num(self.lr_statistic), delta_bic=num(self.delta_bic))
        else:
            d["note"] = self.note
        return d


@dataclass
class Extension:
    """A candidate term ready to be refitted: the extended model's problem, the warm start (the current
    fit, the new parameters at zero) and the extended model's rank there."""

    term: str
    model: Model
    problem: CalibrationProblem
    x0: np.ndarray
    rank: int


def corr(a: np.ndarray, b: np.ndarray) -> float | None:
    """Pearson correlation, None when either side is constant."""
    if np.std(a) == 0 or np.std(b) == 0:
        return None
    return float(np.corrcoef(a, b)[0, 1])


def num(v) -> float | None:
    """A JSON-safe float: None for None, NaN and inf."""
    return float(v) if v is not None and np.isfinite(v) else None


def extend(current: Fit, term: str) -> Extension | Score:
    """``current``'s model with ``term`` added, or the skipped :class:`Score` saying why it cannot be tested
    (missing data columns, no residual degrees of freedom, or directions the positions leave unobservable)."""
    data = current.problem.data
    missing = [c for c in TERMS[term].needs if getattr(data, c) is None]
    if missing:
        return Score(term, note=f"needs column(s) {', '.join(missing)} that the data lack")
    model = current.model.with_term(term)
    m = current.problem.n_position_residuals  # the data's residuals: a gauge row is a constraint, not data
    q_raw = model.n_params - current.model.n_params
    if m - (current.rank + q_raw) < 1:
        return Score(term, note=f"{m} residuals leave no degrees of freedom for {model.n_params} parameters")
    problem = CalibrationProblem(model, data, g_local=current.problem.g_local, backend=current.problem.backend)
    x0 = model.from_dict(current.model.to_dict(current.x), model.default_vector(0.0))
    obs = observability(problem, x0)
    if obs.rank - current.rank < q_raw:
        dirs = "; ".join(" ".join(f"{w['weight']:+.2f}·{w['name']}" for w in d[:4]) for d in obs.unobservable)
        return Score(term, note=f"unobservable on these positions (rank {obs.rank} of {model.n_params}: {dirs})")
    return Extension(term, model, problem, x0, obs.rank)


def nested_test(current: Fit, ext: Extension, x: np.ndarray, nfev: int) -> Score:
    """The F-test (with the likelihood-ratio statistic and ΔBIC) of the extension refitted at ``x`` against
    ``current`` (the module docstring's equations)."""

    r = ext.problem.residuals_full(x)[0]
    if not np.all(np.isfinite(r)):
        return Score(ext.term, note="the refit failed (non-finite residuals)")
    fit = Fit(ext.model, ext.problem, x, r, ext.rank, nfev)
    m = current.problem.n_position_residuals
    q = ext.rank - current.rank
    rss0, rss1 = current.rss, max(fit.rss, np.finfo(float).tiny)
    dof = m - ext.rank
    f_stat = max(rss0 - rss1, 0.0) / q / (rss1 / dof)
    return Score(ext.term, fit=fit, q=q, dof=dof, f_statistic=f_stat, p_value=float(f_sf(f_stat, q, dof)),
                 lr_statistic=m * np.log(rss0 / rss1), delta_bic=m * np.log(rss1 / rss0) + q * np.log(m))


def best_of(scores: list[Score]) -> Score | None:
    """The tested candidate with the lowest p-value; ties broken by the most negative ΔBIC."""
    tested = [s for s in scores if s.tested]
    return min(tested, key=lambda s: (s.p_value, s.delta_bic)) if tested else None


def candidate_pool(model: Model, candidates) -> list[str]:
    """The candidates to try on ``model`` (default: every term of :data:`CANDIDATES` it lacks); unknown
    names and a misalignment already covered by ``misalignment6`` are InputErrors."""
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


# -- noise -------------------------------------------------------------------------------------

def residual_sigma(fit: Fit, noise_g: float | None) -> float:
    """The noise of a norm residual: ``noise_g`` if known, else the fit's residual SD (RSS over m − rank)."""
    if noise_g is not None:
        return noise_g
    return float(np.sqrt(fit.rss / max(fit.problem.n_position_residuals - fit.rank, 1)))


def noise_per_position(fit: Fit, noise_g: float | None, notes: list[str]) -> np.ndarray | None:
    """σ_j, the noise of each norm residual in g: ``noise_g`` if given, else each position's standard error
    per axis (:meth:`~optcal.core.data.PositionsData.noise_of_mean`: se_x, se_y, se_z, correlated noise included,
    as a recording's positions carry them, docs/noise.md; else sx, sy, sz over √n) referred to the input with
    the fitted scale factors and projected on the measured direction, σ_j² = Σ_i â_ji²·(se_ji / K_i)²; None
    when neither is known. A note names the estimator of a recording's floor."""
    m = fit.problem.n_position_residuals
    if noise_g is not None:
        return np.full(m, float(noise_g))
    se = fit.problem.data.noise_of_mean()
    if se is None:
        return None
    A = fit.specific_force
    u = A / np.linalg.norm(A, axis=1, keepdims=True)
    K = np.abs(fit.x[fit.model.groups()["scale"]])
    sigma = np.sqrt(np.sum((u * se / K) ** 2, axis=1))
    floor = fit.problem.data.extra.get("noise_floor") if isinstance(fit.problem.data.extra, dict) else None
    if floor is not None and fit.problem.data.sem is not None:
        notes.append(floor.describe())
    bad = ~(sigma > 0)
    if bad.all():
        notes.append("every position has zero sample SD; the noise floor is unknown")
        return None
    if bad.any():
        notes.append(f"{int(bad.sum())} position(s) with zero sample SD (one sample?) take the median noise")
        sigma[bad] = np.median(sigma[~bad])
    return sigma
