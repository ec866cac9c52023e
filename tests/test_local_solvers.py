"""NLopt, CasADi/Ipopt Gauss-Newton, the convex ellipsoid fit and SciPy differential evolution.

Settings: 24-position simulations (10 µg per axis unless noise-free), PAPER_TRUTH restricted to the model
(the seeds' three extra angles dropped outside seed15), manufacturer presets as the start. The reference
optimum is scipy-lm's. Agreement "to 1e-9 relative" means: the costs agree to 1e-9 of the cost, and the
parameter vectors to 1e-9 of the largest parameter, max|Δx| ≤ 1e-9·max|x| (the parameters are in
natural units: relative scale, g, rad). The stricter per-parameter figure in units of the search
half-widths is printed; it is limited by scipy-lm, which stops once the cost (whose residuals carry
~1e-16 g of rounding on ~1e-5 g) can no longer confirm a step: its last Gauss-Newton step is still
~1e-9 half-widths, Ipopt's (which stops on the exact gradient) ~1e-12.
"""

from __future__ import annotations

import functools

import nlopt
import numpy as np
import pytest

from optcal import solvers
from optcal.core.analysis import crlb
from optcal.core.data import PositionsData
from optcal.core.errors import InputError
from optcal.core.model import Context, get_model
from optcal.core.presets import PAPER_TRUTH, Presets, draw_truth, manufacturer_presets
from optcal.core.problem import CalibrationProblem
from optcal.core.schemes import rotation_groups
from optcal.core.simulate import simulate
from optcal.solvers import casadi_ipopt as ci
from optcal.solvers.ellipsoid import ellipsoid_start, fit_ellipsoid
from optcal.solvers.nlopt_solver import RESULTS

SIGMA = 10e-6


def _truth(model) -> dict:
    m = get_model(model)
    return {k: v for k, v in PAPER_TRUTH.items() if k in m.names}


@functools.cache
def setting(model="nonlinear12", scheme="24", seed=1, reference=False, presets=True, noise=SIGMA):
    m = get_model(model)
    rng = np.random.default_rng(seed)
    truth = _truth(m)
    sim = simulate(m, truth, rng, scheme=scheme, noise_g=noise, reference=reference)
    pre = manufacturer_presets(truth, rng) if presets else None
    return sim, pre


def problem(model="nonlinear12", cls=CalibrationProblem, **kw) -> CalibrationProblem:
    sim, pre = setting(model, **kw)
    return cls(model, sim.data, presets=pre, reference=kw.get("reference", False))


@functools.cache
def reference_optimum(model="nonlinear12", **kw):
    res = solvers.get("scipy-lm").solve(problem(model, **kw), rng=0)
    assert res.success
    return res


def true_cost(p, x_full) -> float:
    """The cost of a full parameter vector, uncounted, without a test subclass's failures."""
    return float(np.sum(CalibrationProblem.residuals_full(p, x_full) ** 2))


def gap(f, f_ref) -> float:
    return (f - f_ref) / f_ref


# == CasADi / Ipopt ====================================================================================
AGREEMENT = [
    ("diag6", "6", False), ("diag6", "24", False), ("linear9", "24", False), ("nonlinear12", "24", False),
    ("seed15", "24", False), ("linear9", "24", True), ("nonlinear12", "24", True),
]


@pytest.mark.parametrize("model,scheme,reference", AGREEMENT)
def test_casadi_ipopt_agrees_with_scipy_lm(model, scheme, reference):
    p = problem(model, scheme=scheme, reference=reference)
    lm = reference_optimum(model, scheme=scheme, reference=reference)
    res = solvers.get("casadi-ipopt").solve(p, rng=0)
    dx = np.abs(res.x_full - lm.x_full)
    rel_x = dx.max() / np.abs(lm.x_full).max()
    rel_f = abs(res.fun - lm.fun) / lm.fun
    print(f"{model} {scheme} ref={reference}: cost {res.fun:.6e} vs {lm.fun:.6e} (rel {rel_f:.1e}), "
          f"max|dx|/max|x| {rel_x:.1e}, max|dx|/halfwidth {np.max(dx / p.halfwidth):.1e}, "
          f"nfev {res.nfev} vs {lm.nfev}, {res.message}")
    assert res.success, res.message
    # diag6 on 6 positions is exactly determined: both costs are rounding noise (~1e-30)
    assert abs(res.fun - lm.fun) <= 1e-9 * lm.fun + 1e-25
    assert rel_x <= 1e-9


