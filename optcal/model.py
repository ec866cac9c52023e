"""The accelerometer sensor model as a sum of named terms (DESIGN §3).

The seeds' model (2020 paper, Eq. 10) is ``N = diag(K)·(T·A + b) + K2 ⊙ A²``. Here it is one instance
of a general sum of terms; each term owns named parameters and says which data columns it needs.

Forward and inverse maps are vectorised over a *population* of parameter vectors: ``X`` of shape
``(S, p)`` and specific forces of shape ``(n, 3)`` give outputs of shape ``(S, n, 3)`` in one call.
The forward map is written once, generically over an "ops" namespace, so that the same term definitions
evaluate NumPy arrays (real or complex, for complex-step derivatives) and CasADi symbols.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .errors import InputError

AXES = ("x", "y", "z")


@dataclass(frozen=True)
class Term:
    """One named effect of the model: its parameters, its group and the data columns it needs."""

    name: str
    params: tuple[str, ...]
    group: str
    needs: tuple[str, ...] = ()
    description: str = ""
    # A typical magnitude of each parameter relative to the scale factor (for normalised search boxes
    # and for the natural scaling used in observability analysis).
    unit: float = 1.0


def _axes(prefix: str) -> tuple[str, ...]:
    return tuple(f"{prefix}_{a}" for a in AXES)


TERMS: dict[str, Term] = {
    t.name: t
    for t in (
        Term("scale", _axes("K"), "scale", description="scale factors, output units per g"),
        Term("bias", _axes("b"), "bias", description="biases in g (output offset K·b)"),
        Term(
            "misalignment",
            ("S_yz", "S_zy", "S_zx"),
            "misalignment",
            description="installation angles in the identifiable gauge S_xz = S_xy = S_yx = 0, rad",
        ),
        Term(
            "misalignment6",
            ("S_xz", "S_xy", "S_yz", "S_yx", "S_zy", "S_zx"),
            "misalignment",
            description="the seeds' six installation angles, rad (three directions unobservable)",
        ),
        Term("quadratic", _axes("K2"), "nonlinear", description="second-order scale, output units per g²"),
        Term("cubic", _axes("K3"), "nonlinear", description="third-order scale, output units per g³"),
        Term(
            "scale_asymmetry",
            _axes("kappa"),
            "nonlinear",
            description="relative scale difference for negative inputs",
        ),
        Term(
            "cross_coupling",
            ("c_xy", "c_xz", "c_yz", "c_yx", "c_zx", "c_zy"),
            "nonlinear",
            description="cross-axis products, per g",
        ),
        Term(
            "temperature_bias",
            _axes("beta"),
            "temperature",
            needs=("temp",),
            description="bias temperature coefficient, g per °C",
        ),
        Term(
            "temperature_scale",
            _axes("gamma"),
            "temperature",
            needs=("temp",),
            description="scale temperature coefficient, per °C",
        ),
        Term("bias_drift", _axes("d"), "drift", needs=("t",), description="bias drift, g per s"),
    )
}

NAMED_MODELS: dict[str, tuple[str, ...]] = {
    "diag6": ("scale", "bias"),
    "linear9": ("scale", "bias", "misalignment"),
    "nonlinear12": ("scale", "bias", "misalignment", "quadratic"),
    "seed15": ("scale", "bias", "misalignment6", "quadratic"),
}

_TERM_ORDER = list(TERMS)


class NumpyOps:
    """Array operations for the generic forward map (works for real and complex arrays)."""

    @staticmethod
    def neg_part(a):
        # min(a, 0); written with `where` on the real part so the complex step passes through.
        return np.where(np.real(a) < 0, a, 0.0)


@dataclass(frozen=True)
class Context:
    """Per-position inputs besides A: temperature and time offsets (DESIGN §3: T0 = mean, t0 = first)."""

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
        (real or complex) or CasADi expressions. This is DESIGN §3's table, term by term.
        """
        Ax, Ay, Az = A
        get = P.get
        zero = 0.0

        def s(name):
            v = get(name)
            return zero if v is None else v

        # Installation matrix T (DESIGN §3); absent angles are zero (the gauge of `misalignment`).
        u = [
            Ax + s("S_xz") * Ay + s("S_xy") * Az,
            s("S_yz") * Ax + Ay + s("S_yx") * Az,
            s("S_zy") * Ax + s("S_zx") * Ay + Az,
        ]
        A3 = (Ax, Ay, Az)
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
            n_i = P[f"K_{a}"] * lin
            if f"K2_{a}" in P:
                n_i = n_i + P[f"K2_{a}"] * A3[i] ** 2
            if f"K3_{a}" in P:
                n_i = n_i + P[f"K3_{a}"] * A3[i] ** 3
            out.append(n_i)
        return out

    # -- vectorised NumPy maps ----------------------------------------------------------------
    def _params(self, X):
        X = np.atleast_2d(X)
        if X.shape[-1] != self.n_params:
            raise ValueError(f"parameters have {X.shape[-1]} columns, model {self.name} has {self.n_params}")
        return {n: X[:, k, None] for k, n in enumerate(self.names)}

    def forward(self, X, A, ctx: Context | None = None) -> np.ndarray:
        """Outputs N (S, n, 3) for parameters X (S, p) and specific force A (n, 3) or (S, n, 3) in g."""
        A = np.asarray(A)
        P = self._params(X)
        N = self.components(P, (A[..., 0], A[..., 1], A[..., 2]), ctx)
        shape = (np.atleast_2d(X).shape[0], A.shape[-2])
        return np.stack([np.broadcast_to(c, shape) for c in N], axis=-1)

    def _linear_inverse(self, P) -> list[list]:
        """Entries of T⁻¹ per candidate, as a 3×3 nested list of (S, 1) arrays (closed form)."""
        one = np.ones_like(P["K_x"])

        def s(name):
            v = P.get(name)
            return 0.0 * one if v is None else v

        t = [[one, s("S_xz"), s("S_xy")], [s("S_yz"), one, s("S_yx")], [s("S_zy"), s("S_zx"), one]]
        cof = [[t[(i + 1) % 3][(j + 1) % 3] * t[(i + 2) % 3][(j + 2) % 3]
                - t[(i + 1) % 3][(j + 2) % 3] * t[(i + 2) % 3][(j + 1) % 3] for j in range(3)] for i in range(3)]
        det = t[0][0] * cof[0][0] + t[0][1] * cof[0][1] + t[0][2] * cof[0][2]
        return [[cof[j][i] / det for j in range(3)] for i in range(3)]

    def inverse(self, X, N, ctx: Context | None = None, *, tol: float = 1e-15, max_iter: int = 60) -> np.ndarray:
        """Specific force A (S, n, 3) from outputs N (n, 3) or (S, n, 3), for parameters X (S, p).

        Iterates A ← A + (diag(K)·T)⁻¹ (N − F(A)), with the linear part inverted in closed form. The
        step is exact for the linear terms, so the error shrinks each sweep by a factor of the order of
        the nonlinear terms' relative size (1e-4 for a navigation-grade sensor): a handful of sweeps
        reach machine precision. Every sweep treats all candidates and positions at once.
        """
        X = np.atleast_2d(X)
        P = self._params(X)
        N = np.asarray(N)
        Nc = [N[..., i] for i in range(3)]
        Ti = self._linear_inverse(P)
        K = [P[f"K_{a}"] for a in AXES]
        b = [P.get(f"b_{a}", 0.0) for a in AXES]
        Y = [Nc[i] / K[i] - b[i] for i in range(3)]
        A = [Ti[i][0] * Y[0] + Ti[i][1] * Y[1] + Ti[i][2] * Y[2] for i in range(3)]
        linear = all(t in ("scale", "bias", "misalignment", "misalignment6") for t in self.terms)
        prev = np.inf
        for _ in range(0 if linear else max_iter):
            F = self.components(P, A, ctx)
            r = [(Nc[i] - F[i]) / K[i] for i in range(3)]
            A = [A[i] + Ti[i][0] * r[0] + Ti[i][1] * r[1] + Ti[i][2] * r[2] for i in range(3)]
            # Stop when the error left after this step, |r|·ρ/(1−ρ) with ρ the observed contraction
            # rate, is below tol (saves the extra sweep a plain |r| test would cost).
            size = max(float(np.max(np.abs(ri))) for ri in r)
            rho = min(size / prev, 0.5) if prev > 0 else 0.0
            if size <= tol or (np.isfinite(prev) and size * rho / (1 - rho) <= tol):
                break
            prev = size
        shape = (X.shape[0],) + N.shape[-2:-1]
        return np.stack([np.broadcast_to(a, shape) for a in A], axis=-1)

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
    (``scale+bias+misalignment+cubic``). Terms are put in DESIGN §3's order."""
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
        else:
            raise InputError(
                f"unknown model or term {p!r}; use one of {', '.join(NAMED_MODELS)} "
                f"or a sum of terms from {', '.join(TERMS)}"
            )
    parts = sorted(set(parts), key=_TERM_ORDER.index)
    if "scale" not in parts:
        raise InputError(f"model {spec!r} has no 'scale' term; every model needs scale factors (add +scale)")
    if "misalignment" in parts and "misalignment6" in parts:
        raise InputError("use either 'misalignment' (3 angles) or 'misalignment6' (6 angles), not both")
    return Model(tuple(parts))
