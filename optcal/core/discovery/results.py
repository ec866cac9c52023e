"""What model discovery found (docs/design.md, "Model discovery"): each added term with the test that chose it
(:class:`Step`) and the whole search (:class:`DiscoveryReport`: the final model, its χ² against the noise
floor, the verdict, the JSON form). Core: built by :func:`optcal.app.workflows.discovery.discover`, read by
anything; the plain text is :mod:`optcal.core.discovery.text`'s and the figure :mod:`optcal.core.plots.discovery`'s.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from optcal.core.analysis import crlb
from optcal.core.discovery.statistics import (
    EXPLAINED,
    NO_DOF,
    REMAINS,
    UNKNOWN,
    Fit,
    Score,
    corr,
    num,
    projected,
    regressors,
    residual_sigma,
)
from optcal.core.model import TERMS, Model


@dataclass
class Step:
    """One added term: its fitted parameters with standard errors, the gap before and after, the test. A step
    of the dictionary's search (``source`` "dictionary") adds a user-defined term; ``equivalents`` are the
    terms the norm cannot tell from it, ``k_tested`` the Bonferroni count of its round and ``atom_scores`` the
    linearised tests of the round's best features."""

    term: str
    before: Fit
    after: Fit
    chosen: Score
    scores: list[Score]
    p_threshold: float
    stderr: dict[str, float]
    alternatives: list[str]
    source: str = "list"
    equivalents: list[str] = field(default_factory=list)
    k_tested: float | None = None
    atom_scores: list = field(default_factory=list)
    replaces: str | None = None  # the list's term this step exchanged for its own
    narrowed_to: str | None = None  # the single-output term a three-output one was reduced to later

    @property
    def formula(self) -> str:
        """The term's formula: a user-defined term's (e.g. ``z output += c·A_x·A_y``), else its description."""
        return TERMS[self.kept].description

    @property
    def kept(self) -> str:
        """The term this step leaves in the model: its own, or the one output it was narrowed to later."""
        return self.narrowed_to or self.term

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
            out[name] = {"regressor": label, "before": corr(r, self.before.residuals),
                         "after": corr(r, self.after.residuals)}
        return out

    def to_dict(self) -> dict:
        c = self.chosen
        m = self.before.problem.n_position_residuals
        return {
            "added": self.term,
            "source": self.source,
            "formula": self.formula,
            "equivalents": self.equivalents,
            "k_tested": self.k_tested,
            "replaces": self.replaces,
            "narrowed_to": self.narrowed_to,
            "parameters": self.parameters,
            "stderr": {n: num(s) for n, s in self.stderr.items()},
            "rms_before_g": self.before.rms, "rms_after_g": self.after.rms,
            "statistic": num(c.f_statistic), "test": "F", "df": [c.q, c.dof],
            "p_value": num(c.p_value), "p_threshold": self.p_threshold,
            "delta_bic": num(c.delta_bic), "lr_statistic": num(c.lr_statistic),
            "alternatives": self.alternatives,
            "correlations": self.correlations(),
            "candidates": ([s.to_dict() for s in self.scores] if self.source == "list"
                           else [s.to_dict(m) for s in self.atom_scores]),
        }