@pytest.mark.parametrize("spec,columns", [("linear9+cubic+scale_asymmetry", {}),
                                          ("linear9+temperature_bias+temperature_scale", {"temp": (10, 40)})])
def test_casadi_ipopt_agrees_beyond_the_named_models(spec, columns):
    """min(A, 0) through CasadiOps.neg_part, and temperature offsets as NLP parameters (six sweeps)."""
    m = get_model(spec)
    rng = np.random.default_rng(5)
    truth = draw_truth(m, rng)
    sim = simulate(m, truth, rng, scheme="36", noise_g=SIGMA, **columns)
    p = CalibrationProblem(m, sim.data, presets=manufacturer_presets(truth, rng))
    lm = solvers.get("scipy-lm").solve(p, rng=0)
    res = solvers.get("casadi-ipopt").solve(p, rng=0)
    assert res.success and abs(res.fun - lm.fun) <= 1e-9 * lm.fun
    assert np.abs(res.x_full - lm.x_full).max() <= 1e-9 * np.abs(lm.x_full).max()


@pytest.mark.parametrize("spec,columns", [("nonlinear12", {}), ("seed15", {}),
                                          ("linear9+cubic+scale_asymmetry+cross_coupling", {}),
                                          ("linear9+temperature_scale+bias_drift", {"temp": (10, 40), "times": True})])
def test_symbolic_residuals_are_the_models_own(spec, columns):
    """The CasADi residuals (model.components in symbols, fixed sweeps) equal the NumPy ones to rounding,
    at parameters on the edge of the default search box (the largest nonlinearity the sweeps are set for)."""
    import casadi as ca

    m = get_model(spec)
    sim = simulate(m, draw_truth(m, np.random.default_rng(2)), np.random.default_rng(3), noise_g=SIGMA, **columns)
    p = CalibrationProblem(m, sim.data, fix_gauge=False)
    x = p.centre + p.halfwidth * np.random.default_rng(4).choice([-1.0, 1.0], m.n_params)
    ctx = Context(p.ctx.dtemp, p.ctx.dt)
    r = ci.symbolic_residuals(m, {n: float(v) for n, v in zip(m.names, x)}, ca.DM(p.data.N), ctx, p.g_local)
    np.testing.assert_allclose(np.asarray(ca.evalf(r)).ravel(), p.residuals_full(x)[0], rtol=0, atol=2e-15)


def test_casadi_ipopt_builds_once_per_structure_and_reuses_it():
    s = solvers.get("casadi-ipopt")
    a = problem("nonlinear12", seed=1)
    b = problem("nonlinear12", seed=2)  # other data, same structure
    s.warm_up(a)
    n_built = len(ci._CACHE)
    entry = ci.build(a, s._ipopt_options())
    ra, rb = s.solve(a, rng=0), s.solve(b, rng=0)
    assert len(ci._CACHE) == n_built and ci.build(b, s._ipopt_options()) is entry
    assert ra.success and rb.success and not np.allclose(ra.x, rb.x)
    # each solved its own data: both at scipy-lm's optimum of their data
    for r, seed in ((ra, 1), (rb, 2)):
        assert gap(r.fun, reference_optimum("nonlinear12", seed=seed).fun) <= 1e-9
    # another number of positions or the reference flag is another structure
    assert ci.build(problem("nonlinear12", scheme="36"), s._ipopt_options()) is not entry
    assert ci.build(problem("nonlinear12", reference=True), s._ipopt_options()) is not entry


def test_casadi_ipopt_counts_every_evaluation_and_keeps_the_budget_exactly():
    p = problem()
    s = solvers.get("casadi-ipopt")
    free = s.solve(p, rng=0)
    calls = ci.build(p, s._ipopt_options())["state"]["calls"]
    # every gated call (objective, gradient+JᵀJ, Hessian at a new point) plus the final point
    assert free.nfev == sum(calls.values()) + 1 and free.nfev < 40
    for budget in range(1, free.nfev):
        res = s.solve(p, budget=budget, rng=0)
        assert res.nfev == budget and res.success and "budget" in res.message, (budget, res.message)
        assert res.fun == pytest.approx(true_cost(p, res.x_full), rel=1e-12)
    assert res.fun <= s.solve(p, budget=3, rng=0).fun  # more budget, no worse


