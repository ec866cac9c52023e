"""The convex ellipsoid fit (cvxpy) of the position means, turned into ``linear9`` parameters: the mathematics
of the ``ellipsoid`` solver (:mod:`optcal.solvers.ellipsoid`) and the default start of the local methods
(:meth:`optcal.solvers.base.Solver.start_point`), kept apart from the Solver class so that the contract in
``optcal/solvers/base.py`` can use it without importing a solver module (which imports the contract).

With the norm cost the position means lie on the ellipsoid (N − o)ᵀ Q (N − o) = g² (2020 paper Eq. 12 with
the linear part of Eq. 10: Q = MᵀM, M = (diag(K)·T)⁻¹, o = diag(K)·b; docs/design.md, "The installation matrix T"). In
homogeneous
coordinates h = (N, 1) every point satisfies hᵀ 𝐌 h = 0 with the 4×4 symmetric 𝐌 = [[Q, q], [qᵀ, c]], which
is linear in the ten entries v of 𝐌: D·v = 0 for the n×10 design matrix D. The fit is

    minimise ‖D·v‖²  subject to  trace(Q) = 1,  Q ⪰ 0

a convex problem (a least-squares objective, a linear normalisation that excludes v = 0 and does not
depend on the frame or the centre, and a semidefinite cone), solved by cvxpy with CLARABEL (or SCS).
For models without misalignment (``diag6``) Q is diagonal. The points are centred and scaled first so
the fit does not depend on the output units.

Interior-point solvers stop at a duality gap of ~1e-9; when the solution is strictly inside the cone
(Q ≻ 0, the case of every genuine ellipsoid) the semidefinite constraint is inactive and the optimum is
that of the equality-constrained least-squares problem, whose KKT system is then solved directly
(``polish``) to recover noise-free data to rounding precision. A solution on the cone's boundary (Q
singular), or one whose quadric has no real points, means the data are not an ellipsoid: refused.

The ellipsoid gives the centre o and Q = MᵀM; :func:`optcal.core.linfit.ellipsoid_to_params` factors Q in the
gauge of docs/design.md, "The gauge of `misalignment`" (lower-triangular T: S_xz = S_xy = S_yx = 0). Terms beyond
``linear9`` (nonlinear,
temperature, drift) are set to zero: for those models the fit is a one-shot initialiser, not an
optimiser. It is the default starting point of the local methods (:func:`ellipsoid_start`).
"""

from __future__ import annotations

import functools
from collections import OrderedDict

import numpy as np

from optcal.core.errors import InputError
from optcal.core.linfit import ellipsoid_to_params


def _cvxpy():
    """cvxpy, imported at the first convex fit: it takes most of a second to import, and the registry
    imports this module whenever any solver is looked up (the solver is listed as unavailable without it)."""
    import cvxpy

    return cvxpy


LINEAR = ("scale", "bias", "misalignment", "misalignment6")
_ANGLES = {"S_xz": (0, 1), "S_xy": (0, 2), "S_yz": (1, 0), "S_yx": (1, 2), "S_zy": (2, 0), "S_zx": (2, 1)}
_START_CACHE: OrderedDict = OrderedDict()


def _design(P: np.ndarray) -> np.ndarray:
    """Rows (x², y², z², 2xy, 2xz, 2yz, 2x, 2y, 2z, 1): D·v = hᵀ𝐌h for v = (Q11, Q22, Q33, Q12, Q13, Q23,
    q1, q2, q3, c)."""
    x, y, z = P.T
    one = np.ones(len(P))
    return np.stack([x * x, y * y, z * z, 2 * x * y, 2 * x * z, 2 * y * z, 2 * x, 2 * y, 2 * z, one], 1)


def _solver_name(choice: str) -> str:
    installed = _cvxpy().installed_solvers()
    if choice != "auto":
        if choice not in installed:
            raise InputError(f"solver ellipsoid: cvxpy has no {choice} installed; installed: {', '.join(installed)}")
        return choice
    for name in ("CLARABEL", "SCS"):
        if name in installed:
            return name
    raise InputError("solver ellipsoid needs CLARABEL or SCS for cvxpy; install one (pip install clarabel)")


