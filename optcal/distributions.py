"""Tail probabilities and quantiles of the χ², F, Student t and normal laws, from scipy.special.

scipy.stats computes these with the same special functions (cephes' chdtrc, fdtrc, stdtrit, ndtri; Boost's
for some), but importing scipy.stats builds every distribution object of the package and its documentation,
which costs 0.4 to 0.7 s of a command's start on the project's machine, several times the fit of a
calibration; scipy.special is already loaded with scipy.optimize. tests/test_distributions.py checks each
function against scipy.stats over a grid of arguments.
"""

from __future__ import annotations

from scipy import special


def chi2_sf(x, df):
    """P(χ²_df > x)."""
    return special.chdtrc(df, x)


def chi2_isf(q, df):
    """x with P(χ²_df > x) = q."""
    return special.chdtri(df, q)


def f_sf(x, dfn, dfd):
    """P(F(dfn, dfd) > x)."""
    return special.fdtrc(dfn, dfd, x)


def t_isf(q, df):
    """t with P(T_df > t) = q (by symmetry, minus the q-quantile: no loss of digits for small q)."""
    return -special.stdtrit(df, q)


def norm_isf(q):
    """z with P(Z > z) = q for a standard normal Z."""
    return -special.ndtri(q)