def test_casadi_ipopt_warm_starts_and_solves_restricted_views():
    p = problem()
    lm = reference_optimum()
    s = solvers.get("casadi-ipopt")
    cold = s.solve(p, rng=0)
    warm = s.solve(p, x0=lm.x, rng=0)
    assert warm.nfev < cold.nfev and gap(warm.fun, lm.fun) <= 1e-9
    # a view with some parameters held (the staged wrapper's stages): fixed by equal bounds in Ipopt
    v = p.restrict(["misalignment", "nonlinear"], at=p.centre)
    ref = solvers.get("scipy-lm").solve(v, rng=0)
    res = s.solve(v, rng=0)
    assert res.x.shape == (6,) and np.array_equal(res.x_full[v.model.groups()["scale"]], p.centre[:3])
    assert abs(res.fun - ref.fun) <= 1e-9 * ref.fun


# == NLopt ============================================================================================
# (solver, problem, budget, tolerance on the relative cost gap, on max |x − x_lm| / CRLB).
# Local methods: the full 12-parameter problem from the presets, to the local tolerance of the
# conformance suite (gap 1e-9). CRS2 and ISRES: the 6 scale and bias parameters with the other six held
# at the optimum (as the conformance suite does for global methods), a fixed budget, looser tolerances.
NLOPT_CASES = {
    "nlopt-bobyqa": ("full", None, 1e-9, 1e-3),
    "nlopt-sbplx": ("full", None, 1e-9, 1e-3),
    "nlopt-neldermead": ("full", None, 1e-9, 1e-3),
    "nlopt-lbfgs": ("full", None, 1e-9, 1e-3),
    "nlopt-slsqp": ("full", None, 1e-9, 1e-3),
    "nlopt-crs2": ("scale+bias", 5000, 1e-6, 1e-2),
    "nlopt-isres": ("scale+bias", 7000, 1e-3, 0.2),
}


def _nlopt_problem(kind):
    p = problem()
    lm = reference_optimum()
    if kind == "full":
        return p, None, p
    v = p.restrict(["scale", "bias"], at=lm.x_full)
    return v, v.from_full(p.centre), p


@pytest.mark.parametrize("name", list(NLOPT_CASES))
def test_nlopt_algorithm_reaches_the_optimum(name):
    kind, budget, tol_gap, tol_crlb = NLOPT_CASES[name]
    prob, x0, full = _nlopt_problem(kind)
    lm = reference_optimum()
    res = solvers.get(name).solve(prob, x0=x0, budget=budget, rng=1)
    sd, _ = crlb(full, lm.x_full, SIGMA)
    err = np.max(np.abs(res.x_full - lm.x_full) / sd)
    g = gap(res.fun, lm.fun)
    print(f"{name}: gap {g:.1e} (tol {tol_gap:g}), max error {err:.1e} CRLB (tol {tol_crlb:g}), "
          f"nfev {res.nfev}, {res.message}")
    assert res.success, res.message
    assert g <= tol_gap and err <= tol_crlb


@pytest.mark.parametrize("name,budget", [("nlopt-bobyqa", 50), ("nlopt-lbfgs", 7), ("nlopt-crs2", 157)])
def test_nlopt_budget_is_used_exactly_and_reported_as_success(name, budget):
    p = problem()
    res = solvers.get(name).solve(p, budget=budget, rng=1)
    assert res.nfev == budget and res.status == 1 and res.success
    assert res.message == "evaluation budget used up"
    assert res.fun == pytest.approx(true_cost(p, res.x_full), rel=1e-12)
    # (CRS2's first random population over the whole box is worse than the presets)
    assert res.fun < true_cost(p, p.centre) if name != "nlopt-crs2" else res.fun <= true_cost(p, p.centre)


@pytest.mark.parametrize("name", ["nlopt-crs2", "nlopt-isres"])
def test_nlopt_stochastic_algorithms_are_seeded_from_rng(name):
    # a box a tenth of the default half-widths, so that 500 evaluations move away from the presets
    sim, pre = setting()
    p0 = problem()
    narrow = Presets(pre.values, {n: 0.1 * h for n, h in zip(p0.model.names, p0.halfwidth)})
    prob = CalibrationProblem("nonlinear12", sim.data, presets=narrow)
    s = solvers.get(name)
    a = s.solve(prob, budget=500, rng=7)
    nlopt.srand(12345)  # NLopt's global generator is reseeded by every run
    b = s.solve(prob, budget=500, rng=7)
    c = s.solve(prob, budget=500, rng=8)
    np.testing.assert_array_equal(a.x, b.x)
    assert a.fun == b.fun and a.fun < true_cost(prob, prob.centre)
    assert not np.array_equal(a.x, c.x)