def _prepare(N, misalignment: bool):
    """Centred, scaled points, the design matrix (columns kept for the model) and the checks that the
    quadric through the points is unique."""
    N = np.asarray(N, float)
    if N.ndim != 2 or N.shape[1] != 3 or not np.all(np.isfinite(N)):
        raise InputError("the ellipsoid fit needs finite position means with three columns")
    mu = N.mean(axis=0)
    s = float(np.sqrt(np.mean(np.sum((N - mu) ** 2, axis=1))))
    P = (N - mu) / (s if s > 0 else 1.0)
    keep = np.arange(10) if misalignment else np.array([0, 1, 2, 6, 7, 8, 9])
    D = _design(P)[:, keep]
    sv = np.linalg.svd(D, compute_uv=False)
    if len(N) < len(keep) - 1 or sv[-2] <= 1e-9 * sv[0]:
        raise InputError(f"{len(N)} positions do not determine an ellipsoid (the quadric through them is not "
                         "unique); use more, and more varied, orientations (e.g. the 24-position scheme)")
    return mu, s, P, D, keep


def _kkt(D: np.ndarray) -> np.ndarray:
    """min ‖D·v‖² subject to trace(Q) = 1 alone, from its KKT system (the fit when Q ⪰ 0 is inactive)."""
    m = D.shape[1]
    a = np.zeros(m)
    a[:3] = 1.0
    K = np.block([[D.T @ D, a[:, None]], [a[None, :], np.zeros((1, 1))]])
    return np.linalg.solve(K, np.concatenate([np.zeros(m), [1.0]]))[:-1]


def _to_params(v, keep, mu, s, g_local) -> dict:
    """K, b, T, centre and Q (radius g_local) from the quadric v in the scaled frame; refuses a
    degenerate quadric (Q singular: the optimum on the cone's boundary) or one without real points."""
    full = np.zeros(10)
    full[keep] = v
    Qp = np.array([[full[0], full[3], full[4]], [full[3], full[1], full[5]], [full[4], full[5], full[2]]])
    eig = np.linalg.eigvalsh(Qp)
    if eig[0] <= 1e-6 * eig[-1]:
        raise InputError("the position means do not lie on an ellipsoid (the best quadric with a positive-"
                         "semidefinite Q is degenerate): wrong units, or the sensor moved during the positions?")
    op = -np.linalg.solve(Qp, full[6:9])
    rho = float(op @ Qp @ op - full[9])
    if rho <= 0:
        raise InputError("the position means do not lie on an ellipsoid (the fitted quadric has no real "
                         "points); check the data")
    o = mu + s * op
    Qn = Qp * g_local**2 / (rho * s**2)
    K, b, T = ellipsoid_to_params(Qn, o)
    return {"K": K, "b": b, "T": T, "o": o, "Q": Qn, "rho": rho}


def check_ellipsoid(N, g_local: float = 1.0, *, misalignment: bool = True) -> None:
    """Refuse (InputError) data that cannot be an ellipsoid, without the conic solver: the trace-only
    least-squares quadric decides it exactly, since when its Q is not positive definite the convex
    problem's optimum lies on the cone's boundary (a singular Q), which :func:`fit_ellipsoid` refuses."""
    mu, s, _, D, keep = _prepare(N, misalignment)
    _to_params(_kkt(D), keep, mu, s, g_local)


@functools.lru_cache(maxsize=16)
def _conic(n: int, misalignment: bool):
    """The convex problem for n points, built once and solved again with new data: its design matrix is
    a cvxpy Parameter (the problem is DPP), so cvxpy compiles it on the first solve only.

    The objective ‖D·v‖²/n is the algebraic residual hᵀ𝐌h of every point (divided by n so that it is
    O(1) whatever the number of positions), with v = (Q11, Q22, Q33, Q12, Q13, Q23, q, c), or
    (Q11, Q22, Q33, q, c) for a diagonal Q."""
    cp = _cvxpy()
    if misalignment:
        Q = cp.Variable((3, 3), symmetric=True)
        cons = [Q >> 0]
        quad = [Q[0, 0], Q[1, 1], Q[2, 2], Q[0, 1], Q[0, 2], Q[1, 2]]
    else:
        d = cp.Variable(3)
        Q = cp.diag(d)
        cons = [d >= 0]
        quad = [d[0], d[1], d[2]]
    q, c = cp.Variable(3), cp.Variable()
    cons.append(cp.trace(Q) == 1)
    v = cp.hstack(quad + [q[0], q[1], q[2], c])
    Dp = cp.Parameter((n, len(quad) + 4))
    prob = cp.Problem(cp.Minimize(cp.sum_squares(Dp @ v) / n), cons)
    return prob, Dp, Q, q, c


