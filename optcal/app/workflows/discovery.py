"""Model discovery's search (docs/design.md, "Model discovery", docs/discovery.md): fit the base model, then forward
selection over the candidate terms, each extension refitted by a solver and scored by the F-test and ΔBIC of
:mod:`optcal.core.discovery.statistics` (whose docstring gives the equations and the stopping rule); then the
residual diagnostics (:mod:`optcal.core.discovery.diagnostics`) and the search of the generated dictionary of
features the list lacks (:mod:`optcal.core.discovery.dictionary`), stepwise: the best feature by its linearised
test, refitted exactly and added at the same α/k and ΔBIC, after which a term that no longer earns its place
(p ≥ α) is removed; the dictionary's terms are kept only when they close the gap to the floor.

Application layer (CONTRIBUTING.md, "Layers"): this is the part of discovery that runs a solver, so it
imports ``solvers``; the statistics, the report and its text and figure are core and do not.
"""

from __future__ import annotations

import numpy as np

from optcal import solvers
from optcal.core.analysis import crlb, goodness_of_fit, observability
from optcal.core.data import PositionsData
from optcal.core.discovery.diagnostics import candidate_periods, diagnose, floor_of, lack_of_fit, periodograms
from optcal.core.discovery.dictionary import (
    Dictionary,
    best,
    feature_context,
    generate,
    model_basis,
    refine_period,
    screen,
)
from optcal.core.discovery.results import DiscoveryReport, Removal, Step
from optcal.core.discovery.statistics import (
    DEFAULT_ALPHA,
    DEFAULT_BIC_THRESHOLD,
    Extension,
    Fit,
    Score,
    best_of,
    candidate_pool,
    extend,
    nested_test,
    noise_per_position,
    residual_sigma,
)
from optcal.core.distributions import chi2_sf, f_sf
from optcal.core.errors import InputError
from optcal.core.model import AXES, TERMS, Model, get_model
from optcal.core.problem import CalibrationProblem

MAX_DICTIONARY_TERMS = 4  # dictionary terms added at most (each one step of the search)


def _backend(solver: str) -> str:
    """The NumPy evaluation for solvers of a few tens of evaluations (Levenberg-Marquardt), as optcal calibrate
    chooses: numba's start costs more than such a fit."""
    return "numpy" if getattr(solvers.get(solver), "few_evaluations", False) else "kernel"


def _solve(problem: CalibrationProblem, x0, solver: str, budget: int) -> tuple[np.ndarray, int]:
    res = solvers.get(solver).solve(problem, x0=x0, budget=budget, rng=np.random.default_rng(0))
    return problem.to_full(res.x)[0], res.nfev


def fit_model(model: Model, data: PositionsData, g_local: float, x0=None, *, solver: str = "lm",
              budget: int = 2000, rank: int | None = None, backend: str | None = None) -> Fit:
    """Least-squares fit of ``model`` to ``data`` with the named solver; ``rank`` by default from the
    observability at the fitted point."""
    problem = CalibrationProblem(model, data, g_local=g_local, backend=backend or _backend(solver))
    x, nfev = _solve(problem, x0, solver, budget)
    if rank is None:
        rank = observability(problem, x).rank
    return Fit(model, problem, x, problem.residuals_full(x)[0], rank, nfev)


def score(current: Fit, term: str, *, solver: str = "lm", budget: int = 2000) -> Score:
    """Refit with ``term`` added (warm start: current fit, new parameters zero) and test the gain."""
    ext = extend(current, term)
    if not isinstance(ext, Extension):
        return ext  # skipped, with the reason
    x, nfev = _solve(ext.problem, ext.x0, solver, budget)
    return nested_test(current, ext, x, nfev)


def _stderr(fit: Fit, term: str, noise_g: float | None) -> dict[str, float]:
    sd, _ = crlb(fit.problem, fit.x, residual_sigma(fit, noise_g if noise_g is not None else fit.problem.noise_g))
    return {n: float(sd[fit.model.index(n)]) for n in TERMS[term].params}


