"""The gyroscope's sensor model: scale factors, six misalignment angles, bias and optional g-sensitivity.

Raw output W (the sensor's units) of body rate ω (rad/s) under specific force f (g), for axis i:

    W_i = K_i · (row_i(T)·ω + b_i + row_i(G)·f)

with T = I plus six off-diagonal angles (cell (i, j) is ``T_ij``: how much of the rate about body axis j
axis i senses), K_i in output units per rad/s, b_i in rad/s (the output offset is K_i·b_i, as for the
accelerometer's model, docs/design.md, "Terms and parameters") and G the g-sensitivity, a rate bias proportional to
specific force (``G_ij``: rad/s per g of f_j sensed by axis i). The body frame is the calibrated
accelerometer's frame, so the six angles place the gyroscope's axes relative to the accelerometer's,
as in Tedaldi, Pretto and Menegatti (ICRA 2014, Eq. 9-10), whose gyroscope model is this one without G.

Calibrating inverts it: ω = M·W + c + D·f with M = T⁻¹·diag(1/K), c = −T⁻¹·b, D = −T⁻¹·G, the 21
"affine numbers" the compiled integrator (:mod:`optcal.core.kernels.gyro`) takes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from optcal.core.errors import InputError

AXES = "xyz"
SCALE = tuple(f"K_{a}" for a in AXES)
MISALIGNMENT = ("T_xy", "T_xz", "T_yx", "T_yz", "T_zx", "T_zy")
BIAS = tuple(f"b_{a}" for a in AXES)
GSENS = tuple(f"G_{i}{j}" for i in AXES for j in AXES)
TERMS = {"scale": SCALE, "misalignment": MISALIGNMENT, "bias": BIAS, "g_sensitivity": GSENS}
# Parameter groups, named as the accelerometer's so that ``staged:`` and NAFSA treat them alike.
GROUP_OF_TERM = {"scale": "scale", "misalignment": "misalignment", "bias": "bias", "g_sensitivity": "nonlinear"}


def param_units(output_units: str) -> dict[str, str]:
    """The unit of every parameter name, for output units ``output_units`` (e.g. ``counts``, ``deg/s``)."""
    k = f"({output_units})/(rad/s)" if "/" in output_units else f"{output_units}/(rad/s)"
    out = {n: k for n in SCALE}
    out.update({n: "rad" for n in MISALIGNMENT})
    out.update({n: "rad/s" for n in BIAS})
    out.update({n: "(rad/s)/g" for n in GSENS})
    return out


@dataclass(frozen=True)
class GyroModel:
    """The gyroscope model with or without g-sensitivity, with or without the bias (``bias=False``: the
    bias is taken from the rests before fitting, :meth:`optcal.core.gyro.data.GyroData.debiased`); the same
    attributes the solvers read from the accelerometer's :class:`optcal.core.model.Model` (``names``,
    ``n_params``, ``terms``, ``needs``, ``groups``)."""

    g_sensitivity: bool = False
    bias: bool = True

    @property
    def terms(self) -> tuple[str, ...]:
        return (("scale", "misalignment") + (("bias",) if self.bias else ())
                + (("g_sensitivity",) if self.g_sensitivity else ()))

    @property
    def name(self) -> str:
        return f"gyro{self.n_params}"

    def slice_of(self, term: str) -> slice | None:
        """Where ``term``'s parameters sit in the vector (None when the model lacks it)."""
        k = 0
        for t in self.terms:
            if t == term:
                return slice(k, k + len(TERMS[t]))
            k += len(TERMS[t])
        return None

    @property
    def names(self) -> list[str]:
        return [n for t in self.terms for n in TERMS[t]]

    @property
    def n_params(self) -> int:
        return len(self.names)

    needs: tuple = ()
    is_affine = True

    def groups(self) -> dict[str, list[int]]:
        out: dict[str, list[int]] = {}
        k = 0
        for t in self.terms:
            out.setdefault(GROUP_OF_TERM[t], []).extend(range(k, k + len(TERMS[t])))
            k += len(TERMS[t])
        return out

    def vector(self, values: dict[str, float]) -> np.ndarray:
        """The parameter vector of a {name: value} mapping (every name of the model required)."""
        missing = [n for n in self.names if n not in values]
        if missing:
            raise InputError(f"gyroscope parameters {', '.join(missing)} are missing; give every parameter of "
                             f"{self.name}")
        return np.array([float(values[n]) for n in self.names])

    def default_vector(self, k: float | np.ndarray) -> np.ndarray:
        """Nominal sensor: scale ``k`` (output units per rad/s), no misalignment, bias or g-sensitivity."""
        x = np.zeros(self.n_params)
        x[:3] = k
        return x

    def matrices(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """K (S, 3), T (S, 3, 3), b (S, 3), G (S, 3, 3) of parameter vectors X (S, p); works on complex X."""
        X = np.atleast_2d(X)
        S = X.shape[0]
        K = X[:, 0:3]
        T = np.broadcast_to(np.eye(3, dtype=X.dtype), (S, 3, 3)).copy()
        for k, n in enumerate(MISALIGNMENT):
            T[:, AXES.index(n[2]), AXES.index(n[3])] = X[:, 3 + k]
        sb, sg = self.slice_of("bias"), self.slice_of("g_sensitivity")
        b = np.zeros((S, 3), X.dtype) if sb is None else X[:, sb]
        G = np.zeros((S, 3, 3), X.dtype) if sg is None else X[:, sg].reshape(S, 3, 3)
        return K, T, b, G

    def affine(self, X: np.ndarray) -> np.ndarray:
        """The affine numbers (S, 21) = (M row-major, c, D row-major) of ω = M·W + c + D·f."""
        K, T, b, G = self.matrices(X)
        Ti = np.linalg.inv(T)
        M = Ti / K[:, None, :]
        c = -np.einsum("sij,sj->si", Ti, b)
        D = -Ti @ G
        return np.concatenate([M.reshape(len(K), 9), c, D.reshape(len(K), 9)], axis=1)

    def affine_jacobian(self, x: np.ndarray) -> np.ndarray:
        """∂(affine numbers)/∂x (21, p) at one parameter vector, by the complex step (exact to rounding)."""
        p = self.n_params
        h = 1e-30
        Z = np.tile(np.asarray(x, complex), (p, 1)) + 1j * h * np.eye(p)
        return (self.affine(Z).imag / h).T

    def forward(self, x: np.ndarray, omega: np.ndarray, f: np.ndarray) -> np.ndarray:
        """Raw outputs (n, 3) of body rates ``omega`` (n, 3) in rad/s under specific force ``f`` (n, 3) in g."""
        K, T, b, G = (a[0] for a in self.matrices(np.asarray(x, float)[None]))
        return K * (omega @ T.T + b + f @ G.T)

    def inverse(self, x: np.ndarray, W: np.ndarray, f: np.ndarray) -> np.ndarray:
        """Calibrated body rates (n, 3) in rad/s of raw outputs ``W`` (n, 3) under specific force ``f`` (g)."""
        P = self.affine(np.asarray(x, float)[None])[0]
        return W @ P[:9].reshape(3, 3).T + P[9:12] + f @ P[12:21].reshape(3, 3).T


def get_gyro_model(g_sensitivity: bool = False, bias: bool = True) -> GyroModel:
    return GyroModel(bool(g_sensitivity), bool(bias))
