"""optcal.core.distributions (plain Python, no scipy at run time) against scipy.stats, over the arguments optcal's
tests of fit use (dof 1 to 10,000, tail probabilities 1e-12 to 0.999, and the non-integer degrees of freedom of a
correlated-noise floor), and at the edges (0, 1, inf, nan)."""

import numpy as np
import pytest
from scipy import stats

from optcal.core import distributions as d

DF = np.array([1, 2, 3, 3.87, 7.5, 21.3, 100, 336, 1e4])
Q = np.array([1e-12, 1e-8, 1e-4, 1e-3, 0.01, 0.05, 0.2, 0.5])


def test_chi2_tail_and_quantile():
    x = np.linspace(0.01, 300, 97)
    for df in DF:
        np.testing.assert_allclose(d.chi2_sf(x, df), stats.chi2.sf(x, df), rtol=1e-10, atol=1e-300)
        np.testing.assert_allclose(d.chi2_isf(Q, df), stats.chi2.isf(Q, df), rtol=1e-10)


@pytest.mark.parametrize("dfd", [1.0, 4.0, 27.0, 336.0, 1e5])
def test_f_tail(dfd):
    x = np.linspace(0.01, 40, 81)
    for dfn in DF[:7]:
        np.testing.assert_allclose(d.f_sf(x, dfn, dfd), stats.f.sf(x, dfn, dfd), rtol=1e-9, atol=1e-300)


def test_t_and_normal_quantiles():
    for df in DF:
        np.testing.assert_allclose(d.t_isf(Q, df), stats.t.isf(Q, df), rtol=1e-9, atol=1e-15)  # the median: 0 or ±1e-16
    np.testing.assert_allclose(d.norm_isf(Q), stats.norm.isf(Q), rtol=1e-12)
    assert d.norm_isf(0.025) == pytest.approx(1.959963984540054, rel=1e-14)


QHIGH = np.array([0.5, 0.6, 0.9, 0.95, 0.99, 0.999, 1 - 1e-6])


def test_lower_tail_quantiles():
    """chi2_isf(1 − α) (a fit's acceptance bound) and t_isf above 0.5 go through the lower tail."""
    for df in DF:
        np.testing.assert_allclose(d.chi2_isf(QHIGH, df), stats.chi2.isf(QHIGH, df), rtol=1e-10)
        np.testing.assert_allclose(d.t_isf(QHIGH, df), stats.t.isf(QHIGH, df), rtol=1e-9, atol=1e-15)


def test_far_tails_and_large_arguments():
    np.testing.assert_allclose(d.chi2_sf([600.0, 2000.0], 3), stats.chi2.sf([600.0, 2000.0], 3), rtol=1e-10)
    np.testing.assert_allclose(d.chi2_sf([9e4, 1.1e5], 1e5), stats.chi2.sf([9e4, 1.1e5], 1e5), rtol=1e-8)
    np.testing.assert_allclose(d.f_sf([100.0, 1e4], 3, 50), stats.f.sf([100.0, 1e4], 3, 50), rtol=1e-9)
    assert d.t_isf(1e-12, 1) == pytest.approx(1 / np.tan(np.pi * 1e-12), rel=1e-10)  # Cauchy: closed form


def test_edges_and_shapes():
    assert d.chi2_sf(0.0, 4) == 1.0 and d.chi2_sf(np.inf, 4) == 0.0 and np.isnan(d.chi2_sf(np.nan, 4))
    assert d.f_sf(-1.0, 2, 3) == 1.0 and d.f_sf(np.inf, 2, 3) == 0.0 and np.isnan(d.f_sf(1.0, 0, 3))
    assert d.chi2_isf(0.0, 3) == np.inf and d.chi2_isf(1.0, 3) == 0.0 and np.isnan(d.chi2_isf(1.5, 3))
    assert d.t_isf(0.5, 7) == 0.0 and d.t_isf(0.0, 7) == np.inf and d.norm_isf(1.0) == -np.inf
    out = d.f_sf(np.array([[1.0, np.nan], [2.0, 3.0]]), 2, np.array([5.0, 6.0]))
    assert out.shape == (2, 2) and np.isnan(out[0, 1])
    np.testing.assert_allclose(out[1], stats.f.sf([2.0, 3.0], 2, [5.0, 6.0]), rtol=1e-10)
    assert isinstance(d.chi2_sf(3.0, 2), np.floating)


def test_no_scipy_at_run_time():
    """The point of the module: importing it and evaluating every function loads no scipy."""
    import subprocess
    import sys

    code = ("import sys; from optcal.core import distributions as d; "
            "d.chi2_sf(3, 2); d.chi2_isf(0.05, 3); d.f_sf(2, 3, 4); d.t_isf(0.01, 5); d.norm_isf(0.01); "
            "print(sorted(m for m in sys.modules if m.split('.')[0] == 'scipy'))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"
