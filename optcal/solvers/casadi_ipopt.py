"""Gauss-Newton least squares with CasADi and Ipopt (the Levenberg-Marquardt family).

The residuals are those of the 2020 paper's Eq. 12 (e_j = ‖A_j‖ − g_local, A_j the model inverted at the
position mean N_j; docs/design.md, "Norm residuals and cost"), or the turntable misfit (N_j − F(A_j))/K0 with
``problem.reference``, plus the problem's gauge rows when it has unobservable directions (seed15). They are written in
CasADi symbols by calling the model's own term definitions, :meth:`Model.components`, with :class:`CasadiOps`: there is
no second copy of the sensor equations.

* **Inverse.** A(N; p) is the fixed-point iteration of :meth:`Model.inverse`,
  A ← A + (diag(K)·T)⁻¹ (N − F(A)), started from the linear inverse and unrolled for a fixed number of
  sweeps (:func:`sweeps_for`). T is read off the model's own components (F at the unit vectors with K = 1,
  b = 0 and no other term) and inverted in closed form (cofactors). Each sweep shrinks the error by ρ, the
  nonlinear terms' relative size. At the edge of the default search boxes (presets.BOX_HALFWIDTH: K2, K3,
  kappa, c ≤ 2e-4, so ρ ≤ 4e-4 and the linear inverse is off by ≤ 2e-4 g) four sweeps leave
  2e-4·ρ⁴ < 1e-17 g (measured: 4e-19 g); a temperature-scale term (γ ≤ 2e-4 /°C over ±15 °C, ρ ≈ 3e-3)
  needs six (measured 9e-19 g); linear models need none, as in ``Model.inverse``.
* **Gauss-Newton Hessian.** The NLP is min_z ½·w·‖r(c + h·z)‖² over normalised variables z (x = c + h·z,
  c and h the problem's centre and half-widths, so that parameters near 1 and near 1e-5 take steps of
  similar size, 2020 paper §3.4), with Ipopt's ``hess_lag`` = λ_f·w·JᵀJ instead of the exact Hessian of
  the Lagrangian: Gauss-Newton steps inside Ipopt's line search, whose inertia correction adds δ·I when
  JᵀJ is singular (Levenberg-Marquardt damping). The "lifted" form (r as variables, r − R(x) = 0 as
  constraints, ½‖r‖² as objective) would still bring second derivatives of R into Ipopt's Hessian unless
  they were dropped by hand as well; the custom Hessian is the smaller problem. w = 1/f(x0) makes the
  objective 1 at the start, so that Ipopt's absolute tolerance means the same for every sensor and noise
  level. No bounds: like ``scipy-lm`` this is a least-squares fit, the box is for the search methods;
  parameters outside a restricted view are fixed by equal bounds, which Ipopt removes.
* **Built once.** The NLP solver is built once per (model, number of positions, reference flag, data
  columns present, gauge rows) and kept in a module-level cache; the data (N, ref, K0, temperature and
  time offsets, g_local, centre, half-widths, gauge) are NLP parameters. :meth:`CasadiIpopt.warm_up`
  builds it outside the timed solve.
* **Honest counting.** Ipopt calls compiled CasADi functions, not the problem, so each call passes through a
  Python gate (``_Gate``, made by :func:`_gate_class`) that charges the problem's counter: an objective
  evaluation is one evaluation, a gradient is one (a residual-and-Jacobian evaluation, as ``problem.jacobian``
  counts one); the same call forms JᵀJ, so the Gauss-Newton Hessian Ipopt asks for next, at the same point,
  costs nothing more. (This is the count Ipopt reports in its statistics, taken as the calls happen rather
  than after the run, so that the budget can stop Ipopt exactly.) Past the budget a gate refuses the call: an
  objective refusal returns a value Ipopt accepts, so that it asks for the gradient there, which is refused
  with NaN, and Ipopt stops at once; the refused points are never reported. One evaluation is kept back: the
  lowest point Ipopt evaluated (its final iterate) is evaluated through the problem, so the best point is
  tracked and the reported cost is the problem's own.
* **Stopping.** Ipopt stops on its gradient test (``tol``, on the objective scaled to 1 at the start) or
  a tiny step (``step_tol``). Near the optimum the cost itself cannot confirm a Gauss-Newton step (the
  residuals ‖A‖ − g ≈ 1e-5 g carry ~1e-16 g of rounding, so relative cost changes below ~1e-11 are noise),
  and without constraints Ipopt's backtracking has no lower limit on the step; a line search that finds
  no decrease in :data:`MAX_TRIALS` trials therefore ends the solve, as converged when the step it was
  trying was below :data:`STALL_STEP` half-widths.
"""

