"""The calibration problem: cost, exact Jacobian, views, budgets, observability and schemes."""

import numpy as np
import pytest

from optcal import Budget, BudgetExhausted, CalibrationProblem, get_model, simulate
from optcal.core.analysis import crlb, observability
from optcal.core.errors import InputError
from optcal.core.presets import PAPER_TRUTH, manufacturer_presets
from optcal.core.schemes import scheme, tilt


def _sim(model="nonlinear12", scheme_="24", seed=0, **kw):
    m = get_model(model)
    truth = {k: v for k, v in PAPER_TRUTH.items() if k in m.names}
    return m, simulate(m, truth, np.random.default_rng(seed), scheme=scheme_, **kw)


def test_schemes_follow_design_section_4():
    s24, s36 = scheme("24"), scheme("36")
    assert s24.shape == (24, 3) and s36.shape == (36, 3)
    np.testing.assert_allclose(np.linalg.norm(s36, axis=1), 1.0)
    # group x starts with y horizontal and z up, then turns 45° about x
    np.testing.assert_allclose(s24[0], [0, 0, 1], atol=1e-15)
    np.testing.assert_allclose(s24[1], [0, np.sqrt(0.5), np.sqrt(0.5)], atol=1e-15)
    np.testing.assert_allclose(s24[8], [1, 0, 0], atol=1e-15)  # group y: (cos θ, 0, sin θ)
    np.testing.assert_allclose(s24[16], [0, 1, 0], atol=1e-15)  # group z: (sin θ, cos θ, 0)
    assert scheme("6").shape == (6, 3)
    assert scheme("random:30", np.random.default_rng(0)).shape == (30, 3)
    tilted = tilt(s24, 1.0, np.random.default_rng(0))
    ang = np.degrees(np.arccos(np.clip(np.sum(tilted * s24, 1), -1, 1)))
    assert 0.3 < np.median(ang) < 3.0 and np.allclose(np.linalg.norm(tilted, axis=1), 1)
    with pytest.raises(InputError, match="unknown scheme"):
        scheme("25")


def test_simulation_is_reproducible_from_the_seed():
    _, a = _sim(seed=7, noise_g=1e-5)
    _, b = _sim(seed=7, noise_g=1e-5)
    _, c = _sim(seed=8, noise_g=1e-5)
    np.testing.assert_array_equal(a.data.N, b.data.N)
    assert np.abs(a.data.N - c.data.N).max() > 1e-7


def test_noise_density_gives_the_documented_sd_of_each_mean():
    m, sim = _sim(noise_g=0.0)
    rng = np.random.default_rng(0)
    diffs = []
    for _ in range(200):
        s = simulate(m, sim.truth, rng, scheme="24", noise_density=100e-6, dwell_s=4.0, rate_hz=100.0)
        diffs.append(s.data.N - sim.data.N)
    sd = np.std(np.array(diffs))
    assert sd == pytest.approx(100e-6 / np.sqrt(4.0), rel=0.05)
    assert s.data.n_samples[0] == 400 and s.data.std[0, 0] == pytest.approx(100e-6 * 10, rel=1e-3)


def test_cost_is_zero_at_the_truth_without_noise_and_batched_equals_single():
    m, sim = _sim(model="seed15", noise_g=0.0)
    p = CalibrationProblem(m, sim.data, fix_gauge=False)
    xt = sim.truth_vector(m)
    assert p.cost(xt) < 1e-28
    # with the gauge held at the linear fit (S_xz = S_xy = S_yx = 0), the truth's rotation shows up
    gauged = CalibrationProblem(m, sim.data)
    assert gauged.n_residuals == 27 and gauged.cost(xt) > 1e-10
    assert gauged.rms(xt) < 1e-15
    X = xt + 1e-4 * np.random.default_rng(0).standard_normal((6, 15))
    batch = p.cost_batch(X)
    np.testing.assert_allclose(batch, [p.cost(x) for x in X], rtol=1e-12)


