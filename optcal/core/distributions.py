"""Tail probabilities and quantiles of the χ², F, Student t and normal laws, in plain Python.

Why not scipy: ``scipy.special`` (cephes' chdtrc, fdtrc, stdtrit) costs 0.15 s to import on the project's
machine and ``scipy.stats`` 0.4–0.7 s, against a budget of 0.5 s for a whole ``optcal calibrate --raw``
process (issue #20, docs/performance.md); a fit needs a handful of these numbers. The functions below
evaluate the regularised incomplete gamma and beta functions by their power series and continued fractions
(Abramowitz & Stegun 6.5.29 and 6.5.31, 26.5.8; continued fractions by the modified Lentz method, Thompson &
Barnett 1986), and the quantiles by safeguarded Newton steps on the logarithm of the tail.
tests/test_distributions.py checks each function against scipy.stats over a grid of arguments (relative
error ≤ 1e-10 for the tails, 1e-10 for the quantiles). The normal quantile is the standard library's
(``statistics.NormalDist.inv_cdf``, Wichura's AS 241), taken from the C function behind it where CPython has
one (:func:`_inv_cdf`).

Every function takes scalars or arrays (broadcast; NumPy's rules) and returns a float or a float array.
"""

from __future__ import annotations

import math

import numpy as np

try:  # CPython's accelerator of the statistics module: the function NormalDist.inv_cdf calls
    from _statistics import _normal_dist_inv_cdf
except ImportError:  # pragma: no cover - another Python
    _normal_dist_inv_cdf = None

_EPS = 1e-16
_TINY = 1e-300
_MAX_TERMS = 100_000


def _inv_cdf(p: float) -> float:
    """The standard normal quantile, ``statistics.NormalDist().inv_cdf(p)`` for 0 < p < 1 (Wichura's AS 241). The
    statistics module itself is imported only where its C function is missing: it imports random, fractions
    and decimal, which every command would pay for one quantile."""
    if _normal_dist_inv_cdf is not None:
        return _normal_dist_inv_cdf(p, 0.0, 1.0)
    from statistics import NormalDist

    return NormalDist().inv_cdf(p)


def _lentz(coef, first: float) -> float:
    """Value of first + a1/(b1 + a2/(b2 + ...)) with ``coef(m) -> (a_m, b_m)`` (modified Lentz)."""
    f = first if first != 0.0 else _TINY
    c, d = f, 0.0
    for m in range(1, _MAX_TERMS):
        a, b = coef(m)
        d = b + a * d
        d = _TINY if d == 0.0 else d
        c = b + a / c
        c = _TINY if c == 0.0 else c
        d = 1.0 / d
        delta = c * d
        f *= delta
        if abs(delta - 1.0) < _EPS:
            return f
    raise ArithmeticError("continued fraction did not converge")


def _gamma_tails(a: float, x: float) -> tuple[float, float]:
    """(P, Q): the regularised lower and upper incomplete gamma functions P(a, x) and Q(a, x) = 1 − P."""
    if x <= 0.0:
        return 0.0, 1.0
    if math.isinf(x):
        return 1.0, 0.0
    log_front = a * math.log(x) - x - math.lgamma(a)
    if x < a + 1.0:  # power series for P (A&S 6.5.29)
        term = total = 1.0 / a
        ap = a
        for _ in range(_MAX_TERMS):
            ap += 1.0
            term *= x / ap
            total += term
            if abs(term) < abs(total) * _EPS:
                break
        p = total * math.exp(log_front)
        return p, 1.0 - p
    # continued fraction for Q (A&S 6.5.31), even form: 1/(x+1−a− 1(1−a)/(x+3−a− 2(2−a)/(x+5−a− ...)))
    b0 = x + 1.0 - a
    q = math.exp(log_front) / _lentz(lambda m: (-m * (m - a), b0 + 2.0 * m), b0)
    return 1.0 - q, q


def _log_beta(a: float, b: float) -> float:
    return math.lgamma(a) + math.lgamma(b) - math.lgamma(a + b)


def _beta_cf(a: float, b: float, x: float) -> float:
    """The continued fraction of I_x(a, b) (A&S 26.5.8): I = x^a (1−x)^b / (a B(a, b)) · 1/(1+ d1/(1+ d2/...))."""
    def coef(k):
        m = k // 2
        if k % 2:  # d_{2m+1}
            return -(a + m) * (a + b + m) * x / ((a + 2 * m) * (a + 2 * m + 1)), 1.0
        return m * (b - m) * x / ((a + 2 * m - 1) * (a + 2 * m)), 1.0

    return 1.0 / _lentz(coef, 1.0)


def _beta_tails(a: float, b: float, x: float, y: float) -> tuple[float, float]:
    """(I_x(a, b), 1 − I_x(a, b)) with y = 1 − x given separately (no loss of digits near x = 1)."""
    if x <= 0.0:
        return 0.0, 1.0
    if y <= 0.0:
        return 1.0, 0.0
    front = math.exp(a * math.log(x) + b * math.log(y) - _log_beta(a, b))
    if x < (a + 1.0) / (a + b + 2.0):
        i = front * _beta_cf(a, b, x) / a
        return i, 1.0 - i
    j = front * _beta_cf(b, a, y) / b  # I_x(a, b) = 1 − I_y(b, a)
    return 1.0 - j, j


