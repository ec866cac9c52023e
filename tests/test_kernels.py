"""The compiled kernel against the NumPy oracle: residuals, costs through views, and the analytic Jacobian.

The kernel is generated from the term table (``optcal.core.kernels.codegen``); the NumPy path
(``CalibrationProblem.residuals_full_numpy`` / ``jacobian_full_numpy``) is the oracle.
"""

import numpy as np
import pytest

from optcal import CalibrationProblem, get_model, simulate
from optcal.core.kernels import codegen
from optcal.core.model import NAMED_MODELS, TERMS
from optcal.core.presets import PAPER_TRUTH

SINGLE_TERMS = [t for t in TERMS if t not in ("scale", "bias", "misalignment", "misalignment6")]
MODELS = list(NAMED_MODELS) + [f"linear9+{t}" for t in SINGLE_TERMS]
N_VECTORS = 200


def truth_for(model) -> dict:
    rng = np.random.default_rng(11)
    values = {}
    for n in model.names:
        if n in PAPER_TRUTH:
            values[n] = PAPER_TRUTH[n]
        elif n.startswith("K_"):
            values[n] = 1.0
        else:  # a small effect of either sign for every other parameter
            values[n] = float(rng.choice([-1, 1]) * rng.uniform(2e-5, 2e-4))
    return values


def make_problem(name: str, reference: bool = False, scheme: str = "24") -> CalibrationProblem:
    m = get_model(name)
    sim = simulate(m, truth_for(m), np.random.default_rng(5), scheme=scheme, noise_g=10e-6, tilt_deg=2.0,
                   reference=reference, reference_error_arcsec=20.0 if reference else 0.0)
    return CalibrationProblem(m, sim.data, reference=reference)