def test_nlopt_return_code_table():
    codes = {getattr(nlopt, k): k for k in ("SUCCESS", "STOPVAL_REACHED", "FTOL_REACHED", "XTOL_REACHED",
                                             "MAXEVAL_REACHED", "MAXTIME_REACHED", "FAILURE", "INVALID_ARGS",
                                             "OUT_OF_MEMORY", "ROUNDOFF_LIMITED", "FORCED_STOP")}
    assert set(RESULTS) == set(codes)
    assert all(RESULTS[c][1] for c in codes if c > 0)
    assert RESULTS[nlopt.ROUNDOFF_LIMITED][1]  # "still typically returns a useful result" (NLopt docs)
    assert not any(RESULTS[c][1] for c in (nlopt.FAILURE, nlopt.INVALID_ARGS, nlopt.OUT_OF_MEMORY,
                                           nlopt.FORCED_STOP))
    # a normal stop is reported from the table, with NLopt's code as the status
    res = solvers.get("nlopt-neldermead", xtol_rel=1e-6, ftol_rel=0.0).solve(problem(), rng=1)
    assert (res.status, res.message) == (nlopt.XTOL_REACHED, RESULTS[nlopt.XTOL_REACHED][0])


class NaNProblem(CalibrationProblem):
    """NaN cost wherever a parameter is more than 30% of its half-width from the presets."""

    def residuals_full(self, X_full):
        R = super().residuals_full(X_full)
        z = np.max(np.abs((np.atleast_2d(X_full) - self.centre) / self.halfwidth), axis=1)
        R = R.copy()
        R[z > 0.3] = np.nan
        return R


@pytest.mark.parametrize("name", ["nlopt-bobyqa", "nlopt-neldermead", "nlopt-lbfgs", "nlopt-crs2"])
def test_nlopt_nan_costs_do_not_lose_the_best_point(name):
    p = problem(cls=NaNProblem)
    prob, x0 = p, None
    if name == "nlopt-crs2":  # global: the 6 scale and bias parameters, as in the accuracy test
        prob = p.restrict(["scale", "bias"], at=reference_optimum().x_full)
        x0 = prob.from_full(p.centre)
    res = solvers.get(name).solve(prob, x0=x0, budget=1500, rng=1)
    z = np.abs((res.x_full - p.centre) / p.halfwidth).max()
    print(f"{name}: {res.message}, fun {res.fun:.3e}, |z| {z:.2f}, nfev {res.nfev}")
    assert np.isfinite(res.fun) and z <= 0.3 and res.nfev <= 1500
    assert res.fun == pytest.approx(true_cost(p, res.x_full), rel=1e-12)
    assert res.fun == p.counter.best_f and res.fun < true_cost(p, prob.to_full(prob.x0 if x0 is None else x0)[0])


def test_nlopt_foreign_errors_propagate_and_the_callback_stops():
    class Broken(CalibrationProblem):
        def residuals_full(self, X_full):
            raise KeyError("not NLopt's to report")

    with pytest.raises(KeyError):
        solvers.get("nlopt-bobyqa").solve(problem(cls=Broken), rng=1)
    seen = []
    res = solvers.get("nlopt-bobyqa").solve(problem(), rng=1, callback=lambda info: seen.append(info) or
                                            len(seen) >= 5)
    assert res.status == 2 and "callback" in res.message and res.nfev == 5 == len(seen)


def test_nlopt_options_are_validated():
    with pytest.raises(InputError, match="choose one of"):
        solvers.get("nlopt", algorithm="LN_NOPE")
    with pytest.raises(InputError, match="population"):
        solvers.get("nlopt", algorithm="LN_BOBYQA", population=20)
    with pytest.raises(InputError, match="fixes option"):
        solvers.get("nlopt-bobyqa", algorithm="LD_LBFGS")
    assert solvers.get("nlopt-crs2").family == "global"
    assert solvers.get("nlopt", algorithm="GN_ISRES").family == "global"
    assert solvers.get("nlopt-slsqp").family == "local"