from __future__ import annotations

import functools
import threading
import time

import numpy as np

from optcal.core.errors import BudgetExhausted
from optcal.core.model import AXES, Context, Model
from optcal.solvers._lazy import LazyModule
from optcal.solvers.base import Option, Solver, positive
from optcal.solvers.registry import register

# imported at the first solve (the registry lists the solver as unavailable without CasADi)
ca = LazyModule("casadi", globals(), "ca")

_CACHE: dict[tuple, dict] = {}
# Near the optimum the cost cannot resolve a Gauss-Newton step: r_j = ‖A_j‖ − g carries a rounding error
# of ~1e-16 g on a residual of ~1e-5 g, so relative differences of the cost below ~1e-11 are noise, and
# Ipopt's backtracking (alpha_min = 0 without constraints) would halve the step ~1000 times.
MAX_TRIALS = 10  # line-search trials without acceptance before the solve is stopped
STALL_STEP = 1e-6  # a step this small (in half-widths) that the cost cannot confirm is convergence


class CasadiOps:
    """Operations for :meth:`Model.components` on CasADi expressions."""

    @staticmethod
    def neg_part(a):
        return ca.fmin(a, 0)


def sweeps_for(model: Model) -> int:
    """Fixed-point sweeps of the unrolled inverse for ``model`` (derivation in the module docstring)."""
    if all(t in ("scale", "bias", "misalignment", "misalignment6") for t in model.terms):
        return 0
    return 6 if "temperature_scale" in model.terms else 4


def _inverse3(t):
    """Closed-form inverse of a 3×3 nested list (cofactors / determinant)."""
    cof = [[t[(i + 1) % 3][(j + 1) % 3] * t[(i + 2) % 3][(j + 2) % 3]
            - t[(i + 1) % 3][(j + 2) % 3] * t[(i + 2) % 3][(j + 1) % 3] for j in range(3)] for i in range(3)]
    det = t[0][0] * cof[0][0] + t[0][1] * cof[0][1] + t[0][2] * cof[0][2]
    return [[cof[j][i] / det for j in range(3)] for i in range(3)]


def symbolic_residuals(model: Model, P: dict, N, ctx: Context, g, ref=None, K0=None):
    """Position residuals in CasADi symbols, in the order of ``CalibrationProblem.residuals``."""
    n = N.shape[0]
    if ref is not None:
        F = model.components(P, (ref[:, 0], ref[:, 1], ref[:, 2]), ctx, ops=CasadiOps)
        cols = [(N[:, i] - F[i]) / K0[i] for i in range(3)]
        return ca.reshape(ca.horzcat(*cols).T, 3 * n, 1)  # position-major, as NumPy's reshape
    A = _inverse_columns(model, P, N, ctx)
    return ca.sqrt(A[0] ** 2 + A[1] ** 2 + A[2] ** 2) - g


