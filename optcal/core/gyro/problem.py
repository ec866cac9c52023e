"""The gyroscope calibration problem, behind the interface of :class:`optcal.core.problem.CalibrationProblem`.

Residuals (Tedaldi, Pretto and Menegatti, ICRA 2014, Eq. 15, with whitening and the rests added):

* one pair per motion: the first rest's gravity direction u0, carried through the motion by the rate
  the candidate calibrates (RK4 on the sample times, :mod:`optcal.core.kernels.gyro`), against the second
  rest's direction u1, along two unit vectors orthogonal to u1 (rad), divided by its SD;
* three per rest (when the bias is fitted): the calibrated rate of the rest's mean output, which must be
  zero (rad/s), divided by its SD. They determine the bias, and with g-sensitivity they determine G from
  the rests' different specific forces.

Every residual is whitened (:mod:`optcal.core.gyro.data`), so the cost is a χ² and the noise level handed to
:func:`optcal.core.analysis.crlb` is 1. The Earth's rate (7.3e-5 rad/s) is not modelled: it is below the
noise of the MEMS gyroscopes this is for; its vertical part looks like an isotropic g-sensitivity of
−7.3e-5·sin(latitude) (rad/s)/g.

The class offers what the solvers and :mod:`optcal.core.analysis` use of the accelerometer's problem: views
(``restrict``, ``normalised``), the shared evaluation counter and budget, ``cost``/``cost_batch``/
``residuals``/``residuals_batch``/``jacobian``/``gradient`` in view coordinates and ``residuals_full``/
``jacobian_full`` on full vectors, ``model`` (names, groups), ``presets`` (the search centre: not None, so
local methods start there) and ``noise_g`` (1: whitened residuals).
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from optcal.core.budget import Counter
from optcal.core.errors import InputError
from optcal.core.gyro.data import GyroData
from optcal.core.gyro.model import GyroModel, get_gyro_model
from optcal.core.motion_integrator import log_vertex
from optcal.core.view import ParameterViews


def _kernel():
    global _kernel
    from optcal.core.kernels import gyro

    _kernel = lambda: gyro  # noqa: E731
    return gyro


# How a problem integrates the motions (GyroProblem's ``backend``), as the accelerometer's problem
BACKENDS = ("kernel", "numpy")


class _KernelRotations:
    """The compiled integrator (:mod:`optcal.core.kernels.gyro`) behind the interface of
    :class:`optcal.core.motion_integrator.NumpyRotations`, over the motions ``motions`` (indices; all by default)."""

    def __init__(self, data: GyroData, motions=None):
        k = np.arange(data.n_motions) if motions is None else np.asarray(motions, np.intp)
        self.data, self.n_motions = data, len(k)
        self.start, self.stop = np.ascontiguousarray(data.start[k]), np.ascontiguousarray(data.stop[k])
        self.u0, self.E = np.ascontiguousarray(data.u0[k]), np.ascontiguousarray(data.E[k])

    def rotate_batch(self, P: np.ndarray) -> np.ndarray:
        d = self.data
        R = np.empty((len(P), self.n_motions, 2))
        _kernel().rotate_batch(np.ascontiguousarray(P), d.W, d.F, d.t, self.start, self.stop, self.u0, self.E, R)
        return R

    def rotate_jacobian(self, P: np.ndarray, n_dir: int) -> np.ndarray:
        d = self.data
        J = np.empty((self.n_motions, 2, n_dir))
        _kernel().rotate_jacobian(np.ascontiguousarray(P), n_dir, d.W, d.F, d.t, self.start, self.stop, self.u0,
                                  self.E, J)
        return J


def rotations(data: GyroData, backend: str, motions=None):
    """The residuals and Jacobian of ``data``'s motions (``motions``: indices, all by default) by ``backend``
    (:data:`BACKENDS`)."""
    if backend == "numpy":
        from optcal.core.motion_integrator import NumpyRotations

        k = np.arange(data.n_motions) if motions is None else np.asarray(motions, np.intp)
        return NumpyRotations(data.W, data.F, data.t, data.start[k], data.stop[k], data.u0[k], data.E[k])
    return _KernelRotations(data, motions)


# Search half-widths around the centre (the box of the search methods; least squares ignores it): 5 % of
# the scale, 0.05 rad of misalignment, 0.02 rad/s of bias around the rests' mean, 0.01 (rad/s)/g of G.
HALFWIDTH = {"K": 0.05, "T": 0.05, "b": 0.02, "G": 0.01}


class GyroPresets:
    """Search centre and half-widths of a gyroscope problem (full vectors)."""

    def __init__(self, centre: np.ndarray, halfwidth: np.ndarray):
        self.centre, self.halfwidth = np.asarray(centre, float), np.asarray(halfwidth, float)


def start_vector(model: GyroModel, data: GyroData, K) -> np.ndarray:
    """Nominal scale ``K`` (one number or three), no misalignment or g-sensitivity, the bias of the rests' mean
    output; ``K`` (S, 1) or (S, 3) gives S such vectors (S, p)."""
    K = np.asarray(K, float)
    x = np.zeros(K.shape[:-1] + (model.n_params,) if K.ndim == 2 else (model.n_params,))
    x[..., :3] = K
    if model.bias:
        x[..., model.slice_of("bias")] = np.mean(data.rest_W, axis=0) / K
    return x


# The scale search's coarse grid integrates only this many motions, those that turn gravity the most
SCALE_SEARCH_MOTIONS = 8
# The scale's bracket below the bound of :func:`scale_bound`: the bound is met by a turn about one axis across
# gravity; a hand's turns are near that, and a gyroscope's axes differ by a few % (the gates refuse 25 %)
SCALE_BRACKET = (0.5, 1.1)
SCALE_BRACKET_POINTS = 24
SCALE_NEAR = (0.88, 1.1)  # × the bound: the candidates tried first (5.7 % apart)
SCALE_NEAR_POINTS = 5
SCALE_FINE_POINTS = 7
BOUND_MIN_TURN = np.deg2rad(20.0)  # motions that turn gravity less than this give no useful bound


def scale_bound(data: GyroData) -> float:
    """An upper bound of the gyroscope's scale (output units per rad/s) from the motions alone: a motion turns
    the gravity direction by θ no more than it rotates, and rotates no more than its rate's path length, so
    ∫|W| dt ≥ K·θ for each motion (W the outputs less the rests' level); the bound is the least of
    ∫|W| dt / θ over the motions that turn gravity by :data:`BOUND_MIN_TURN` or more (NaN without one)."""
    speed = np.linalg.norm(data.W, axis=1)
    c = np.concatenate([[0.0], np.cumsum(0.5 * (speed[1:] + speed[:-1]) * np.diff(data.t))])
    path = c[data.stop] - c[data.start]
    big = data.turn >= BOUND_MIN_TURN
    return float(np.min(path[big] / data.turn[big])) if big.any() else float("nan")


def common_scale(model: GyroModel, data: GyroData, k_min: float, k_max: float, n: int = 240,
                 backend: str = "kernel", every=None) -> float:
    """The one scale factor (output units per rad/s, every axis) under which the motions best carry each
    rest's gravity direction onto the next's. For raw counts with no nominal scale; ``backend``: the
    integrator's (:data:`BACKENDS`).

    The search is bracketed by the motions themselves (:func:`scale_bound`): :data:`SCALE_NEAR_POINTS`
    log-spaced candidates over :data:`SCALE_NEAR` times the bound (where the scale lies when some motion turns
    about an axis across gravity), or, when the best of them is at an end, :data:`SCALE_BRACKET_POINTS` over
    :data:`SCALE_BRACKET` times it, on the :data:`SCALE_SEARCH_MOTIONS` motions that turn gravity the most (a
    wrong scale by a few % shows on any turn); then
    :data:`SCALE_FINE_POINTS` over the two neighbours of the best, on every motion, and the vertex of the
    parabola in log k through the best of those and its neighbours. Without a bound, or when the best lies at
    the bracket's edge (turns mostly about gravity), the bracket is a log-spaced grid of ``n`` candidates
    from ``k_min`` to ``k_max``. ``every``: the integrator of every motion (:func:`rotations`), when the caller
    has built it already."""
    def cost(rot, ks):
        R = rot.rotate_batch(model.affine(start_vector(model, data, ks[:, None])))
        return np.sum(R**2, axis=(1, 2))

    turning = np.sort(np.argsort(data.turn, kind="stable")[::-1][:SCALE_SEARCH_MOTIONS])
    few = rotations(data, backend, turning)
    bound = scale_bound(data)
    ks = None
    if np.isfinite(bound) and bound > 0:
        # first near the bound, where the scale lies when a motion turns about an axis across gravity
        ks = np.geomspace(SCALE_NEAR[0] * bound, SCALE_NEAR[1] * bound, SCALE_NEAR_POINTS)
        i = int(np.argmin(cost(few, ks)))
        if i in (0, len(ks) - 1):
            ks = np.geomspace(SCALE_BRACKET[0] * bound, SCALE_BRACKET[1] * bound, SCALE_BRACKET_POINTS)
            i = int(np.argmin(cost(few, ks)))
            if i in (0, len(ks) - 1):
                ks = None
    if ks is None:
        ks = np.geomspace(k_min, k_max, n)
        i = int(np.argmin(cost(few, ks)))
    fine = np.geomspace(ks[max(i - 1, 0)], ks[min(i + 1, len(ks) - 1)], SCALE_FINE_POINTS)
    # the parabola's vertex in log k: the grid's spacing no longer limits the start
    return log_vertex(fine, cost(rotations(data, backend) if every is None else every, fine))


BIAS_MODES = ("fit", "rests")


def _check_rotation_seen(data: GyroData) -> None:
    """Refuse a gyroscope that stays within its rest noise (5 SD) through every motion that turned the
    gravity direction by 5° or more: wrong columns, or a gyroscope that was off."""
    quiet = []
    for k in np.flatnonzero(data.turn >= np.deg2rad(5.0)):
        a, b = data.start[k], data.stop[k]
        dev = np.abs(data.W[a:b + 1] - data.rest_W[k]) / np.maximum(data.rest_sd_W[k], 1e-300)
        quiet.append(dev.max() < 5.0)
    if quiet and all(quiet):
        raise InputError("the gyroscope's output stays within its rest noise through every motion although the "
                         "gravity direction turns: wrong gyroscope columns, or the gyroscope was off; check them")


class GyroProblem(ParameterViews):
    """Gyroscope calibration from ``data`` (:class:`GyroData`) with the model of
    :mod:`optcal.core.gyro.model` (``g_sensitivity`` adds G). ``bias``: ``fit`` (parameters, determined by
    the rests' residuals and the motions together) or ``rests`` (taken from the rests before fitting,
    interpolated between them, :meth:`GyroData.debiased`: the model then has no bias parameters and the
    problem no rest residuals; G needs ``fit``). Either way the data are fitted minus an offset in raw
    units (``data.extra["offset_raw"]``: with ``fit`` the rests' mean output, :meth:`GyroData.centred`),
    and the bias parameters are the rate bias beyond it. ``scale``: nominal scale factor (output units per
    rad/s, one number or three); without it, :func:`common_scale` finds one. ``presets``: a
    :class:`GyroPresets` to centre the search elsewhere. ``backend``: ``"kernel"``, the compiled integrator
    (:mod:`optcal.core.kernels.gyro`, for populations), or ``"numpy"`` (:mod:`optcal.core.motion_integrator`: the same
    residuals and Jacobian to rounding without loading numba, for the tens of evaluations of least squares)."""

    reference = False
    g_local = 1.0

    def __init__(self, data: GyroData, *, g_sensitivity: bool = False, bias: str = "fit", scale=None,
                 presets: GyroPresets | None = None, backend: str = "kernel"):
        if backend not in BACKENDS:
            raise InputError(f"`backend` {backend!r}: use one of {', '.join(BACKENDS)}")
        self.backend = backend
        if bias not in BIAS_MODES:
            raise InputError(f"unknown gyroscope bias mode {bias!r}; use one of {', '.join(BIAS_MODES)}")
        if bias == "rests" and g_sensitivity:
            raise InputError("g-sensitivity needs the bias fitted (`bias` fit): the rests' outputs hold both")
        self.bias_mode = bias
        self.model = get_gyro_model(g_sensitivity, bias=bias == "fit")
        data = data.debiased() if bias == "rests" else data.centred()
        self.data = data
        if data.n_motions < 1:
            raise InputError("no motion between rests: record rotations between the rests")
        still = data.turn < np.deg2rad(5.0)
        if np.all(still):
            raise InputError("no motion turns the gravity direction by 5° or more: the recording has no rotation "
                             "between its rests; turn the sensor between rests")
        _check_rotation_seen(data)
        self._rotations = rotations(data, backend)
        if scale is None:
            scale = common_scale(self.model, data, 1e-3, 1e7, backend=backend, every=self._rotations)
        K = np.broadcast_to(np.asarray(scale, float), (3,)).copy()
        if not np.all(np.isfinite(K) & (K > 0)):
            raise InputError(f"the gyroscope's nominal scale must be positive (output units per rad/s), got {scale}")
        if presets is None:
            centre = start_vector(self.model, data, K)
            width = np.concatenate([HALFWIDTH["K"] * K, np.full(6, HALFWIDTH["T"])]
                                   + ([np.full(3, HALFWIDTH["b"])] if self.model.bias else [])
                                   + ([np.full(9, HALFWIDTH["G"])] if self.model.g_sensitivity else []))
            presets = GyroPresets(centre, width)
        self.presets = presets
        self.centre, self.halfwidth = presets.centre.copy(), presets.halfwidth.copy()
        self._K0 = np.abs(self.centre[:3])
        self.noise_g = 1.0  # whitened residuals
        self.ctx = SimpleNamespace(dtemp=None, dt=None)
        self.sd_motion = data.motion_sd(self._K0)
        self.sd_rest = data.rest_sd(self._K0)
        if not (np.all(self.sd_motion > 0) and np.all(self.sd_rest > 0)):
            raise InputError("a rest's gyroscope or accelerometer output does not vary at all (a constant column?), "
                             "so its noise is unknown; check the columns")
        self.free = np.arange(self.model.n_params)
        self.x_fixed = self.centre.copy()
        self.is_normalised = False
        self.counter = Counter()
        self._last_jacobian = None

    @property
    def whitening_scale(self) -> np.ndarray:
        """The scale factors (3,) with which the rests' output noise is turned into rad/s (:meth:`whiten_at`)."""
        return self._K0.copy()

    def whiten_at(self, K: np.ndarray) -> None:
        """Whiten with scale factors ``K`` (3,) output units per rad/s, the rests' output noise turned into
        rad/s with them (by default the nominal scale, the search centre's): the fit's own scale once it is
        known (:func:`optcal.app.workflows.gyro.calibrate_gyro`)."""
        K = np.abs(np.broadcast_to(np.asarray(K, float), (3,)))
        self._K0 = K.copy()
        self.sd_motion = self.data.motion_sd(K)
        self.sd_rest = self.data.rest_sd(K)
        self._last_jacobian = None

    # -- residuals --------------------------------------------------------------------------
    @property
    def n_motion_residuals(self) -> int:
        return 2 * self.data.n_motions

    @property
    def n_position_residuals(self) -> int:
        return self.n_motion_residuals + self.n_rest_residuals

    @property
    def n_rest_residuals(self) -> int:
        return 3 * self.data.n_rests if self.model.bias else 0

    n_residuals = n_position_residuals
    rows_per_position = 1

    def residuals_full(self, X_full) -> np.ndarray:
        """Whitened residuals (S, m) of full parameter vectors (S, p): motions then rests; not counted."""
        X = np.atleast_2d(np.asarray(X_full, float))
        if X.shape[1] != self.model.n_params:
            raise ValueError(f"parameters have {X.shape[1]} columns, model {self.model.name} has "
                             f"{self.model.n_params}")
        d = self.data
        with np.errstate(all="ignore"):
            P = np.ascontiguousarray(self.model.affine(X))
        bad = ~np.all(np.isfinite(P), axis=1)
        P[bad] = 0.0
        R = self._rotations.rotate_batch(P) / self.sd_motion[None, :, None]
        parts = [R.reshape(len(X), -1)]
        if self.model.bias:
            rest = (np.einsum("sij,rj->sri", P[:, :9].reshape(-1, 3, 3), d.rest_W) + P[:, None, 9:12]
                    + np.einsum("sij,rj->sri", P[:, 12:].reshape(-1, 3, 3), d.rest_F)) / self.sd_rest[None]
            parts.append(rest.reshape(len(X), -1))
        out = np.concatenate(parts, axis=1)
        out[bad] = np.nan
        return out

    def position_residuals(self, x_full) -> np.ndarray:
        return self.residuals_full(x_full)[0]

    def motion_angles(self, x_full) -> np.ndarray:
        """Angle (rad) between each motion's carried and measured gravity directions (the residual a user
        reads: unwhitened)."""
        R = self.residuals_full(x_full)[0][: self.n_motion_residuals].reshape(-1, 2) * self.sd_motion[:, None]
        return np.linalg.norm(R, axis=1)

    def from_sensor(self, x_sensor) -> np.ndarray:
        """This problem's parameter vector of a sensor whose bias b includes the whole output offset (the
        model of :mod:`optcal.core.gyro.model` on the raw data): b − offset/K, the bias dropped without a bias
        term (a simulation's truth in the problem's coordinates)."""
        x = np.asarray(x_sensor, float).copy()
        full = get_gyro_model(self.model.g_sensitivity)
        if len(x) != full.n_params:
            raise ValueError(f"expected the {full.n_params} parameters of {full.name}, got {len(x)}")
        x[9:12] -= np.asarray(self.data.extra["offset_raw"], float) / x[:3]
        return x if self.model.bias else np.delete(x, np.s_[9:12])

    def rotation(self, x_full, start: int, stop: int) -> np.ndarray:
        """Rotation vector (3,) in rad, body frame, of the attitude change from sample ``start`` to ``stop``
        integrated with the rate ``x_full`` calibrates (the integrator of the residuals)."""
        from optcal.core.motion_integrator import NumpyRotations

        d = self.data
        one = NumpyRotations(d.W, d.F, d.t, [int(start)], [int(stop)], d.u0[:1], d.E[:1])
        q = one.integrator.attitudes(one.rates(self.model.affine(np.asarray(x_full, float)[None])))[:, 0, 0]
        v = q[1:] * np.sign(q[0] if q[0] != 0 else 1.0)
        n = np.linalg.norm(v)
        return np.zeros(3) if n == 0 else v / n * 2.0 * np.arctan2(n, abs(q[0]))

    def rms(self, x_full) -> float:
        return float(np.sqrt(np.mean(self.position_residuals(x_full) ** 2)))

    def _evaluate(self, X, keep_residuals: bool = True):
        X = np.ascontiguousarray(np.atleast_2d(X), dtype=float)
        S = X.shape[0]
        if X.ndim != 2 or X.shape[1] != self.n:
            raise ValueError(f"expected {self.n} coordinates, got {X.shape[-1]}")
        counter = self.counter
        k = counter.allow(S)
        f = np.full(S, np.inf)
        R = np.full((S, self.n_residuals), np.nan) if keep_residuals else None
        if k:
            Xf = self.to_full(X[:k])
            Rk = self.residuals_full(Xf)
            with np.errstate(all="ignore"):
                fk = np.sum(Rk**2, axis=1)
            fk[~np.isfinite(fk)] = np.nan
            f[:k] = fk
            if R is not None:
                R[:k] = Rk
            counter.record(fk, Xf)
        return R, f

    # -- derivatives ------------------------------------------------------------------------
    def jacobian_full(self, x_full) -> np.ndarray:
        """Exact Jacobian (m, p) of the whitened residuals: the integrator's forward-mode derivatives with
        respect to the affine numbers, times their complex-step derivatives with respect to the parameters."""
        x = np.asarray(x_full, float)
        if x.shape != (self.model.n_params,):
            raise ValueError(f"expected {self.model.n_params} parameters, got shape {x.shape}")
        # the last one kept: a fit asks for it at the start (observability, then the solver's first step) and
        # at the solution (the solver's last, observability, the Cramér-Rao bound)
        if self._last_jacobian is not None and np.array_equal(self._last_jacobian[0], x):
            return self._last_jacobian[1].copy()
        d = self.data
        P = np.ascontiguousarray(self.model.affine(x[None])[0])
        # the affine numbers that can move: M always, c with a bias, D with g-sensitivity (which needs c)
        n_dir = 21 if self.model.g_sensitivity else 12 if self.model.bias else 9
        Jm = self._rotations.rotate_jacobian(P, n_dir) / self.sd_motion[:, None, None]
        rows = [Jm.reshape(-1, n_dir)]
        if self.model.bias:  # rests: ω = M·W̄ + c + D·f̄, linear in the affine numbers
            Jr = np.zeros((d.n_rests, 3, n_dir))
            for i in range(3):
                Jr[:, i, 3 * i:3 * i + 3] = d.rest_W
                Jr[:, i, 9 + i] = 1.0
                if n_dir == 21:
                    Jr[:, i, 12 + 3 * i:15 + 3 * i] = d.rest_F
            rows.append((Jr / self.sd_rest[:, :, None]).reshape(-1, n_dir))
        J = np.concatenate(rows) @ self.model.affine_jacobian(x)[:n_dir]
        self._last_jacobian = (x.copy(), J)
        return J.copy()

    def jacobian(self, x) -> np.ndarray:
        self.counter.allow(1)
        self.counter.njev += 1
        self.counter.nfev += 1
        J = self.jacobian_full(self.to_full(x)[0])[:, self.free]
        return J * self.halfwidth[self.free] if self.is_normalised else J

    def gradient(self, x) -> np.ndarray:
        r = self.residuals(x)
        return 2.0 * self.jacobian(x).T @ r