# == ellipsoid ========================================================================================
def test_ellipsoid_recovers_noise_free_linear9_truth():
    p = problem("linear9", noise=0.0, presets=False)
    truth = setting("linear9", noise=0.0, presets=False)[0].truth_vector("linear9")
    res = solvers.get("ellipsoid").solve(p, rng=0)
    err = np.abs(res.x_full - truth)
    print(f"noise-free linear9: max error {err.max():.1e}, {res.message}")
    assert res.success and res.nfev == 1 and err.max() <= 1e-9
    assert res.extra["fit"]["polished"]


def test_ellipsoid_is_within_a_fraction_of_a_crlb_of_the_least_squares_fit():
    worst = 0.0
    for seed in range(3):
        p = problem("linear9", seed=seed, presets=False)
        lm = reference_optimum("linear9", seed=seed, presets=False)
        sd, _ = crlb(p, lm.x_full, SIGMA)
        res = solvers.get("ellipsoid").solve(p, rng=0)
        worst = max(worst, np.max(np.abs(res.x_full - lm.x_full) / sd))
        assert gap(res.fun, lm.fun) <= 1e-6
    print(f"ellipsoid vs least squares, 10 µg, 3 data sets: max difference {worst:.1e} CRLB")
    assert worst <= 0.05  # measured 3.5e-5: the algebraic and geometric fits of a near-sphere coincide


def test_ellipsoid_refuses_data_that_cannot_be_an_ellipsoid():
    one_plane = rotation_groups(45.0)[:8]  # group x only: every mean in the y-z plane
    with pytest.raises(InputError, match="do not determine an ellipsoid"):
        fit_ellipsoid(one_plane)
    u = np.random.default_rng(0).uniform(-1.0, 1.0, (40, 2))
    hyperboloid = np.column_stack([u, np.sqrt(1.5 + u[:, 0] ** 2 - u[:, 1] ** 2)])  # y² + z² − x² = 1.5
    hyperboloid[::2, 2] *= -1
    with pytest.raises(InputError, match="do not lie on an ellipsoid"):
        fit_ellipsoid(hyperboloid)
    with pytest.raises(InputError, match="finite"):
        fit_ellipsoid(np.full((24, 3), np.nan))
    # through the solver the refusal comes before the run (the CLI prints it as one line)
    p = CalibrationProblem("linear9", PositionsData(hyperboloid))
    with pytest.raises(InputError, match="do not lie on an ellipsoid"):
        solvers.get("ellipsoid").solve(p, rng=0)
    assert p.nfev == 0
    with pytest.raises(InputError, match="turntable"):
        solvers.get("ellipsoid").solve(problem("linear9", reference=True), rng=0)


def test_ellipsoid_beyond_linear9_is_an_initialiser():
    p = problem("nonlinear12", presets=False)
    res = solvers.get("ellipsoid").solve(p, rng=0)
    assert res.success and "K2_x, K2_y, K2_z" in res.message and "initialiser" in res.message
    assert np.all(res.x_full[p.model.groups()["nonlinear"]] == 0.0)
    s15 = problem("seed15", presets=False)
    r15 = solvers.get("ellipsoid").solve(s15, rng=0)
    for name in ("S_xz", "S_xy", "S_yx"):
        assert r15.x_full[s15.model.index(name)] == 0.0
    # diag6: the axis-aligned fit (Q diagonal) recovers a noise-free diag6 sensor
    d6 = problem("diag6", noise=0.0, presets=False)
    truth = setting("diag6", noise=0.0, presets=False)[0].truth_vector("diag6")
    assert np.abs(solvers.get("ellipsoid").solve(d6, rng=0).x_full - truth).max() <= 1e-9
    assert solvers.get("ellipsoid").family == "convex"


def test_ellipsoid_start_is_the_local_methods_default():
    p = problem("nonlinear12", presets=False)
    x = ellipsoid_start(p)
    fit = solvers.get("ellipsoid").solve(p, rng=0)
    np.testing.assert_array_equal(x, fit.x)
    # a restricted view keeps its held values; turntable data keep the regression start
    v = p.restrict(["nonlinear"], at=p.centre)
    np.testing.assert_array_equal(ellipsoid_start(v), v.x0)
    r = problem("nonlinear12", reference=True, presets=False)
    np.testing.assert_array_equal(ellipsoid_start(r), r.x0)
    # from it, a local method reaches the optimum of a problem without presets
    res = solvers.get("casadi-ipopt").solve(p, x0=x, rng=0)
    assert gap(res.fun, reference_optimum("nonlinear12", presets=False).fun) <= 1e-9


# == SciPy differential evolution ======================================================================
def _de_problem():
    prob, x0, _ = _nlopt_problem("scale+bias")
    return prob, x0