def _inverse_columns(model: Model, P: dict, N, ctx: Context) -> list:
    """A (three columns of n) from N by :meth:`Model.inverse`'s iteration, unrolled."""
    groups = model.groups()
    lin = [model.names[k] for k in groups["scale"] + groups.get("misalignment", [])]
    P_lin = {k: (1.0 if k.startswith("K_") else P[k]) for k in lin}
    T = [[None] * 3 for _ in range(3)]
    for j in range(3):
        col = model.components(P_lin, tuple(1.0 if m == j else 0.0 for m in range(3)), None, ops=CasadiOps)
        for i in range(3):
            T[i][j] = col[i]
    Ti = _inverse3(T)
    K = [P[f"K_{a}"] for a in AXES]
    b = [P.get(f"b_{a}", 0.0) for a in AXES]
    Nc = [N[:, i] for i in range(3)]
    Y = [Nc[i] / K[i] - b[i] for i in range(3)]
    A = [Ti[i][0] * Y[0] + Ti[i][1] * Y[1] + Ti[i][2] * Y[2] for i in range(3)]
    for _ in range(sweeps_for(model)):
        F = model.components(P, tuple(A), ctx, ops=CasadiOps)
        e = [(Nc[i] - F[i]) / K[i] for i in range(3)]
        A = [A[i] + Ti[i][0] * e[0] + Ti[i][1] * e[1] + Ti[i][2] * e[2] for i in range(3)]
    return A


def norm_jacobian(model: Model, n: int, ctx: Context):
    """∂r/∂x of the norm residuals r_j = ‖A_j‖ − g by the implicit function theorem, in terms of symbols
    ``xs`` for the parameters and ``As`` (n, 3) for the inverses; returns (J, xs, As), for the caller to
    substitute the parameters and the unrolled inverse.

    At the inverse A_j of position j, F(A_j; x) = N_j, so ∂A_j/∂x = −(∂F/∂A)⁻¹ ∂F/∂x and
    ∂r_j/∂x = −w_jᵀ ∂F/∂x with (∂F/∂A)ᵀ w_j = A_j/‖A_j‖. Differentiating through the unrolled sweeps
    instead gives the same values (to rounding) from a graph about ten times larger."""
    As, xs = ca.SX.sym("A", n, 3), ca.SX.sym("x", model.n_params)
    P = {name: xs[k] for k, name in enumerate(model.names)}
    F = model.components(P, (As[:, 0], As[:, 1], As[:, 2]), ctx, ops=CasadiOps)
    Fa = [[ca.diag(ca.jacobian(F[i], As[:, k])) for k in range(3)] for i in range(3)]
    Fai = _inverse3(Fa)
    norm = ca.sqrt(As[:, 0] ** 2 + As[:, 1] ** 2 + As[:, 2] ** 2)
    u = [As[:, k] / norm for k in range(3)]
    # w = (∂F/∂A)⁻ᵀ u, position by position (element-wise on the n positions)
    w = [Fai[0][i] * u[0] + Fai[1][i] * u[1] + Fai[2][i] * u[2] for i in range(3)]
    J = -sum(ca.repmat(w[i], 1, model.n_params) * ca.jacobian(F[i], xs) for i in range(3))
    return J, xs, As


