"""Observability, Cramér-Rao bounds and goodness of fit of a calibration problem.

The norm ‖A‖ does not change when the body frame rotates, so with the norm cost only six of the nine
entries of diag(K)·T are observable (docs/design.md, "Observability and the gauge"): ``seed15`` holds three
unobservable directions, which only the small nonlinear terms tie down. They show up here as near-zero singular values
of the Jacobian, after each column is put in natural units (relative scale change, g, rad, ...), so that the threshold
does not depend on the sensor's output units (the linear algebra is in :mod:`optcal.core.gauge`, which the
problem also uses for its gauge rows).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from optcal.core.gauge import RTOL, n_position_residuals, natural_units, null_space
from optcal.core.problem import CalibrationProblem

__all__ = ["GoodnessOfFit", "Observability", "chi2_moments", "crlb", "floor_estimator", "goodness_of_fit",
           "natural_units", "observability", "projected_crlb", "loss_weights", "hat_values", "PositionDiagnostics",
           "position_diagnostics", "position_sigma", "white_sigma", "ROBUST_LOSSES"]


@dataclass(frozen=True)
class Observability:
    names: tuple[str, ...]
    rank: int
    singular_values: np.ndarray  # of the Jacobian in natural units, relative to the largest
    null_space: np.ndarray  # (p, p - rank) directions in natural units, sparse basis
    rtol: float

    @property
    def n_parameters(self) -> int:
        return len(self.names)

    @property
    def unobservable(self) -> list[list[dict]]:
        """Each unobservable direction as a list of {name, weight} (weights of unit norm, largest first)."""
        out = []
        for v in self.null_space.T:
            idx = [i for i in np.argsort(-np.abs(v)) if abs(v[i]) > 1e-3]
            out.append([{"name": self.names[i], "weight": round(float(v[i]), 6)} for i in idx])
        return out

    def observable_mask(self) -> np.ndarray:
        """True for parameters that the data determine on their own (no weight in any null direction)."""
        if self.null_space.size == 0:
            return np.ones(len(self.names), bool)
        return np.max(np.abs(self.null_space), axis=1) < 1e-3

    def to_dict(self) -> dict:
        return {"rank": self.rank, "n_parameters": self.n_parameters, "unobservable": self.unobservable}

    def describe(self) -> str:
        if self.rank == self.n_parameters:
            return f"all {self.n_parameters} parameters observable (rank {self.rank})"
        lines = [f"rank {self.rank} of {self.n_parameters}: {self.n_parameters - self.rank} unobservable "
                 "direction(s), set by the presets, not by the data:"]
        for d in self.unobservable:
            lines.append("  " + " ".join(f"{w['weight']:+.3f}·{w['name']}" for w in d))
        return "\n".join(lines)


def observability(problem: CalibrationProblem, x_full: np.ndarray | None = None, rtol: float = RTOL) -> Observability:
    """Rank and null space of the residual Jacobian at ``x_full`` (default: the problem's centre).

    A direction is unobservable when its singular value, in natural units, is below ``rtol`` times the
    largest (Fisher information below rtol² of the best-determined direction).
    """
    x = problem.centre if x_full is None else np.asarray(x_full, float)
    rank, rel, null, _ = null_space(problem, x, rtol)
    return Observability(problem.model.names, rank, rel, null, rtol)



def projected_crlb(problem: CalibrationProblem, x_full: np.ndarray, noise_g: float, rtol: float = RTOL,
                   weights: np.ndarray | None = None):
    """Cramér-Rao SDs of every parameter's observable part, the projector onto the observable subspace (in
    natural units), the natural units and the observability (docs/design.md, "Cramér-Rao bound"; studies score against
    it).

    Fisher information JᵀJ/σ² of the position residuals (gauge rows excluded) in natural units; with
    unobservable directions it is projected, P·F·P with P = I − N N⁺ (N the null space), and
    pseudo-inverted (rcond = rtol²), so every SD is finite: that of the parameter's component outside the
    null directions. ``weights`` (one per position residual) weight the information, JᵀWJ/σ² (design.md, "Per-position
    residuals, outliers, the robust loss, what the data determine and weak fits").
    """
    x = np.asarray(x_full, float)
    obs = observability(problem, x, rtol)
    u = natural_units(problem, x)
    J = problem.jacobian_full(x)[: n_position_residuals(problem)] * u
    if weights is not None:
        J = J * np.sqrt(np.asarray(weights, float))[:, None]
    F = J.T @ J / noise_g**2
    P = np.eye(len(u))
    if obs.null_space.size:
        P = P - obs.null_space @ np.linalg.pinv(obs.null_space)
        cov = np.linalg.pinv(P @ F @ P, rcond=rtol**2, hermitian=True)
    else:
        cov = np.linalg.inv(F)
    return np.sqrt(np.clip(np.diag(cov), 0, None)) * u, P, u, obs


def crlb(problem: CalibrationProblem, x_full: np.ndarray | None = None, noise_g: float | None = None,
         rtol: float = RTOL, weights: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Cramér-Rao standard deviations of every parameter, and a mask of those that are observable.

    Noise is white, input-referred, ``noise_g`` (g) per axis on each position's mean, so each norm
    residual has SD noise_g. The bound is :func:`projected_crlb`'s (the gauge the presets fix); parameters
    with weight in an unobservable direction are marked not observable and their SD is NaN. ``weights``
    (one per position residual, e.g. a robust fit's :func:`loss_weights`) weight the Fisher information,
    JᵀWJ/σ²: the covariance that iteratively reweighted least squares reports (docs/design.md, "Per-position
    residuals, outliers, the robust loss, what the data determine and weak fits").
    """
    x = problem.centre if x_full is None else np.asarray(x_full, float)
    sigma = noise_g if noise_g is not None else problem.noise_g
    if sigma is None:
        raise ValueError("crlb needs the noise level: give noise_g or data with n and sx, sy, sz")
    sd, _, _, obs = projected_crlb(problem, x, sigma, rtol, weights)
    mask = obs.observable_mask()
    sd[~mask] = np.nan
    return sd, mask



@dataclass(frozen=True)
class GoodnessOfFit:
    rms_g: float
    cost: float
    dof: int
    noise_g: float  # noise used (given, the RMS of the data's per-position floor, or estimated from the residuals)
    chi2: float | None
    p_value: float | None
    # where the noise comes from: "stated" (given), "measured" (the data's standard error of each mean: χ² is
    # Σ (r_i/σ_i)² over the positions' own floors, docs/noise.md) or "residuals" (no noise known: no test)
    noise_source: str = "residuals"
    estimator: str | None = None  # measured: how the data's floor was found (optcal.core.recording.floor.ESTIMATORS)
    white_noise_g: float | None = None  # measured: the RMS of the white-noise floor σ/√n alone, for comparison
    # measured: the floor's effective degrees of freedom (optcal.core.recording.floor.NoiseFloor.edf); when finite the
    # p-value is the F test's, P(F(dof, floor_dof) > χ²/dof), an estimated variance against an estimated floor
    floor_dof: float | None = None
    # measured with a recording's floor: the mean and the effective degrees of freedom of χ² under the floor's
    # correlated noise (Satterthwaite), against which χ² is judged: χ²/expected ~ F(effective, floor_dof)
    expected_chi2: float | None = None
    effective_dof: float | None = None

    def describe(self) -> str:
        """One line: the noise floor (where from, its value in µg, σ/√n beside a recording's) and the χ² verdict."""
        if self.dof == 0:
            noise = ("" if not np.isfinite(self.noise_g) else
                     f"; standard errors from the noise of the position means, {self.noise_g * 1e6:.4g} µg RMS")
            return f"exact fit: no residual degree of freedom, so no χ² test{noise}"
        if self.chi2 is None:
            return (f"noise floor unknown (no n and sx, sy, sz or se_x, se_y, se_z in the data): residual SD "
                    f"{self.noise_g * 1e6:.4g} µg on {self.dof} dof, no χ² test")
        how = {"allan": "each mean's SD with the sensor's correlated noise (Allan model of the static intervals)",
               "white": "σ/√n, the within-interval scatter", "stated": "the data's se_x, se_y, se_z"}
        src = ("stated" if self.noise_source == "stated" else how.get(self.estimator, str(self.estimator)))
        white = (f"; σ/√n alone {self.white_noise_g * 1e6:.4g} µg" if self.white_noise_g is not None
                 and self.estimator != "white" else "")
        law = ("" if self.expected_chi2 is None else
               f", judged against E = {self.expected_chi2:.3g} on {self.effective_dof:.3g} effective dof"
               + ("" if self.floor_dof is None else f" and the floor's {self.floor_dof:.3g}"))
        return (f"noise floor {self.noise_g * 1e6:.4g} µg RMS ({src}{white}); χ²/dof = {self.chi2 / self.dof:.3g} "
                f"on {self.dof} dof{law}: p = {self.p_value:.2g}")

    def to_dict(self) -> dict:
        return {k: getattr(self, k) for k in ("rms_g", "cost", "dof", "noise_g", "chi2", "p_value", "noise_source",
                                              "estimator", "white_noise_g", "floor_dof", "expected_chi2",
                                              "effective_dof")}


def floor_estimator(data) -> str | None:
    """How the standard errors of ``data``'s means were found: the estimator of the recording's noise floor
    (a key of :data:`optcal.core.recording.floor.ESTIMATORS`), "stated" for se_x, se_y, se_z read from a file, "white"
    for sx, sy, sz over √n, None without them."""
    if data.sem is not None:
        floor = data.extra.get("noise_floor") if isinstance(data.extra, dict) else None
        return getattr(floor, "estimator", "stated")
    return "white" if data.noise_of_mean() is not None else None


def goodness_of_fit(problem: CalibrationProblem, x_full: np.ndarray, noise_g: float | None = None) -> GoodnessOfFit:
    """Residual RMS, and χ² with its p-value when the noise is known: Σ r²/σ² with ``noise_g`` or a stated
    noise level, Σ (r_i/σ_i)² with each position's own floor when the noise comes from the data
    (:func:`position_sigma`: the standard error of each mean, correlated noise included when the data have
    se_x, se_y, se_z). With a recording's floor (:class:`optcal.core.recording.floor.NoiseFloor`) the means' noise is
    correlated and the floor estimated: χ² is judged by its mean E and effective degrees of freedom ν under
    that noise (:func:`chi2_moments`) and by the floor's degrees of freedom ``edf``, p = P(F(ν, edf) > χ²/E),
    which is the χ² test's P(χ²_dof > χ²) for white noise and a floor of many degrees of freedom
    (docs/noise.md)."""
    from optcal.core.distributions import chi2_sf, f_sf

    x = np.asarray(x_full, float)
    r = problem.position_residuals(x)
    obs = observability(problem, x)
    if len(r) <= obs.rank:  # an exact fit: no residual left to test, the means' noise alone gives the errors
        return _exact_fit(problem, x, float(np.sqrt(np.mean(r**2))), float(r @ r), noise_g)
    dof = max(len(r) - obs.rank, 1)
    cost = float(r @ r)
    rms = float(np.sqrt(np.mean(r**2)))
    if noise_g is None and problem.noise_g is not None and problem.noise_from_data:
        sig = position_sigma(problem, x)
        chi2 = float(np.sum((r / sig) ** 2))
        white = white_sigma(problem, x) if problem.data.sem is not None else sig
        floor = problem.data.extra.get("noise_floor") if isinstance(problem.data.extra, dict) else None
        if problem.data.sem is None or floor is None or floor.sem.shape != problem.data.sem.shape:
            floor = None
        edf = None if floor is None or not np.isfinite(floor.edf) else float(floor.edf)
        mom = None if floor is None else chi2_moments(problem, x, sig, floor)
        expected, nu = mom if mom is not None else (float(dof), float(dof))
        p = float(f_sf(chi2 / expected, nu, edf) if edf is not None else chi2_sf(chi2 * nu / expected, nu))
        w_rms = None if white is None else float(np.sqrt(np.mean(white**2)))
        return GoodnessOfFit(rms, cost, dof, float(np.sqrt(np.mean(sig**2))), chi2, p, "measured",
                             floor_estimator(problem.data), w_rms, edf, *((expected, nu) if mom else (None, None)))
    sigma = noise_g if noise_g is not None else problem.noise_g
    if sigma is None:
        return GoodnessOfFit(rms, cost, dof, float(np.sqrt(cost / dof)), None, None)
    chi2 = cost / sigma**2
    return GoodnessOfFit(rms, cost, dof, float(sigma), chi2, float(chi2_sf(chi2, dof)), "stated")


def _exact_fit(problem: CalibrationProblem, x: np.ndarray, rms: float, cost: float, noise_g) -> GoodnessOfFit:
    """The goodness of fit of an exact fit (as many residuals as determined parameters, dof 0): no χ², the noise of
    the position means as the data give it (or as stated) for the standard errors, NaN when nothing gives it."""
    if noise_g is None and problem.noise_g is not None and problem.noise_from_data:
        sig = position_sigma(problem, x)
        return GoodnessOfFit(rms, cost, 0, float(np.sqrt(np.mean(sig**2))), None, None, "measured",
                             floor_estimator(problem.data))
    sigma = noise_g if noise_g is not None else problem.noise_g
    return GoodnessOfFit(rms, cost, 0, float("nan") if sigma is None else float(sigma), None, None,
                         "residuals" if sigma is None else "stated")


def chi2_moments(problem: CalibrationProblem, x_full: np.ndarray, sigma: np.ndarray, floor) -> tuple[float, float]:
    """Mean and Satterthwaite degrees of freedom of χ² = Σ (r_i/σ_i)² when the position means carry the
    correlated noise of a recording's floor (:meth:`optcal.core.recording.floor.NoiseFloor.covariance`, per axis): with
    r = (I − H)e to first order (H the hat matrix of :func:`_hat_factor`), e the means' noise as residuals
    (Σ_e = Σ_k D_k Σ^k D_k / K_k², D_k the specific force's direction cosines; per axis with a reference) and
    W = diag(1/σ²), E χ² = tr(W M Σ_e M) and Var χ² = 2 tr((W M Σ_e M)²), M = I − H; the degrees of freedom
    are 2 (E χ²)² / Var χ² (Satterthwaite 1946; Box 1954). For white noise they are m − rank."""
    x = np.asarray(x_full, float)
    n = len(problem.data)
    K = problem._K0
    if problem.reference:
        S = np.zeros((3 * n, 3 * n))
        for k in range(3):
            S[k::3, k::3] = floor.covariance(k) / K[k] ** 2
    else:
        A = problem.specific_force(x)
        u = A / np.linalg.norm(A, axis=1, keepdims=True)
        S = sum(np.outer(u[:, k], u[:, k]) * floor.covariance(k) / K[k] ** 2 for k in range(3))
    U, _ = _hat_factor(problem, x)
    M = np.eye(len(U)) - U @ U.T  # dense: the floor's covariance S is too (a raw recording's few positions)
    Q = (M @ S @ M) / np.asarray(sigma, float)[:, None] ** 2
    expected = float(np.trace(Q))
    return expected, float(2.0 * expected**2 / (2.0 * np.sum(Q * Q.T)))


# -- per-position residuals, outliers and robust weights (docs/design.md, "Per-position residuals, outliers, the
# robust loss, what the data determine and weak fits") -----------------------------

# SciPy least_squares' robust losses ρ(z), z = (r / f_scale)², and their derivative ρ'(z), which is the weight
# of a residual in the iteratively reweighted least-squares view of the fit (Holland & Welsch 1977).
ROBUST_LOSSES = ("linear", "soft_l1", "huber", "cauchy", "arctan")
# Family-wise probability that a clean data set flags a position (Šidák-corrected per position).
OUTLIER_ALPHA = 0.01


def loss_weights(r: np.ndarray, loss: str, f_scale: float) -> np.ndarray:
    """ρ'(z) of SciPy's ``loss`` at z = (r/f_scale)²: 1 for ``linear``, below 1 for residuals beyond f_scale."""
    z = (np.asarray(r, float) / f_scale) ** 2
    if loss == "linear":
        return np.ones_like(z)
    if loss == "soft_l1":
        return 1.0 / np.sqrt(1.0 + z)
    if loss == "huber":
        return np.where(z <= 1.0, 1.0, 1.0 / np.sqrt(np.maximum(z, 1.0)))
    if loss == "cauchy":
        return 1.0 / (1.0 + z)
    if loss == "arctan":
        return 1.0 / (1.0 + z**2)
    raise ValueError(f"unknown loss {loss!r}; one of {', '.join(ROBUST_LOSSES)}")


def _hat_factor(problem: CalibrationProblem, x_full: np.ndarray, weights=None) -> tuple[np.ndarray, int]:
    """The hat matrix W½J(JᵀWJ)⁺JᵀW½ of the position residuals (J in natural units, over the directions with
    relative singular value above RTOL) as its factor U (m, rank), H = UUᵀ, and the residual degrees of freedom,
    m − rank. The factor, not H: H is m × m, and a file of thousands of positions made it gigabytes and its
    uses minutes, where U has a column per parameter."""
    u = natural_units(problem, x_full)
    J = problem.jacobian_full(np.asarray(x_full, float))[: n_position_residuals(problem)] * u
    if weights is not None:
        J = J * np.sqrt(np.asarray(weights, float))[:, None]
    U, s, _ = np.linalg.svd(J, full_matrices=False)
    keep = s > RTOL * s[0]
    return U[:, keep], len(J) - int(keep.sum())


def hat_values(problem: CalibrationProblem, x_full: np.ndarray, weights: np.ndarray | None = None) -> np.ndarray:
    """Leverage h of each position residual: the diagonal of the hat matrix (Hoaglin & Welsch 1978). A
    residual with h near 1 is fitted by its own parameters and cannot show an error; Σh is the rank."""
    return np.clip(_leverages(_hat_factor(problem, x_full, weights)[0]), 0.0, 1.0)


def _leverages(U: np.ndarray) -> np.ndarray:
    """The diagonal of H = UUᵀ."""
    return np.einsum("ij,ij->i", U, U)


def _residual_sigma(problem: CalibrationProblem, x_full: np.ndarray, sm: np.ndarray) -> np.ndarray:
    """Per-axis SDs of the position means ``sm`` (n, 3, output units) as the SD of each position residual (g):
    per axis sm/K0; for the norm residual the axes combine along the specific force's direction,
    σ_i² = Σ_k (A_k/‖A‖)² σ_ik² (first order); a zero SD takes its axis's median."""
    s = np.array(sm, float) / problem._K0
    # an axis whose samples did not change (quantised output) has a sample SD of 0, which is no noise level:
    # it takes the median of that axis's other positions
    for k in range(3):
        pos = s[:, k] > 0
        if pos.any() and not pos.all():
            s[~pos, k] = np.median(s[pos, k])
    if problem.reference:
        return s.ravel()
    A = problem.specific_force(x_full)
    w = A / np.linalg.norm(A, axis=1, keepdims=True)
    return np.sqrt(np.sum((w * s) ** 2, axis=1))


def position_sigma(problem: CalibrationProblem, x_full: np.ndarray) -> np.ndarray | None:
    """Noise SD (g) of each position residual from the data's standard error of each mean
    (:meth:`~optcal.core.data.PositionsData.noise_of_mean`: se_x, se_y, se_z, correlated noise included, or else
    sx, sy, sz over √n; docs/design.md, "Uncertainty: Cramér-Rao bounds, goodness of fit, standard errors",
    docs/noise.md) through :func:`_residual_sigma`. None when the data
    lack them."""
    sm = problem.data.noise_of_mean()
    return None if sm is None else _residual_sigma(problem, x_full, sm)


def white_sigma(problem: CalibrationProblem, x_full: np.ndarray) -> np.ndarray | None:
    """As :func:`position_sigma` with the white-noise floor alone, sx, sy, sz over √n (None without them)."""
    d = problem.data
    if d.std is None or d.n_samples is None:
        return None
    return _residual_sigma(problem, x_full, d.std / np.sqrt(d.n_samples)[:, None])


@dataclass(frozen=True)
class PositionDiagnostics:
    """Per-position residuals with their noise, leverage and outlier test (docs/design.md, "Per-position residuals,
    outliers, the robust loss, what the data determine and weak fits")."""

    index: np.ndarray  # (n,) row of the data, from 0
    position: np.ndarray  # (n,) the data's position numbers
    labels: list  # (n,) str or None
    residual_g: np.ndarray  # (n,) signed norm residual, or the 3-axis misfit's length with a reference
    noise_g: np.ndarray  # (n,) noise SD of that residual, or the scale used when no noise is known
    leverage: np.ndarray  # (n,) hat value (largest of the three axes with a reference)
    statistic: np.ndarray  # (n,) |residual| / (σ·√(1−h)), in σ; NaN where h ≈ 1
    p_value: np.ndarray  # (n,) two-sided, NaN where untested
    weight: np.ndarray  # (n,) robust weight ρ'(z) (1 in a plain fit)
    outlier: np.ndarray  # (n,) bool
    off: np.ndarray  # (n,) residual of the fit without the outliers; an outlier's prediction error from the rest
    threshold: float  # the statistic's flagging threshold, in σ
    alpha: float  # per-position test level (Šidák)
    sigma_source: str  # "stated", "measured", "robust scale" or "leave-one-out"
    tested: bool  # False when the residuals cannot be tested (too few degrees of freedom)
    unchecked: np.ndarray | None = None  # (n,) bool: alone pins part of the model, not tested (:func:`_unchecked`)
    pose: np.ndarray | None = None  # (n,) the pose each position belongs to (:func:`pose_groups`)
    force_g: np.ndarray | None = None  # (n, 3) each position's calibrated specific force, g
    unchecked_pose: np.ndarray | None = None  # (n,) bool: its pose, of several positions, alone pins part of the
    # model (:func:`_unchecked_poses`): the positions are tested against each other, the pose by no other

    def rows(self) -> list[dict]:
        """One dict per position, keys naming their units (the calibration's ``positions``)."""
        def num(v, nd=6):
            return None if not np.isfinite(v) else round(float(v), nd)
        return [{"index": int(i), "position": int(p), "label": lab, "residual_ug": num(r * 1e6, 3),
                 "sigma_ug": num(s * 1e6, 3), "standardised": num(r / s if s > 0 else np.nan, 3),
                 "leverage": num(h, 4), "statistic_sigma": num(t, 3), "p_value": num(pv, 8),
                 "weight": num(w, 4), "outlier": bool(o), "off_ug": num(f * 1e6, 3)}
                for i, p, lab, r, s, h, t, pv, w, o, f in zip(
                    self.index, self.position, self.labels, self.residual_g, self.noise_g, self.leverage,
                    self.statistic, self.p_value, self.weight, self.outlier, self.off)]

    def name(self, i: int) -> str:
        lab = self.labels[i]
        return f"position {int(self.position[i])}" + (f" (label {lab})" if lab not in (None, "") else "")


def _labels(data) -> list:
    extra = data.extra if isinstance(data.extra, dict) else {}
    if isinstance(extra.get("label"), list | tuple) and len(extra["label"]) == len(data):
        return [str(v) for v in extra["label"]]
    det = extra.get("detection")
    names = getattr(det, "names", None)
    if names is not None and len(names) == len(data):
        return [str(v) for v in names]
    return [None] * len(data)


GROUP_BLOCK = 512  # positions whose neighbours pose_groups finds at a time
POSE_GROUP_DEG = 1.0  # positions whose specific forces lie within this angle of each other are one pose (a rest
# split by a drift or a knock): together they can pin part of the model as a lone position does


def pose_groups(A: np.ndarray, deg: float = POSE_GROUP_DEG) -> np.ndarray:
    """A group number per position (n,) of the specific forces ``A`` (n, 3): positions joined when their
    directions lie within ``deg`` of each other, and through chains of such positions (single linkage): each
    position takes the least group number among its neighbours, and each number the number of the position it
    names (pointer jumping, so a long chain takes a few rounds), until nothing changes. The neighbours are found
    :data:`GROUP_BLOCK` rows at a time: a file of thousands of samples never makes an n × n array."""
    u = A / np.maximum(np.linalg.norm(A, axis=1, keepdims=True), 1e-300)
    n = len(u)
    cos = np.cos(np.radians(deg))
    group = np.arange(n)
    while True:
        new = np.empty_like(group)
        for i in range(0, n, GROUP_BLOCK):
            near = (u[i:i + GROUP_BLOCK] @ u.T) >= cos
            new[i:i + GROUP_BLOCK] = np.min(np.where(near, group[None, :], n), axis=1)
        while not np.array_equal(new[new], new):
            new = new[new]
        if np.array_equal(new, group):
            return group
        group = new


def _unchecked(h: np.ndarray, sig: np.ndarray, d: int) -> np.ndarray:
    """Positions (n,) that alone pin part of the model, so that the others cannot check them: the linear
    downdate of the outlier test predicts a position from the others with SD σ_p = σ/√(1−h) (h its leverage, σ
    its residual's noise in g), and the magnitude's curvature adds about ½σ_p² to its residual, which must stay
    under the residual's own SD σ√(1−h): untested where 1 − h ≤ (σ/2)^(2/3) (a leverage above 0.9997 at 10 µg of
    noise, 0.9991 at 57 µg: there a residual of a few µg reads as many σ and a prediction error of grams).
    ``h``: the leverages (m,)."""
    with np.errstate(invalid="ignore"):
        bad = (1.0 - h) <= (np.abs(np.asarray(sig, float)) / 2.0) ** (2.0 / 3.0)
    return bad.reshape(-1, d).any(axis=1)


def _unchecked_poses(U: np.ndarray, sig: np.ndarray, d: int, groups: np.ndarray) -> np.ndarray:
    """Positions (n,) of poses of several positions (``groups``, :func:`pose_groups`) that together alone pin part
    of the model, by the criterion of :func:`_unchecked` on the least eigenvalue of I − H over their rows (1 − h
    for a lone position): two halves of one rest that alone sees an axis upside down pin its scale factor and
    offset as one position would (leverages 0.499 and 0.501). Each position is still tested against the others
    (its sibling predicts it); what no other pose can check is an error of the pose as a whole. ``U``: the hat
    matrix's factor (:func:`_hat_factor`)."""
    sig = np.abs(np.asarray(sig, float))
    out = np.zeros(len(groups), bool)
    for g in np.unique(groups[np.bincount(groups)[groups] > 1]):  # the poses of several positions (few)
        rows = (np.flatnonzero(groups == g)[:, None] * d + np.arange(d)).ravel()
        # the least eigenvalue of I − H over the rows, 1 − (the largest singular value of U's rows)²: a pose of
        # thousands of positions (a file of samples) is an SVD of (rows, rank), not an eigenproblem of rows²
        least = 1.0 - float(np.linalg.norm(U[rows], 2)) ** 2
        out[groups == g] = least <= (float(np.min(sig[rows])) / 2.0) ** (2.0 / 3.0)
    return out


def _scan(r, U, sigma, d, dof, alpha1, sequential):
    """Backward outlier scan (Belsley, Kuh & Welsch 1980, §2.1, repeated): the position whose deletion
    residual is least plausible is set aside while its p-value is below ``alpha1``, and the others are judged
    on the fit without the set-aside ones (the linear downdate r + H_·D (I − H_DD)⁻¹ r_D). ``sigma`` per
    residual, or None: then σ is the RMS of the fit without the set-aside positions and the candidate
    (externally studentised, Student's t / F). Returns the set-aside positions, each position's statistic
    (in σ), p-value, its prediction error from the other positions (g) and the noise used (per residual).
    ``U``: the hat matrix's factor (:func:`_hat_factor`); H's blocks are formed only over the set-aside rows."""
    from optcal.core.distributions import chi2_sf, f_sf

    m = len(r)
    n = m // d
    h = _leverages(U)
    starts = np.arange(0, m, d)

    def p_values(qv, nu):  # p-values of the positions' statistics, with nu residual degrees of freedom
        if sigma is not None:
            return chi2_sf(qv, d)
        if nu - d < 1:
            return np.full(len(qv), np.nan)
        with np.errstate(invalid="ignore"):
            return f_sf(qv / d, d, nu - d)

    D: list[int] = []
    while True:
        rows = np.array([k for i in D for k in range(i * d, i * d + d)], int)
        if rows.size:
            # the downdate through the factor (Woodbury): with G = U_Dᵀ U_D, (I − H_DD)⁻¹ = I + U_D (I − G)⁻¹ U_Dᵀ,
            # and H + H_·D (I − H_DD)⁻¹ H_D· = U (I − G)⁻¹ Uᵀ; nothing of size m × |D| or |D| × |D|
            UD = U[rows]
            B = np.linalg.inv(np.eye(U.shape[1]) - UD.T @ UD)
            t = B @ (UD.T @ r[rows])
            rr = r + U @ t
            hh = np.einsum("ij,ij->i", U @ B, U)
            eD = r[rows] + UD @ t  # the set-aside positions' prediction errors from the others, (I − H_DD)⁻¹ r_D
        else:
            rr, hh = r, h
        with np.errstate(divide="ignore", invalid="ignore"):
            e2 = np.where(hh < 1 - 1e-9, rr**2 / (1.0 - hh), np.nan)
        keep = np.ones(m, bool)
        keep[rows] = False
        nu = dof - rows.size
        if sigma is None:
            rss = float(np.sum(rr[keep] ** 2))
            per = np.add.reduceat(np.where(keep, e2, 0.0), starts)
            s2 = np.clip(rss - per, 0.0, None) / max(nu - d, 1)
            sig = np.repeat(np.sqrt(s2), d)
            with np.errstate(divide="ignore", invalid="ignore"):  # s = 0: no degrees of freedom left
                q = np.add.reduceat(e2 / sig**2, starts)
        else:
            sig = sigma
            q = np.add.reduceat(e2 / sig**2, starts)
        q[_unchecked(hh, sig, d)] = np.nan
        # the candidates: tested positions not set aside (all untested when no degree of freedom is left)
        cand = np.isfinite(q)
        cand[D] = False
        if sigma is None and nu - d < 1:
            cand[:] = False
        cand = np.flatnonzero(cand)
        stop = not sequential or not len(cand) or len(D) >= n // 2 or (sigma is None and nu - 2 * d < 1)
        if not stop:  # the least plausible is the largest statistic (p-values underflow to 0 together)
            j = int(cand[np.argmax(q[cand])])
            stop = p_values(q[j:j + 1], nu)[0] >= alpha1
        if stop:  # p-values only now, for every position: the scan needs the worst one's alone
            pv = np.where(np.isfinite(q), p_values(q, nu), np.nan)
            if D:  # the set-aside positions, judged by their prediction errors from the others
                sD = np.full(rows.size, np.sqrt(rss / max(nu, 1))) if sigma is None else sigma[rows]
                qD = (eD**2 / ((1.0 + hh[rows]) * sD**2)).reshape(-1, d).sum(axis=1)
                q[D] = qD
                pv[D] = f_sf(qD / d, d, max(nu, 1)) if sigma is None else chi2_sf(qD, d)
                sig = sig.copy()
                sig[rows] = sD
            break
        D.append(j)
    off = rr.copy()
    if D:
        off[rows] = eD
    return D, np.sqrt(q), pv, off, sig


def position_diagnostics(problem: CalibrationProblem, x_full: np.ndarray, noise_g: float | None = None,
                         weights: np.ndarray | None = None, f_scale: float | None = None,
                         alpha: float = OUTLIER_ALPHA) -> PositionDiagnostics:
    """Each position's residual against its noise, and which positions are outliers.

    The noise σ_i is ``noise_g`` when given (stated), else the data's per-position noise (measured,
    :func:`position_sigma`), else, for a robust fit, its ``f_scale``, else it is estimated from the residuals
    of the other positions (leave-one-out). A residual r has SD σ·√(1−h) (h its leverage, :func:`hat_values`),
    so a position's statistic is |r|/(σ√(1−h)), tested against the normal (χ² with 3 degrees of freedom with a
    reference) or, with σ estimated, Student's t (F). A plain fit spreads a displaced position over the
    others, so the plain fit's positions are scanned backwards (:func:`_scan`): the worst is set aside and the
    rest judged without it. The per-position level is Šidák's α₁ = 1 − (1 − ``alpha``)^(1/n), so a clean
    data set flags none with probability about 1 − alpha.
    """
    x = np.asarray(x_full, float)
    r = problem.position_residuals(x)
    d = problem.rows_per_position
    n = len(problem.data)
    w = np.ones(len(r)) if weights is None else np.asarray(weights, float)
    U, dof = _hat_factor(problem, x, weights)
    alpha1 = 1.0 - (1.0 - alpha) ** (1.0 / n)
    if noise_g is not None:
        sig, source = np.full(len(r), float(noise_g)), "stated"
    elif (ps := position_sigma(problem, x)) is not None:
        sig, source = ps, "measured"
    elif weights is not None and f_scale is not None:
        sig, source = np.full(len(r), float(f_scale)), "robust scale"
    else:
        sig, source = None, "leave-one-out"
    D, stat, pv, off, sig = _scan(r, U, sig, d, dof, alpha1, sequential=weights is None)
    out = np.zeros(n, bool)
    out[D] = True
    if weights is not None:
        out = np.isfinite(pv) & (pv < alpha1)
    tested = bool(np.any(np.isfinite(pv)))
    h = _leverages(U)
    from optcal.core.distributions import chi2_isf, norm_isf, t_isf

    if d == 1:
        thr = (float(t_isf(alpha1 / 2, max(dof - 2, 1))) if source == "leave-one-out"
               else float(norm_isf(alpha1 / 2)))
        res, sg, lev, wt, offp = r, sig, h, w, off
    else:
        thr = float(np.sqrt(chi2_isf(alpha1, 3)))
        res = np.linalg.norm(r.reshape(n, 3), axis=1)
        offp = np.linalg.norm(off.reshape(n, 3), axis=1)
        sg = np.sqrt(np.mean(sig.reshape(n, 3) ** 2, axis=1))
        lev, wt = h.reshape(n, 3).max(axis=1), w.reshape(n, 3).min(axis=1)
    groups = pose_groups(problem.specific_force(x))
    return PositionDiagnostics(np.arange(n), np.asarray(problem.data.position), _labels(problem.data), res, sg,
                               lev, stat, pv, wt, out, offp, thr, alpha1, source, tested,
                               _unchecked(h, sig, d), groups, problem.specific_force(x) / problem.g_local,
                               _unchecked_poses(U, sig, d, groups))


def noise_scale(problem: CalibrationProblem, x_full: np.ndarray, alpha: float = OUTLIER_ALPHA) -> float:
    """The noise SD (g) of the position residuals estimated from a plain fit at ``x_full`` with its outliers
    set aside (:func:`_scan`, σ unknown): √(RSS/dof) of the fit without them; the robust loss's default
    ``f_scale`` when no noise is known (docs/design.md, "Per-position residuals, outliers, the robust loss, what the
    data determine and weak fits")."""
    x = np.asarray(x_full, float)
    r = problem.position_residuals(x)
    d = problem.rows_per_position
    U, dof = _hat_factor(problem, x)
    D, _, _, off, _ = _scan(r, U, None, d, dof, 1.0 - (1.0 - alpha) ** (1.0 / len(problem.data)), True)
    keep = np.ones(len(r), bool)
    for i in D:
        keep[i * d: i * d + d] = False
    return float(np.sqrt(np.sum(off[keep] ** 2) / max(dof - d * len(D), 1)))