def test_scipy_de_evaluates_each_generation_in_one_batched_call(monkeypatch):
    prob, x0 = _de_problem()
    sizes = []
    original = CalibrationProblem.cost_batch

    def spy(self, X):
        sizes.append(np.shape(X))
        return original(self, X)

    monkeypatch.setattr(CalibrationProblem, "cost_batch", spy)
    res = solvers.get("scipy-de", popsize=10).solve(prob, x0=x0, budget=2000, rng=1)
    # popsize·n = 60 candidates per call, one call for the initial population and one per generation;
    # the last generation is cut by the budget (2000 = 33·60 + 20)
    assert sizes and all(s == (10 * 6, 6) for s in sizes)
    assert len(sizes) == res.nit + 1 == 34 and res.nfev == 2000


@pytest.mark.parametrize("budget", [1, 60, 157, 1000])
def test_scipy_de_uses_a_binding_budget_exactly(budget):
    prob, x0 = _de_problem()
    res = solvers.get("scipy-de").solve(prob, x0=x0, budget=budget, rng=1)
    assert res.nfev == budget and res.success and "budget" in res.message
    assert res.fun <= true_cost(prob, prob.to_full(x0)[0])  # the start is a member of the first population


def test_scipy_de_polish_gets_a_tenth_of_the_budget():
    prob, x0 = _de_problem()
    plain = solvers.get("scipy-de").solve(prob, x0=x0, budget=1000, rng=1)
    polished = solvers.get("scipy-de", polish=True).solve(prob, x0=x0, budget=1000, rng=1)
    # 900 evaluations for the generations (10 populations of 90), the rest for L-BFGS-B
    assert 900 < polished.nfev <= 1000 and polished.nit == 9
    assert polished.fun < plain.fun and "polish" in polished.message


def test_scipy_de_is_seeded_and_converges():
    prob, x0 = _de_problem()
    lm = reference_optimum()
    s = solvers.get("scipy-de")
    a, b, c = (s.solve(prob, x0=x0, budget=3000, rng=seed) for seed in (1, 1, 2))
    np.testing.assert_array_equal(a.x, b.x)
    assert not np.array_equal(a.x, c.x)
    free = s.solve(prob, x0=x0, rng=1)
    polished = solvers.get("scipy-de", polish=True).solve(prob, x0=x0, rng=1)
    print(f"scipy-de: gap {gap(free.fun, lm.fun):.1e} in {free.nfev} evaluations ({free.message}); "
          f"with polish {gap(polished.fun, lm.fun):.1e} in {polished.nfev}")
    assert free.success and gap(free.fun, lm.fun) <= 0.01
    assert polished.nfev > free.nfev and gap(polished.fun, lm.fun) <= 1e-9


def test_scipy_de_turns_nan_into_inf_and_validates_options():
    class Flaky(CalibrationProblem):
        calls = 0

        def residuals_full(self, X_full):
            R = super().residuals_full(X_full)
            self.calls += 1
            return np.full_like(R, np.nan) if self.calls % 3 == 0 else R

    p = problem(cls=Flaky)
    v = p.restrict(["scale", "bias"], at=reference_optimum().x_full)
    res = solvers.get("scipy-de").solve(v, x0=v.from_full(p.centre), budget=1000, rng=1)
    assert np.isfinite(res.fun) and res.fun == pytest.approx(true_cost(p, res.x_full), rel=1e-12)
    assert solvers.get("scipy-de", mutation="0.4,0.9").config["mutation"] == (0.4, 0.9)
    assert solvers.get("scipy-de", mutation=0.6).config["mutation"] == 0.6
    for bad in ({"mutation": "0.9,0.4"}, {"mutation": 3.0}, {"strategy": "best3bin"}, {"popsize": 0},
                {"recombination": 1.5}):
        with pytest.raises(InputError):
            solvers.get("scipy-de", **bad)


def test_presets_box_is_what_the_search_methods_see():
    """The search methods work in z = (x − centre)/half-width: the presets' box, whatever the units."""
    sim, pre = setting()
    narrow = Presets(pre.values, {"K_x": 1e-4})
    p = CalibrationProblem("nonlinear12", sim.data, presets=narrow)
    res = solvers.get("nlopt-bobyqa").solve(p, budget=300, rng=1)
    assert abs(res.x_full[0] - p.centre[0]) <= 1e-4 + 1e-15
