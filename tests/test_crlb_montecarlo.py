"""Monte-Carlo checks of the SciPy LM fit against the Cramér-Rao bound (issue: core, "What it must show")."""

import numpy as np
import pytest

from optcal import CalibrationProblem, get_model, simulate, solvers
from optcal.core.analysis import crlb
from optcal.core.presets import PAPER_TRUTH, draw_truth

SIGMA = 10e-6


def _monte_carlo(model_name, scheme, runs, seed, reference=False, reference_error_arcsec=0.0):
    m = get_model(model_name)
    ss = np.random.SeedSequence(seed)
    truth = {k: v for k, v in PAPER_TRUTH.items() if k in m.names} if model_name != "linear9" else \
        draw_truth(m, np.random.default_rng(seed))
    errors, problem = [], None
    lm = solvers.get("scipy-lm")
    for child in ss.spawn(runs):
        sim = simulate(m, truth, np.random.default_rng(child), scheme=scheme, noise_g=SIGMA, reference=reference,
                       reference_error_arcsec=reference_error_arcsec)
        problem = CalibrationProblem(m, sim.data, reference=reference)
        res = lm.solve(problem, rng=0)
        assert res.success, res.message
        errors.append(res.x_full - sim.truth_vector(m))
    xt = m.from_dict(truth)
    sd, mask = crlb(CalibrationProblem(m, sim.data, reference=reference), xt, SIGMA)
    rmse = np.sqrt(np.mean(np.square(errors), axis=0))
    return m, rmse, sd, np.array(errors)


@pytest.mark.parametrize("model, scheme", [("nonlinear12", "24"), ("linear9", "36")])
def test_lm_rmse_is_within_0p8_to_1p25_of_the_cramer_rao_bound(model, scheme):
    m, rmse, sd, _ = _monte_carlo(model, scheme, runs=200, seed=2024)
    ratio = rmse / sd
    print(f"\n{model} on {scheme} positions, 200 runs, RMSE/CRLB:",
          " ".join(f"{n}={r:.3f}" for n, r in zip(m.names, ratio)))
    assert np.all(ratio > 0.8) and np.all(ratio < 1.25), dict(zip(m.names, ratio))


def test_reference_calibration_recovers_all_15_seed_parameters():
    """Turntable data without orientation error: every seed15 parameter observable and within 4 CRLB SDs."""
    m, rmse, sd, errors = _monte_carlo("seed15", "24", runs=20, seed=7, reference=True)
    assert np.all(np.isfinite(sd))
    z = np.abs(errors) / sd
    print("\nreference seed15: max |error|/CRLB per parameter:", np.round(z.max(0), 2))
    assert np.all(z < 4.0)
    assert np.all(rmse / sd < 1.5)