MANY = "scale+bias+misalignment+cubic+scale_asymmetry+cross_coupling"


@pytest.mark.parametrize("model, reference", [("nonlinear12", False), ("seed15", False), (MANY, False),
                                              ("seed15", True)])
def test_exact_jacobian_matches_finite_differences(model, reference):
    m, sim = _sim(model="seed15" if model == "seed15" else "nonlinear12", noise_g=1e-5, reference=reference)
    m = get_model(model)
    p = CalibrationProblem(m, sim.data, reference=reference)
    x = p.centre + 1e-4 * np.random.default_rng(1).standard_normal(m.n_params)
    J = p.jacobian_full(x)
    h = 1e-7
    fd = np.stack([(p.residuals_full(x + h * e)[0] - p.residuals_full(x - h * e)[0]) / (2 * h)
                   for e in np.eye(m.n_params)], 1)
    np.testing.assert_allclose(J, fd, rtol=0, atol=1e-7 * np.abs(J).max())


def test_views_restrict_and_normalise_share_one_counter():
    m, sim = _sim(noise_g=1e-5)
    p = CalibrationProblem(m, sim.data)
    p.start(Budget(max_evals=100))
    sub = p.restrict(["scale", "bias"], at=p.centre)
    assert sub.n == 6 and sub.names == ["K_x", "K_y", "K_z", "b_x", "b_y", "b_z"]
    z = sub.normalised()
    np.testing.assert_allclose(z.lb, -1) and np.testing.assert_allclose(z.ub, 1)
    np.testing.assert_allclose(z.to_full(np.zeros((1, 6)))[0], p.centre)
    one = np.ones((1, 6))
    np.testing.assert_allclose(z.to_full(one)[0][:6], (p.centre + p.halfwidth)[:6])
    z.cost_batch(np.zeros((10, 6)))
    sub.cost(sub.x0)
    assert p.nfev == 11
    # normalised Jacobian is the chain rule of the plain one
    Jz = z.jacobian(np.zeros(6))
    np.testing.assert_allclose(Jz, p.jacobian_full(p.centre)[:, :6] * p.halfwidth[:6], rtol=1e-12)


def test_budget_is_enforced_exactly_and_the_best_point_is_kept():
    m, sim = _sim(noise_g=1e-5)
    p = CalibrationProblem(m, sim.data)
    p.start(Budget(max_evals=25))
    X = p.centre + 1e-5 * np.random.default_rng(0).standard_normal((20, m.n_params))
    f1 = p.cost_batch(X)
    f2 = p.cost_batch(X)  # only 5 of these may be evaluated
    assert np.all(np.isfinite(f1)) and np.isfinite(f2[:5]).all() and np.isinf(f2[5:]).all()
    assert p.nfev == 25
    with pytest.raises(BudgetExhausted, match="evaluation budget"):
        p.cost(X[0])
    x_best, f_best = p.best
    assert f_best == pytest.approx(min(f1.min(), f2[:5].min()))
    assert p.cost_batch.__self__ is p and len(p.counter.trace) >= 1


def test_target_budget_stops_after_reaching_the_target():
    m, sim = _sim(noise_g=0.0)
    p = CalibrationProblem(m, sim.data)
    p.start(Budget(target=1e-20))
    p.cost(sim.truth_vector(m))
    with pytest.raises(BudgetExhausted, match="target"):
        p.cost(p.centre)