@functools.cache
def _gate_class() -> type:
    """The class of :class:`_Gate`, made at the first solve: it derives from ``casadi.Callback``, and casadi
    is imported only when a CasADi solver runs."""
    class _Gate(ca.Callback):
        """A compiled function behind a Python gate: charges the evaluation, refuses it past the allowance,
        the deadline or a stalled line search (module docstring), and scales the outputs by the objective
        weight w (set from the first objective value, at the start). The gradient gate also keeps JᵀJ for
        the Hessian gate, and the lowest point evaluated is remembered for the final evaluation."""

        def __init__(self, kind: str, fun, state: dict, n_out: int, jac=None):
            ca.Callback.__init__(self)
            self.kind, self.fun, self.state, self.n_out, self.jac = kind, fun, state, n_out, jac
            self.construct(f"optcal_{kind}", {})

        def get_n_in(self):
            return self.fun.n_in()

        def get_n_out(self):
            return self.n_out

        def get_sparsity_in(self, i):
            return self.fun.sparsity_in(i)

        def get_sparsity_out(self, i):
            return self.fun.sparsity_out(i)

        def get_name_in(self, i):
            return self.fun.name_in(i)

        def get_name_out(self, i):
            return self.fun.name_out(i)

        def eval(self, arg):
            st = self.state
            if self.kind == "hess":
                z, H = st["H"]
                if z is not None and np.array_equal(z, np.asarray(arg[0]).ravel()):
                    return [float(arg[2]) * st["w"] * H]
            if self.kind == "f":
                st["trials"] += 1
                if st["trials"] == 1 and st["H"][0] is not None:
                    st["step"] = float(np.max(np.abs(np.asarray(arg[0]).ravel() - st["H"][0])))
            elif self.kind == "grad":
                st["trials"] = 0
            if not st["stop"]:
                if st["left"] <= 0:
                    st["stop"] = "evaluation budget used up"
                elif st["deadline"] is not None and time.perf_counter() >= st["deadline"]:
                    st["stop"] = "time budget used up"
                elif st["trials"] > MAX_TRIALS:
                    st["stop"] = "stall"
            if st["stop"]:
                st["refused"] += 1
                if self.kind == "f":
                    # Below any true objective (≥ 0): Ipopt accepts the trial and asks for its gradient,
                    # which is refused with NaN, and stops at once. (NaN here would make it halve the step
                    # down to zero: without constraints its alpha_min is 0, about 1000 trials.)
                    return [ca.DM(-1.0)]
                return [ca.DM.nan(self.fun.sparsity_out(i)) for i in range(self.n_out)]
            st["left"] -= 1
            st["calls"][self.kind] += 1
            out = self.fun.call(arg)
            if self.kind in ("f", "grad"):
                f = float(out[0])
                if np.isfinite(f) and f < st["best"][0]:
                    st["best"] = (f, np.asarray(arg[0]).ravel().copy())
                if st["w"] is None:
                    st["w"] = 1.0 / f if np.isfinite(f) and f > 0 else 1.0
            if self.kind == "grad":
                st["H"] = (np.asarray(arg[0]).ravel().copy(), out[2])
            if self.kind == "hess":
                return [st["w"] * out[0]]
            return [o * st["w"] for o in out[: self.n_out]]

        # CasADi builds a gradient of the objective expression for multipliers; with calc_lam_p off it is
        # never called (and it would go through a gate and be counted if it were).
        def has_jacobian(self):
            return self.jac is not None

        def get_jacobian(self, name, inames, onames, opts):
            return self.jac

    return _Gate


def _structure(problem) -> tuple:
    cols = tuple(c for c in ("temp", "t") if c in problem.model.needs)
    gauge = getattr(problem, "_gauge", None)
    return (problem.model.terms, len(problem.data), problem.reference, cols, 0 if gauge is None else len(gauge))


class _Numeric:
    """A problem's own residuals and Jacobian (NumPy, uncounted: the gates count) behind the methods
    ``_Gate`` uses of a CasADi Function, for problems whose model is not the accelerometer's term
    table and so has no CasADi symbols (the gyroscope's, :mod:`optcal.core.gyro`). ``kind``: f, grad, hess or
    jac, with the outputs of the symbolic functions of :func:`build` (JᵀJ as its upper triangle)."""

    def __init__(self, kind: str, problem):
        self.kind, self.problem, self.p = kind, problem, problem.model.n_params
        p = self.p
        self._in = [ca.Sparsity.dense(p, 1), ca.Sparsity.dense(0, 1)] + {
            "f": [], "grad": [], "hess": [ca.Sparsity.dense(1, 1), ca.Sparsity.dense(0, 1)],
            "jac": [ca.Sparsity.dense(1, 1)]}[kind]
        self._out = {"f": [ca.Sparsity.dense(1, 1)],
                     "grad": [ca.Sparsity.dense(1, 1), ca.Sparsity.dense(p, 1), ca.Sparsity.upper(p)],
                     "hess": [ca.Sparsity.upper(p)],
                     "jac": [ca.Sparsity.dense(1, p), ca.Sparsity.dense(1, 0)]}[kind]

    def n_in(self):
        return len(self._in)

    def sparsity_in(self, i):
        return self._in[i]

    def sparsity_out(self, i):
        return self._out[i]

    def name_in(self, i):
        return ("x", "p", "lam_f", "lam_g")[i] if self.kind != "jac" else ("x", "p", "out_f")[i]

    def name_out(self, i):
        return {"f": ("f",), "grad": ("f", "grad_f_x", "JtJ"), "hess": ("hess_gamma_x_x",),
                "jac": ("jac_f_x", "jac_f_p")}[self.kind][i]

    def call(self, arg):
        pr = self.problem
        z = np.asarray(arg[0], float).ravel()
        x = pr.centre + pr.halfwidth * z
        r = pr.residuals_full(x)[0]
        f = 0.5 * float(r @ r)
        if self.kind == "f":
            return [ca.DM(f)]
        J = pr.jacobian_full(x) * pr.halfwidth
        if self.kind == "jac":
            return [ca.DM(r @ J).T, ca.DM(1, 0)]
        JtJ = ca.triu(ca.DM(J.T @ J))
        if self.kind == "hess":
            return [float(arg[2]) * JtJ]
        return [ca.DM(f), ca.DM(J.T @ r), JtJ]


