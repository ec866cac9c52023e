"""The accelerometer sensor model as a sum of named terms (docs/design.md, "The sensor model").

The seeds' model (2020 paper, Eq. 10) is ``N = diag(K)·(T·A + b) + K2 ⊙ A²``. Here it is one instance
of a general sum of terms; each term owns named parameters and says which data columns it needs.

Forward and inverse maps are vectorised over a *population* of parameter vectors: ``X`` of shape
``(S, p)`` and specific forces of shape ``(n, 3)`` give outputs of shape ``(S, n, 3)`` in one call.
The forward map is written once, generically over an "ops" namespace, so that the same term definitions
evaluate NumPy arrays (real or complex, for complex-step derivatives) and CasADi symbols.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from optcal.core.errors import InputError
from optcal.core.terms import (  # noqa: F401 - re-exported
    AXES,
    NAMED_MODELS,
    T_CELLS,
    TERM_ORDER,
    TERMS,
    UNIT_NAMES,
    Term,
    previous_signs,
    user_term_error,
)


class NumpyOps:
    """Array operations for the generic forward map (works for real and complex arrays)."""

    @staticmethod
    def neg_part(a):
        # min(a, 0); written with `where` on the real part so the complex step passes through.
        return np.where(np.real(a) < 0, a, 0.0)

    # sgn of the previous pose's specific force (a user-defined hysteresis term, optcal.core.terms.Feature)
    previous_signs = staticmethod(previous_signs)


@dataclass(frozen=True)
class Context:
    """Per-position inputs besides A: temperature and time offsets (docs/design.md, "Context: temperature and time
    offsets": T0 = mean, t0 = first)."""

    dtemp: np.ndarray | None = None
    dt: np.ndarray | None = None

    @classmethod
    def from_columns(cls, temp=None, t=None) -> Context:
        dtemp = None if temp is None else np.asarray(temp, float) - float(np.mean(temp))
        dt = None if t is None else np.asarray(t, float) - float(np.asarray(t, float)[0])
        return cls(dtemp, dt)


@dataclass(frozen=True)
class Model:
    """A sum of named terms. Build one with :func:`get_model`."""

    terms: tuple[str, ...]
    names: tuple[str, ...] = field(init=False)

    def __post_init__(self):
        object.__setattr__(self, "names", tuple(p for t in self.terms for p in TERMS[t].params))

    # -- description -------------------------------------------------------------------------
    @property
    def name(self) -> str:
        for key, terms in NAMED_MODELS.items():
            if terms == self.terms:
                return key
        return "+".join(self.terms)

    @property
    def n_params(self) -> int:
        return len(self.names)

    @property
    def needs(self) -> tuple[str, ...]:
        return tuple(sorted({c for t in self.terms for c in TERMS[t].needs}))

    @property
    def is_affine(self) -> bool:
        """True when every term is affine in the specific force (the inverse is then closed-form)."""
        return all(TERMS[t].affine for t in self.terms)

    def units(self, output_units: str) -> dict[str, str]:
        """{parameter name: its unit} for data whose outputs are in ``output_units`` (docs/design.md, "Units and
        frames", "Terms and parameters"):
        K in output units per g, b in g, angles in rad, K2 per g², K3 per g³, temperature terms per °C,
        drift per s. The one statement of the parameters' units: printed tables and files take them from here."""
        out = UNIT_NAMES.get(output_units, output_units)
        out = f"({out})" if "/" in out else out
        return {p: TERMS[t].param_unit.format(out=out) for t in self.terms for p in TERMS[t].params}

    @property
    def user_terms(self) -> tuple[str, ...]:
        """The model's user-defined terms (:func:`optcal.core.terms.user_term`), in model order."""
        return tuple(t for t in self.terms if TERMS[t].user)

    @property
    def user_formulas(self) -> dict[str, str]:
        """{user-defined term: its formula} (:func:`optcal.core.terms.term_formula`; a calibration file's
        ``user_terms``)."""
        return {t: TERMS[t].description for t in self.user_terms}

    @cached_property
    def _user(self) -> tuple:
        """(column, output axis, parameter, feature, kind) of each parameter of a user-defined term."""
        out = []
        for t in self.user_terms:
            term = TERMS[t]
            names = iter(term.params)
            for i in term.axes:
                for kind in term.feature.kinds:
                    name = next(names)
                    out.append((self.names.index(name), i, name, term.feature, kind))
        return tuple(out)

    def index(self, name: str) -> int:
        return self.names.index(name)

    def groups(self) -> dict[str, list[int]]:
        """Parameter indices by group (scale, bias, misalignment, nonlinear, temperature, drift)."""
        out: dict[str, list[int]] = {}
        k = 0
        for t in self.terms:
            term = TERMS[t]
            out.setdefault(term.group, []).extend(range(k, k + len(term.params)))
            k += len(term.params)
        return out

    def term_slices(self) -> dict[str, slice]:
        out, k = {}, 0
        for t in self.terms:
            m = len(TERMS[t].params)
            out[t] = slice(k, k + m)
            k += m
        return out

    def with_term(self, term: str) -> Model:
        if term in self.terms:
            return self
        return get_model("+".join(self.terms + (term,)))

    def default_vector(self, scale: float | np.ndarray = 1.0) -> np.ndarray:
        """Nominal parameters: the given scale factors, everything else zero."""
        x = np.zeros(self.n_params)
        x[self.groups()["scale"]] = scale
        return x

    def to_dict(self, x) -> dict[str, float]:
        return {n: float(v) for n, v in zip(self.names, np.asarray(x, float))}

    def from_dict(self, values: dict[str, float], base: np.ndarray | None = None) -> np.ndarray:
        """Parameter vector from {name: value}; names not in the model are an error, missing ones keep `base`."""
        x = self.default_vector() if base is None else np.array(base, float)
        unknown = sorted(set(values) - set(self.names))
        if unknown:
            raise InputError(
                f"parameter(s) {', '.join(unknown)} are not in model {self.name}; "
                f"its parameters are {', '.join(self.names)}"
            )
        for k, v in values.items():
            x[self.index(k)] = float(v)
        return x

    # -- the generic forward map --------------------------------------------------------------
    def components(self, P: dict, A, ctx: Context | None, ops=NumpyOps):
        """Outputs (N_x, N_y, N_z) from parameters ``P`` {name: value} and inputs ``A = (A_x, A_y, A_z)``.

        Written once for every backend: values in ``P`` and ``A`` may be broadcastable NumPy arrays
        (real or complex) or CasADi expressions. This is the table of docs/design.md, "Terms and parameters", term by
        term.
        """
        Ax, Ay, Az = A
        get = P.get
        zero = 0.0

        def s(name):
            v = get(name)
            return zero if v is None else v

        # Installation matrix T (docs/design.md, "The installation matrix T"): unit diagonal, the angles in the cells
        # of T_CELLS;
        # absent angles are zero (the gauge of `misalignment`). Row by row, u_i = t_i0 + t_i1 + t_i2.
        A3 = (Ax, Ay, Az)
        u = []
        for i in range(3):
            t = [A3[j] if j == i else s(T_CELLS[i, j]) * A3[j] for j in range(3)]
            u.append(t[0] + t[1] + t[2])
        out = []
        for i, a in enumerate(AXES):
            lin = u[i] + s(f"b_{a}")
            if ctx is not None and ctx.dtemp is not None:
                if f"gamma_{a}" in P:
                    lin = lin * (1.0 + P[f"gamma_{a}"] * ctx.dtemp)
                if f"beta_{a}" in P:
                    lin = lin + P[f"beta_{a}"] * ctx.dtemp
            if f"kappa_{a}" in P:
                lin = lin + P[f"kappa_{a}"] * ops.neg_part(A3[i])
            if "c_xy" in P:
                j, k = [m for m in range(3) if m != i]
                lin = lin + A3[i] * (P[f"c_{a}{AXES[j]}"] * A3[j] + P[f"c_{a}{AXES[k]}"] * A3[k])
            if ctx is not None and ctx.dt is not None and f"d_{a}" in P:
                lin = lin + P[f"d_{a}"] * ctx.dt
            for _, axis, name, feature, kind in self._user:  # user-defined terms, inside K as the bias is
                if axis == i and name in P:
                    lin = lin + P[name] * feature.values(A3, ctx, kind, ops)
            n_i = P[f"K_{a}"] * lin
            if f"K2_{a}" in P:
                n_i = n_i + P[f"K2_{a}"] * A3[i] ** 2
            if f"K3_{a}" in P:
                n_i = n_i + P[f"K3_{a}"] * A3[i] ** 3
            out.append(n_i)
        return out

    # -- vectorised NumPy maps ----------------------------------------------------------------
    # The NumPy maps below evaluate the same table as `components`, written on (S, n, 3) arrays with the
    # installation matrix as (S, 3, 3) matrices: a few dozen array operations per call whatever the
    # model, instead of a few hundred per-axis ones. Single-candidate calls (what NLopt and the
    # derivative-free methods make) are overhead-bound, and this form makes them 3-4x faster; at large
    # S both forms cost the same. `tests/test_model.py` checks the two forms agree for every term.
    def _columns(self, X) -> np.ndarray:
        """X as (S, p), refusing a parameter count that is not this model's."""
        X = np.atleast_2d(X)
        if X.shape[-1] != self.n_params:
            raise ValueError(f"parameters have {X.shape[-1]} columns, model {self.name} has {self.n_params}")
        return X

    def _params(self, X):
        X = self._columns(X)
        return {n: X[:, k, None] for k, n in enumerate(self.names)}

    @cached_property
    def _layout(self) -> dict:
        """Column indices of each parameter family in X (computed once per model)."""
        ix = {n: k for k, n in enumerate(self.names)}

        def axes(prefix):
            cols = [ix.get(f"{prefix}_{a}") for a in AXES]
            return None if cols[0] is None else np.array(cols)

        def offdiag(prefix):
            pairs = [(i, j) for i in range(3) for j in range(3) if i != j]
            got = [(i, j, ix[f"{prefix}_{AXES[i]}{AXES[j]}"]) for i, j in pairs
                   if f"{prefix}_{AXES[i]}{AXES[j]}" in ix]
            return tuple(np.array(c) for c in zip(*got)) if got else None

        present = [(i, j, ix[n]) for (i, j), n in T_CELLS.items() if n in ix]
        return {
            "K": axes("K"), "b": axes("b"), "K2": axes("K2"), "K3": axes("K3"), "kappa": axes("kappa"),
            "beta": axes("beta"), "gamma": axes("gamma"), "d": axes("d"),
            "S": tuple(np.array(c) for c in zip(*present)) if present else None,
            # c_ij multiplies A_i·A_j in axis i's output: C[i, j] = c_ij.
            "c": offdiag("c"),
            "user": tuple((col, i, feature, kind) for col, i, _, feature, kind in self._user),
        }

    def _pack(self, X) -> dict:
        """The parameters of a population X (S, p) as (S, 1, 3) rows and the (S, 3, 3) matrix T."""
        X = self._columns(X)
        L = self._layout
        S = X.shape[0]
        pk = {k: (None if L[k] is None else X[:, None, L[k]])
              for k in ("K", "b", "K2", "K3", "kappa", "beta", "gamma", "d")}
        T = np.zeros((S, 3, 3), dtype=X.dtype)
        T[:, (0, 1, 2), (0, 1, 2)] = 1.0
        if L["S"] is not None:
            rows, cols, src = L["S"]
            T[:, rows, cols] = X[:, src]
        pk["T"] = T
        if L["c"] is not None:
            rows, cols, src = L["c"]
            C = np.zeros((S, 3, 3), dtype=X.dtype)
            C[:, rows, cols] = X[:, src]
            pk["C"] = C
        else:
            pk["C"] = None
        pk["user"], pk["X"] = L["user"], X
        return pk

    @staticmethod
    def _apply(pk: dict, A, ctx: Context | None):
        """Outputs F(A) (S, n, 3) for packed parameters and A (n, 3) or (S, n, 3): docs/design.md, "Terms and
        parameters"."""
        lin = A @ pk["T"].transpose(0, 2, 1)
        if pk["b"] is not None:
            lin = lin + pk["b"]
        if ctx is not None and ctx.dtemp is not None:
            dT = np.asarray(ctx.dtemp)[:, None]
            if pk["gamma"] is not None:
                lin = lin * (1.0 + pk["gamma"] * dT)
            if pk["beta"] is not None:
                lin = lin + pk["beta"] * dT
        if pk["kappa"] is not None:
            lin = lin + pk["kappa"] * NumpyOps.neg_part(A)
        if pk["C"] is not None:
            lin = lin + A * (A @ pk["C"].transpose(0, 2, 1))
        if ctx is not None and ctx.dt is not None and pk["d"] is not None:
            lin = lin + pk["d"] * np.asarray(ctx.dt)[:, None]
        if pk.get("user"):
            # user-defined terms (optcal.core.terms.Feature): c·φ on their axis; φ may depend on the previous pose's
            # A, so it is formed from the whole (S, n) component arrays
            comps = (A[..., 0], A[..., 1], A[..., 2])
            U = np.zeros(lin.shape, dtype=np.result_type(lin, pk["X"]))
            for col, i, feature, kind in pk["user"]:
                U[..., i] += pk["X"][:, col, None] * feature.values(comps, ctx, kind, NumpyOps)
            lin = lin + U
        F = pk["K"] * lin
        if pk["K2"] is not None:
            F = F + pk["K2"] * (A * A)
        if pk["K3"] is not None:
            F = F + pk["K3"] * (A * A * A)
        return F

    def forward(self, X, A, ctx: Context | None = None) -> np.ndarray:
        """Outputs N (S, n, 3) for parameters X (S, p) and specific force A (n, 3) or (S, n, 3) in g."""
        X = np.atleast_2d(X)
        A = np.asarray(A)
        F = self._apply(self._pack(X), A, ctx)
        return np.broadcast_to(F, (X.shape[0], A.shape[-2], 3))

    @staticmethod
    def _inverse_T(T):
        """T⁻¹ per candidate (S, 3, 3) by the adjugate: a singular T gives inf/nan for that candidate
        alone, where a batched LAPACK inverse would fail the whole population."""
        i1, i2 = np.array([1, 2, 0]), np.array([2, 0, 1])
        a, b = i1[:, None], i2[:, None]
        # cof[i, j] = T[i1, j1]·T[i2, j2] − T[i1, j2]·T[i2, j1]
        cof = T[:, a, i1] * T[:, b, i2] - T[:, a, i2] * T[:, b, i1]
        det = np.sum(T[:, 0, :] * cof[:, 0, :], axis=-1)
        return cof.transpose(0, 2, 1) / det[:, None, None]

    def inverse(self, X, N, ctx: Context | None = None, *, tol: float = 1e-15, max_iter: int = 60) -> np.ndarray:
        """Specific force A (S, n, 3) from outputs N (n, 3) or (S, n, 3), for parameters X (S, p).

        Iterates A ← A + (diag(K)·T)⁻¹ (N − F(A)), with the linear part inverted in closed form. The
        step is exact for the linear terms, so the error shrinks each sweep by a factor of the order of
        the nonlinear terms' relative size (1e-4 for a navigation-grade sensor): a handful of sweeps
        reach machine precision. Every sweep treats all candidates and positions at once.
        """
        X = np.atleast_2d(X)
        N = np.asarray(N)
        pk = self._pack(X)
        with np.errstate(divide="ignore", invalid="ignore"):
            TiT = self._inverse_T(pk["T"]).transpose(0, 2, 1)
        K, b = pk["K"], pk["b"]
        A = (N / K - (0.0 if b is None else b)) @ TiT
        prev = np.inf
        for _ in range(0 if self.is_affine else max_iter):
            r = (N - self._apply(pk, A, ctx)) / K
            A = A + r @ TiT
            # Stop when the error left after this step, |r|·ρ/(1−ρ) with ρ the observed contraction
            # rate, is below tol (saves the extra sweep a plain |r| test would cost).
            size = float(np.max(np.abs(r)))
            rho = min(size / prev, 0.5) if prev > 0 else 0.0
            if size <= tol or (np.isfinite(prev) and size * rho / (1 - rho) <= tol):
                break
            prev = size
        return np.broadcast_to(A, (X.shape[0],) + N.shape[-2:-1] + (3,))

    def dforward_dA(self, X, A, ctx=None, h: float = 1e-30) -> np.ndarray:
        """∂N/∂A of shape (S, n, 3, 3) by complex step (exact to rounding)."""
        X = np.atleast_2d(X)
        A = np.asarray(A, float)
        if A.ndim == 2:
            A = np.broadcast_to(A, (X.shape[0],) + A.shape)
        P = self._params(X.astype(complex))
        cols = []
        for j in range(3):
            Ac = A.astype(complex)
            Ac[..., j] += 1j * h
            N = self.components(P, (Ac[..., 0], Ac[..., 1], Ac[..., 2]), ctx)
            cols.append(np.stack([np.broadcast_to(c, A.shape[:2]) for c in N], -1).imag / h)
        return np.stack(cols, -1)

    def dforward_dp(self, x, A, ctx=None, h: float = 1e-30) -> np.ndarray:
        """∂N/∂p for one parameter vector x: shape (n, 3, p), by complex step over all p at once."""
        x = np.asarray(x, float)
        p = x.size
        Xc = np.tile(x.astype(complex), (p, 1)) + 1j * h * np.eye(p)
        A = np.asarray(A, float)
        if A.ndim == 3:
            A = A[0]
        Nc = self.forward(Xc, A, ctx)  # (p, n, 3)
        return np.moveaxis(Nc.imag / h, 0, -1)



def get_model(spec: str | Model) -> Model:
    """A model from a name (``diag6``, ``linear9``, ``nonlinear12``, ``seed15``) or a sum of terms
    (``scale+bias+misalignment+cubic``, ``linear9+ax.ay@z``). Terms are put in docs/design.md, "Terms and
    parameters"'s order, and
    user-defined terms (:func:`optcal.core.terms.user_term`) after them in the order of their names."""
    if isinstance(spec, Model):
        return spec
    spec = str(spec).strip()
    if spec in NAMED_MODELS:
        return Model(NAMED_MODELS[spec])
    parts = []
    for p in spec.split("+"):
        p = p.strip()
        if p in NAMED_MODELS:
            parts.extend(NAMED_MODELS[p])
        elif p in TERMS:
            parts.append(p)
        elif user_term_error(p):
            raise InputError(f"term {p!r}: {user_term_error(p)} (user-defined terms: docs/discovery.md)")
        else:
            raise InputError(
                f"unknown model or term {p!r}; use one of {', '.join(NAMED_MODELS)} "
                f"or a sum of terms from {', '.join(TERMS)}, or a user-defined term such as ax.ay@z"
            )
    parts = sorted(set(parts), key=lambda t: (0, TERM_ORDER.index(t), "") if t in TERM_ORDER else (1, 0, t))
    if "scale" not in parts:
        raise InputError(f"model {spec!r} has no 'scale' term; every model needs scale factors (add +scale)")
    if "misalignment" in parts and "misalignment6" in parts:
        raise InputError("use either 'misalignment' (3 angles) or 'misalignment6' (6 angles), not both")
    names = [n for t in parts for n in TERMS[t].params]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        holders = [t for t in parts if set(TERMS[t].params) & set(twice)]
        raise InputError(f"terms {' and '.join(holders)} share parameter(s) {', '.join(twice)}; keep one of them")
    return Model(tuple(parts))
