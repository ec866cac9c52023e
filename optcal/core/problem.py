"""The calibration problem: model + data + cost, with batched evaluation and an enforced budget.

Norm cost (2020 paper, Eq. 12): for each position j, invert the model to get A_j from N_j and take
e_j = ‖A_j‖ − g_local; the cost is Σ e_j² (the paper writes Σ e_j; squares make it least squares).
With ``reference=True`` (turntable data with known A_j) the residuals are the 3-D misfit
(N_j − model(A_j)) / K0, in g, the "traditional" calibration.

A problem can be *viewed* restricted to some parameters (the rest held fixed; the papers' four stages)
and in normalised coordinates x = centre + halfwidth · z with z in [−1, 1] (2020 paper §3.4: search
methods need parameters of similar magnitude). Views share one evaluation counter, so a budget covers
everything done on a problem, and the counter keeps the best point ever evaluated so no solver can lose it.

The budget and the counter are in :mod:`optcal.core.budget` (re-exported here), the linear algebra of the gauge
rows in :mod:`optcal.core.gauge`, and the NumPy oracle of the residuals and Jacobian in :mod:`optcal.core.oracle`.
"""

from __future__ import annotations

import numpy as np

from optcal.core import oracle
from optcal.core.budget import Budget, Counter  # noqa: F401 - Budget re-exported (the budget is the problem's)
from optcal.core.data import PositionsData, residuals_per_position
from optcal.core.errors import InputError
from optcal.core.gauge import gauge_rows
from optcal.core.linfit import linear_start
from optcal.core.model import Context, Model, get_model
from optcal.core.presets import Presets, default_halfwidth
from optcal.core.view import ParameterViews

_NO_RESIDUALS = np.empty((0, 0))
_FLOAT64 = np.dtype(np.float64)


def _kernel():
    """The compiled kernels, imported at first use: importing optcal does not import numba."""
    global _kernel
    from optcal.core.kernels.cache import load

    evaluate = load()

    _kernel = lambda: evaluate  # noqa: E731
    return evaluate


# How a problem evaluates itself (CalibrationProblem's ``backend``)
BACKENDS = ("kernel", "numpy")


# Every static position sees the same specific force, 1 g: output magnitudes of a sensor differ by its
# scale-factor differences and biases (a few per cent; up to ~1.4x for raw counts around an offset), never by
# this factor. A position beyond it is a typo, a unit mix-up or a sensor that moved.
MAGNITUDE_FACTOR = 4.0


def _check_magnitudes(data: PositionsData) -> None:
    with np.errstate(over="ignore"):  # a value near 1e300 overflows to inf here, which is what it is reported as
        norms = np.linalg.norm(data.N, axis=1)
    med = float(np.median(norms))
    if not med > 0:
        raise InputError("the position means are all zero: no sensor output to calibrate; check the file's columns")
    bad = np.flatnonzero((norms > MAGNITUDE_FACTOR * med) | (norms < med / MAGNITUDE_FACTOR))
    if bad.size:
        labels = ", ".join(f"{data.position[i]} (|output| {norms[i]:.3g})" for i in bad[:5])
        raise InputError(f"position(s) {labels} are more than {MAGNITUDE_FACTOR:g}x away from the other positions' "
                         f"output magnitude ({med:.4g}): a typo, a unit mix-up or a moved sensor? fix or remove them")