def _numeric_entry(problem, options: dict) -> dict:
    """The NLP solver of a problem without CasADi symbols, on its NumPy residuals and Jacobian; built for
    each solve (it holds the problem), which costs a few milliseconds."""
    funs = {k: _Numeric(k, problem) for k in ("f", "grad", "hess", "jac")}
    return _assemble(funs, problem.model.n_params, 0, options)


def build(problem, options: dict) -> dict:
    """The NLP solver for ``problem``'s structure and these Ipopt options: built on first use, then cached."""
    if not isinstance(problem.model, Model):
        return _numeric_entry(problem, options)
    key = _structure(problem) + tuple(sorted(options.items()))
    if key in _CACHE:
        return _CACHE[key]
    model, n, ref_mode, cols, n_gauge = problem.model, *_structure(problem)[1:]
    p = model.n_params
    z = ca.SX.sym("z", p)
    N, c, h, g = ca.SX.sym("N", n, 3), ca.SX.sym("c", p), ca.SX.sym("h", p), ca.SX.sym("g")
    dtemp = ca.SX.sym("dtemp", n) if "temp" in cols else None
    dt = ca.SX.sym("dt", n) if "t" in cols else None
    ref = ca.SX.sym("ref", n, 3) if ref_mode else None
    K0 = ca.SX.sym("K0", 3) if ref_mode else None
    G = ca.SX.sym("G", n_gauge, p) if n_gauge else None
    x = c + h * z
    P, ctx = {name: x[k] for k, name in enumerate(model.names)}, Context(dtemp, dt)
    if ref_mode:
        r = symbolic_residuals(model, P, N, ctx, g, ref, K0)
        J = ca.jacobian(r, z)
    else:
        # The inverse is built once and shared by the residuals and their Jacobian (implicit function
        # theorem, evaluated at it), not differentiated through its unrolled sweeps.
        A = _inverse_columns(model, P, N, ctx)
        r = ca.sqrt(A[0] ** 2 + A[1] ** 2 + A[2] ** 2) - g
        Jx, xs, As = norm_jacobian(model, n, ctx)
        Jx = ca.substitute([Jx], [xs, ca.vec(As)], [x, ca.vec(ca.horzcat(*A))])[0]
        J = Jx * ca.repmat(h.T, n, 1)
    if G is not None:  # the problem's minimum-constraint gauge rows, G·(x − centre)
        r = ca.vertcat(r, ca.mtimes(G, h * z))
        J = ca.vertcat(J, G * ca.repmat(h.T, n_gauge, 1))
    par = ca.vertcat(*[ca.vec(s) for s in (N, c, h, g, dtemp, dt, ref, K0, G) if s is not None])
    f = 0.5 * ca.dot(r, r)
    JtJ = ca.triu(ca.mtimes(J.T, J))
    lam_f, lam_g = ca.SX.sym("lam_f"), ca.SX.sym("lam_g", 0)
    funs = {
        "f": ca.Function("gn_f", [z, par], [f], ["x", "p"], ["f"]),
        "grad": ca.Function("gn_grad", [z, par], [f, ca.mtimes(J.T, r), JtJ], ["x", "p"], ["f", "grad_f_x", "JtJ"]),
        "hess": ca.Function("gn_hess", [z, par, lam_f, lam_g], [lam_f * JtJ], ["x", "p", "lam_f", "lam_g"],
                            ["hess_gamma_x_x"]),
        "jac": ca.Function("gn_jac", [z, par, ca.SX.sym("out_f")], [ca.jacobian(f, z), ca.jacobian(f, par)]),
    }
    entry = _assemble(funs, p, par.shape[0], options)
    _CACHE[key] = entry
    return entry