def test_seed15_reports_three_unobservable_rotation_directions():
    m, sim = _sim(model="seed15", noise_g=1e-5)
    obs = observability(CalibrationProblem(m, sim.data), sim.truth_vector(m))
    assert (obs.rank, obs.n_parameters) == (12, 15)
    dirs = [{w["name"]: w["weight"] for w in d} for d in obs.unobservable]
    pairs = sorted(tuple(sorted(d)) for d in dirs)
    # rotations of the body frame: (S_xz, S_yz), (S_xy, S_zy), (S_yx, S_zx) with opposite signs
    assert pairs == [("S_xy", "S_zy"), ("S_xz", "S_yz"), ("S_yx", "S_zx")]
    for d in dirs:
        a, b = d.values()
        assert a == pytest.approx(-b) and abs(a) == pytest.approx(np.sqrt(0.5), abs=1e-6)
    for model in ("diag6", "linear9", "nonlinear12"):
        mm = get_model(model)
        assert observability(CalibrationProblem(mm, sim.data)).rank == mm.n_params


def test_too_few_positions_and_missing_columns_are_clear_errors():
    m, sim = _sim(scheme_="6", noise_g=1e-5)
    with pytest.raises(InputError, match="fewer than the 12 parameters"):
        CalibrationProblem(m, sim.data)
    with pytest.raises(InputError, match="needs column"):
        CalibrationProblem(get_model("linear9+temperature_bias"), _sim()[1].data)
    with pytest.raises(InputError, match="ref_x"):
        CalibrationProblem(get_model("linear9"), _sim()[1].data, reference=True)


def test_presets_set_the_search_centre():
    m, sim = _sim(noise_g=1e-5)
    pre = manufacturer_presets(sim.truth, np.random.default_rng(0))
    p = CalibrationProblem(m, sim.data, presets=pre)
    np.testing.assert_allclose(p.centre, m.from_dict(pre.values))
    assert np.all(np.abs(p.centre - sim.truth_vector(m)) < p.halfwidth)


def test_crlb_scales_with_noise_and_positions():
    m, sim24 = _sim(noise_g=0.0)
    _, sim36 = _sim(scheme_="36", noise_g=0.0)
    sd24, mask = crlb(CalibrationProblem(m, sim24.data), sim24.truth_vector(m), 10e-6)
    sd24b, _ = crlb(CalibrationProblem(m, sim24.data), sim24.truth_vector(m), 20e-6)
    sd36, _ = crlb(CalibrationProblem(m, sim36.data), sim36.truth_vector(m), 10e-6)
    assert mask.all()
    np.testing.assert_allclose(sd24b, 2 * sd24, rtol=1e-9)
    assert np.all(sd36 < sd24)


def test_standard_errors_grow_with_the_residual_when_the_model_misses_an_effect():
    """Data whose means carry their own noise (n and s*): a fit that matches it keeps the noise-based
    bounds; a model that misses a cubic term leaves residuals far above that noise, and its standard
    errors are scaled by the Birge ratio sqrt(χ²/dof), with a note saying so."""
    from dataclasses import replace

    from optcal.app.fit import calibrate

    truth = {k: v for k, v in PAPER_TRUTH.items() if k in get_model("linear9").names}
    for effects, misfit in ((None, False), ({"cubic": {"K3_x": 3e-4, "K3_y": -2e-4, "K3_z": 2e-4}}, True)):
        sim = simulate("linear9", truth, np.random.default_rng(8), scheme="36", noise_g=10e-6, effects=effects)
        n = np.full(len(sim.data), 1000)
        data = replace(sim.data, n_samples=n, std=np.full((len(n), 3), 10e-6 * np.sqrt(1000)))
        cal = calibrate(data, "linear9")
        # the noise the fit judged by: the RMS of each position residual's own floor (docs/noise.md)
        plain = crlb(cal.problem, cal.x, cal.fit.noise_g)[0]
        birge = np.sqrt(cal.fit.chi2 / cal.fit.dof)
        if misfit:
            assert birge > 3 and cal.notes and "Birge ratio" in cal.notes[0]
            np.testing.assert_allclose(cal.stderr, birge * plain, rtol=1e-9)
        else:
            assert birge < 1.5 and cal.notes == []
            np.testing.assert_allclose(cal.stderr, plain, rtol=1e-9)