class CalibrationProblem(ParameterViews):
    """Calibration of ``model`` from static positions ``data``.

    Parameters ----------
    model : name or :class:`~optcal.core.model.Model` data : :class:`~optcal.core.data.PositionsData`
    g_local : local gravity in units of g0 (1.0 by default) reference : use the turntable reference ``data.ref``
    (traditional calibration) presets : :class:`~optcal.core.presets.Presets` giving the search centre and half-widths;
    without them the
        centre is a closed-form linear fit of the data (never the truth)
    noise_g : input-referred SD of each position's mean in g (for Cramér-Rao bounds); when not given, the RMS
        over positions and axes of the data's standard error of each mean (``se_x, se_y, se_z``, correlated
        noise included, or else ``sx, sy, sz`` over √n: :meth:`PositionsData.noise_of_mean`), and
        ``noise_from_data`` is True (the χ² test then takes each position's own floor)
    fix_gauge : hold the unobservable directions (if any) at the centre with one extra residual each
    backend : ``"kernel"``, the compiled kernel (:mod:`optcal.core.kernels`), or ``"numpy"``, the NumPy model
        (:mod:`optcal.core.oracle`): the same residuals and Jacobian to rounding, without loading numba, whose start
        (most of a second per process) outweighs the tens of evaluations of one least-squares fit
    """

    def __init__(self, model, data: PositionsData, *, g_local: float = 1.0, reference: bool = False,
                 presets: Presets | None = None, noise_g: float | None = None, check: bool = True,
                 fix_gauge: bool = True, backend: str = "kernel"):
        if backend not in BACKENDS:
            raise InputError(f"`backend` {backend!r}: use one of {', '.join(BACKENDS)}")
        self.backend = backend
        self.model: Model = get_model(model)
        self.data = data
        self.g_local = float(g_local)
        self.reference = bool(reference)
        self.presets = presets
        if reference and data.ref is None:
            raise InputError("--reference needs turntable columns ref_x, ref_y, ref_z in the data")
        missing = [c for c in self.model.needs if getattr(data, c) is None]
        if missing:
            raise InputError(
                f"model {self.model.name} needs column(s) {', '.join(missing)} that the data lack; "
                "add them or drop the terms that need them"
            )
        _check_magnitudes(data)
        m = len(data) * residuals_per_position(reference)
        if check and m < self.model.n_params:
            raise InputError(
                f"{len(data)} positions give {m} residuals, fewer than the {self.model.n_params} parameters of "
                f"{self.model.name}; use more positions or a smaller model"
            )
        self.ctx = Context.from_columns(
            temp=data.temp if "temp" in self.model.needs else None,
            t=data.t if "t" in self.model.needs else None,
        )
        try:
            start = linear_start(self.model, data.N, self.g_local, data.ref if reference else None)
        except InputError:
            # Degenerate geometry (e.g. every position in one plane): start from the nominal sensor so
            # that the observability analysis, not the starting point, reports what is missing.
            k = np.median(np.linalg.norm(data.N, axis=1)) / self.g_local
            start = self.model.default_vector(k)
        kscale = start[self.model.groups()["scale"]]
        if presets is not None:
            centre, width = presets.vectors(self.model, kscale)
        else:
            centre, width = start, default_halfwidth(self.model, start)
        self.centre = centre
        self.halfwidth = width
        self._K0 = np.abs(centre[self.model.groups()["scale"]])
        if noise_g is not None and not (np.isfinite(noise_g) and noise_g > 0):
            raise InputError(f"the noise SD must be a positive number of g, got {noise_g!r}")
        self.noise_g = noise_g
        self.noise_from_data = False
        if noise_g is None and data.noise_of_mean() is not None:
            self.noise_g = float(np.sqrt(np.mean((data.noise_of_mean() / self._K0) ** 2)))
            self.noise_from_data = True
            if not (np.isfinite(self.noise_g) and self.noise_g > 0):
                what = ("standard errors (columns se_x, se_y, se_z)" if data.sem is not None
                        else "sample SDs (columns sx, sy, sz)")
                raise InputError(f"the positions' {what} are all zero or invalid, so they give no noise level; fix "
                                 "them, or drop the columns and state the noise")
        # Gauge: directions the norm cost cannot see (seed15's three rotations) are held at the centre
        # (presets or linear fit) by minimum-constraint residuals, as geodesy fixes a datum. They are zero
        # at the centre and orthogonal to every observable direction, so the fit of those is unchanged.
        # View state
        self.free = np.arange(self.model.n_params)
        self.x_fixed = centre.copy()
        self.is_normalised = False
        self.counter = Counter()
        # The compiled kernel serves this class's own residuals and Jacobian; a subclass that overrides
        # them (to inject faults, or to log what is evaluated) is evaluated through its overrides.
        cls = type(self)
        self._compiled = (backend == "kernel" and cls.residuals_full is CalibrationProblem.residuals_full
                          and cls.jacobian_full is CalibrationProblem.jacobian_full)
        self._gauge = None
        self._full_buffers = self._view_buffers = None
        self._last_jacobian = None
        if fix_gauge and not reference:
            self._gauge = gauge_rows(self, centre)
            if self._gauge is not None:
                self._full_buffers = None  # packed without the gauge rows while they were being found

    def _new_view(self) -> None:
        self._view_buffers = None  # the kernel's buffers hold the view (free parameters, z → x)

    # -- the compiled kernel's buffers -----------------------------------------------------
    def _pack(self, full: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The kernel's buffers for this view (``full``: for full parameter vectors) and its scratch."""
        from optcal.core.kernels.codegen import slot_indices, variant_of

        kernel = _kernel()

        p = self.model.n_params
        if full:
            free, offset, scale = np.arange(p), np.zeros(p), np.ones(p)
        else:
            free = self.free
            offset = self.centre[free] if self.is_normalised else np.zeros(len(free))
            scale = self.halfwidth[free] if self.is_normalised else np.ones(len(free))
        return kernel.pack(N=self.data.N, ref=self.data.ref if self.reference else None, dtemp=self.ctx.dtemp,
                           dtime=self.ctx.dt, K0=self._K0, g=self.g_local, centre=self.centre, gauge=self._gauge,
                           slots=slot_indices(self.model), affine=self.model.is_affine,
                           variant=variant_of(self.model), free=free, x_fixed=self.x_fixed, offset=offset,
                           scale=scale)

    def _buffers(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
        """This view's kernel buffers and its number of free coordinates (built at first use)."""
        if self._view_buffers is None:
            self._view_buffers = (*self._pack(full=False), len(self.free))
        return self._view_buffers

    # -- residuals and cost (uncounted kernels on full vectors) -----------------------------
    def residuals_full(self, X_full) -> np.ndarray:
        """Residuals (S, m) for full parameter vectors (S, p); not counted against the budget."""
        X_full = np.ascontiguousarray(np.atleast_2d(X_full), dtype=float)
        if X_full.ndim != 2 or X_full.shape[1] != self.model.n_params:
            raise ValueError(f"parameters have {X_full.shape[-1]} columns, model {self.model.name} has "
                             f"{self.model.n_params}")
        if self.backend == "numpy":
            return oracle.residuals(self, X_full)
        if self._full_buffers is None:
            self._full_buffers = self._pack(full=True)
        R = np.empty((len(X_full), self.n_residuals))
        _kernel().evaluate_batch(X_full, *self._full_buffers, np.empty(len(X_full)), R, True)
        return R

    def residuals_full_numpy(self, X_full) -> np.ndarray:
        """:meth:`residuals_full` through the NumPy model (:func:`optcal.core.oracle.residuals`)."""
        return oracle.residuals(self, X_full)

    def position_residuals(self, x_full) -> np.ndarray:
        """Residuals of the positions alone (n or 3n), in g, without gauge rows."""
        return self.residuals_full(x_full)[0][: self.n_position_residuals]

    def specific_force(self, x_full) -> np.ndarray:
        """Calibrated specific force (n, 3) in g at each position, for one full parameter vector."""
        return self.model.inverse(np.atleast_2d(x_full), self.data.N, self.ctx)[0]

    def _evaluate(self, X, keep_residuals: bool = True) -> tuple[np.ndarray | None, np.ndarray]:
        """Residuals (S, m) (when kept) and costs (S,) of candidates X (S, n), counted; candidates past
        the budget cost inf (residuals NaN), non-finite costs are NaN."""
        if not (type(X) is np.ndarray and X.dtype == np.float64 and X.ndim == 2 and X.flags.c_contiguous):
            X = np.ascontiguousarray(np.atleast_2d(X), dtype=float)
        S = X.shape[0]
        if X.ndim != 2 or X.shape[1] != self.n:
            raise ValueError(f"expected {self.n} coordinates, got {X.shape[-1]}")
        counter = self.counter
        k = S if (counter.nfev + S <= counter.limit and not counter.stopped) else counter.allow(S)
        f = np.empty(S)
        R = np.empty((S, self.n_residuals)) if keep_residuals else None
        Xk = X if k == S else X[:k]
        if k < S:
            f[k:] = np.inf
            if R is not None:
                R[k:] = np.nan
        if self._compiled:
            fb, ib, work, _ = self._view_buffers or self._buffers()
            i = _kernel().evaluate_batch(Xk, fb, ib, work, f, _NO_RESIDUALS if R is None else R, R is not None)
        else:
            Rk = self.residuals_full(self.to_full(Xk))
            with np.errstate(all="ignore"):
                fk = np.sum(Rk**2, axis=1)
            fk[~np.isfinite(fk)] = np.nan
            f[:k] = fk
            if R is not None:
                R[:k] = Rk
            i = -1 if np.all(np.isnan(fk)) else int(np.nanargmin(fk))
        counter.nfev += k
        if i >= 0 and f[i] < counter.best_f:
            counter.improve(f[i], self.to_full(Xk[i])[0])
        return R, f

    @property
    def rows_per_position(self) -> int:
        """Residuals per position: 3 against a turntable's reference, else 1 (:func:`residuals_per_position`)."""
        return residuals_per_position(self.reference)

    @property
    def n_position_residuals(self) -> int:
        """Residuals of the positions (gauge rows excluded)."""
        return len(self.data) * self.rows_per_position

    @property
    def n_residuals(self) -> int:
        return self.n_position_residuals + (0 if self._gauge is None else len(self._gauge))

    def cost(self, x) -> float:
        """Cost of one candidate (counted). The lean path of solvers that evaluate one point per call:
        the compiled kernel plus an evaluation count and a comparison with the best cost."""
        counter = self.counter
        if not self._compiled or counter.nfev >= counter.limit or counter.stopped:
            return float(self._evaluate(np.asarray(x, float)[None], keep_residuals=False)[1][0])
        if not (type(x) is np.ndarray and x.dtype is _FLOAT64 and x.ndim == 1 and x.flags.c_contiguous):
            x = np.ascontiguousarray(x, dtype=float)
        fb, ib, work, n_free = self._view_buffers or self._buffers()
        if x.shape[0] != n_free:
            raise ValueError(f"expected {n_free} coordinates, got shape {x.shape}")
        f = _kernel().cost_one(x, fb, ib, work)
        counter.nfev += 1
        if f < counter.best_f:
            counter.improve(f, self.to_full(x)[0])
        return f

    # -- derivatives ----------------------------------------------------------------------
    def jacobian_full(self, x_full) -> np.ndarray:
        """Analytic Jacobian (m, p) of the residuals w.r.t. all parameters (implicit function theorem for
        the norm cost); not counted."""
        x_full = np.ascontiguousarray(x_full, dtype=float)
        if x_full.shape != (self.model.n_params,):
            raise ValueError(f"expected {self.model.n_params} parameters, got shape {x_full.shape}")
        if self.backend == "numpy":
            return self._numpy_jacobian(x_full)
        if self._full_buffers is None:
            self._full_buffers = self._pack(full=True)
        J = np.empty((self.n_residuals, self.model.n_params))
        _kernel().jacobian(x_full, *self._full_buffers, J)
        return J

    def _numpy_jacobian(self, x_full: np.ndarray) -> np.ndarray:
        """:func:`optcal.core.oracle.jacobian` at ``x_full``, the last one kept: a fit asks for it twice at the
        centre (the gauge rows, then the observability) and again and again at the solution (the solver's last
        step, the observability, the diagnostics' and the χ² moments' hat matrices, the Cramér-Rao bound). The
        one kept serves the same model, data, context and gauge rows (a view, a shallow copy, shares them) at
        the same bits of x."""
        inputs = (self.model, self.data, self.ctx, self._gauge, self.reference)
        last = getattr(self, "_last_jacobian", None)
        if (last is not None and last[1].tobytes() == x_full.tobytes()
                and all(a is b for a, b in zip(last[0], inputs))):
            return last[2].copy()
        J = oracle.jacobian(self, x_full)
        self._last_jacobian = (inputs, x_full.copy(), J)
        return J.copy()

    def jacobian_full_numpy(self, x_full) -> np.ndarray:
        """:meth:`jacobian_full` through the NumPy model (:func:`optcal.core.oracle.jacobian`)."""
        return oracle.jacobian(self, x_full)

    def jacobian(self, x) -> np.ndarray:
        """Jacobian (m, n) in this view's coordinates; counts one evaluation."""
        self.counter.allow(1)
        self.counter.njev += 1
        self.counter.nfev += 1
        if self._compiled:
            x = np.ascontiguousarray(x, dtype=float)
            if x.shape != (self.n,):
                raise ValueError(f"expected {self.n} coordinates, got shape {x.shape}")
            J = np.empty((self.n_residuals, self.n))
            _kernel().jacobian(x, *self._buffers()[:3], J)
            return J
        J = self.jacobian_full(self.to_full(x)[0])[:, self.free]
        return J * self.halfwidth[self.free] if self.is_normalised else J

    def gradient(self, x) -> np.ndarray:
        """Gradient of the cost, 2 Jᵀ r; counts the residual and the Jacobian."""
        r = self.residuals(x)
        return 2.0 * self.jacobian(x).T @ r

    def rms(self, x_full) -> float:
        return float(np.sqrt(np.mean(self.position_residuals(x_full) ** 2)))
