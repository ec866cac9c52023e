"""The term-based model: names, composition, vectorised forward/inverse, and their agreement."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from optcal.core.errors import InputError
from optcal.core.model import NAMED_MODELS, TERMS, Context, get_model
from optcal.core.schemes import random_orientations

ALL_TERMS = ("scale+bias+misalignment6+quadratic+cubic+scale_asymmetry+cross_coupling"
             "+temperature_bias+temperature_scale+bias_drift")


def test_named_models_have_the_design_parameter_names():
    assert get_model("diag6").names == ("K_x", "K_y", "K_z", "b_x", "b_y", "b_z")
    assert get_model("linear9").names[6:] == ("S_yz", "S_zy", "S_zx")
    assert get_model("nonlinear12").names[9:] == ("K2_x", "K2_y", "K2_z")
    assert get_model("seed15").names == (
        "K_x", "K_y", "K_z", "b_x", "b_y", "b_z", "S_xz", "S_xy", "S_yz", "S_yx", "S_zy", "S_zx",
        "K2_x", "K2_y", "K2_z")
    assert set(NAMED_MODELS) == {"diag6", "linear9", "nonlinear12", "seed15"}


def test_sum_of_terms_is_ordered_as_in_design():
    m = get_model("cubic+misalignment+bias+scale")
    assert m.terms == ("scale", "bias", "misalignment", "cubic")
    assert get_model("nonlinear12+cubic").terms == ("scale", "bias", "misalignment", "quadratic", "cubic")
    assert get_model("linear9+temperature_bias").needs == ("temp",)


@pytest.mark.parametrize("spec, fragment", [
    ("linear10", "unknown model or term 'linear10'"),
    ("bias+misalignment", "no 'scale' term"),
    ("scale+misalignment+misalignment6", "either 'misalignment'"),
])
def test_bad_model_names_are_clear_errors(spec, fragment):
    with pytest.raises(InputError, match=fragment):
        get_model(spec)


def test_forward_matches_the_seed_equation():
    """2020 paper Eq. 10: N = diag(K)(T·A + b) + K2 ⊙ A², with T as in docs/design.md, "The installation matrix T"."""
    m = get_model("seed15")
    rng = np.random.default_rng(0)
    x = m.default_vector(1.0) + 1e-3 * rng.standard_normal(15)
    A = random_orientations(7, rng)
    p = m.to_dict(x)
    T = np.array([[1, p["S_xz"], p["S_xy"]], [p["S_yz"], 1, p["S_yx"]], [p["S_zy"], p["S_zx"], 1]])
    K = np.array([p["K_x"], p["K_y"], p["K_z"]])
    b = np.array([p["b_x"], p["b_y"], p["b_z"]])
    K2 = np.array([p["K2_x"], p["K2_y"], p["K2_z"]])
    expected = K * (A @ T.T + b) + K2 * A**2
    np.testing.assert_allclose(m.forward(x, A)[0], expected, rtol=0, atol=1e-15)


def test_forward_and_inverse_are_vectorised_over_a_population():
    m = get_model(ALL_TERMS)
    rng = np.random.default_rng(1)
    S, n = 5, 11
    X = np.tile(m.default_vector(1.0), (S, 1)) + 1e-4 * rng.standard_normal((S, m.n_params))
    A = random_orientations(n, rng)
    ctx = Context.from_columns(temp=np.linspace(15, 35, n), t=np.linspace(0, 600, n))
    N = m.forward(X, A, ctx)
    assert N.shape == (S, n, 3)
    for s in range(S):  # each row equals the single-candidate evaluation
        np.testing.assert_array_equal(N[s], m.forward(X[s], A, ctx)[0])
    A_back = m.inverse(X, N, ctx)
    assert A_back.shape == (S, n, 3)
    np.testing.assert_allclose(A_back, np.broadcast_to(A, (S, n, 3)), rtol=0, atol=1e-13)


def _term_values(draw_value, model):
    # Realistic magnitudes (navigation-grade to consumer-grade): relative to K for K2/K3.
    scale = {"K": 1e-2, "b": 5e-2, "S": 1e-2, "K2": 1e-3, "K3": 1e-3, "kappa": 1e-3, "c": 1e-3,
             "beta": 1e-4, "gamma": 1e-4, "d": 1e-6}
    return np.array([(1.0 if n.startswith("K_") else 0.0) + scale[n.split("_")[0]] * draw_value(n)
                     for n in model.names])


@settings(max_examples=60, deadline=None)
@given(data=st.data(), k=st.floats(0.5, 20000.0), model_name=st.sampled_from(
    ["diag6", "linear9", "nonlinear12", "seed15", ALL_TERMS]))
def test_inverse_agrees_with_forward_to_1e12_relative(data, k, model_name):
    m = get_model(model_name)
    unit = st.floats(-1.0, 1.0, allow_nan=False)
    x = _term_values(lambda n: data.draw(unit, label=n), m)
    x[list(m.groups()["scale"])] *= k  # output units of any size (counts, volts, g)
    for f in ("K2", "K3"):
        for i, n in enumerate(m.names):
            if n.startswith(f + "_"):
                x[i] *= k
    seed = data.draw(st.integers(0, 2**32 - 1), label="seed")
    rng = np.random.default_rng(seed)
    g = data.draw(st.floats(0.1, 2.0), label="g")
    A = g * random_orientations(24, rng)
    ctx = Context.from_columns(temp=rng.uniform(-20, 60, 24), t=np.sort(rng.uniform(0, 3600, 24)))
    N = m.forward(x, A, ctx)
    A_back = m.inverse(x, N, ctx)[0]
    np.testing.assert_allclose(A_back, A, rtol=0, atol=1e-12 * g)
    # and the other way round: forward of the inverse reproduces the outputs
    np.testing.assert_allclose(m.forward(x, A_back, ctx), N, rtol=0, atol=1e-12 * np.abs(N).max())


def test_every_term_changes_the_output():
    m = get_model(ALL_TERMS)
    rng = np.random.default_rng(3)
    A = random_orientations(9, rng)
    ctx = Context.from_columns(temp=np.linspace(10, 30, 9), t=np.linspace(0, 100, 9))
    base = m.default_vector(1.0)
    N0 = m.forward(base, A, ctx)
    for term, sl in m.term_slices().items():
        if term == "scale":
            continue
        x = base.copy()
        x[sl] = 1e-3
        assert np.abs(m.forward(x, A, ctx) - N0).max() > 1e-6, term
    assert set(m.terms) == set(TERMS) - {"misalignment"}


@pytest.mark.parametrize("model_name", ["diag6", "linear9", "seed15", ALL_TERMS])
def test_array_form_equals_the_term_table(model_name):
    """forward/inverse run on (S, n, 3) arrays; `components` (used by CasADi and the complex step) is the
    term-by-term table of docs/design.md, "Terms and parameters". Both must give the same outputs, real and complex."""
    m = get_model(model_name)
    rng = np.random.default_rng(11)
    S, n = 4, 13
    X = np.tile(m.default_vector(1.0), (S, 1)) + 1e-3 * rng.standard_normal((S, m.n_params))
    A = 1.3 * random_orientations(n, rng)
    ctx = Context.from_columns(temp=np.linspace(-5, 40, n), t=np.linspace(0, 900, n))
    for dtype in (float, complex):
        Xd = X.astype(dtype) + (1e-20j * rng.standard_normal(X.shape) if dtype is complex else 0)
        P = {k: Xd[:, i, None] for i, k in enumerate(m.names)}
        table = np.stack(np.broadcast_arrays(*m.components(P, (A[:, 0], A[:, 1], A[:, 2]), ctx)), -1)
        got = m.forward(Xd, A, ctx)
        np.testing.assert_allclose(got.real, table.real, rtol=0, atol=1e-15)
        np.testing.assert_allclose(got.imag, table.imag, rtol=1e-12, atol=0)


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
def test_singular_installation_matrix_spoils_only_its_candidate():
    m = get_model("seed15")
    X = np.tile(m.default_vector(1.0), (3, 1))
    X[1, m.index("S_xz")] = X[1, m.index("S_yz")] = 1.0  # rows 0 and 1 of T equal: singular
    A = random_orientations(5, np.random.default_rng(2))
    N = m.forward(np.tile(m.default_vector(1.0), (3, 1)), A)
    out = m.inverse(X, N)
    assert not np.isfinite(out[1]).all()
    np.testing.assert_allclose(out[[0, 2]], np.broadcast_to(A, (2, 5, 3)), atol=1e-15)