def _assemble(funs: dict, p: int, n_par: int, options: dict) -> dict:
    """Ipopt behind the gates on the functions ``funs`` (f, grad, hess, jac) of p variables and n_par NLP
    parameters."""
    state = {"H": (None, None)}
    gate = _gate_class()
    jac = gate("jac", funs["jac"], state, 2)
    gates = {"f": gate("f", funs["f"], state, 1, jac=jac), "grad": gate("grad", funs["grad"], state, 2),
             "hess": gate("hess", funs["hess"], state, 1), "jac": jac}
    Z, PAR = ca.MX.sym("z", p), ca.MX.sym("p", n_par)
    LF, LG = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", 0)
    grad_f = ca.Function("nlp_grad_f", [Z, PAR], gates["grad"](Z, PAR), ["x", "p"], ["f", "grad_f_x"])
    hess_lag = ca.Function("nlp_hess_l", [Z, PAR, LF, LG], [gates["hess"](Z, PAR, LF, LG)],
                           ["x", "p", "lam_f", "lam_g"], ["hess_gamma_x_x"])
    ipopt = {"print_level": 0, "sb": "yes", "nlp_scaling_method": "none", "tol": options["tol"],
             "tiny_step_tol": options["step_tol"], "max_iter": options["max_iter"],
             "fixed_variable_treatment": "make_parameter", "max_resto_iter": 0}
    solver = ca.nlpsol("optcal_gn", "ipopt", {"x": Z, "p": PAR, "f": gates["f"](Z, PAR)},
                       {"grad_f": grad_f, "hess_lag": hess_lag, "print_time": False, "ipopt": ipopt,
                        "error_on_fail": False, "calc_lam_p": False, "calc_lam_x": False,
                        "show_eval_warnings": False})
    # the gates share one state per cached solver: one solve at a time on it
    return {"solver": solver, "state": state, "gates": gates, "funs": funs, "lock": threading.Lock()}


def parameters(problem) -> np.ndarray:
    """The NLP parameter vector of :func:`build` for ``problem``'s data (CasADi's vec is column-major); none
    for a problem without CasADi symbols, whose functions hold their data."""
    if not isinstance(problem.model, Model):
        return np.zeros(0)
    d = problem.data
    parts = [np.ravel(d.N, order="F"), problem.centre, problem.halfwidth, [problem.g_local]]
    cols = _structure(problem)[3]
    if "temp" in cols:
        parts.append(problem.ctx.dtemp)
    if "t" in cols:
        parts.append(problem.ctx.dt)
    if problem.reference:
        parts += [np.ravel(d.ref, order="F"), problem._K0]
    if getattr(problem, "_gauge", None) is not None:
        parts.append(np.ravel(problem._gauge, order="F"))
    return np.concatenate([np.asarray(v, float).ravel() for v in parts])


_CONVERGED = {"Solve_Succeeded": "converged", "Solved_To_Acceptable_Level": "converged to Ipopt's acceptable level",
              "Search_Direction_Becomes_Too_Small": "converged (step below step_tol)"}


