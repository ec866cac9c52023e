"""Residual diagnostics (docs/discovery.md, "Residual diagnostics"): what the residuals of a fit still follow,
each against the recording's own floor. Core: nothing here runs a solver.

The remaining norm residuals are set against each thing a position carries:

* **orientation**: the monomials of the measured direction â up to degree 4 (per-axis polynomials; on the
  unit sphere they span the same functions as the real spherical harmonics of degrees 0–4; degree 4 is how the
  dictionary's third-order features look through the norm), to degree 3 or 2 when the residuals' degrees of
  freedom are few;
* **temperature**: â_i·θ^k (a bias of each axis as a polynomial in θ = (T − T̄)/scale, k = 1–3) and
  â_i·θ·A_i (scale factors changing with temperature);
* **time**: â_i·τ^k (bias trends in τ = (t − t0)/scale, k = 1–3) and **periodicity**: the Lomb–Scargle
  periodogram (scipy.signal.lombscargle; Lomb 1976, Scargle 1982, the weighted form of Zechmeister & Kürster
  2009) of the residuals and of each axis' share of them (weights â_i², values e/â_i, so that the periodogram
  is the least-squares fit e ≈ â_i·(a·sin ωt + b·cos ωt)); its highest peak tested with the false-alarm
  probability 1 − (1 − p)^M over M = 4 × the independent frequencies searched (Horne & Baliunas 1986);
* **order**: â_i·sgn(A_k of the previous pose), the hysteresis of output i by the load on axis k before;
* **duration**: â_i·(d/d̄ − 1) and â_i·(d̄/d − 1), with d each position's number of samples.

Each set of columns is made orthogonal to the fitted model's Jacobian (what the model would absorb) and its
reduction of the residual sum of squares tested at the floor (:class:`Floor`): with known noise σ_j, the
reduction of χ² = Σ(e_j/σ_j)² is χ²(q) under a correct model; with replicates (poses held twice), the
F-test against their pure-error scatter; and in every case also against the residual scatter that remains, so
that a large misfit of another kind does not make every diagnostic significant (:func:`column_test`); without
a floor only the latter, and the report says what to record. A diagnostic is significant below α/k, k the
diagnostics tested.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from optcal.core.discovery.dictionary import RANK_RTOL, model_basis, nice_scale, project_out
from optcal.core.distributions import chi2_sf, f_sf
from optcal.core.terms import SAME_POSE_DEG, previous_signs

REPLICATE_DEG = SAME_POSE_DEG  # positions whose directions lie within this angle are replicates of one pose
# Fewer degrees of freedom of pure error make no floor: its own scatter (χ² on so few) would decide the verdict
MIN_REPLICATE_DOF = 4
OVERSAMPLE = 10  # frequencies per independent one in the periodogram
ORIENTATION_DEGREE = 4
MIN_TEST_DOF = 10
WHAT_TO_RECORD = ("record the poses from a raw recording (each position then carries n and its standard errors), "
                  "give --noise-ug, or hold some poses twice (within 2°) so that their scatter gives the floor")


@dataclass
class Floor:
    """What a residual is judged against: known noise σ_j (stated or the data's), or the pure-error scatter of
    replicated poses, or nothing (then the residual scatter itself, and what to record)."""

    kind: str | None  # "stated" | "data" | "replicates" | None
    sigma: np.ndarray | None = None  # σ_j, g
    pure_ss: float = 0.0  # Σ over replicate groups of the squared deviations from the group's mean, g²
    pure_dof: int = 0
    groups: list = field(default_factory=list)

    @property
    def rms_g(self) -> float | None:
        if self.sigma is not None:
            return float(np.sqrt(np.mean(self.sigma**2)))
        if self.kind == "replicates":
            return float(np.sqrt(self.pure_ss / self.pure_dof))
        return None

    def describe(self) -> str:
        if self.kind in ("stated", "data"):
            return f"the {'stated' if self.kind == 'stated' else 'data’s'} noise floor σ = {self.rms_g * 1e6:.3f} µg"
        if self.kind == "replicates":
            return (f"the scatter of {len(self.groups)} replicated pose(s) ({self.pure_dof} degrees of freedom): "
                    f"σ = {self.rms_g * 1e6:.3f} µg")
        return "no floor (no noise information, no replicated poses): " + WHAT_TO_RECORD

    def to_dict(self) -> dict:
        return {"kind": self.kind, "sigma_g": self.rms_g, "replicate_groups": len(self.groups),
                "pure_error_dof": self.pure_dof, "what_to_record": None if self.kind else WHAT_TO_RECORD}


def replicate_groups(A: np.ndarray, max_deg: float = REPLICATE_DEG) -> list[np.ndarray]:
    """Groups of two or more positions whose directions lie within ``max_deg`` of each other (connected
    components of that relation; scipy.sparse.csgraph)."""
    u = A / np.linalg.norm(A, axis=1, keepdims=True)
    close = (u @ u.T) >= np.cos(np.radians(max_deg))
    if close.sum() == len(u):  # only each position with itself: no replicates (and no scipy to import)
        return []
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import connected_components

    _, label = connected_components(csr_matrix(close), directed=False)
    return [g for g in (np.flatnonzero(label == k) for k in range(label.max() + 1)) if len(g) > 1]


def floor_of(fit, sigma_j: np.ndarray | None, stated: bool) -> Floor:
    """The floor for ``fit``'s residuals: σ_j when known, else the replicates' pure error, else none."""
    if sigma_j is not None:
        return Floor("stated" if stated else "data", sigma=np.asarray(sigma_j, float))
    n = fit.problem.n_position_residuals
    r = fit.residuals[:n]
    groups = replicate_groups(fit.specific_force)
    dof = sum(len(g) - 1 for g in groups)
    if dof >= MIN_REPLICATE_DOF:
        ss = float(sum(np.sum((r[g] - r[g].mean()) ** 2) for g in groups))
        if ss > 0:
            return Floor("replicates", pure_ss=ss, pure_dof=dof, groups=groups)
    return Floor(None)


def lack_of_fit(fit, floor: Floor) -> tuple[float, int, int, float] | None:
    """The lack-of-fit F-test against replicates (Draper & Smith, Applied Regression Analysis, §2.1):
    F = ((RSS − SS_pe)/(dof − dof_pe)) / (SS_pe/dof_pe); (F, dof − dof_pe, dof_pe, p) or None."""
    if floor.kind != "replicates":
        return None
    n = fit.problem.n_position_residuals
    r = fit.residuals[:n]
    dof = n - fit.rank
    q = dof - floor.pure_dof
    if q < 1:
        return None
    f = max(float(r @ r) - floor.pure_ss, 0.0) / q / (floor.pure_ss / floor.pure_dof)
    return f, q, floor.pure_dof, float(f_sf(f, q, floor.pure_dof))


@dataclass
class Diagnostic:
    """One diagnostic: the residuals against one thing the positions carry."""

    name: str
    columns: str  # what was regressed on
    q: int = 0
    statistic: float = float("nan")
    test: str = ""  # "chi2" | "F"
    dof: int | None = None
    p_value: float = float("nan")
    significant: bool = False
    note: str = ""
    x: np.ndarray | None = None  # the abscissa of its figure panel
    fitted: np.ndarray | None = None  # the residuals' part its columns explain, g
    extra: dict = field(default_factory=dict)

    @property
    def tested(self) -> bool:
        return not self.note

    def to_dict(self) -> dict:
        from optcal.core.discovery.statistics import num

        d = {"name": self.name, "columns": self.columns, "tested": self.tested}
        if self.tested:
            d.update(q=self.q, statistic=num(self.statistic), test=self.test, dof=self.dof,
                     p_value=num(self.p_value), significant=self.significant)
        else:
            d["note"] = self.note
        for k, v in self.extra.items():
            if k in ("period_s", "false_alarm", "n_independent", "series", "p_single", "p_floor", "p_residual"):
                d[k] = num(v) if isinstance(v, float) else v
        return d


@dataclass
class Diagnostics:
    items: list[Diagnostic]
    floor: Floor
    alpha: float
    periodogram: dict | None = None  # freqs (Hz) and the powers of each series, for the figure

    @property
    def significant(self) -> list[Diagnostic]:
        return [d for d in self.items if d.significant]

    def get(self, name: str) -> Diagnostic | None:
        return next((d for d in self.items if d.name == name), None)

    def to_dict(self) -> dict:
        return {"floor": self.floor.to_dict(), "alpha": self.alpha, "k": sum(d.tested for d in self.items),
                "items": [d.to_dict() for d in self.items]}

    def summary(self) -> str:
        tested = [d for d in self.items if d.tested]
        parts = []
        for d in tested:
            extra = f" at {d.extra['period_s']:.4g} s" if "period_s" in d.extra else ""
            parts.append(f"{d.name}{extra} p = {d.p_value:.2g}{' (significant)' if d.significant else ''}")
        skipped = [f"{d.name} ({d.note})" for d in self.items if not d.tested]
        text = "; ".join(parts) if parts else "none testable"
        return text + ("; not tested: " + "; ".join(skipped) if skipped else "")


def _weighted(fit, floor: Floor, G: np.ndarray):
    """(residuals, model basis, columns) weighted by 1/σ_j when the floor knows σ_j."""
    n = fit.problem.n_position_residuals
    r = fit.residuals[:n]
    if floor.sigma is None:
        return r, model_basis(fit), G
    from optcal.core.gauge import natural_units

    s = floor.sigma
    J = fit.problem.jacobian_full(fit.x)[:n] * natural_units(fit.problem, fit.x) / s[:, None]
    U, _, _ = np.linalg.svd(J, full_matrices=False)
    return r / s, U[:, :fit.rank], G / s[:, None]


@dataclass
class ColumnTest:
    """The residuals regressed on a set of columns (:func:`column_test`)."""

    q: int  # the columns' rank beyond the model
    statistic: float  # χ² reduction (known σ_j) or F
    test: str  # "chi2" | "F" | "" (nothing to test)
    dof: int | None  # the F-test's denominator degrees of freedom
    p: float  # the larger of p_floor and p_residual (p_residual alone without a floor)
    p_floor: float | None  # against the floor
    p_residual: float  # against the residual scatter that remains
    fitted: np.ndarray  # the residuals' part the columns explain, g


def column_test(fit, floor: Floor, G: np.ndarray) -> ColumnTest:
    """The residuals of ``fit`` regressed on ``G`` (n, c) orthogonal to the model (module docstring). The p-value
    is the larger of two: the reduction against the floor (χ²(q) with known σ_j, or the F-test against the
    replicates' pure error) and against the residual scatter that remains (the F-test of q columns on
    n − p − q degrees of freedom). The first asks whether the columns explain more than noise; the second
    whether they explain more than any q directions would of a residual that is larger than the noise for
    another reason, which keeps a diagnostic specific when some other structure remains. Without a floor only
    the second applies."""
    r, Q, Gw = _weighted(fit, floor, G)
    Gp = project_out(Q, Gw)
    U, s, _ = np.linalg.svd(Gp, full_matrices=False)
    # directions the columns add beyond the model with less than RANK_RTOL of their size do not count (the
    # dictionary's rule: such a leftover is the model's nonlinearity, lined up with the residual)
    keep = s > RANK_RTOL * max(float(np.max(np.linalg.norm(Gw, axis=0), initial=0.0)), np.finfo(float).tiny)
    U = U[:, keep]
    q = int(keep.sum())
    r = project_out(Q, r[:, None])[:, 0]
    part = U @ (U.T @ r)
    red = float(part @ part)
    fitted = part if floor.sigma is None else part * floor.sigma
    dof = len(r) - fit.rank - q
    if q == 0 or dof < 1:
        return ColumnTest(q, float("nan"), "", dof, float("nan"), None, float("nan"), fitted)
    f = (red / q) / (max(float(r @ r) - red, np.finfo(float).tiny) / dof)
    p_resid = float(f_sf(f, q, dof))
    if floor.sigma is not None:
        p_floor = float(chi2_sf(red, q))
        return ColumnTest(q, red, "chi2", None, max(p_floor, p_resid), p_floor, p_resid, fitted)
    if floor.kind == "replicates":
        fr = (red / q) / (floor.pure_ss / floor.pure_dof)
        p_floor = float(f_sf(fr, q, floor.pure_dof))
        return ColumnTest(q, fr, "F", floor.pure_dof, max(p_floor, p_resid), p_floor, p_resid, fitted)
    return ColumnTest(q, f, "F", dof, p_resid, None, p_resid, fitted)


def direction_polynomials(u: np.ndarray, degree: int) -> np.ndarray:
    """The monomials u_x^a·u_y^b·u_z^c of the unit vectors ``u`` (n, 3) with 1 ≤ a + b + c ≤ ``degree``: on the
    sphere their span is that of the spherical harmonics of degrees 0 to ``degree`` (the sphere's relation
    |u|² = 1 makes some of them dependent, which the test's rank takes care of)."""
    cols = []
    for d in range(1, degree + 1):
        for e in _exponents(d):
            cols.append(np.prod(u ** np.array(e), axis=1))
    return np.column_stack(cols)


def _exponents(d: int) -> list[tuple[int, int, int]]:
    return [(a, b, d - a - b) for a in range(d, -1, -1) for b in range(d - a, -1, -1)]


def independent_frequencies(t: np.ndarray) -> tuple[float, float, int]:
    """(lowest, highest frequency in Hz, how many independent ones lie between): from one cycle over the span to
    half the median spacing of the positions (the periodogram's effective number: Horne & Baliunas 1986)."""
    ts = np.sort(np.asarray(t, float))
    span = float(ts[-1] - ts[0])
    spacing = float(np.median(np.diff(ts))) if len(ts) > 1 else 0.0
    if span <= 0 or spacing <= 0:
        return 0.0, 0.0, 0
    f_lo, f_hi = 1.0 / span, 0.5 / spacing
    return f_lo, f_hi, max(int(np.ceil(span * (f_hi - f_lo))), 0)


def periodograms(fit, t: np.ndarray, floor: Floor) -> dict | None:
    """Lomb–Scargle periodograms (scipy.signal.lombscargle, weighted, floating mean) of the residuals and of each
    axis' share of them (module docstring), on an oversampled grid: {freqs_hz, powers (4, F), series names,
    peaks (Hz, one per series), n_independent}."""
    from scipy.signal import lombscargle

    f_lo, f_hi, n_ind = independent_frequencies(t)
    if n_ind < 2:
        return None
    n = fit.problem.n_position_residuals
    r = fit.residuals[:n]
    A = fit.specific_force
    u = A / np.linalg.norm(A, axis=1, keepdims=True)
    w0 = 1.0 / floor.sigma**2 if floor.sigma is not None else np.ones(n)
    freqs = np.linspace(f_lo, f_hi, OVERSAMPLE * n_ind + 1)
    dt = np.asarray(t, float) - float(t[0])
    series = [("residual", r, w0)]
    for i, a in enumerate("xyz"):
        ok = np.abs(u[:, i]) > 1e-3
        y = np.where(ok, r / np.where(ok, u[:, i], 1.0), 0.0)
        series.append((f"{a} axis", y, w0 * np.where(ok, u[:, i] ** 2, 0.0)))
    powers, peaks = [], []
    for _, y, w in series:
        p = lombscargle(dt, y, 2.0 * np.pi * freqs, weights=w / w.sum(), floating_mean=True, normalize=True)
        powers.append(p)
        k = int(np.argmax(p))
        if 0 < k < len(p) - 1:  # the vertex of the parabola through the peak and its neighbours
            a, b, c = p[k - 1], p[k], p[k + 1]
            den = a - 2 * b + c
            shift = 0.5 * (a - c) / den if den < 0 else 0.0
            peaks.append(float(freqs[k] + shift * (freqs[1] - freqs[0])))
        else:
            peaks.append(float(freqs[k]))
    return {"freqs_hz": freqs, "powers": np.array(powers), "series": [s[0] for s in series], "peaks_hz": peaks,
            "n_independent": n_ind}


def candidate_periods(pg: dict | None, span: float) -> tuple[float, ...]:
    """The periodograms' peaks as periods in s (3 significant digits), one per peak closer than half a
    frequency bin merged."""
    if pg is None:
        return ()
    out: list[float] = []
    for f in sorted(pg["peaks_hz"]):
        if not out or f - out[-1] > 0.5 / span:
            out.append(f)
    return tuple(float(f"{1.0 / f:.3g}") for f in out)


def diagnose(fit, data, floor: Floor, alpha: float, ctx) -> Diagnostics:
    """Every diagnostic of the module docstring on ``fit``'s residuals (``ctx``: the offsets of every position,
    :func:`optcal.core.discovery.dictionary.feature_context`)."""
    n = fit.problem.n_position_residuals
    A = fit.specific_force
    u = A / np.linalg.norm(A, axis=1, keepdims=True)
    room = n - fit.rank
    items: list[Diagnostic] = []

    def run(name, columns, G, x, **extra):
        if G is None:
            items.append(Diagnostic(name, columns, note=extra.pop("note"), extra=extra))
            return
        t = column_test(fit, floor, G)
        if t.q == 0 or not np.isfinite(t.p):
            why = "the model explains these columns already" if t.q == 0 else "no degrees of freedom left"
            items.append(Diagnostic(name, columns, note=why, x=x, extra=extra))
            return
        extra.update(p_floor=t.p_floor, p_residual=t.p_residual)
        items.append(Diagnostic(name, columns, t.q, t.statistic, t.test, t.dof, t.p, x=x, fitted=t.fitted, extra=extra))

    # orientation: the highest degree (4, what the dictionary's third-order features look like through the norm,
    # down to 2) whose columns beyond the model leave the test MIN_TEST_DOF or a third of the residuals' degrees
    # of freedom (a model with scale, bias and misalignment spans the degrees up to 2 already: the rank counts
    # what is left)
    for degree in range(ORIENTATION_DEGREE, 1, -1):
        G = direction_polynomials(u, degree)
        if room - column_test(fit, floor, G).q >= max(MIN_TEST_DOF, room // 3):
            break
    run("orientation", f"polynomials of the direction to degree {degree} (spherical harmonics of degrees 1–{degree})",
        G, np.degrees(np.arctan2(u[:, 1], u[:, 0])))
    if ctx.dtemp is not None and np.ptp(ctx.dtemp) > 0:
        th = ctx.dtemp / nice_scale(float(np.std(ctx.dtemp)))
        G = np.column_stack([u * th[:, None] ** k for k in (1, 2, 3)] + [u * A * th[:, None]])
        run("temperature", "â_i·θ, θ², θ³ and â_i·A_i·θ", G, ctx.dtemp + float(np.mean(data.temp)))
    else:
        run("temperature", "", None, None, note="no temperature column" if ctx.dtemp is None else
            "the temperature does not change")
    if ctx.dt is not None and np.ptp(ctx.dt) > 0:
        tau = ctx.dt / nice_scale(float(np.std(ctx.dt)))
        run("time trend", "â_i·τ, τ², τ³", np.column_stack([u * tau[:, None] ** k for k in (1, 2, 3)]),
            np.asarray(data.t, float))
        _periodicity(fit, data, floor, u, items)
    else:
        why = "no time column" if ctx.dt is None else "the time does not change"
        run("time trend", "", None, None, note=why)
        run("periodicity", "", None, None, note=why)
    signs = previous_signs(A.T).T  # (n, 3)
    run("order", "â_i·sgn(A_k of the previous pose)",
        np.column_stack([u[:, [i]] * signs for i in range(3)]), np.arange(n))
    d = None if data.n_samples is None else np.asarray(data.n_samples, float)
    if d is not None and np.ptp(d) > 0:
        med = float(np.median(d))
        run("duration", "â_i·(d/d̄ − 1) and â_i·(d̄/d − 1), d the samples averaged",
            np.column_stack([u * (d / med - 1.0)[:, None], u * (med / d - 1.0)[:, None]]), d)
    else:
        run("duration", "", None, None, note="no n column" if d is None else "every position has as many samples")
    k = sum(x.tested for x in items)
    for x in items:
        x.significant = x.tested and x.p_value < alpha / max(k, 1)
    pg = next((x.extra.pop("periodogram") for x in items if "periodogram" in x.extra), None)
    return Diagnostics(items, floor, alpha, pg)


def _periodicity(fit, data, floor: Floor, u: np.ndarray, items: list) -> None:
    """The periodicity diagnostic: each periodogram's peak tested as a sinusoid (on the residual, or on one
    axis' bias), the best p-value turned into a false-alarm probability over the frequencies searched."""
    times = np.asarray(data.t, float)
    pg = periodograms(fit, times, floor)
    if pg is None:
        items.append(Diagnostic("periodicity", "", note="too few distinct times"))
        return
    dt = times - times[0]
    best = None
    for name, f in zip(pg["series"], pg["peaks_hz"]):
        s, c = np.sin(2 * np.pi * f * dt), np.cos(2 * np.pi * f * dt)
        scale = np.ones(len(times)) if name == "residual" else u[:, "xyz".index(name[0])]
        t = column_test(fit, floor, np.column_stack([scale * s, scale * c]))
        if t.q and np.isfinite(t.p) and (best is None or t.p < best[1].p):
            best = (name, t, f)
    M = 4 * pg["n_independent"]
    if best is None:
        items.append(Diagnostic("periodicity", "", note="the model explains the sinusoids already"))
        return
    name, test, f = best

    def alarm(p):
        return None if p is None else float(-np.expm1(M * np.log1p(-min(p, 1 - 1e-16))))

    fap = alarm(test.p)
    items.append(Diagnostic("periodicity", "Lomb–Scargle periodograms of the residual and each axis' share", test.q,
                            test.statistic, test.test, test.dof, fap, x=times, fitted=test.fitted,
                            extra={"period_s": 1.0 / f, "false_alarm": fap, "p_single": test.p, "series": name,
                                   "n_independent": pg["n_independent"], "periodogram": pg,
                                   "p_floor": alarm(test.p_floor), "p_residual": alarm(test.p_residual)}))