def fit_ellipsoid(N: np.ndarray, g_local: float = 1.0, *, misalignment: bool = True, solver: str = "auto",
                  polish: bool = True) -> dict:
    """The convex fit: returns K, b, T (gauge of docs/design.md, "The gauge of `misalignment`"), the centre o, Q
    (radius g_local) and
    solver details. Raises InputError for data that cannot be an ellipsoid."""
    mu, s, P, D, keep = _prepare(N, misalignment)
    name = _solver_name(solver)
    prob, Dp, Q, q, c = _conic(len(P), misalignment)
    Dp.value = D
    kwargs = {"tol_gap_abs": 1e-12, "tol_gap_rel": 1e-12, "tol_feas": 1e-12} if name == "CLARABEL" else \
        {"eps": 1e-10, "max_iters": 100000}
    try:
        prob.solve(solver=name, **kwargs)
    except _cvxpy().error.SolverError as exc:
        raise InputError(f"the convex ellipsoid fit failed in {name} ({exc}); check the data") from None
    if prob.status not in ("optimal", "optimal_inaccurate") or Q.value is None:
        raise InputError(f"the convex ellipsoid fit found no solution ({name}: {prob.status}); check the data")
    Qv = np.array(Q.value, float)
    v = np.concatenate([Qv[[0, 1, 2], [0, 1, 2]], Qv[[0, 0, 1], [1, 2, 2]], q.value, [c.value]])[keep]
    eig = np.linalg.eigvalsh(Qv)
    polished = bool(polish and eig[0] > 1e-6 * eig[-1])
    if polished:  # the cone constraint is inactive: the optimum solves the equality-constrained KKT system
        v = _kkt(D)
    out = _to_params(v, keep, mu, s, g_local)
    out.update(solver=name, status=prob.status, polished=polished,
               algebraic_rms=float(np.sqrt(np.mean((D @ v) ** 2)) / out["rho"]))  # relative to the radius²
    return out


def fit_to_vector(model, fit: dict) -> np.ndarray:
    """Full parameter vector of ``model`` from a fit: scale, bias, gauge angles; every other term zero."""
    values = {f"K_{a}": fit["K"][i] for i, a in enumerate("xyz")}
    values.update({f"b_{a}": fit["b"][i] for i, a in enumerate("xyz")})
    values.update({n: fit["T"][ij] for n, ij in _ANGLES.items()})
    x = np.zeros(model.n_params)
    for k, n in enumerate(model.names):
        x[k] = values.get(n, 0.0)
    return x


def fit_problem(problem, solver: str = "auto", polish: bool = True) -> dict:
    """The convex fit of a problem's position means (norm cost only: turntable data are refused)."""
    if problem.reference:
        raise InputError("the ellipsoid fit uses the norm of the specific force; with a turntable reference "
                         "use a least-squares solver (e.g. --solver scipy-lm)")
    misalignment = "misalignment" in problem.model.groups()
    return fit_ellipsoid(problem.data.N, problem.g_local, misalignment=misalignment, solver=solver, polish=polish)


def ellipsoid_start(problem) -> np.ndarray:
    """Starting point (in ``problem``'s coordinates) for the local methods when neither x0 nor presets are
    given: the convex fit's ``linear9`` part, other terms zero. A restricted view keeps its own start (the
    values it holds), turntable data and data the fit refuses keep the problem's closed-form start.

    The conic solver is not needed for it: the convex fit either polishes to the trace-only KKT solution
    (the cone Q ⪰ 0 inactive) or refuses (an optimum on the cone's boundary has a singular Q), so the KKT
    solution, when :func:`_to_params` accepts it, is :func:`fit_ellipsoid`'s result to the bit, without
    importing cvxpy (most of a second) in every process that runs a local method."""
    if problem.reference or problem.n < problem.model.n_params:
        return problem.x0
    key = (problem.model.terms, problem.g_local, problem.data.N.tobytes())
    if key not in _START_CACHE:
        try:
            misalignment = "misalignment" in problem.model.groups()
            mu, s, _, D, keep = _prepare(problem.data.N, misalignment)
            _START_CACHE[key] = fit_to_vector(problem.model, _to_params(_kkt(D), keep, mu, s, problem.g_local))
        except InputError:
            _START_CACHE[key] = None
        while len(_START_CACHE) > 32:
            _START_CACHE.popitem(last=False)
    x = _START_CACHE[key]
    return problem.x0 if x is None else problem.from_full(x)
