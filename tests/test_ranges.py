"""optcal.core.ranges: the means and standard deviations of many ranges of rows in one pass equal NumPy's, range
by range (a range of one row has SD 0 with ddof=1)."""

import numpy as np

from optcal.core.ranges import range_means, range_means_sds, range_rows


def test_range_statistics_equal_numpys_range_by_range():
    rng = np.random.default_rng(3)
    x = 32768.0 + 40.0 * rng.standard_normal((2000, 3))  # raw counts: a large offset, a small scatter
    r = np.array([[0, 1], [5, 9], [9, 400], [350, 1200], [1999, 2000]])  # one row, back to back, overlapping
    m, sd = range_means_sds(x, r)
    for k, (a, b) in enumerate(r):
        np.testing.assert_allclose(m[k], x[a:b].mean(axis=0), rtol=1e-14)
        np.testing.assert_allclose(sd[k], x[a:b].std(axis=0, ddof=1) if b - a > 1 else 0.0, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(range_means(x[:, 1], r)[k], x[a:b, 1].mean(), rtol=1e-14)
    rows, which = range_rows(r[1:3])
    assert rows.tolist() == list(range(5, 400)) and which.tolist() == [0] * 4 + [1] * 391