def random_vectors(p: CalibrationProblem, S: int = N_VECTORS, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return p.centre + p.halfwidth * rng.uniform(-1.0, 1.0, (S, p.model.n_params))


def assert_rows_close(got, want, rtol):
    """Each candidate's residuals agree to ``rtol`` relative to that candidate's largest residual."""
    scale = np.max(np.abs(want), axis=1, keepdims=True)
    assert np.all(np.isfinite(got)) and np.all(np.isfinite(want))
    err = np.max(np.abs(got - want) / scale)
    assert err <= rtol, err


def test_generated_terms_are_up_to_date():
    assert codegen.TARGET.read_text() == codegen.source(), \
        "optcal/core/kernels/_terms.py is stale: run `python -m optcal.core.kernels.codegen`"


def test_every_parameter_has_a_slot_and_named_models_use_the_small_variant():
    from optcal.core.kernels import _terms

    assert _terms.SLOTS == codegen.slots()
    for name in MODELS:
        m = get_model(name)
        assert [_terms.SLOTS[k] for k in codegen.slot_indices(m)] == list(m.names)
    assert {codegen.variant_of(get_model(n)) for n in NAMED_MODELS} == {0}
    assert codegen.variant_of(get_model("linear9+cubic")) == 1


@pytest.mark.parametrize("name", MODELS)
@pytest.mark.parametrize("reference", [False, True], ids=["norm", "reference"])
def test_compiled_residuals_equal_the_numpy_path(name, reference):
    p = make_problem(name, reference)
    X = random_vectors(p)
    R = p.residuals_full(X)
    assert R.shape == (N_VECTORS, p.n_residuals)
    assert_rows_close(R, p.residuals_full_numpy(X), 1e-12)


@pytest.mark.parametrize("name", MODELS)
def test_analytic_jacobian_agrees_with_finite_differences_and_the_complex_step(name):
    p = make_problem(name)
    X = random_vectors(p, seed=1)
    # central differences: truncation error ~h², rounding ~ε/h; steps of 1e-5 search half-widths balance them
    h = 1e-5 * p.halfwidth
    worst_fd = worst_cs = 0.0
    for k, x in enumerate(X):
        J = p.jacobian_full(x)
        steps = h[:, None] * np.eye(x.size)
        fd = ((p.residuals_full(x + steps) - p.residuals_full(x - steps)) / (2 * h[:, None])).T
        col = np.max(np.abs(J), axis=0)
        worst_fd = max(worst_fd, float(np.max(np.abs(J - fd) / col)))
        if k < 20:  # the complex step through the NumPy model is slow: a tenth of the vectors
            worst_cs = max(worst_cs, float(np.max(np.abs(J - p.jacobian_full_numpy(x))) / np.max(np.abs(J))))
    print(f"{name}: Jacobian vs central differences {worst_fd:.1e}, vs complex step {worst_cs:.1e}")
    assert worst_fd <= 1e-6 and worst_cs <= 1e-11


@pytest.mark.parametrize("name", ["seed15", "linear9+scale_asymmetry"])
def test_reference_jacobian_agrees_with_the_complex_step(name):
    p = make_problem(name, reference=True)
    for x in random_vectors(p, S=3, seed=2):
        np.testing.assert_allclose(p.jacobian_full(x), p.jacobian_full_numpy(x), rtol=0, atol=1e-13)


@pytest.mark.parametrize("name", ["seed15", "linear9+cubic+temperature_scale"])
def test_views_evaluate_through_the_kernel_as_the_oracle_does(name):
    """Restricted and normalised views: cost, cost_batch, residuals and the Jacobian agree with the oracle
    evaluated on the same full vectors, and every call is counted."""
    p = make_problem(name)
    at = random_vectors(p, S=1, seed=3)[0]
    view = p.restrict(["bias", "nonlinear"], at=at).normalised()
    Z = np.random.default_rng(4).uniform(-1, 1, (50, view.n))
    full = view.to_full(Z)
    want = np.sum(p.residuals_full_numpy(full) ** 2, axis=1)
    view.start(None)
    np.testing.assert_allclose(view.cost_batch(Z), want, rtol=1e-12)
    np.testing.assert_allclose([view.cost(z) for z in Z], want, rtol=1e-12)
    R = view.residuals_batch(Z)
    assert_rows_close(R, p.residuals_full_numpy(full), 1e-12)
    J = view.jacobian(Z[0])
    np.testing.assert_allclose(J, p.jacobian_full_numpy(full[0])[:, view.free] * p.halfwidth[view.free],
                               rtol=0, atol=1e-11 * np.max(np.abs(J)))
    assert view.nfev == 50 + 50 + 50 + 1 and view.counter.njev == 1
    i = int(np.argmin(want))
    assert view.counter.best_f == pytest.approx(want[i], rel=1e-12)
    np.testing.assert_array_equal(view.counter.best_x, full[i])


def test_single_candidate_path_keeps_budget_best_point_and_trace():
    p = make_problem("nonlinear12")
    z = p.normalised()
    z.start(5)
    pts = np.random.default_rng(7).uniform(-0.1, 0.1, (6, z.n))
    costs = [z.cost(x) for x in pts[:5]]
    from optcal.core.errors import BudgetExhausted

    with pytest.raises(BudgetExhausted):
        z.cost(pts[5])
    assert z.nfev == 5
    best = int(np.argmin(costs))
    assert z.counter.best_f == costs[best]
    np.testing.assert_array_equal(z.counter.best_x, z.to_full(pts[best])[0])
    assert [t[1] for t in z.counter.trace] == sorted({c for k, c in enumerate(costs)
                                                     if c == min(costs[:k + 1])}, reverse=True)


def test_non_finite_candidates_cost_nan_and_never_become_best():
    p = make_problem("seed15")
    x = p.centre.copy()
    bad = x.copy()
    bad[0] = 0.0  # a zero scale factor: no inverse
    p.start(None)
    f = p.cost_batch(np.stack([bad, x]))
    assert np.isnan(f[0]) and np.isfinite(f[1])
    assert np.isnan(p.cost(bad)) and p.counter.best_f == f[1]


def test_a_cold_cache_is_announced_and_a_warm_one_is_not(tmp_path, monkeypatch, caplog):
    """The first evaluation after an install compiles the kernel (tens of seconds): it says so."""
    import logging

    from optcal.core import warmup
    from optcal.core.kernels import cache

    warmup.warm()
    assert cache.is_cold() is False
    with caplog.at_level(logging.WARNING, logger="optcal"):
        cache.load()
    assert caplog.text == ""
    # a tree with no cache beside it, and no cache anywhere else
    monkeypatch.setattr(cache, "__file__", str(tmp_path / "cache.py"))
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(cache.Path, "home", lambda: tmp_path)
    assert cache.is_cold() is True
    with caplog.at_level(logging.WARNING, logger="optcal"):
        cache.load()
    assert "compiling the evaluation kernels" in caplog.text
    # the CLI's handler prefixes "optcal: warning: "; the message does not name optcal again
    assert caplog.records[-1].getMessage().startswith("compiling the evaluation kernels")


@pytest.mark.parametrize("name", ["scipy-lm", "bsas", "staged:bas", "nlopt-bobyqa"])
def test_the_trace_keeps_the_best_point_of_every_improvement(name):
    """Anytime analyses need the point behind each entry of the convergence trace, not only its cost."""
    from optcal import solvers

    p = make_problem("nonlinear12")
    res = solvers.get(name).solve(p, budget=3000, rng=3)
    assert len(res.trace_x) == len(res.trace) > 1
    costs = np.sum(p.residuals_full(np.array(res.trace_x)) ** 2, axis=1)
    np.testing.assert_allclose(costs, [t[1] for t in res.trace], rtol=1e-12)
    assert np.all(np.diff([t[0] for t in res.trace]) > 0) and np.all(np.diff(costs) < 0)
    np.testing.assert_array_equal(res.trace_x[-1], res.x_full)
