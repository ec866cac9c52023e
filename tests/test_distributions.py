"""optcal.distributions against scipy.stats, over the arguments optcal's tests of fit use (dof 1 to 10,000,
tail probabilities 1e-12 to 0.5, and the non-integer degrees of freedom of a correlated-noise floor)."""

import numpy as np
import pytest
from scipy import stats

from optcal import distributions as d

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
        np.testing.assert_allclose(d.t_isf(Q, df), stats.t.isf(Q, df), rtol=1e-9)
    np.testing.assert_allclose(d.norm_isf(Q), stats.norm.isf(Q), rtol=1e-12)
    assert d.norm_isf(0.025) == pytest.approx(1.959963984540054, rel=1e-14)