@register
class CasadiIpopt(Solver):
    """Gauss-Newton least squares (JᵀJ Hessian) in Ipopt on the model written in CasADi symbols."""

    name = "casadi-ipopt"
    family = "local"
    requires = ("casadi",)
    default_budget = 2000
    options = {
        "tol": Option(1e-9, float, "Ipopt's tol on the gradient of the objective scaled to 1 at the start",
                      check=positive, check_doc="> 0"),
        "step_tol": Option(2.2e-15, float, "Ipopt's tiny_step_tol: stop when the step is below this, in "
                           "units of the search half-widths", check=positive, check_doc="> 0"),
        "max_iter": Option(100, int, "Ipopt's iteration cap", check=positive, check_doc="> 0"),
    }

    def _ipopt_options(self) -> dict:
        return {k: self.config[k] for k in ("tol", "step_tol", "max_iter")}

    def warm_up(self, problem) -> None:
        """Build (and cache) the NLP solver for ``problem``'s structure; not part of any timed solve."""
        build(problem, self._ipopt_options())

    def _solve(self, problem, x0, rng, callback):
        entry = build(problem, self._ipopt_options())
        counter = problem.counter
        budget = counter.budget
        left = np.inf if budget.max_evals is None else budget.max_evals - counter.nfev - 1
        if left < 1:
            problem.cost(x0)
            return {"nit": 0, "status": 1, "success": True,
                    "message": "evaluation budget used up (too small for Ipopt; returned the start)"}
        with entry["lock"]:
            return self._run(problem, x0, entry, left, callback)

    def _run(self, problem, x0, entry, left, callback):
        counter, budget = problem.counter, problem.counter.budget
        state = entry["state"]
        state.update(left=left, w=None, refused=0, H=(None, None), trials=0, step=np.inf, stop="",
                     best=(np.inf, None), calls={"f": 0, "grad": 0, "hess": 0, "jac": 0},
                     deadline=None if budget.max_time is None else counter.t0 + budget.max_time)
        c, h = problem.centre, problem.halfwidth
        z0 = (problem.to_full(x0)[0] - c) / h
        lbx, ubx = np.full_like(z0, -np.inf), np.full_like(z0, np.inf)
        fixed = np.setdiff1d(np.arange(z0.size), problem.free)
        lbx[fixed] = ubx[fixed] = z0[fixed]
        solver = entry["solver"]
        try:
            res = solver(x0=z0, p=parameters(problem), lbx=lbx, ubx=ubx)
        finally:
            calls = state["calls"]
            counter.nfev += sum(calls.values())
            counter.njev += calls["grad"] + calls["hess"] + calls["jac"]
        st = solver.stats()
        # The lowest point Ipopt evaluated (its last iterate, unless it stopped on a refused trial) is
        # evaluated through the problem: the evaluation kept back, and the best point tracked.
        z = state["best"][1] if state["best"][1] is not None else np.asarray(res["x"], float).ravel()
        x = problem.from_full(c + h * z)
        try:
            problem.cost(x)
        except BudgetExhausted:  # a time budget ran out inside Ipopt: the kept evaluation is still made
            X = problem.to_full(x)
            f = float(np.sum(problem.residuals_full(X) ** 2))
            counter.record(np.array([f if np.isfinite(f) else np.nan]), X)
        nit = int(st["iter_count"])
        callback(nit)
        status = st["return_status"]
        if state["stop"] == "stall":
            ok = state["step"] < STALL_STEP
            return {"nit": nit, "status": 0 if ok else -1, "success": ok,
                    "message": f"{'converged: ' if ok else ''}no decrease of the cost in {MAX_TRIALS} line-search "
                               f"trials on a step of {state['step']:.1e} half-widths"}
        if state["stop"]:
            return {"nit": nit, "status": 1, "success": True, "message": f"{state['stop']} (Ipopt: {status})"}
        if status in _CONVERGED:
            return {"nit": nit, "status": 0, "success": True, "message": f"Ipopt: {_CONVERGED[status]}"}
        return {"nit": nit, "status": -1, "success": False, "message": f"Ipopt: {status}"}