def _solve_log(logtail, u0: float, target: float) -> float:
    """u with logtail(u) = target for a decreasing ``logtail(u) -> (value, derivative)`` of u = ln(argument):
    Newton steps kept inside a bracket that bisection shrinks."""
    lo, hi = -math.inf, math.inf
    u = u0
    for _ in range(400):
        v, dv = logtail(u)
        g = v - target
        if g == 0.0:
            return u
        if g > 0.0:
            lo = u
        else:
            hi = u
        step = -g / dv if dv < 0.0 and math.isfinite(dv) else math.nan
        new = u + step
        if not math.isfinite(new) or new <= lo or new >= hi:
            if math.isinf(hi):
                new = u + max(1.0, abs(u))
            elif math.isinf(lo):
                new = u - max(1.0, abs(u))
            else:
                new = 0.5 * (lo + hi)
        if abs(new - u) <= 1e-15 * max(1.0, abs(u)):
            return new
        u = new
    return u


def _chi2_sf(x, df):
    if not (df > 0) or math.isnan(x):
        return math.nan
    return _gamma_tails(0.5 * df, 0.5 * x)[1]


def _chi2_isf(q, df):
    if not (df > 0) or not (0.0 <= q <= 1.0):
        return math.nan
    if q == 0.0:
        return math.inf
    if q == 1.0:
        return 0.0
    a = 0.5 * df
    upper = q <= 0.5
    target = math.log(q if upper else 1.0 - q)

    def logtail(u):  # ln Q (upper) or −ln P (lower: negated so that it decreases in u)
        x = math.exp(u)
        p, qq = _gamma_tails(a, 0.5 * x)
        # x·f(x), f the χ² density: the derivative of the tail with respect to u = ln x
        xf = math.exp(a * math.log(0.5 * x) - 0.5 * x - math.lgamma(a))
        if upper:
            return (math.log(qq) if qq > 0 else -math.inf), (-xf / qq if qq > 0 else -math.inf)
        return (-math.log(p) if p > 0 else math.inf), (-xf / p if p > 0 else -math.inf)

    z = -_inv_cdf(q)
    c = 2.0 / (9.0 * df)
    guess = df * max(1.0 - c + z * math.sqrt(c), 0.1) ** 3  # Wilson & Hilferty (1931)
    return math.exp(_solve_log(logtail, math.log(guess), target if upper else -target))


def _f_sf(x, dfn, dfd):
    if not (dfn > 0 and dfd > 0) or math.isnan(x):
        return math.nan
    if x <= 0.0:
        return 1.0
    if math.isinf(x):
        return 0.0
    s = dfd + dfn * x
    return _beta_tails(0.5 * dfd, 0.5 * dfn, dfd / s, dfn * x / s)[0]  # P(F > x) = I_{dfd/s}(dfd/2, dfn/2)


def _t_sf(t, df):
    """P(T > t) for t > 0 (0.5 I_{ν/(ν+t²)}(ν/2, 1/2)) and the derivative of its log with respect to ln t."""
    s = df + t * t
    sf = 0.5 * _beta_tails(0.5 * df, 0.5, df / s, t * t / s)[0]
    log_pdf = (math.lgamma(0.5 * (df + 1)) - math.lgamma(0.5 * df) - 0.5 * math.log(df * math.pi)
               - 0.5 * (df + 1) * math.log1p(t * t / df))
    return sf, t * math.exp(log_pdf)


def _t_isf(q, df):
    if not (df > 0) or not (0.0 <= q <= 1.0):
        return math.nan
    if q == 0.5:
        return 0.0
    if q > 0.5:
        return -_t_isf(1.0 - q, df)
    if q == 0.0:
        return math.inf

    def logtail(u):
        sf, tf = _t_sf(math.exp(u), df)
        return (math.log(sf), -tf / sf) if sf > 0 else (-math.inf, -math.inf)

    z = -_inv_cdf(q)
    guess = z * (1.0 + (z * z + 1.0) / (4.0 * df))  # Cornish-Fisher's first term
    return math.exp(_solve_log(logtail, math.log(max(guess, 1e-3)), math.log(q)))


def _norm_isf(q):
    if not (0.0 <= q <= 1.0):
        return math.nan
    if q == 0.0:
        return math.inf
    if q == 1.0:
        return -math.inf
    return -_inv_cdf(q)


def _elementwise(f, *args):
    arrays = np.broadcast_arrays(*(np.asarray(a, float) for a in args))
    if arrays[0].ndim == 0:
        return np.float64(f(*(float(a) for a in arrays)))
    flat = [a.ravel() for a in arrays]
    out = np.fromiter((f(*vals) for vals in zip(*(a.tolist() for a in flat))), float, count=flat[0].size)
    return out.reshape(arrays[0].shape)


def chi2_sf(x, df):
    """P(χ²_df > x)."""
    return _elementwise(_chi2_sf, x, df)


def chi2_isf(q, df):
    """x with P(χ²_df > x) = q."""
    return _elementwise(_chi2_isf, q, df)


def f_sf(x, dfn, dfd):
    """P(F(dfn, dfd) > x)."""
    return _elementwise(_f_sf, x, dfn, dfd)


def t_isf(q, df):
    """t with P(T_df > t) = q."""
    return _elementwise(_t_isf, q, df)


def norm_isf(q):
    """z with P(Z > z) = q for a standard normal Z."""
    return _elementwise(_norm_isf, q)