@dataclass
class Removal:
    """A term taken out again. ``kind`` "removed": once ``after`` was added it no longer earned its place
    (p ≥ α); "replaced": the exchange that added ``after`` took it out; "narrowed": a term of the three outputs
    reduced to ``after``, its one significant output (the others' p ≥ α together)."""

    term: str
    p_value: float
    after: str
    kind: str = "removed"

    def to_dict(self) -> dict:
        from optcal.core.discovery.statistics import num

        return {"term": self.term, "kind": self.kind, "p_value": num(self.p_value), "after": self.after}


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
    # the final fit judged against a recording's noise floor (optcal.core.analysis.GoodnessOfFit), when the noise
    # comes from the data's floor rather than a stated level
    floor_fit: object | None = None
    # the list's final fit (before the dictionary), the floor (optcal.core.discovery.diagnostics.Floor) and the
    # lack-of-fit test against replicates (F, q, pure-error dof, p) when that is the floor
    listed: Fit | None = None
    floor: object | None = None
    lack_of_fit: tuple | None = None
    # the residual diagnostics after the list's search and of the final model (diagnostics.Diagnostics)
    diagnostics_listed: object | None = None
    diagnostics: object | None = None
    # the dictionary's search: what it was generated from, its last round (dictionary.AtomScore), the terms
    # removed again, the dictionary's steps that did not close the gap (not in the final model) and that test
    dictionary: dict | None = None
    dictionary_last_round: list = field(default_factory=list)
    removed: list[Removal] = field(default_factory=list)
    partial: list[Step] = field(default_factory=list)
    gap_p: float | None = None
    closes_gap: bool | None = None

    @property
    def final_model(self) -> Model:
        return self.final.model

    @property
    def added(self) -> list[str]:
        """The added terms the final model holds, in the order they were added."""
        return [s.kept for s in self.steps if s.kept in self.final.model.terms]

    @property
    def found(self) -> list[Step]:
        """The dictionary's steps whose terms the final model holds: named, and closing the gap (or no floor)."""
        return [s for s in self.steps if s.source == "dictionary" and s.kept in self.final.model.terms]

    @property
    def m(self) -> int:
        """The data's residuals (a gauge row holding an unobservable direction is a constraint, not data)."""
        return self.final.problem.n_position_residuals

    @property
    def dof(self) -> int:
        return self.m - self.final.rank

    @property
    def expected_rms(self) -> float | None:
        """The RMS a correct model leaves: σ·√((m − p)/m)."""
        return None if self.noise_g is None else self.noise_g * np.sqrt(self.dof / self.m)

    @property
    def chi2(self) -> tuple[float, int, float] | None:
        """χ² goodness of fit of the final model against the known noise, Σ (e_j/σ_j)²: (χ², dof, p-value).
        With a recording's noise floor (correlated noise, estimated: ``floor_fit``) the p-value is the F test
        of :func:`optcal.core.analysis.goodness_of_fit`, as ``optcal calibrate`` judges the same fit (docs/noise.md);
        else P(χ²_dof > χ²)."""
        from optcal.core.distributions import chi2_sf

        if self.sigma_j is None or self.dof < 1:
            return None
        if self.floor_fit is not None and self.floor_fit.chi2 is not None:
            return float(self.floor_fit.chi2), self.dof, float(self.floor_fit.p_value)
        c = float(np.sum((self.final.residuals[:self.m] / self.sigma_j) ** 2))
        return c, self.dof, float(chi2_sf(c, self.dof))

    @property
    def verdict(self) -> str:
        """χ² test of the final residual against the noise floor at level α (needs the noise), or the lack-of-fit
        test against replicated poses when they are the floor."""
        if self.dof < 1:
            return NO_DOF
        chi = self.chi2
        if chi is None:
            if self.lack_of_fit is not None:
                return EXPLAINED if self.lack_of_fit[3] >= self.alpha else REMAINS
            return UNKNOWN
        return EXPLAINED if chi[2] >= self.alpha else REMAINS

    def final_stderr(self) -> np.ndarray:
        f = self.final
        sd, _ = crlb(f.problem, f.x, residual_sigma(f, self.noise_g))
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
            "final_stderr": {n: num(s) for n, s in zip(f.model.names, self.final_stderr())},
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
            "floor": None if self.floor is None else self.floor.to_dict(),
            "lack_of_fit": None if self.lack_of_fit is None else dict(zip(("F", "q", "pure_error_dof", "p_value"),
                                                                          map(num, self.lack_of_fit))),
            "diagnostics_listed": None if self.diagnostics_listed is None else self.diagnostics_listed.to_dict(),
            "diagnostics": None if self.diagnostics is None else self.diagnostics.to_dict(),
            "dictionary": self.dictionary,
            "found": [{"term": s.kept, "formula": s.formula, "equivalents": s.equivalents,
                       "parameters": {n: float(f.x[f.model.index(n)]) for n in TERMS[s.kept].params}}
                      for s in self.found],
            "closes_gap": self.closes_gap,
            "removed": [r.to_dict() for r in self.removed],
            "partial": [{"term": s.term, "formula": s.formula, "rms_before_g": s.before.rms,
                         "rms_after_g": s.after.rms, "p_value": num(s.chosen.p_value)} for s in self.partial],
            "gap_p_value": num(self.gap_p),
            "dictionary_last_round": [s.to_dict(len(f.problem.data)) for s in
                                      sorted([s for s in self.dictionary_last_round if s.tested],
                                             key=lambda s: s.p_value)[:10]],
        }

    def summary(self) -> str:
        """A plain-text report (what the CLI prints; :func:`optcal.core.discovery.text.summary`)."""
        from optcal.core.discovery.text import summary

        return summary(self)

    def plot(self, path):
        """Write the residual figure to ``path`` and return it (:func:`optcal.core.plots.discovery.figure`)."""
        from optcal.core.plots.discovery import figure

        return figure(self, path)

    def plot_diagnostics(self, path):
        """Write the residual diagnostics' figure to ``path`` and return it
        (:func:`optcal.core.discovery.figures.diagnostics_figure`)."""
        from optcal.core.discovery.figures import diagnostics_figure

        return diagnostics_figure(self, path)