def discover(data: PositionsData, base: str | Model = "linear9", candidates=None, g_local: float = 1.0,
             alpha: float = DEFAULT_ALPHA, bic_threshold: float = DEFAULT_BIC_THRESHOLD, *,
             noise_g: float | None = None, max_steps: int | None = None, solver: str = "lm",
             budget: int = 2000, dictionary: bool | None = None,
             max_dictionary_terms: int = MAX_DICTIONARY_TERMS) -> DiscoveryReport:
    """Forward selection of the missing terms (see :mod:`optcal.core.discovery.statistics` for the tests), the
    residual diagnostics and the dictionary's search (module docstring).

    ``noise_g``: input-referred noise of each position's mean per axis, in g; by default from the data's
    ``n`` and ``sx, sy, sz`` (else the scatter of replicated poses, else unknown, and the report says what to
    record). ``dictionary``: search the generated dictionary too (default: unless ``candidates`` names the
    terms to try).
    """
    if not 0.0 < alpha < 1.0:
        raise InputError(f"alpha must be between 0 and 1, got {alpha}")
    if noise_g is not None and not noise_g > 0:
        raise InputError(f"noise_g must be positive, got {noise_g}")
    if max_dictionary_terms < 0:
        raise InputError(f"max_dictionary_terms must be 0 or more, got {max_dictionary_terms}")
    model = get_model(base)
    pool = candidate_pool(model, candidates)
    current = fit_model(model, data, g_local, solver=solver, budget=budget)
    notes = []
    if current.rank < model.n_params:
        notes.append(f"base {model.name} has {model.n_params - current.rank} unobservable direction(s) on these "
                     "positions; degrees of freedom use its rank")
    initial, steps, last_round = current, [], []
    while pool and (max_steps is None or len(steps) < max_steps):
        scores = [score(current, t, solver=solver, budget=budget) for t in pool]
        best_score = best_of(scores)
        k = sum(s.tested for s in scores)
        threshold = alpha / max(k, 1)
        if best_score is None or not (best_score.p_value < threshold and best_score.delta_bic < bic_threshold):
            last_round = scores
            break
        alternatives = [s.term for s in scores
                        if s.tested and s is not best_score and s.delta_bic < best_score.delta_bic + 2.0]
        steps.append(Step(best_score.term, current, best_score.fit, best_score, scores, threshold,
                          _stderr(best_score.fit, best_score.term, noise_g), alternatives))
        current = best_score.fit
        pool = [t for t in pool if t != best_score.term]
    listed = current
    ctx = feature_context(data)
    sigma_j = noise_per_position(current, noise_g, notes)
    floor = floor_of(listed, sigma_j, stated=noise_g is not None)
    diag_listed = diagnose(listed, data, floor, alpha, ctx)
    search = None
    if (candidates is None if dictionary is None else dictionary) and max_dictionary_terms > 0:
        search = _DictionarySearch(data, g_local, alpha, bic_threshold, noise_g, solver, budget, floor, ctx)
        current = search.run(listed, steps, max_dictionary_terms, max_steps)
        if search.steps:
            closed, p = _closes_gap(current, sigma_j, noise_g, floor_of(current, sigma_j, noise_g is not None),
                                    alpha)
            search.closes_gap = closed
            if closed is False:  # never name a term that leaves the gap open: back to the list's model
                search.partial, search.gap_p = search.steps, p
                current = listed
            else:
                steps += search.steps
    sigma_j = noise_per_position(current, noise_g, [])
    final_floor = floor_of(current, sigma_j, noise_g is not None)
    diag_final = diag_listed if current is listed else diagnose(current, data, final_floor, alpha, ctx)
    floor_rms = None if sigma_j is None else float(np.sqrt(np.mean(sigma_j**2)))
    gof = None
    if noise_g is None and sigma_j is not None:
        fit = goodness_of_fit(current.problem, current.x)
        gof = fit if fit.expected_chi2 is not None else None  # a recording's floor: judged as calibrate does
    report = DiscoveryReport(model.name, initial, current, steps, last_round, alpha, bic_threshold, floor_rms,
                             sigma_j, notes, gof)
    report.listed = listed
    report.floor = final_floor
    report.lack_of_fit = lack_of_fit(current, final_floor)
    report.diagnostics_listed, report.diagnostics = diag_listed, diag_final
    if search is not None:
        report.dictionary = search.info()
        report.dictionary_last_round = search.last_round
        report.removed = search.removed
        report.partial = search.partial
        report.gap_p = search.gap_p
        report.closes_gap = search.closes_gap
    return report


def _closes_gap(fit: Fit, sigma_j, noise_g, floor, alpha: float) -> tuple[bool | None, float | None]:
    """Whether ``fit`` reaches the floor: the χ² test (against a recording's floor as calibrate judges it) or the
    lack-of-fit test against replicates; (None, None) without a floor."""
    if sigma_j is not None:
        if noise_g is None:
            gof = goodness_of_fit(fit.problem, fit.x)
            if gof.expected_chi2 is not None:
                return gof.p_value >= alpha, float(gof.p_value)
        n = fit.problem.n_position_residuals
        dof = n - fit.rank
        if dof < 1:
            return None, None
        p = float(chi2_sf(float(np.sum((fit.residuals[:n] / sigma_j) ** 2)), dof))
        return p >= alpha, p
    lof = lack_of_fit(fit, floor)
    if lof is None:
        return None, None
    return lof[3] >= alpha, lof[3]


class _DictionarySearch:
    """Stepwise selection over the generated dictionary (module docstring), from the list's final fit."""

    def __init__(self, data, g_local, alpha, bic_threshold, noise_g, solver, budget, floor, ctx):
        self.data, self.g_local, self.alpha, self.bic = data, g_local, alpha, bic_threshold
        self.noise_g, self.solver, self.budget, self.floor, self.ctx = noise_g, solver, budget, floor, ctx
        self.steps: list[Step] = []
        self.removed: list[Removal] = []
        self.partial: list[Step] = []
        self.last_round: list = []
        self.last: Dictionary | None = None
        self.periods: list[tuple[float, ...]] = []  # each round's candidate periods
        self.k = 0.0
        self.closes_gap: bool | None = None
        self.gap_p: float | None = None

    def _dictionary(self, fit: Fit) -> Dictionary:
        periods, n_ind = (), 0
        if self.data.t is not None and np.ptp(self.data.t) > 0:
            pg = periodograms(fit, np.asarray(self.data.t, float), self.floor)
            if pg is not None:
                periods, n_ind = candidate_periods(pg, float(np.ptp(self.data.t))), pg["n_independent"]
        return generate(fit.model, self.data, periods, n_ind)

    def _round(self, current: Fit):
        """The dictionary at ``current``, the model's basis, every atom's linearised test and the threshold."""
        d = self._dictionary(current)
        Q = model_basis(current)
        scores = screen(current, d, self.ctx, Q)
        k = d.k_effective([s.atom for s in scores if s.tested])
        return d, Q, scores, k, self.alpha / max(k, 1.0)

    def _step(self, current: Fit, pick, scores, threshold: float, k: float, replaces: str | None = None):
        """The exact refit of ``current`` with the chosen atom, as a Step, or None when it fails the test."""
        exact = score(current, pick.term, solver=self.solver, budget=self.budget)
        if not exact.tested or not (exact.p_value < threshold and exact.delta_bic < self.bic):
            return None
        near = [s.term for s in scores if s.tested and s is not pick and s.delta_bic < pick.delta_bic + 2.0]
        return Step(pick.term, current, exact.fit, exact, [], threshold, _stderr(exact.fit, pick.term, self.noise_g),
                    near, source="dictionary", equivalents=list(pick.atom.equivalents), k_tested=k,
                    atom_scores=sorted([s for s in scores if s.tested], key=lambda s: s.p_value)[:10],
                    replaces=replaces)

    def run(self, current: Fit, list_steps: list[Step], max_terms: int, max_steps: int | None) -> Fit:
        added = [s.term for s in list_steps]
        while len(self.steps) < max_terms and (max_steps is None or len(list_steps) + len(self.steps) < max_steps):
            swapped = self._swap(current, list_steps)
            if swapped is not None:
                step = swapped
            else:
                d, Q, scores, self.k, threshold = self._round(current)
                self.last = d
                self.periods.append(d.periods)
                pick = best(scores)
                if pick is None or not (pick.p_value < threshold and pick.delta_bic < self.bic):
                    self.last_round = scores
                    break
                if pick.atom.kind == "sinusoid":
                    pick = _refined(pick, current, self.ctx, Q, float(np.ptp(self.data.t)))
                step = self._step(current, pick, scores, threshold, self.k)
                if step is None:
                    self.last_round = scores
                    break
            self.steps.append(step)
            current = step.after
            if step.replaces:
                added.remove(step.replaces)
            added.append(step.term)
            current = self._prune(current, added, step.term)
            current = self._single_axis(current, added)
        return current

    def _swap(self, current: Fit, list_steps: list[Step]):
        """An exchange move (Miller, Subset Selection in Regression, 2002, §3.5): a term the list added replaced by
        the dictionary's best feature in its absence, when that model is better by BIC (ΔBIC below the threshold)
        and the feature passes its test against the model without the term. Greedy forward selection commits to
        the list's terms first; an effect outside the list is often partly absorbed by one of them (a cubic
        temperature bias by temperature_bias and temperature_scale) and then never named. Only a term with an
        output that was not significant on its own when the list added it (|value| below z(1 − α/2) standard
        errors) is offered: one whose every parameter is significant explains what it was named for. None when no
        exchange helps."""
        from optcal.core.distributions import norm_isf

        z = float(norm_isf(self.alpha / 2))
        list_terms = [s.term for s in list_steps if s.term in current.model.terms
                      and any(not abs(v) >= z * s.stderr[n] for n, v in s.parameters.items())]
        if not list_terms:
            return None
        n = current.problem.n_position_residuals
        bic_now = n * np.log(current.rss / n) + current.rank * np.log(n)
        options = []
        for term in list_terms:
            model = get_model("+".join(t for t in current.model.terms if t != term))
            x0 = model.from_dict({k: v for k, v in current.model.to_dict(current.x).items() if k in model.names})
            without = fit_model(model, self.data, self.g_local, x0, solver=self.solver, budget=self.budget)
            _, _, scores, k, threshold = self._round(without)
            pick = best(scores)
            if pick is None or not pick.p_value < threshold:
                continue
            bic = n * np.log(pick.rss_after / n) + (without.rank + pick.q) * np.log(n)
            if bic - bic_now < self.bic:
                options.append((bic, term, without, pick, scores, k, threshold))
        for _, term, without, pick, scores, k, threshold in sorted(options, key=lambda o: o[0]):
            step = self._step(without, pick, scores, threshold, k, replaces=term)
            if step is not None:
                step.before = current
                self.removed.append(Removal(term, float("nan"), step.term, "replaced"))
                return step
        return None

    def _prune(self, current: Fit, added: list[str], newest: str) -> Fit:
        """Remove, one at a time, an added term (of the list or the dictionary) that is no longer significant
        at α once ``newest`` is in: the linearised F-test of dropping its columns (:func:`_drop_increase`), the
        least significant one refitted without it exactly (stepwise regression's removal step: Efroymson 1960,
        with α to stay above the α/k to enter, so that no term cycles in and out)."""
        while True:
            n = current.problem.n_position_residuals
            rss, dof = current.rss, n - current.rank
            worst = None
            for term in [t for t in added if t != newest and t in current.model.terms]:
                drop = np.zeros(current.model.n_params, bool)
                drop[current.model.term_slices()[term]] = True
                inc, q = _drop_increase(current, drop)
                if q < 1 or dof < 1:
                    continue
                p = float(f_sf((inc / q) / (rss / dof), q, dof))
                if p >= self.alpha and (worst is None or p > worst[1]):
                    worst = (term, p)
            if worst is None:
                return current
            term, p = worst
            model = get_model("+".join(t for t in current.model.terms if t != term))
            x0 = model.from_dict({k: v for k, v in current.model.to_dict(current.x).items() if k in model.names})
            current = fit_model(model, self.data, self.g_local, x0, solver=self.solver, budget=self.budget)
            self.removed.append(Removal(term, p, newest))
            added.remove(term)

    def _single_axis(self, current: Fit, added: list[str]) -> Fit:
        """A dictionary term on the three outputs reduced to one, when the other two outputs' coefficients are
        not significant together (p ≥ α, the linearised F-test of dropping them): SINDy's thresholding of small
        coefficients, at the error rate of the search."""
        for term in [t for t in added if TERMS[t].user and len(TERMS[t].axes) == 3 and t in current.model.terms]:
            n = current.problem.n_position_residuals
            dof = n - current.rank
            feature = TERMS[term].feature
            sl = current.model.term_slices()[term]
            per = len(feature.kinds)
            best_axis = None
            for i in range(3):
                drop = np.zeros(current.model.n_params, bool)
                drop[sl] = True
                drop[sl.start + per * i: sl.start + per * (i + 1)] = False
                inc, q = _drop_increase(current, drop)
                if q < 1 or dof < 1:
                    continue
                p = float(f_sf((inc / q) / (current.rss / dof), q, dof))
                if p >= self.alpha and (best_axis is None or p > best_axis[1]):
                    best_axis = (i, p)
            if best_axis is None:
                continue
            single = f"{feature.token()}@{AXES[best_axis[0]]}"
            model = get_model("+".join(single if t == term else t for t in current.model.terms))
            values = current.model.to_dict(current.x)
            x0 = model.from_dict({k: v for k, v in values.items() if k in model.names})
            current = fit_model(model, self.data, self.g_local, x0, solver=self.solver, budget=self.budget)
            self.removed.append(Removal(term, best_axis[1], single, "narrowed"))
            added[added.index(term)] = single
            for s in self.steps:
                if s.term == term:
                    s.narrowed_to = single
        return current

    def info(self) -> dict:
        d = self.last
        return {"atoms": 0 if d is None else len(d.atoms), "k": self.k,
                "temp_scale_C": None if d is None else d.temp_scale,
                "time_scale_s": None if d is None else d.time_scale,
                "periods_s": [] if d is None else list(d.periods),
                "periods_by_round_s": [list(p) for p in self.periods],
                "n_independent_frequencies": 0 if d is None else d.n_independent_frequencies,
                "notes": [] if d is None else d.notes}


def _refined(pick, fit: Fit, ctx, Q, span: float):
    """The chosen sinusoid at its refined period (:func:`optcal.core.discovery.dictionary.refine_period`)."""
    from dataclasses import replace

    return replace(pick, atom=refine_period(fit, pick.atom, ctx, Q, span))


def _drop_increase(fit: Fit, drop: np.ndarray) -> tuple[float, int]:
    """(RSS increase, rank lost) when the parameters ``drop`` (a mask) are set to zero in ``fit`` and the others
    refitted linearly (Frisch–Waugh: ‖(I − P_others)·J_drop·β_drop‖²)."""
    from optcal.core.gauge import RTOL, natural_units

    n = fit.problem.n_position_residuals
    u = natural_units(fit.problem, fit.x)
    J = fit.problem.jacobian_full(fit.x)[:n] * u
    U, s, _ = np.linalg.svd(J[:, ~drop], full_matrices=False)
    Q = U[:, s > RTOL * s[0]] if s.size else U[:, :0]
    v = J[:, drop] @ (fit.x[drop] / u[drop])
    v = v - Q @ (Q.T @ v)
    return float(v @ v), fit.rank - Q.shape[1]
